"""Old import path of :mod:`quatarray.app.cli` (the same module object)."""

import importlib
import sys

sys.modules[__name__] = importlib.import_module("quatarray.app.cli")
