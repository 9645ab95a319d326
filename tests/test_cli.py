"""Tests for the command line: every verb, in-process through ``main([...])`` and,
for a representative few, as ``python -m quatarray`` subprocesses."""

import os
import subprocess
import sys
import types

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

import quatarray as qa
from quatarray.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def cli(capsys, *argv):
    rc = main([str(a) for a in argv] + (["--no-progress"] if _takes_io(argv) else []))
    out, err = capsys.readouterr()
    return rc, out, err


def _takes_io(argv):
    return argv and argv[0] not in ("demo", "bench") and "--progress" not in argv and "--help" not in argv


def run(*argv, **kw):
    """``python -m quatarray ...`` in a subprocess."""
    return subprocess.run(
        [sys.executable, "-m", "quatarray", *map(str, argv)], capture_output=True, text=True, cwd=ROOT, **kw
    )


def rot(q):
    return Rotation.from_quat(np.asarray(q, float), scalar_first=True)


def same_rotation(a, b, atol=1e-9):
    d = np.abs(np.sum(np.asarray(a) * np.asarray(b), axis=-1))
    return np.allclose(d, 1, atol=atol)


def unit(rng, n):
    q = rng.standard_normal((n, 4))
    return q / np.linalg.norm(q, axis=1)[:, None]


def smooth_stream(rng, n=60):
    """A smooth pose stream with uneven times, sign flips and slightly non-unit quaternions."""
    t = np.cumsum(rng.uniform(0.05, 0.15, n))
    q = rot(qa.identity()).as_quat(scalar_first=True)
    rv = np.cumsum(rng.normal(0, 0.15, (n, 3)), axis=0)
    q = Rotation.from_rotvec(rv).as_quat(scalar_first=True)
    q[rng.random(n) < 0.3] *= -1
    q *= rng.uniform(0.9999, 1.0001, (n, 1))
    pos = np.cumsum(rng.normal(0, 0.1, (n, 3)), axis=0)
    return t, pos, q


def write_csv(path, t=None, pos=None, q=None, header=True):
    cols, names = [], []
    if t is not None:
        cols.append(t[:, None])
        names.append("t")
    if pos is not None:
        cols.append(pos)
        names += ["x", "y", "z"]
    cols.append(q)
    names += ["qw", "qx", "qy", "qz"] if q.shape[1] == 4 else ["x", "y", "z"]
    data = np.concatenate(cols, axis=1)
    lines = ([",".join(names)] if header else []) + [",".join(repr(float(v)) for v in row) for row in data]
    path.write_text("\n".join(lines) + "\n")
    return path


def read_csv(path):
    import pyarrow.csv as pcsv

    table = pcsv.read_csv(path)
    return {n: table.column(n).to_numpy() for n in table.column_names}


@pytest.fixture
def stream(tmp_path, rng):
    t, pos, q = smooth_stream(rng)
    return write_csv(tmp_path / "s.csv", t, pos, q), t, pos, q


# --------------------------------------------------------------------------
# parsing and help


def test_help_and_usage(capsys):
    assert main(["--help"]) == 0
    assert "resample" in capsys.readouterr().out
    assert main([]) == 2
    assert main(["convert", "a.npy"]) == 2
    assert "required" in capsys.readouterr().err
    assert main(["resample", "a.npy", "b.npy"]) == 2  # --rate or --times
    assert main(["convert", "a.npy", "b.npy", "--to", "quat", "--chunk", "0"]) == 2
    assert main(["nope"]) == 2


def test_python_m_help_subprocess():
    res = run("--help")
    assert res.returncode == 0 and "convert" in res.stdout
    res = run("convert", "missing.npy", "o.npy", "--to", "quat")
    assert res.returncode == 2
    assert res.stderr.strip() == "quatarray convert: error: missing.npy: no such file"


# --------------------------------------------------------------------------
# convert


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


def test_convert_axis_angle_and_layout(capsys, tmp_path, rng):
    q = unit(rng, 20)
    np.save(tmp_path / "q.npy", q[:, [1, 2, 3, 0]])
    rc, _, err = cli(capsys, "convert", tmp_path / "q.npy", tmp_path / "o.npy", "--to", "axis-angle",
                     "--layout", "xyzw")
    assert rc == 0, err
    got = np.load(tmp_path / "o.npy")
    np.testing.assert_allclose(got[:, :3] * got[:, 3:], rot(q).as_rotvec(), atol=1e-12)


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


# --------------------------------------------------------------------------
# resample


def test_resample_real_tum_slerp_equals_scipy(capsys, data_dir, tmp_path):
    src = data_dir / "tum_freiburg1_xyz_groundtruth.txt"
    rc, _, err = cli(capsys, "resample", src, tmp_path / "o.csv", "--rate", 250, "--method", "slerp",
                     "--chunk", 700)
    assert rc == 0, err
    raw = np.loadtxt(src)
    got = read_csv(tmp_path / "o.csv")
    t = got["t"]
    np.testing.assert_allclose(t, raw[0, 0] + np.arange(t.size) / 250.0, rtol=0, atol=1e-6)
    assert t[-1] <= raw[-1, 0] and t[-1] + 1 / 250 > raw[-1, 0]
    ref = Slerp(raw[:, 0], Rotation.from_quat(raw[:, 4:8]))(t)
    q = np.column_stack([got[c] for c in ("qw", "qx", "qy", "qz")])
    assert same_rotation(q, ref.as_quat(scalar_first=True), 1e-12)
    for k, c in enumerate("xyz"):
        np.testing.assert_allclose(got[c], np.interp(t, raw[:, 0], raw[:, 1 + k]), atol=1e-12)
    # output signs are continuous although the keys were flipped in places
    assert (np.sum(q[1:] * q[:-1], axis=1) > 0).all()


