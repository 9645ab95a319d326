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
    # a conversion runs a kernel: numba, nothing else (not scipy, which numba probes for BLAS)
    assert _loaded("convert", tmp_path / "q.npy", tmp_path / "m.npy", "--to", "matrix") == (0, {"numba"})
    # a csv output: pyarrow writes it (and pandas, which pyarrow's conversions import, stays out)
    assert _loaded("unflip", tum, tmp_path / "u.csv") == (0, {"numba", "pyarrow"})
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
