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


@pytest.hookimpl(trylast=True)  # after -k and -m have deselected
def pytest_collection_modifyitems(session, config, items):
    """The longest test (the interpreted pass, two minutes on one core) first, so that
    one worker runs it while the others take the rest."""
    first = [item for item in items if item.nodeid.endswith("test_kernels_as_plain_python")]
    items[:] = first + [item for item in items if item not in first]


def _scipy_has_scalar_first():
    from scipy.spatial.transform import Rotation

    try:
        Rotation.identity().as_quat(scalar_first=True)
    except TypeError:
        return False
    return True


SCIPY_SCALAR_FIRST = _scipy_has_scalar_first()


def _needs_scalar_first(exc):
    """True for the TypeError of an older scipy's Rotation given ``scalar_first=``."""
    if isinstance(exc, TypeError) and ("scalar_first" in str(exc) or "takes no keyword arguments" in str(exc)):
        return True
    return any(_needs_scalar_first(e) for e in getattr(exc, "exceptions", ()))


@pytest.hookimpl(wrapper=True)
def pytest_pyfunc_call(pyfuncitem):
    """On scipy < 1.14 (the floor), a test whose oracle is scipy's ``Rotation`` with
    ``scalar_first=`` skips, saying so, instead of failing."""
    try:
        return (yield)
    except BaseException as exc:
        if not SCIPY_SCALAR_FIRST and _needs_scalar_first(exc):
            import scipy

            pytest.skip(f"the oracle needs scipy >= 1.14 (Rotation's scalar_first=), scipy {scipy.__version__} here")
        raise
