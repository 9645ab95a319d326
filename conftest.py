"""The test run on every core (the README's ``python -m pytest -n auto``).

pytest-xdist's workers, and every process they start (the command line, the
warm-up's workers, Dask's), share numba's on-disk cache, whose index update is
not atomic across processes: ``QUATARRAY_CACHE_LOCK`` makes each of their
cache writes hold an exclusive lock on one file (see ``quatarray._jit``), here
one in the checkout (ignored by git). Set before any test module imports
quatarray, in this file at the root so that it holds whatever paths are run.
"""

import os
import pathlib

if os.environ.get("PYTEST_XDIST_TESTRUNUID") and not os.environ.get("QUATARRAY_CACHE_LOCK"):
    os.environ["QUATARRAY_CACHE_LOCK"] = str(pathlib.Path(__file__).resolve().parent / ".quatarray-tests.lock")

# the app's old module paths (quatarray/cli.py & co.) only alias quatarray.app's modules,
# whose doctests run there
collect_ignore = [f"quatarray/{m}.py" for m in ("cli", "demo", "bench", "plot", "evaluate")]
