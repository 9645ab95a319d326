"""Old import path of :mod:`quatarray.app.eval_verb` (the same module object)."""

import importlib
import sys

sys.modules[__name__] = importlib.import_module("quatarray.app.eval_verb")
