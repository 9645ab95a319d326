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
