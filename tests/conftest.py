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
    from quatarray import _jit

    if _jit.CHECK_BOUNDS:  # the debug mode turns off what these tests check
        reasons = {"needs_cache": "QUATARRAY_CHECK_BOUNDS=1 keeps numba's on-disk cache off",
                   "needs_simd": "QUATARRAY_CHECK_BOUNDS=1: the bounds checks keep loops from vectorising"}
        for item in items:
            for name, why in reasons.items():
                if item.get_closest_marker(name):
                    item.add_marker(pytest.mark.skip(reason=why))


# tests/typing holds scripts for the type checker (tests/test_typing.py), not tests:
# one of them fails on purpose when run
collect_ignore_glob = ["typing/*"]


def _scipy_rotation_refused(exc):
    """True for the TypeError of a scipy older than a test's oracle needs: its
    ``Rotation`` refusing a keyword that newer releases take (``scalar_first=`` before
    scipy 1.14; ``mean(axis=)``, ``from_matrix(assume_valid=)`` later). quatarray's own
    functions of the same name take the keyword, so the refusal is not theirs."""
    import inspect
    import re

    from scipy.spatial.transform import Rotation

    import quatarray

    if isinstance(exc, AttributeError) and re.fullmatch(
            r"(?:type object )?'[\w.]*Rotation'(?: object)? has no attribute '(\w+)'", str(exc)):
        return True  # a method of a newer scipy (from_davenport: 1.12), the oracle's, not ours
    if isinstance(exc, TypeError):
        msg = str(exc)
        if msg.startswith("Rotation.") and "takes no keyword arguments" in msg:  # Cython's words (scipy < 1.14)
            return True
        m = re.match(r"(?:Rotation\.)?(\w+)\(\) got an unexpected keyword argument '(\w+)'", msg)
        if m and hasattr(Rotation, m[1]):
            ours = getattr(quatarray, m[1], None)
            if ours is None or m[2] in inspect.signature(ours).parameters:
                return True
    if isinstance(exc, ValueError) and _raised_in_scipy_rotation(exc):
        import scipy

        from quatarray._compat import scipy_nd_stacks

        if "to have shape (4,) or (N, 4)" in str(exc) and not scipy_nd_stacks():
            return True  # the oracle is a stack of more dimensions (scipy 1.17)
        # before 1.14 Rotation took fewer shapes (align_vectors of one pair of (3,) vectors)
        return tuple(int(x) for x in scipy.__version__.split(".")[:2]) < (1, 14)
    return any(_scipy_rotation_refused(e) for e in getattr(exc, "exceptions", ()))


def _raised_in_scipy_rotation(exc):
    tb = exc.__traceback__
    while tb is not None and tb.tb_next is not None:
        tb = tb.tb_next
    if tb is None:
        return False
    code = tb.tb_frame.f_code
    return "scipy.spatial.transform" in code.co_name or "_rotation.pyx" in code.co_filename


@pytest.hookimpl(wrapper=True)
def pytest_pyfunc_call(pyfuncitem):
    """A test whose oracle is a newer scipy's ``Rotation`` (a keyword the installed
    scipy lacks: the floor's 1.11, or Python 3.10's newest 1.15) skips, saying so,
    instead of failing."""
    try:
        return (yield)
    except BaseException as exc:
        if _scipy_rotation_refused(exc):
            import scipy

            pytest.skip(f"the oracle needs a newer scipy than {scipy.__version__} ({exc})")
        raise


@pytest.hookimpl(wrapper=True)
def pytest_fixture_setup(fixturedef, request):
    """A fixture built with a newer scipy's ``Rotation`` (see :func:`pytest_pyfunc_call`)
    skips its tests on an older scipy, saying so."""
    try:
        return (yield)
    except BaseException as exc:
        if _scipy_rotation_refused(exc):
            import scipy

            pytest.skip(f"the fixture needs a newer scipy than {scipy.__version__} ({exc})")
        raise

