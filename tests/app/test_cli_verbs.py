"""The command line: unflip, rotate, compose and info (in-process through ``main([...])``, a few as
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

from cli_common import cli, read_csv, rot, same_rotation, unit, write_csv  # noqa: E402


def test_unflip_keeps_columns(capsys, stream, tmp_path):
    path, t, pos, q = stream
    rc, _, err = cli(capsys, "unflip", path, tmp_path / "o.csv", "--chunk", 3)
    assert rc == 0, err
    got = read_csv(tmp_path / "o.csv")
    u = np.column_stack([got[c] for c in ("qw", "qx", "qy", "qz")])
    assert (np.sum(u[1:] * u[:-1], axis=1) > 0).all()
    qn = q / np.linalg.norm(q, axis=1)[:, None]
    np.testing.assert_allclose(np.abs(u), np.abs(qn), atol=1e-15)
    np.testing.assert_allclose(u[0], qn[0], atol=1e-15)
    np.testing.assert_array_equal(got["t"], t)
    np.testing.assert_array_equal(got["z"], pos[:, 2])


def test_rotate_vs_scipy_and_broadcast(capsys, tmp_path, rng):
    q, v = unit(rng, 50), rng.standard_normal((50, 3))
    np.save(tmp_path / "q.npy", q)
    np.save(tmp_path / "v.npy", v)
    rc, _, err = cli(capsys, "rotate", tmp_path / "q.npy", tmp_path / "v.npy", tmp_path / "o.npy", "--chunk", 16)
    assert rc == 0, err
    np.testing.assert_allclose(np.load(tmp_path / "o.npy"), rot(q).apply(v), atol=1e-12)
    write_csv(tmp_path / "v1.csv", q=v[:1])
    rc, _, err = cli(capsys, "rotate", tmp_path / "q.npy", tmp_path / "v1.csv", tmp_path / "o.csv")
    assert rc == 0, err
    got = read_csv(tmp_path / "o.csv")
    np.testing.assert_allclose(np.column_stack([got["x"], got["y"], got["z"]]), rot(q).apply(v[0]), atol=1e-12)
    np.save(tmp_path / "v9.npy", v[:9])
    rc, _, err = cli(capsys, "rotate", tmp_path / "q.npy", tmp_path / "v9.npy", tmp_path / "o2.npy", "--chunk", 4)
    assert rc == 1 and "has 50 rows but" in err and "has 9" in err
    assert not (tmp_path / "o2.npy").exists()


def test_rotate_drop_pairs(capsys, tmp_path, rng):
    q, v = unit(rng, 6), rng.standard_normal((6, 3))
    q[2] = 0
    v[4] = np.nan
    np.save(tmp_path / "q.npy", q)
    np.save(tmp_path / "v.npy", v)
    rc, _, err = cli(capsys, "rotate", tmp_path / "q.npy", tmp_path / "v.npy", tmp_path / "o.npy")
    assert rc == 1 and "q.npy: row 2: zero quaternion" in err
    rc, _, err = cli(capsys, "rotate", tmp_path / "q.npy", tmp_path / "v.npy", tmp_path / "o.npy",
                     "--on-invalid", "drop")
    assert rc == 0 and "dropped 2 invalid rows" in err
    keep = [0, 1, 3, 5]
    np.testing.assert_allclose(np.load(tmp_path / "o.npy"), rot(q[keep]).apply(v[keep]), atol=1e-12)


def test_compose_vs_scipy(capsys, tmp_path, rng):
    a, b = unit(rng, 40), unit(rng, 40)
    np.save(tmp_path / "a.npy", a)
    np.save(tmp_path / "b.npy", b)
    rc, _, err = cli(capsys, "compose", tmp_path / "a.npy", tmp_path / "b.npy", tmp_path / "o.npy", "--chunk", 16)
    assert rc == 0, err
    assert same_rotation(np.load(tmp_path / "o.npy"), (rot(a) * rot(b)).as_quat(scalar_first=True), 1e-12)
    np.save(tmp_path / "one.npy", b[:1])
    rc, _, err = cli(capsys, "compose", tmp_path / "one.npy", tmp_path / "a.npy", tmp_path / "o1.npy")
    assert rc == 0, err
    assert same_rotation(np.load(tmp_path / "o1.npy"), (rot(b[0]) * rot(a)).as_quat(scalar_first=True), 1e-12)


def test_compose_poses(capsys, tmp_path, rng):
    t = np.arange(5.0)
    qa_, qb = unit(rng, 5), unit(rng, 5)
    pa, pb = rng.standard_normal((5, 3)), rng.standard_normal((5, 3))
    write_csv(tmp_path / "a.csv", t, pa, qa_)
    write_csv(tmp_path / "b.csv", t, pb, qb)
    rc, _, err = cli(capsys, "compose", tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "o.csv")
    assert rc == 0, err
    got = read_csv(tmp_path / "o.csv")
    pos = np.column_stack([got["x"], got["y"], got["z"]])
    np.testing.assert_allclose(pos, pa + rot(qa_).apply(pb), atol=1e-12)
    q = np.column_stack([got[c] for c in ("qw", "qx", "qy", "qz")])
    assert same_rotation(q, (rot(qa_) * rot(qb)).as_quat(scalar_first=True), 1e-12)
    np.testing.assert_array_equal(got["t"], t)


def test_info(capsys, stream):
    path, t, pos, q = stream
    rc, out, err = cli(capsys, "info", path)
    assert rc == 0, err
    fields = dict(line.split(":", 1) for line in out.splitlines())
    assert fields["rows"].strip() == "60"
    assert fields["columns"].split() == ["t", "x", "y", "z", "qw", "qx", "qy", "qz"]
    flips = int(np.count_nonzero(np.sum(q[1:] * q[:-1], axis=1) < 0))
    assert fields["sign flips"].split()[0] == str(flips) and flips > 0
    rate = float(fields["rate"].split()[0])
    assert rate == pytest.approx(59 / (t[-1] - t[0]), rel=1e-5)
    assert "strictly increasing" in fields["rate"]
    n = np.linalg.norm(q, axis=1)
    assert f"{n.min():.9g}" in fields["norm"] and f"{n.max():.9g}" in fields["norm"]
    assert fields["invalid rows"].strip() == "0"


def test_info_real_files(capsys, data_dir):
    rc, out, _ = cli(capsys, "info", data_dir / "euroc_v102_groundtruth.csv")
    assert rc == 0 and "format:       euroc" in out and "200 Hz" in out
    rc, out, _ = cli(capsys, "info", data_dir / "mocapbank_walk.bvh", "--joint", "LeftKnee")
    assert rc == 0 and "LeftKnee.Zrotation" in out


def test_info_one_row(capsys, tmp_path):
    (tmp_path / "one.csv").write_text("t,qw,qx,qy,qz\n0.5,1,0,0,0\n")
    rc, out, _ = cli(capsys, "info", tmp_path / "one.csv")
    assert rc == 0 and "rate:" in out
    rate = next(ln for ln in out.splitlines() if ln.startswith("rate:"))
    assert rate.split(":", 1)[1].strip() == "- (one row)"
    body = out.split("\n", 1)[1]  # after the file line (its path may hold "inf")
    assert "nan" not in body and "inf" not in body


def test_info_bvh_lists_hierarchy(capsys, data_dir):
    rc, out, err = cli(capsys, "info", data_dir / "free_mocap.bvh")
    assert rc == 0, err
    assert "rows:" in out and "hierarchy: 70 joints (15 end sites, 1 root)" in out
    assert "\n  mixamorig:Hips  ZYX + XYZ position\n    mixamorig:Spine  ZYX\n" in out
