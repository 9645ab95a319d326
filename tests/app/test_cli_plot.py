"""The command line: the plot verb (in-process through ``main([...])``, a few as
``python -m quatarray`` subprocesses)."""

import os
import subprocess
import sys
import types

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

import quatarray as qa
from quatarray.app.cli import main

from cli_common import _leftovers, cli, unit  # noqa: E402


def test_plot_refuses_a_bad_seq(capsys, tmp_path):
    pytest.importorskip("matplotlib")
    np.save(tmp_path / "q.npy", unit(np.random.default_rng(11), 10))
    rc, _, err = cli(capsys, "plot", tmp_path / "q.npy", tmp_path / "p.png", "--seq", "ABC")
    assert rc == 2 and err.startswith("quatarray plot: error: --seq ABC: SEQ is three axes")
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "p.png").exists()


@pytest.mark.parametrize("ext, magic", [("pdf", b"%PDF"), ("svg", b"<?xml"), ("jpg", b"\xff\xd8"),
                                        ("png", b"\x89PNG")])
def test_plot_writes_the_format_its_extension_names(capsys, tmp_path, ext, magic):
    pytest.importorskip("matplotlib")
    np.save(tmp_path / "q.npy", unit(np.random.default_rng(15), 10))
    out = tmp_path / f"p.{ext}"
    old = os.umask(0o022)
    try:
        assert cli(capsys, "plot", tmp_path / "q.npy", out)[0] == 0
    finally:
        os.umask(old)
    assert out.read_bytes().startswith(magic) and out.stat().st_mode & 0o777 == 0o644
    assert _leftovers(tmp_path) == []


def test_plot_refuses_an_unknown_extension(capsys, tmp_path):
    pytest.importorskip("matplotlib")
    np.save(tmp_path / "q.npy", unit(np.random.default_rng(16), 10))
    rc, _, err = cli(capsys, "plot", tmp_path / "q.npy", tmp_path / "p.xyz")
    assert rc == 2 and "cannot tell the image format from the extension '.xyz'" in err and ".pdf" in err
    assert not (tmp_path / "p.xyz").exists() and _leftovers(tmp_path) == []


def test_plot_speed_per_row_without_times(capsys, tmp_path):
    matplotlib = pytest.importorskip("matplotlib")
    np.save(tmp_path / "q.npy", unit(np.random.default_rng(17), 10))
    with matplotlib.rc_context({"svg.fonttype": "none"}):  # text kept as text
        assert cli(capsys, "plot", tmp_path / "q.npy", tmp_path / "p.svg")[0] == 0
    svg = (tmp_path / "p.svg").read_text()
    assert "angular speed (deg/row)" in svg and "deg/s" not in svg
