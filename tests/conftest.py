"""Shared test fixtures."""

import pathlib

import numpy as np
import pytest

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
