"""The command line: the resample verb (in-process through ``main([...])``, a few as
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

from cli_common import _leftovers, _peak_kib, cli, read_csv, run, same_rotation, smooth_stream, unit, write_csv  # noqa: E402


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


def test_resample_bvh_clip_every_joint(capsys, tmp_path):
    from quatarray import io
    from quatarray.io import sample_path

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


def test_resample_bad_bvh_clip_one_line(tmp_path):
    path = tmp_path / "bad.bvh"
    path.write_text("HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n}\n"
                    "MOTION\nFrames: 2\nFrame Time: 0.1\n1 2 3\n1 2\n")
    r = run("resample", path, tmp_path / "out.bvh", "--rate", 100)
    assert r.returncode == 1 and r.stderr == f"{path}:11: expected 3 numbers, got 2\n"
    assert not (tmp_path / "out.bvh").exists()
