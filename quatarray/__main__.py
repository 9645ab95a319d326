"""``python -m quatarray``: the command line (see :mod:`quatarray.cli`)."""

import sys

from .cli import main

sys.exit(main())
