"""``python -m quatarray``: the command line (see :mod:`quatarray.app.cli`)."""

import sys

from .app.cli import main

sys.exit(main())
