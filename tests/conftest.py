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


# tests/typing holds scripts for the type checker (tests/test_typing.py), not tests:
# one of them fails on purpose when run
collect_ignore_glob = ["typing/*"]
