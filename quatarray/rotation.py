"""Old import path of :mod:`quatarray.vectors` (the same module object)."""

import importlib
import sys

sys.modules[__name__] = importlib.import_module("quatarray.vectors")
