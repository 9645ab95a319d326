"""Fixtures of the command-line tests."""

import pathlib
import sys

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).parent))  # cli_common, also when imported for doctests

from cli_common import _tum, smooth_stream, write_csv  # noqa: E402


@pytest.fixture
def stream(tmp_path, rng):
    t, pos, q = smooth_stream(rng)
    return write_csv(tmp_path / "s.csv", t, pos, q), t, pos, q


@pytest.fixture
def several(tmp_path, rng):
    """Three TUM files a.txt, b.txt, c.txt in tmp_path/in, and their quaternions."""
    (tmp_path / "in").mkdir()
    return {k: _tum(tmp_path / "in" / f"{k}.txt", rng) for k in "abc"}
