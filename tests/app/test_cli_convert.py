"""The command line: the convert verb (in-process through ``main([...])``, a few as
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

from cli_common import _leftovers, _peak_kib, cli, read_csv, rot, run, same_rotation, smooth_stream, unit  # noqa: E402


TARGETS = [
    ("quat", False, lambda r: r.as_quat(scalar_first=True)),
    ("xyzw", False, lambda r: r.as_quat()),
    ("matrix", False, lambda r: r.as_matrix()),
    ("rotvec", False, lambda r: r.as_rotvec()),
    ("rotvec", True, lambda r: r.as_rotvec(degrees=True)),
    ("euler:ZXY", True, lambda r: r.as_euler("ZXY", degrees=True)),
    ("euler:xyz", False, lambda r: r.as_euler("xyz")),
]


@pytest.mark.parametrize("to, degrees, ref", TARGETS, ids=[f"{t}{'-deg' if d else ''}" for t, d, _ in TARGETS])
def test_convert_npy_vs_scipy(capsys, tmp_path, rng, to, degrees, ref):
    q = unit(rng, 100)
    np.save(tmp_path / "q.npy", q)
    out = tmp_path / "o.npy"
    rc, _, err = cli(capsys, "convert", tmp_path / "q.npy", out, "--to", to, "--chunk", 7,
                     *(["--degrees"] if degrees else []))
    assert rc == 0, err
    got, want = np.load(out), ref(rot(q))
    if to in ("quat", "xyzw"):
        w = got[:, 0] if to == "quat" else got[:, 3]
        got = got * np.sign(w)[:, None]
        want = want * np.sign(want[:, 0] if to == "quat" else want[:, 3])[:, None]
    np.testing.assert_allclose(got, want, atol=1e-10)


def test_convert_csv_keeps_time_and_position(capsys, stream, tmp_path):
    path, t, pos, q = stream
    rc, _, err = cli(capsys, "convert", path, tmp_path / "o.csv", "--to", "matrix")
    assert rc == 0, err
    assert "normalised 60 non-unit quaternions" in err
    got = read_csv(tmp_path / "o.csv")
    assert list(got) == ["t", "x", "y", "z"] + [f"r{i}{j}" for i in range(3) for j in range(3)]
    np.testing.assert_array_equal(got["t"], t)
    np.testing.assert_array_equal(np.column_stack([got["x"], got["y"], got["z"]]), pos)
    m = np.column_stack([got[f"r{i}{j}"] for i in range(3) for j in range(3)]).reshape(-1, 3, 3)
    np.testing.assert_allclose(m, rot(q).as_matrix(), atol=1e-12)


def test_convert_parquet_and_tum_outputs(capsys, stream, tmp_path):
    path, t, pos, q = stream
    assert cli(capsys, "convert", path, tmp_path / "o.parquet", "--to", "quat")[0] == 0
    assert cli(capsys, "convert", tmp_path / "o.parquet", tmp_path / "o.txt", "--to", "quat")[0] == 0
    back = np.loadtxt(tmp_path / "o.txt")
    np.testing.assert_array_equal(back[:, 0], t)
    np.testing.assert_array_equal(back[:, 1:4], pos)
    assert same_rotation(back[:, [7, 4, 5, 6]], q / np.linalg.norm(q, axis=1)[:, None], 1e-12)


def test_convert_real_bvh_subprocess(data_dir, tmp_path):
    out = tmp_path / "walk.csv"
    res = run("convert", data_dir / "mocapbank_walk.bvh", out, "--to", "euler:ZXY", "--degrees")
    assert res.returncode == 0, res.stderr
    got = read_csv(out)
    assert list(got)[:4] == ["t", "x", "y", "z"]
    lines = (data_dir / "mocapbank_walk.bvh").read_text().splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.startswith("Frame Time")) + 1
    motion = np.array([ln.split() for ln in lines[start:] if ln.strip()], float)
    ang = np.column_stack([got["e1_Z"], got["e2_X"], got["e3_Y"]])
    a = Rotation.from_euler("ZXY", ang, degrees=True)
    b = Rotation.from_euler("ZXY", motion[:, 3:6], degrees=True)
    np.testing.assert_allclose((a.inv() * b).magnitude(), 0, atol=1e-9)
    np.testing.assert_array_equal(got["x"], motion[:, 0])


@pytest.mark.slow
def test_bounded_memory_conversion(tmp_path):
    """A 2·10⁶-row npy (61 MiB in, 137 MiB out as matrices) converts with a few MiB above the
    interpreter's own footprint: only a few chunks are ever mapped or held."""
    n = 2_000_000
    mm = np.lib.format.open_memmap(tmp_path / "big.npy", "w+", np.float64, (n, 4))
    mm[:] = [0.5, 0.5, 0.5, 0.5]
    mm[::7] = [0, 0, 0, 1]
    del mm
    np.save(tmp_path / "tiny.npy", np.array([[1.0, 0, 0, 0]]))
    base = _peak_kib("convert", tmp_path / "tiny.npy", tmp_path / "tiny_o.npy", "--to", "matrix")
    peak = _peak_kib("convert", tmp_path / "big.npy", tmp_path / "o.npy", "--to", "matrix", "--chunk", 65536)
    grown = (peak - base) / 1024
    assert grown < 40, f"peak RSS grew by {grown:.0f} MiB over the {base / 1024:.0f} MiB baseline"
    out = np.load(tmp_path / "o.npy", mmap_mode="r")
    assert out.shape == (n, 3, 3)
    np.testing.assert_allclose(out[-1], rot([0.5, 0.5, 0.5, 0.5]).as_matrix(), atol=1e-15)
    np.testing.assert_allclose(out[7], rot([0, 0, 0, 1]).as_matrix(), atol=1e-15)


