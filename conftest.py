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

# the old module paths that only alias another module (quatarray/cli.py & co. quatarray.app's,
# quatarray/rotation.py quatarray.vectors), whose doctests run there
collect_ignore = [f"quatarray/{m}.py" for m in ("cli", "demo", "bench", "plot", "evaluate", "rotation")]
import pytest  # noqa: E402


_SKIP_DOCTEST = pytest.StashKey[str]()


def _llvm_version():
    from llvmlite import binding

    return tuple(binding.llvm_version_info)


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """On the declared floor: doctests show numpy 2's reprs (``np.float64(0.0)``), so
    they skip on numpy 1; the tests that check a loop's SIMD code (``*vectoris*``) hold
    for LLVM 17 and later (numba 0.60's LLVM 14 leaves some of those loops scalar: the
    same results, slower), so they skip with an older LLVM."""
    import numpy as np

    numpy1 = int(np.__version__.split(".")[0]) < 2
    old_llvm = _llvm_version() < (17,)
    for item in items:
        if numpy1 and type(item).__name__ == "DoctestItem":
            # skipped in pytest_runtest_setup, not by a skip marker: a marker's skip is
            # reported at the item's line, and pytest (8.0 and later) fails with an
            # INTERNALERROR on a doctest without one (a function made by a factory)
            item.stash[_SKIP_DOCTEST] = f"doctest outputs are numpy 2's reprs; numpy {np.__version__} here"
        elif old_llvm and "vectoris" in item.name:
            item.add_marker(pytest.mark.skip(reason="SIMD-code checks hold from LLVM 17 on; LLVM "
                                             + ".".join(map(str, _llvm_version())) + " here"))


def pytest_runtest_setup(item):
    why = item.stash.get(_SKIP_DOCTEST, None)
    if why is not None:
        pytest.skip(why)
