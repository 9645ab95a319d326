"""Shared test fixtures."""

import os
import pathlib

import numpy as np
import pytest
from hypothesis import settings

# Property tests draw the same examples on every run (a landing gate must not
# flip on a lucky draw); QUATARRAY_HYPOTHESIS=explore draws new ones each run.
settings.register_profile("repeatable", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("QUATARRAY_HYPOTHESIS", "repeatable"))

ROOT = pathlib.Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"


@pytest.fixture
def data_dir():
    """The real rotation streams in ../shared/data (skipped on a user's machine)."""
    if not DATA.is_dir():
        pytest.skip(f"real data folder {DATA} is absent (it sits beside the repository in CI)")
    return DATA


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)


# The README's test command runs the suite on every core (pytest-xdist's ``-n auto``).
# The workers share numba's on-disk cache, whose index update is not atomic across
# processes: each worker's cache writes hold an exclusive lock on one file, as the
# warm-up's workers do (one file for every run of a user: runs at once only wait).
if os.environ.get("PYTEST_XDIST_TESTRUNUID"):
    import tempfile

    from quatarray import _warmup

    if _warmup._CAN_LOCK:
        _warmup._locked_cache_writes(os.path.join(tempfile.gettempdir(), f"quatarray-tests-{os.getuid()}.lock"))


@pytest.hookimpl(trylast=True)  # after -k and -m have deselected
def pytest_collection_modifyitems(session, config, items):
    """The longest test (the interpreted pass, two minutes on one core) first, so that
    one worker runs it while the others take the rest."""
    first = [item for item in items if item.nodeid.endswith("test_kernels_as_plain_python")]
    items[:] = first + [item for item in items if item not in first]