def test_tum_output(capsys, tmp_path):
    t, pos, q = smooth_stream(np.random.default_rng(19), 30)
    np.savetxt(tmp_path / "s.csv", np.column_stack([t, pos, q]), delimiter=",",
               header="t,x,y,z,qw,qx,qy,qz", comments="", fmt="%.17g")
    rc, _, err = cli(capsys, "unflip", tmp_path / "s.csv", tmp_path / "o.tum")
    assert rc == 0, err
    lines = (tmp_path / "o.tum").read_text().splitlines()
    assert lines[0] == "# timestamp tx ty tz qx qy qz qw" and len(lines) == 31
    got = np.loadtxt(tmp_path / "o.tum")
    np.testing.assert_array_equal(got[:, 0], t)
    np.testing.assert_allclose(got[:, 1:4], pos)
    assert same_rotation(got[:, [7, 4, 5, 6]], q / np.linalg.norm(q, axis=1)[:, None])
    # and it reads back as a TUM stream
    rc, out, _ = cli(capsys, "info", tmp_path / "o.tum")
    assert rc == 0 and "tum" in out


def test_tum_output_refusals_say_what_is_wrong(capsys, tmp_path):
    t, pos, q = smooth_stream(np.random.default_rng(20), 10)
    np.savetxt(tmp_path / "s.csv", np.column_stack([t, pos, q]), delimiter=",",
               header="t,x,y,z,qw,qx,qy,qz", comments="", fmt="%.17g")
    rc, _, err = cli(capsys, "convert", tmp_path / "s.csv", tmp_path / "o.tum", "--to", "xyzw")
    assert rc == 2 and "holds quaternions only" in err and "--to xyzw" in err and "--to quat" in err
    np.save(tmp_path / "q.npy", q)  # no times, no positions
    rc, _, err = cli(capsys, "unflip", tmp_path / "q.npy", tmp_path / "o.tum")
    assert rc == 2 and "needs times and positions; this stream has no times and no positions" in err
    assert _leftovers(tmp_path) == []


def test_convert_bvh_to_positions(capsys, tmp_path):
    import pyarrow.csv as pcsv
    import pyarrow.parquet as pq

    from quatarray import io
    from quatarray.io import sample_path

    clip = io.read_bvh(sample_path())
    _, p = clip.world()
    for name in ("p.npy", "p.csv", "p.parquet"):
        rc, _, err = cli(capsys, "convert", sample_path(), tmp_path / name, "--to", "positions")
        assert rc == 0, err
    np.testing.assert_array_equal(np.load(tmp_path / "p.npy"), p)
    for table in (pcsv.read_csv(tmp_path / "p.csv"), pq.read_table(tmp_path / "p.parquet")):
        assert table.column_names == ["t", "joint", "x", "y", "z"]
        assert table.num_rows == clip.frames * len(clip.joints)
        assert [str(j) for j in table.column("joint").to_pylist()[:2]] == ["Hips", "Chest"]
        xyz = np.column_stack([table.column(c).to_numpy() for c in "xyz"])
        np.testing.assert_array_equal(xyz, p.reshape(-1, 3))
        np.testing.assert_array_equal(table.column("t").to_numpy()[::len(clip.joints)], clip.times)
    rc, _, err = cli(capsys, "convert", tmp_path / "p.npy", tmp_path / "x.npy", "--to", "positions")
    assert rc == 2 and "BVH" in err