@pytest.mark.parametrize("method", ["bezier", "squad", "nlerp"])
def test_resample_chunked_equals_in_memory(capsys, stream, tmp_path, method):
    path, t, pos, q = stream
    times = np.linspace(t[0], t[-1], 333)
    np.save(tmp_path / "times.npy", times)
    for chunk in (4, 10**6):
        rc, _, err = cli(capsys, "resample", path, tmp_path / f"o{chunk}.npy", "--times", tmp_path / "times.npy",
                         "--method", method, "--chunk", chunk)
        assert rc == 0, err
    small, whole = np.load(tmp_path / "o4.npy"), np.load(tmp_path / f"o{10**6}.npy")
    np.testing.assert_allclose(small, whole, rtol=0, atol=1e-14)
    np.testing.assert_allclose(whole, qa.spline(t, q, times, method=method), rtol=0, atol=1e-14)


def test_resample_npy_needs_in_rate(capsys, tmp_path, rng):
    q = qa.unflip(unit(rng, 30))
    np.save(tmp_path / "q.npy", q)
    rc, _, err = cli(capsys, "resample", tmp_path / "q.npy", tmp_path / "o.npy", "--rate", 4)
    assert rc == 2 and "--in-rate" in err
    rc, _, err = cli(capsys, "resample", tmp_path / "q.npy", tmp_path / "o.csv", "--rate", 4, "--in-rate", 2,
                     "--chunk", 8)
    assert rc == 0, err
    got = read_csv(tmp_path / "o.csv")
    np.testing.assert_allclose(got["t"], np.arange(0, 14.5 * 4 + 1) / 4)
    want = qa.spline(np.arange(30) / 2, q, got["t"])
    np.testing.assert_allclose(np.column_stack([got[c] for c in ("qw", "qx", "qy", "qz")]), want, atol=1e-14)


def test_resample_bad_times(capsys, stream, tmp_path):
    path, t, pos, q = stream
    np.save(tmp_path / "late.npy", np.array([t[0], t[-1] + 1]))
    rc, _, err = cli(capsys, "resample", path, tmp_path / "o.npy", "--times", tmp_path / "late.npy")
    assert rc == 1 and "is after the last key time" in err
    assert not (tmp_path / "o.npy").exists()
    np.save(tmp_path / "early.npy", np.array([t[0] - 1, t[1]]))
    rc, _, err = cli(capsys, "resample", path, tmp_path / "o.npy", "--times", tmp_path / "early.npy")
    assert rc == 1 and "before the first key time" in err
    np.save(tmp_path / "back.npy", np.array([t[1], t[0]]))
    rc, _, err = cli(capsys, "resample", path, tmp_path / "o.npy", "--times", tmp_path / "back.npy")
    assert rc == 1 and "must not decrease" in err


def test_resample_repeated_time_real(capsys, data_dir, tmp_path):
    src = data_dir / "tum_freiburg2_desk_groundtruth.txt"
    rc, _, err = cli(capsys, "resample", src, tmp_path / "o.npy", "--rate", 30)
    assert rc == 1
    lineno = int(err.split(":")[1])
    prev, line = src.read_text().splitlines()[lineno - 2 : lineno]
    assert prev.split()[0] == line.split()[0]  # the named line repeats the previous time
    assert "repeated time" in err and not (tmp_path / "o.npy").exists()
    rc, _, err = cli(capsys, "resample", src, tmp_path / "o.npy", "--rate", 30, "--on-invalid", "drop")
    assert rc == 0 and "dropped 1 invalid row" in err


# --------------------------------------------------------------------------
# unflip


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


# --------------------------------------------------------------------------
# rotate and compose


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


# --------------------------------------------------------------------------
# info


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


# --------------------------------------------------------------------------
# bad files, overwriting, drop


BAD = {
    "short row": ("t,qw,qx,qy,qz\n0,1,0,0,0\n1,1,0,0\n", "bad.csv:3: expected 5 fields, got 4"),
    "text in number": ("t,qw,qx,qy,qz\n0,1,0,0,0\n1,1,zero,0,0\n", "bad.csv:3: not a number: 'zero' in column qx"),
    "zero quaternion": ("t,qw,qx,qy,qz\n0,1,0,0,0\n1,0,0,0,0\n", "bad.csv:3: zero quaternion"),
    "empty file": ("", "bad.csv: empty file"),
    "missing column": ("t,qw,qx,qy\n0,1,0,0\n", "bad.csv:1: missing column qz"),
    "wrong layout": ("0,0,1\n", "bad.csv:1: expected 4 (quaternion)"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_files(capsys, tmp_path, monkeypatch, case):
    text, msg = BAD[case]
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.csv").write_text(text)
    rc, _, err = cli(capsys, "convert", "bad.csv", "out.npy", "--to", "quat")
    assert rc == 1
    assert err.strip().splitlines() == [msg] or err.startswith(msg)
    assert len(err.strip().splitlines()) == 1
    assert sorted(os.listdir(tmp_path)) == ["bad.csv"]  # no output, no temporary file


def test_bad_npy_layout(capsys, tmp_path):
    np.save(tmp_path / "v.npy", np.zeros((4, 3)))
    rc, _, err = cli(capsys, "unflip", tmp_path / "v.npy", tmp_path / "o.npy")
    assert rc == 1 and "expected quaternions of shape (N, 4)" in err and "got (4, 3)" in err
    assert not (tmp_path / "o.npy").exists()


def test_bad_file_subprocess(tmp_path):
    (tmp_path / "walk.csv").write_text("t,qw,qx,qy,qz\n0,1,0,0,0\n1,1,0,0\n")
    res = run("unflip", tmp_path / "walk.csv", tmp_path / "o.csv")
    assert res.returncode == 1
    assert res.stderr.strip() == f"{tmp_path / 'walk.csv'}:3: expected 5 fields, got 4"
    assert "Traceback" not in res.stderr and not (tmp_path / "o.csv").exists()


def test_drop(capsys, tmp_path):
    (tmp_path / "bad.csv").write_text("t,qw,qx,qy,qz\n0,1,0,0,0\n1,1,0,0\n2,x,0,0,0\n3,0,0,0,0\n4,0,2,0,0\n")
    rc, _, err = cli(capsys, "convert", tmp_path / "bad.csv", tmp_path / "o.csv", "--to", "quat",
                     "--on-invalid", "drop")
    assert rc == 0
    assert "dropped 3 invalid rows" in err and "largest | |q| - 1 | = 1" in err
    got = read_csv(tmp_path / "o.csv")
    np.testing.assert_array_equal(got["t"], [0, 4])
    np.testing.assert_array_equal(got["qx"], [0, 1])
    (tmp_path / "all.csv").write_text("t,qw,qx,qy,qz\n0,0,0,0,0\n")
    rc, _, err = cli(capsys, "convert", tmp_path / "all.csv", tmp_path / "o2.csv", "--to", "quat",
                     "--on-invalid", "drop")
    assert rc == 1 and "no valid rows" in err and not (tmp_path / "o2.csv").exists()


def test_overwrite_rules(capsys, tmp_path, rng):
    np.save(tmp_path / "q.npy", unit(rng, 5))
    (tmp_path / "o.npy").write_bytes(b"keep")
    rc, _, err = cli(capsys, "convert", tmp_path / "q.npy", tmp_path / "o.npy", "--to", "matrix")
    assert rc == 2 and "exists; use --force" in err
    assert (tmp_path / "o.npy").read_bytes() == b"keep"
    rc, _, err = cli(capsys, "convert", tmp_path / "q.npy", tmp_path / "o.npy", "--to", "matrix", "--force")
    assert rc == 0 and np.load(tmp_path / "o.npy").shape == (5, 3, 3)
    rc, _, err = cli(capsys, "unflip", tmp_path / "q.npy", tmp_path / "q.npy", "--force")
    assert rc == 2 and "the output is the input" in err
    assert sorted(os.listdir(tmp_path)) == ["o.npy", "q.npy"]


def test_failure_keeps_existing_output(capsys, tmp_path):
    (tmp_path / "bad.csv").write_text("t,qw,qx,qy,qz\n0,1,0,0,0\n1,0,0,0,0\n")
    (tmp_path / "o.csv").write_text("old")
    rc, _, _ = cli(capsys, "convert", tmp_path / "bad.csv", tmp_path / "o.csv", "--to", "quat", "--force")
    assert rc == 1 and (tmp_path / "o.csv").read_text() == "old"
    assert sorted(os.listdir(tmp_path)) == ["bad.csv", "o.csv"]


def test_progress_bar_on_stderr(capsys, tmp_path, rng):
    np.save(tmp_path / "q.npy", unit(rng, 100))
    rc = main(["convert", str(tmp_path / "q.npy"), str(tmp_path / "o.npy"), "--to", "quat", "--progress"])
    err = capsys.readouterr().err
    assert rc == 0 and "convert:" in err and "/100 " in err
    rc, _, err = cli(capsys, "convert", tmp_path / "q.npy", tmp_path / "o2.npy", "--to", "quat")
    assert rc == 0 and err == ""


# --------------------------------------------------------------------------
# several inputs in one process


def _tum(path, rng, n=40):
    t, pos, q = smooth_stream(rng, n)
    np.savetxt(path, np.column_stack([t, pos, q[:, [1, 2, 3, 0]]]), header="timestamp tx ty tz qx qy qz qw")
    return q


@pytest.fixture
def several(tmp_path, rng):
    """Three TUM files a.txt, b.txt, c.txt in tmp_path/in, and their quaternions."""
    (tmp_path / "in").mkdir()
    return {k: _tum(tmp_path / "in" / f"{k}.txt", rng) for k in "abc"}


def test_several_inputs_outputs_named_after_inputs(capsys, tmp_path, several):
    src = [tmp_path / "in" / f"{k}.txt" for k in "abc"]
    rc, _, err = cli(capsys, "convert", *src, tmp_path / "new" / "deeper", "--to", "matrix", "--ext", "npy")
    assert rc == 0, err
    assert sorted(os.listdir(tmp_path / "new" / "deeper")) == ["a.npy", "b.npy", "c.npy"]  # folder created
    for k, q in several.items():
        np.testing.assert_allclose(np.load(tmp_path / "new" / "deeper" / f"{k}.npy"), rot(q).as_matrix(), atol=1e-12)
    # default extension: each input's own (TUM in, TUM out); `.csv` via --ext keeps the columns
    rc, _, err = cli(capsys, "unflip", *src, tmp_path / "u")
    assert rc == 0, err
    assert sorted(os.listdir(tmp_path / "u")) == ["a.txt", "b.txt", "c.txt"]
    got, q = np.loadtxt(tmp_path / "u" / "b.txt"), several["b"]
    assert got.shape == (40, 8) and same_rotation(got[:, [7, 4, 5, 6]], q / np.linalg.norm(q, axis=1)[:, None])
    assert (np.sum(got[1:, 4:] * got[:-1, 4:], axis=1) >= 0).all()
    rc, _, err = cli(capsys, "resample", *src, tmp_path / "r", "--rate", "50", "--ext", ".csv")
    assert rc == 0, err
    assert sorted(os.listdir(tmp_path / "r")) == ["a.csv", "b.csv", "c.csv"]
    assert list(read_csv(tmp_path / "r" / "c.csv")) == ["t", "x", "y", "z", "qw", "qx", "qy", "qz"]
    np.save(tmp_path / "times.npy", [1.0, 1.5, 2.0])  # read once, for every input
    rc, _, err = cli(capsys, "resample", *src, tmp_path / "rt", "--times", tmp_path / "times.npy", "--ext", "csv")
    assert rc == 0, err
    assert all(list(read_csv(tmp_path / "rt" / f"{k}.csv")["t"]) == [1.0, 1.5, 2.0] for k in "abc")
    # one input into an existing folder, OUT/ with a slash, or with --ext is the folder form too
    (tmp_path / "one").mkdir()
    assert cli(capsys, "convert", src[0], tmp_path / "one", "--to", "quat", "--ext", "npy")[0] == 0
    assert cli(capsys, "convert", src[1], f"{tmp_path / 'one'}{os.sep}", "--to", "quat", "--ext", "npy")[0] == 0
    assert cli(capsys, "convert", src[2], tmp_path / "one", "--to", "quat")[0] == 0
    assert cli(capsys, "convert", src[0], tmp_path / "two", "--to", "quat", "--ext", "csv")[0] == 0
    assert sorted(os.listdir(tmp_path / "one")) == ["a.npy", "b.npy", "c.txt"]
    assert os.listdir(tmp_path / "two") == ["a.csv"]


def test_several_inputs_one_bad_file(capsys, tmp_path, several):
    bad = tmp_path / "in" / "bad.txt"
    bad.write_text("# timestamp tx ty tz qx qy qz qw\n1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n")
    src = [tmp_path / "in" / "a.txt", bad, tmp_path / "in" / "c.txt", tmp_path / "in" / "none.txt"]
    rc, _, err = cli(capsys, "convert", *src, tmp_path / "o", "--to", "rotvec", "--ext", "npy")
    assert rc == 1
    assert sorted(os.listdir(tmp_path / "o")) == ["a.npy", "c.npy"]  # the others written, no temporary left
    lines = err.splitlines()
    assert f"{bad}:3: expected 8 numbers, got 7" in lines
    assert f"quatarray convert: error: {src[3]}: no such file" in lines
    assert lines[-1] == "quatarray convert: 2 of 4 inputs failed"
    assert "Traceback" not in err
    # info: each good file under its name, the bad one named on stderr
    rc, out, err = cli(capsys, "info", *src[:3])
    assert rc == 1 and f"{bad}:3: expected 8 numbers, got 7" in err
    blocks = out.split("\n\n")
    assert [b.splitlines()[0].split(None, 1)[1] for b in blocks] == [str(src[0]), str(src[2])]
    assert all("rows:         40" in b for b in blocks)


def test_several_inputs_existing_output_and_exit_codes(capsys, tmp_path, several):
    src = [tmp_path / "in" / f"{k}.txt" for k in "abc"]
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "b.npy").write_bytes(b"keep")
    rc, _, err = cli(capsys, "convert", *src, tmp_path / "o", "--to", "quat", "--ext", "npy")
    assert rc == 1 and f"{tmp_path / 'o' / 'b.npy'}: exists; use --force" in err
    assert (tmp_path / "o" / "b.npy").read_bytes() == b"keep"
    assert sorted(os.listdir(tmp_path / "o")) == ["a.npy", "b.npy", "c.npy"]
    rc, _, err = cli(capsys, "convert", *src, tmp_path / "o", "--to", "quat", "--ext", "npy", "--force")
    assert rc == 0 and np.load(tmp_path / "o" / "b.npy").shape == (40, 4)

    def refused(*argv):
        before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
        rc, _, err = cli(capsys, *argv)
        assert rc == 2 and len(err.splitlines()) == 1, err
        assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before  # nothing ran
        return err

    # the folder forgotten: the last input taken for OUT is a file, not a folder
    assert "not a folder" in refused("convert", *src, "--to", "quat")
    # two inputs with the same name, from different folders: no silent overwrite
    (tmp_path / "in2").mkdir()
    _tum(tmp_path / "in2" / "a.txt", np.random.default_rng(3))
    err = refused("convert", src[0], tmp_path / "in2" / "a.txt", tmp_path / "p", "--to", "quat", "--ext", "npy")
    assert "would both be written to" in err and str(tmp_path / "p" / "a.npy") in err
    # OUT holding the inputs, with their own extension: each output would be its input
    err = refused("unflip", *src, tmp_path / "in", "--force")
    assert "the output is the input file" in err
    err = refused("convert", src[0], src[1], src[0], "--to", "quat")  # OUT equal to an input
    assert "not a folder" in err
    assert "cannot tell the output format" in refused("convert", *src, tmp_path / "p", "--to", "quat", "--ext", "xyz")
    assert "SEQ is three axes" in refused("convert", *src, tmp_path / "p", "--to", "euler:XXY")


def test_several_inputs_subprocess(tmp_path, several):
    src = [tmp_path / "in" / f"{k}.txt" for k in "abc"]
    (tmp_path / "in" / "b.txt").write_text("1 2 3\n")
    res = run("convert", *src, tmp_path / "o", "--to", "quat", "--ext", "npy")
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert sorted(os.listdir(tmp_path / "o")) == ["a.npy", "c.npy"]
    assert any(line.startswith(f"{src[1]}:1: ") for line in res.stderr.splitlines())
    assert run("convert", *src, "--to", "quat").returncode == 2


# --------------------------------------------------------------------------
# start-up: a verb imports only what it needs

IMPORTS = (
    "import sys\n"
    "from quatarray.cli import main\n"
    "rc = main(sys.argv[1:])\n"
    "heavy = ('numba', 'scipy', 'pandas', 'pyarrow', 'pyarrow.compute', 'dask', 'distributed', 'matplotlib',\n"
    "         'tqdm', 'zarr')\n"
    "print(rc, *[m for m in heavy if m in sys.modules])\n"
)


def _loaded(*argv):
    """The exit status and the heavy modules loaded by ``main(argv)`` in a fresh process."""
    res = subprocess.run([sys.executable, "-c", IMPORTS, *map(str, argv)], capture_output=True, text=True, cwd=ROOT)
    assert res.returncode == 0, res.stderr
    rc, *mods = res.stdout.splitlines()[-1].split()  # after what the verb prints
    assert rc == "0", res.stderr
    return int(rc), set(mods)


def test_startup_imports_only_what_the_verb_needs(tmp_path, rng):
    t, pos, q = smooth_stream(rng, 50)
    tum = tmp_path / "x.txt"
    np.savetxt(tum, np.column_stack([t, pos, q[:, [1, 2, 3, 0]]]), header="timestamp tx ty tz qx qy qz qw")
    np.save(tmp_path / "q.npy", unit(rng, 50))
    # text is parsed by pyarrow.csv; checking and writing the quaternions needs no kernel
    assert _loaded("convert", tum, tmp_path / "y.npy", "--to", "quat") == (0, {"pyarrow"})
    assert _loaded("info", tum) == (0, {"pyarrow"})
    assert _loaded("convert", tmp_path / "q.npy", tmp_path / "y2.npy", "--to", "quat") == (0, set())
    assert _loaded("convert", tmp_path / "q.npy", tmp_path / "y3.npy", "--to", "xyzw") == (0, set())
    # a conversion runs a kernel: numba (which imports scipy itself), nothing else
    assert _loaded("convert", tmp_path / "q.npy", tmp_path / "m.npy", "--to", "matrix") == (0, {"numba", "scipy"})
    # a csv output: pyarrow writes it (and pandas, which pyarrow's conversions import, stays out)
    assert _loaded("unflip", tum, tmp_path / "u.csv") == (0, {"numba", "scipy", "pyarrow"})
    assert np.load(tmp_path / "y.npy").shape == (50, 4)


# --------------------------------------------------------------------------
# demo, bench, plot, --scheduler: argument wiring to the modules that do the work


def test_optional_verbs_wiring(capsys, monkeypatch, tmp_path):
    calls = {}
    fake = types.ModuleType("quatarray.demo")
    fake.run = lambda out_dir=None: calls.setdefault("demo", out_dir) and 0
    monkeypatch.setitem(sys.modules, "quatarray.demo", fake)
    fake_b = types.ModuleType("quatarray.bench")
    fake_b.run = lambda n=None, json_path=None: calls.setdefault("bench", (n, json_path)) and 3
    monkeypatch.setitem(sys.modules, "quatarray.bench", fake_b)
    fake_p = types.ModuleType("quatarray.plot")
    fake_p.plot_file = lambda i, o, **kw: calls.setdefault("plot", (i, o, kw)) and 0
    monkeypatch.setitem(sys.modules, "quatarray.plot", fake_p)
    assert main(["demo", "--out", "d"]) == 0 and calls["demo"] == "d"
    assert main(["bench", "--n", "1000", "--json", "b.json"]) == 3 and calls["bench"] == (1000, "b.json")
    (tmp_path / "s.csv").write_text("qw,qx,qy,qz\n1,0,0,0\n")
    assert main(["plot", str(tmp_path / "s.csv"), str(tmp_path / "p.png"), "--joint", "Hips"]) == 0
    assert calls["plot"][2]["joint"] == "Hips" and calls["plot"][2]["fmt"] == "auto"
    monkeypatch.setitem(sys.modules, "quatarray.demo", None)  # not installed
    assert main(["demo"]) == 2
    assert "demo is not available" in capsys.readouterr().err


def test_scheduler_wiring(capsys, monkeypatch):
    pytest.importorskip("dask")
    import quatarray.dask as qd

    seen = {}
    monkeypatch.setattr(qd, "convert_file", lambda src, dst, **kw: seen.setdefault("c", (src, dst, kw)) and 0,
                        raising=False)
    monkeypatch.setattr(qd, "resample_file", lambda src, dst, **kw: seen.setdefault("r", (src, dst, kw)) and 0,
                        raising=False)
    assert main(["convert", "a.npy", "b.npy", "--to", "matrix", "--scheduler", "local", "--chunk", "10"]) == 0
    assert seen["c"] == ("a.npy", "b.npy", dict(to="matrix", degrees=False, layout="wxyz", chunk=10,
                                                  scheduler="local", on_invalid="error", force=False))
    assert main(["resample", "a.npy", "b.npy", "--rate", "50", "--scheduler", "tcp://h:8786"]) == 0
    assert seen["r"][2]["rate"] == 50 and seen["r"][2]["scheduler"] == "tcp://h:8786"


# --------------------------------------------------------------------------
# bounded memory


RSS = (
    "import resource, subprocess, sys\n"
    "subprocess.run(sys.argv[1:], check=True)\n"
    "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n"
)


def _peak_kib(*argv):
    res = subprocess.run([sys.executable, "-c", RSS, sys.executable, "-m", "quatarray", *map(str, argv)],
                         capture_output=True, text=True, cwd=ROOT)
    assert res.returncode == 0, res.stderr
    return int(res.stdout.split()[-1])


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


# --------------------------------------------------------------------------
# hardening (issue 14)


def test_headerless_comma_tum_layout_said_and_chosen(capsys, tmp_path):
    rows = [[0.0, 1, 2, 3, 0, 0, 0, 1], [0.5, 1, 2, 3, 0, 0, 1, 0]]
    (tmp_path / "c.csv").write_text("".join(",".join(map(str, r)) + "\n" for r in rows))
    rc, _, err = cli(capsys, "convert", tmp_path / "c.csv", tmp_path / "o.csv", "--to", "quat")
    assert rc == 0 and err.splitlines() == [
        f"{tmp_path / 'c.csv'}: no column names: read as t x y z qw qx qy qz (scalar first); "
        "choose with --layout xyzw or --format tum"
    ]
    for opt in (["--layout", "xyzw"], ["--format", "tum"]):
        rc, _, err = cli(capsys, "convert", tmp_path / "c.csv", tmp_path / "o.csv", "--to", "quat", "--force", *opt)
        assert rc == 0 and err == ""
        got = read_csv(tmp_path / "o.csv")
        np.testing.assert_array_equal(np.column_stack([got[c] for c in ("qw", "qx", "qy", "qz")]),
                                      [[1, 0, 0, 0], [0, 0, 0, 1]])
    rc, out, _ = cli(capsys, "convert", "--help")
    assert rc == 0 and "--format tum" in " ".join(out.split())


def test_layout_on_named_columns_said(capsys, stream, tmp_path):
    path, t, pos, q = stream
    rc, _, err = cli(capsys, "unflip", path, tmp_path / "o.csv", "--layout", "xyzw")
    assert rc == 0 and f"{path}: --layout xyzw ignored: the file names its columns" in err.splitlines()
    got = read_csv(tmp_path / "o.csv")
    assert same_rotation(np.column_stack([got[c] for c in ("qw", "qx", "qy", "qz")]),
                         q / np.linalg.norm(q, axis=1)[:, None])


def test_resample_in_times(capsys, tmp_path, rng):
    t, pos, q = smooth_stream(rng, 40)
    q = q / np.linalg.norm(q, axis=1)[:, None]
    np.save(tmp_path / "q.npy", q)
    (tmp_path / "times.txt").write_text("".join(f"{float(v)!r}\n" for v in t))  # uneven steps, as KITTI's
    write_csv(tmp_path / "ref.csv", t, None, q)
    rc, _, err = cli(capsys, "resample", tmp_path / "q.npy", tmp_path / "o.csv", "--rate", "20",
                     "--in-times", tmp_path / "times.txt")
    assert rc == 0 and err == ""
    rc, _, _ = cli(capsys, "resample", tmp_path / "ref.csv", tmp_path / "ref_o.csv", "--rate", "20")
    got, want = read_csv(tmp_path / "o.csv"), read_csv(tmp_path / "ref_o.csv")
    assert rc == 0 and sorted(got) == sorted(want)
    for c in want:
        np.testing.assert_array_equal(got[c], want[c])


def test_resample_in_times_bad(capsys, tmp_path, rng):
    np.save(tmp_path / "q.npy", unit(rng, 4))
    tt = tmp_path / "times.txt"
    out = tmp_path / "o.csv"
    tt.write_text("0\n0.1\n0.2\n")
    rc, _, err = cli(capsys, "resample", tmp_path / "q.npy", out, "--rate", "20", "--in-times", tt)
    assert rc == 1 and err == f"{tt} has 3 times but {tmp_path / 'q.npy'} has 4 rows; they must match\n"
    tt.write_text("0\n0.1\n0.2\n0.3\n0.4\n")
    rc, _, err = cli(capsys, "resample", tmp_path / "q.npy", out, "--rate", "20", "--in-times", tt, "--chunk", "2")
    assert rc == 1 and err == f"{tt} has 5 times but {tmp_path / 'q.npy'} has 4 rows; they must match\n"
    tt.write_text("# times\n0\n0.1\n0.1\n0.3\n")
    rc, _, err = cli(capsys, "resample", tmp_path / "q.npy", out, "--rate", "20", "--in-times", tt)
    assert rc == 1 and err == f"{tt}:4: repeated time 0.1 (previous 0.1); times must increase\n"
    rc, _, err = cli(capsys, "resample", tmp_path / "q.npy", out, "--rate", "20", "--in-times", tt,
                     "--in-rate", "10")
    assert rc == 2 and "not allowed with argument" in err
    assert not out.exists()


def test_resample_in_rate_on_timed_stream_said(capsys, stream, tmp_path):
    path, t, pos, q = stream
    rc, _, err = cli(capsys, "resample", path, tmp_path / "o.csv", "--rate", "20", "--in-rate", "100")
    assert rc == 0 and f"{path}: has a time column; --in-rate ignored" in err.splitlines()
    np.testing.assert_allclose(read_csv(tmp_path / "o.csv")["t"][:2], [t[0], t[0] + 0.05])


# --------------------------------------------------------------------------
# hardening (issue 14): permissions, signals, write errors


def _leftovers(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


@pytest.mark.parametrize("ext", ["npy", "csv", "parquet", "txt"])
def test_output_mode_is_0666_less_umask(capsys, tmp_path, ext):
    t, pos, q = smooth_stream(np.random.default_rng(1), 20)
    np.savetxt(tmp_path / "s.csv", np.column_stack([t, pos, q]), delimiter=",",
               header="t,x,y,z,qw,qx,qy,qz", comments="")
    out = tmp_path / f"o.{ext}"
    old = os.umask(0o027)
    try:
        assert cli(capsys, "unflip", tmp_path / "s.csv", out)[0] == 0
    finally:
        os.umask(old)
    assert out.stat().st_mode & 0o777 == 0o640


def test_force_keeps_the_mode_of_the_file_it_replaces(capsys, tmp_path):
    np.save(tmp_path / "q.npy", unit(np.random.default_rng(2), 10))
    out = tmp_path / "o.csv"
    out.write_text("old\n")
    out.chmod(0o604)
    assert cli(capsys, "convert", tmp_path / "q.npy", out, "--to", "quat", "--force")[0] == 0
    assert out.stat().st_mode & 0o777 == 0o604 and out.read_text().startswith("qw,")


def test_force_refuses_a_fifo(capsys, tmp_path):
    np.save(tmp_path / "q.npy", unit(np.random.default_rng(3), 10))
    os.mkfifo(tmp_path / "o.csv")
    rc, _, err = cli(capsys, "convert", tmp_path / "q.npy", tmp_path / "o.csv", "--to", "quat", "--force")
    assert rc == 2 and "not a regular file" in err and len(err.strip().splitlines()) == 1
    assert (tmp_path / "o.csv").is_fifo()


def test_parent_that_is_a_file(capsys, tmp_path):
    np.save(tmp_path / "q.npy", unit(np.random.default_rng(4), 10))
    rc, _, err = cli(capsys, "convert", tmp_path / "q.npy", tmp_path / "q.npy" / "o.csv", "--to", "quat")
    assert rc == 2 and "is not a folder" in err and "does not exist" not in err


def test_unwritable_destination_names_out(capsys, tmp_path, monkeypatch):
    import tempfile

    np.save(tmp_path / "q.npy", unit(np.random.default_rng(5), 10))

    def refused(prefix, suffix, dir):
        path = os.path.join(dir, prefix + "abc123" + suffix)
        raise PermissionError(13, "Permission denied", path)

    monkeypatch.setattr(tempfile, "mkstemp", refused)
    out = tmp_path / "o.npy"
    rc, _, err = cli(capsys, "convert", tmp_path / "q.npy", out, "--to", "quat")
    assert rc == 2 and err.strip() == f"quatarray convert: error: {out}: cannot write the output: Permission denied"


FSIZE = (
    "import resource, signal, sys\n"
    "signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
    "lim = int(sys.argv[1])\n"
    "resource.setrlimit(resource.RLIMIT_FSIZE, (lim, lim))\n"
    "from quatarray.cli import main\n"
    "sys.exit(main(sys.argv[2:]))\n"
)


@pytest.mark.parametrize("ext", ["csv", "npy"])
def test_write_error_at_the_end_leaves_nothing(tmp_path, ext):
    """A file-size limit one byte short of the output: the last write (the final flush) fails."""
    np.save(tmp_path / "q.npy", unit(np.random.default_rng(6), 5000))
    args = ["convert", tmp_path / "q.npy", tmp_path / f"full.{ext}", "--to", "quat", "--no-progress"]
    assert run(*args).returncode == 0
    size = (tmp_path / f"full.{ext}").stat().st_size
    out = tmp_path / f"o.{ext}"
    args[2] = out
    res = subprocess.run([sys.executable, "-c", FSIZE, str(size - 1), *map(str, args)], capture_output=True,
                         text=True, cwd=ROOT)
    assert res.returncode == 2, res.stderr
    assert res.stderr.strip().startswith(f"quatarray convert: error: {out}: cannot write the output: ")
    assert len(res.stderr.strip().splitlines()) == 1
    assert not out.exists() and _leftovers(tmp_path) == []


@pytest.mark.parametrize("method", ["bezier", "squad"])
def test_resample_in_pieces_is_the_same(capsys, tmp_path, method):
    """New times written --chunk at a time, each piece from the keys around it: the same
    samples as in one piece."""
    t, pos, q = smooth_stream(np.random.default_rng(7), 40)
    np.savetxt(tmp_path / "s.csv", np.column_stack([t, pos, q]), delimiter=",",
               header="t,x,y,z,qw,qx,qy,qz", comments="")
    for chunk in (7, 100000):
        rc, _, err = cli(capsys, "resample", tmp_path / "s.csv", tmp_path / f"r{chunk}.npy", "--rate", 97,
                         "--method", method, "--chunk", chunk)
        assert rc == 0, err
    np.testing.assert_array_equal(np.load(tmp_path / "r7.npy"), np.load(tmp_path / "r100000.npy"))


@pytest.mark.slow
def test_bounded_memory_resample_to_a_high_rate(tmp_path):
    """20 keys at 1 Hz to 2·10⁵ Hz: 3.8·10⁶ new rows (116 MiB out) with a few MiB above the
    interpreter's own footprint: the new times are made and evaluated --chunk at a time."""
    np.save(tmp_path / "k.npy", unit(np.random.default_rng(8), 20))
    base = _peak_kib("resample", tmp_path / "k.npy", tmp_path / "b.npy", "--in-rate", 1, "--rate", 10)
    peak = _peak_kib("resample", tmp_path / "k.npy", tmp_path / "o.npy", "--in-rate", 1, "--rate", 2e5,
                     "--chunk", 65536)
    grown = (peak - base) / 1024
    assert grown < 40, f"peak RSS grew by {grown:.0f} MiB over the {base / 1024:.0f} MiB baseline"
    assert np.load(tmp_path / "o.npy", mmap_mode="r").shape == (19 * 200000 + 1, 4)


@pytest.mark.parametrize("sig, code", [("SIGTERM", 143), ("SIGHUP", 129), ("SIGINT", 130)])
def test_signals_leave_nothing_behind(tmp_path, sig, code):
    import signal
    import time

    np.save(tmp_path / "k.npy", unit(np.random.default_rng(9), 20))
    out = tmp_path / "o.npy"
    # SIGINT's default (KeyboardInterrupt) only where it is not ignored, as it is under `cmd &`
    proc = subprocess.Popen(
        [sys.executable, "-m", "quatarray", "resample", str(tmp_path / "k.npy"), str(out), "--in-rate", "1",
         "--rate", "1e7", "--chunk", "10000", "--no-progress"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        deadline = time.monotonic() + 120
        while not any(p.stat().st_size > 1 << 20 for p in tmp_path.glob(".o.npy.*")):
            assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read()
            time.sleep(0.02)
        proc.send_signal(getattr(signal, sig))
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == code, err
    assert err.strip() == f"quatarray: interrupted ({sig})"
    assert not out.exists() and _leftovers(tmp_path) == []


def test_float16_npy_is_read_as_float32(capsys, tmp_path):
    q = unit(np.random.default_rng(10), 30)
    np.save(tmp_path / "h.npy", q.astype(np.float16))
    rc, _, err = cli(capsys, "convert", tmp_path / "h.npy", tmp_path / "o.npy", "--to", "matrix")
    assert rc == 0, err
    out = np.load(tmp_path / "o.npy")
    assert out.dtype == np.float32
    np.testing.assert_allclose(out, rot(q.astype(np.float16).astype(np.float64)).as_matrix(), atol=1e-6)
    rc, out, _ = cli(capsys, "info", tmp_path / "h.npy")
    assert rc == 0 and "float32" in out


def test_plot_refuses_a_bad_seq(capsys, tmp_path):
    pytest.importorskip("matplotlib")
    np.save(tmp_path / "q.npy", unit(np.random.default_rng(11), 10))
    rc, _, err = cli(capsys, "plot", tmp_path / "q.npy", tmp_path / "p.png", "--seq", "ABC")
    assert rc == 2 and err.startswith("quatarray plot: error: --seq ABC: SEQ is three axes")
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "p.png").exists()


def test_resample_beyond_the_disk_is_one_line(capsys, tmp_path):
    np.save(tmp_path / "q.npy", unit(np.random.default_rng(12), 20))
    rc, _, err = cli(capsys, "resample", tmp_path / "q.npy", tmp_path / "r.npy", "--in-rate", 1, "--rate", 1e12)
    assert rc == 2 and "free on its disk" in err and len(err.strip().splitlines()) == 1
    assert _leftovers(tmp_path) == [] and not (tmp_path / "r.npy").exists()


def test_memory_error_is_one_line(capsys, tmp_path, monkeypatch):
    np.save(tmp_path / "q.npy", unit(np.random.default_rng(13), 20))

    def no_memory(*a, **kw):
        raise MemoryError("Unable to allocate 267. GiB for an array with shape (35800000000000,)")

    import quatarray.conversions

    monkeypatch.setattr(quatarray.conversions, "as_matrix", no_memory)  # what convert --to matrix calls
    rc, _, err = cli(capsys, "convert", tmp_path / "q.npy", tmp_path / "o.npy", "--to", "matrix")
    assert rc == 2 and err.strip() == "quatarray convert: error: out of memory; try a smaller --chunk"
    assert _leftovers(tmp_path) == []


def test_rate_finer_than_the_time_resolution(capsys, tmp_path):
    t = 1.3e9 + np.arange(20) * 0.01  # epoch seconds: float64 steps of 2.4e-7 s
    q = unit(np.random.default_rng(14), 20)
    np.savetxt(tmp_path / "s.csv", np.column_stack([t, q]), delimiter=",", header="t,qw,qx,qy,qz",
               comments="", fmt="%.17g")
    rc, _, err = cli(capsys, "resample", tmp_path / "s.csv", tmp_path / "r.csv", "--rate", 1e9)
    assert rc == 2 and "finer than the time resolution" in err and len(err.strip().splitlines()) == 1
    assert _leftovers(tmp_path) == [] and not (tmp_path / "r.csv").exists()
    assert cli(capsys, "resample", tmp_path / "s.csv", tmp_path / "r.csv", "--rate", 1e5)[0] == 0
    assert (np.diff(np.loadtxt(tmp_path / "r.csv", delimiter=",", skiprows=1)[:, 0]) > 0).all()


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


def test_resample_times_messages_are_plain_and_by_line(capsys, tmp_path):
    t = 1311868164.0 + np.arange(10) * 0.1
    np.savetxt(tmp_path / "s.csv", np.column_stack([t, unit(np.random.default_rng(18), 10)]), delimiter=",",
               header="t,qw,qx,qy,qz", comments="", fmt="%.17g")
    cases = {
        "back.txt": ("# new times\n1311868164.5\n1311868164.25\n", "back.txt:3: decreasing time 1311868164.25 "
                     "(previous 1311868164.5); times must not decrease"),
        "late.txt": ("1311868164.5\n\n1311868200.5\n", "late.txt:3: time 1311868200.5 is after the last key time "
                     "1311868164.9"),
        "early.txt": ("# t\n1311868163.5\n", "early.txt:2: time 1311868163.5 is before the first key time "
                      "1311868164.0"),
    }
    for name, (text, want) in cases.items():
        (tmp_path / name).write_text(text)
        rc, _, err = cli(capsys, "resample", tmp_path / "s.csv", tmp_path / "o.csv", "--times", tmp_path / name)
        assert rc == 1 and err.strip() == f"{tmp_path / name}:{want.split(':', 1)[1]}", err
        assert "np.float64" not in err


def test_resample_times_garbage_npy(capsys, stream, tmp_path):
    path = stream[0]
    (tmp_path / "g.npy").write_bytes(b"garbage" * 10)
    rc, _, err = cli(capsys, "resample", path, tmp_path / "o.npy", "--times", tmp_path / "g.npy")
    assert rc == 1 and "not a valid .npy float array" in err and "pickle" not in err


def test_info_one_row(capsys, tmp_path):
    (tmp_path / "one.csv").write_text("t,qw,qx,qy,qz\n0.5,1,0,0,0\n")
    rc, out, _ = cli(capsys, "info", tmp_path / "one.csv")
    assert rc == 0 and "rate:" in out
    rate = next(ln for ln in out.splitlines() if ln.startswith("rate:"))
    assert rate.split(":", 1)[1].strip() == "- (one row)"
    body = out.split("\n", 1)[1]  # after the file line (its path may hold "inf")
    assert "nan" not in body and "inf" not in body


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


# whole BVH clips (issue 17)


def test_resample_bvh_clip_every_joint(capsys, tmp_path):
    from quatarray import io
    from quatarray.demo import sample_path

    out = tmp_path / "w120.bvh"
    rc, _, err = cli(capsys, "resample", sample_path(), out, "--rate", 120)
    assert rc == 0, err
    clip, back = io.read_bvh(sample_path()), io.read_bvh(out)
    ref = clip.resample(rate=120)
    assert back.joints == clip.joints and back.frames == ref.frames and back.frame_time == 1 / 120
    assert qa.distance(back.rotations, ref.rotations).max() < 1e-9
    np.testing.assert_allclose(back.world()[1], ref.world()[1], rtol=0, atol=1e-9)
    rc, _, err = cli(capsys, "resample", sample_path(), tmp_path / "s.bvh", "--rate", 60, "--method", "slerp")
    assert rc == 0, err


def test_convert_bvh_to_positions(capsys, tmp_path):
    import pyarrow.csv as pcsv
    import pyarrow.parquet as pq

    from quatarray import io
    from quatarray.demo import sample_path

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


def test_info_bvh_lists_hierarchy(capsys, data_dir):
    rc, out, err = cli(capsys, "info", data_dir / "free_mocap.bvh")
    assert rc == 0, err
    assert "rows:" in out and "hierarchy: 70 joints (15 end sites, 1 root)" in out
    assert "\n  mixamorig:Hips  ZYX + XYZ position\n    mixamorig:Spine  ZYX\n" in out


def test_resample_bad_bvh_clip_one_line(tmp_path):
    path = tmp_path / "bad.bvh"
    path.write_text("HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n}\n"
                    "MOTION\nFrames: 2\nFrame Time: 0.1\n1 2 3\n1 2\n")
    r = run("resample", path, tmp_path / "out.bvh", "--rate", 100)
    assert r.returncode == 1 and r.stderr == f"{path}:11: expected 3 numbers, got 2\n"
    assert not (tmp_path / "out.bvh").exists()
