"""The command line on BVH clips (issue 36): several BVH inputs to an output folder,
``--ext bvh``, ``resample --method cubic`` (streams and clips), a 1-frame clip."""

import shutil

import numpy as np
import pytest

import quatarray as qa
from quatarray import io
from quatarray.app.cli import main
from quatarray.io import sample_path


def cli(capsys, *argv):
    rc = main([str(a) for a in argv] + ["--no-progress"])
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture
def two_clips(tmp_path):
    a, b = tmp_path / "a.bvh", tmp_path / "b.bvh"
    shutil.copy(sample_path(), a)
    clip = io.read_bvh(a)
    io.write_bvh(b, clip.resample(times=clip.times[10:200]))  # another clip: frames 10-199
    return a, b


def test_resample_bvh_inputs_to_a_folder(capsys, tmp_path, two_clips):
    rc, _, err = cli(capsys, "resample", *two_clips, tmp_path / "OUT/", "--rate", 50)
    assert rc == 0, err
    for src in two_clips:
        got = io.read_bvh(tmp_path / "OUT" / src.name)
        ref = io.read_bvh(src).resample(rate=50)
        assert got.frames == ref.frames and got.frame_time == 0.02
        assert qa.distance(got.rotations, ref.rotations).max() < 1e-9


def test_ext_bvh_and_other_extensions(capsys, tmp_path, two_clips):
    a, _ = two_clips
    rc, _, err = cli(capsys, "resample", a, tmp_path / "B", "--ext", "bvh", "--rate", 40, "--method", "slerp")
    assert rc == 0, err
    assert io.read_bvh(tmp_path / "B" / "a.bvh").frame_time == 1 / 40
    # --ext csv: the root joint's stream, as for one output file
    rc, _, err = cli(capsys, "resample", a, tmp_path / "C", "--ext", "csv", "--rate", 40)
    assert rc == 0, err
    rc, _, err = cli(capsys, "resample", a, tmp_path / "one.csv", "--rate", 40)
    assert rc == 0, err
    assert (tmp_path / "C" / "a.csv").read_bytes() == (tmp_path / "one.csv").read_bytes()
    # what a BVH cannot hold: refused before anything runs, naming the output
    rc, _, err = cli(capsys, "convert", a, tmp_path / "D", "--ext", "bvh", "--to", "quat")
    assert rc == 2 and "D/a.bvh: a BVH output holds a whole clip" in err and not (tmp_path / "D").exists()
    np.save(tmp_path / "q.npy", qa.random(5, rng=0))
    rc, _, err = cli(capsys, "unflip", tmp_path / "q.npy", tmp_path / "E", "--ext", "bvh")
    assert rc == 2 and "a BVH output holds a whole clip" in err


def test_convert_bvh_inputs_to_positions_in_a_folder(capsys, tmp_path, two_clips):
    rc, _, err = cli(capsys, "convert", *two_clips, tmp_path / "P", "--to", "positions")
    assert rc == 0, err
    for src in two_clips:  # default: .npy, the (F, J, 3) array
        np.testing.assert_array_equal(np.load(tmp_path / "P" / (src.stem + ".npy")), io.read_bvh(src).world()[1])
    rc, _, err = cli(capsys, "convert", *two_clips, tmp_path / "Q", "--to", "positions", "--ext", "parquet")
    assert rc == 0, err
    assert (tmp_path / "Q" / "b.parquet").exists()
    rc, _, err = cli(capsys, "convert", *two_clips, tmp_path / "R", "--to", "positions", "--ext", "txt")
    assert rc == 2 and "positions are written as .npy, .csv or .parquet" in err
    # another target of a BVH input: the root joint's stream, .csv by default (it keeps the times)
    rc, _, err = cli(capsys, "convert", *two_clips, tmp_path / "S", "--to", "euler:ZXY")
    assert rc == 0, err
    assert (tmp_path / "S" / "a.csv").exists() and (tmp_path / "S" / "b.csv").exists()


def _stream(rng, n):
    t = np.cumsum(rng.uniform(0.05, 0.15, n))
    q = qa.from_rotvec(np.cumsum(rng.normal(0, 0.3, (n, 3)), axis=0))
    q[rng.random(n) < 0.3] *= -1  # sign flips
    return t, q


@pytest.mark.parametrize("chunk", [7, 100_000])
def test_resample_method_cubic_stream(capsys, tmp_path, rng, chunk):
    """--method cubic: scipy's RotationSpline over the whole stream, whatever --chunk
    (the keys are held and the system solved once), equal to the library's spline."""
    from scipy.spatial.transform import Rotation, RotationSpline

    t, q = _stream(rng, 40)
    pos = np.cumsum(rng.normal(0, 1, (40, 3)), axis=0)
    src = tmp_path / "in.csv"
    with open(src, "w") as f:
        f.write("t,x,y,z,qw,qx,qy,qz\n")
        for row in np.column_stack([t, pos, q]):
            f.write(",".join(repr(float(v)) for v in row) + "\n")
    out = tmp_path / f"out{chunk}.csv"
    rc, _, err = cli(capsys, "resample", src, out, "--rate", 25, "--method", "cubic", "--chunk", chunk)
    assert rc == 0, err
    got = np.loadtxt(out, delimiter=",", skiprows=1)
    nt = t[0] + np.arange(got.shape[0]) / 25
    np.testing.assert_array_equal(got[:, 0], nt)
    assert nt[-1] <= t[-1] < nt[-1] + 1 / 25
    np.testing.assert_array_equal(got[:, 4:], qa.spline(t, q, nt, method="cubic"))
    ref = RotationSpline(t, Rotation.from_quat(q, scalar_first=True))(nt).as_quat(scalar_first=True)
    assert qa.distance(got[:, 4:], ref).max() < 1e-10
    np.testing.assert_allclose(got[:, 1:4], np.column_stack([np.interp(nt, t, pos[:, k]) for k in range(3)]),
                               rtol=0, atol=1e-12)


def test_resample_method_cubic_times_file_and_errors(capsys, tmp_path, rng):
    t, q = _stream(rng, 30)
    np.save(tmp_path / "q.npy", q)
    (tmp_path / "keys.txt").write_text("\n".join(repr(float(x)) for x in t) + "\n")
    new = np.sort(rng.uniform(t[0], t[-1], 50))
    np.save(tmp_path / "new.npy", new)
    rc, _, err = cli(capsys, "resample", tmp_path / "q.npy", tmp_path / "o.npy", "--times", tmp_path / "new.npy",
                     "--in-times", tmp_path / "keys.txt", "--method", "cubic")
    assert rc == 0, err
    np.testing.assert_array_equal(np.load(tmp_path / "o.npy"), qa.spline(t, q, new, method="cubic"))
    np.save(tmp_path / "late.npy", np.r_[new, t[-1] + 1])
    rc, _, err = cli(capsys, "resample", tmp_path / "q.npy", tmp_path / "p.npy", "--times", tmp_path / "late.npy",
                     "--in-times", tmp_path / "keys.txt", "--method", "cubic")
    assert rc == 1 and "is after the last key time" in err and not (tmp_path / "p.npy").exists()
    np.save(tmp_path / "one.npy", q[:1])
    rc, _, err = cli(capsys, "resample", tmp_path / "one.npy", tmp_path / "r.npy", "--in-rate", 10, "--rate", 20,
                     "--method", "cubic")
    assert rc == 1 and "needs at least 2 valid rows, got 1" in err
    rc, _, err = cli(capsys, "resample", tmp_path / "q.npy", tmp_path / "s.npy", "--in-rate", 10, "--rate", 20,
                     "--method", "cubic", "--scheduler", "local")
    assert rc == 2 and "--method cubic is not available with --scheduler" in err


def test_resample_clip_method_cubic(capsys, tmp_path):
    rc, _, err = cli(capsys, "resample", sample_path(), tmp_path / "c.bvh", "--rate", 90, "--method", "cubic")
    assert rc == 0, err
    ref = io.read_bvh(sample_path()).resample(rate=90, method="cubic")
    assert qa.distance(io.read_bvh(tmp_path / "c.bvh").rotations, ref.rotations).max() < 1e-9


def test_resample_one_frame_clip(capsys, tmp_path):
    clip = io.read_bvh(sample_path())
    one = clip.replace(rotations=clip.rotations[5:6], translations=clip.translations[5:6], times=clip.times[:1])
    io.write_bvh(tmp_path / "one.bvh", one)
    rc, _, err = cli(capsys, "resample", tmp_path / "one.bvh", tmp_path / "out.bvh", "--rate", 120)
    assert rc == 0, err
    got = io.read_bvh(tmp_path / "out.bvh")
    assert got.frames == 1 and got.frame_time == 1 / 120
    assert qa.distance(got.rotations, one.rotations).max() < 1e-9


def test_resample_clip_times_that_go_back(capsys, tmp_path):
    """New times for a clip must increase: a repeated time is bad data naming the file
    (it gave a negative or zero frame time, a BVH that read_bvh refused)."""
    times = tmp_path / "t.txt"
    times.write_text("0.5\n0.5\n0.6\n")
    rc, _, err = cli(capsys, "resample", sample_path(), tmp_path / "out.bvh", "--times", times)
    assert rc == 1 and err.startswith(f"{times}: Expected `times` to be strictly increasing, got times[1] = 0.5")
    assert not (tmp_path / "out.bvh").exists()


def test_zero_frame_clip_on_the_command_line(capsys, tmp_path):
    """``Frames: 0`` (a hierarchy without motion): info shows it, positions are (0, J, 3),
    a stream verb has no rows to write (bad data, exit 1)."""
    clip = io.read_bvh(sample_path())
    path = tmp_path / "empty.bvh"
    io.write_bvh(path, clip.replace(rotations=clip.rotations[:0], translations=clip.translations[:0],
                                    times=clip.times[:0]))
    rc, out, err = cli(capsys, "info", path)
    assert rc == 0, err
    assert "rows:         0" in out and "hierarchy: 24 joints (5 end sites, 1 root)" in out
    rc, _, err = cli(capsys, "convert", path, tmp_path / "p.npy", "--to", "positions")
    assert rc == 0, err
    assert np.load(tmp_path / "p.npy").shape == (0, 24, 3)
    rc, _, err = cli(capsys, "resample", path, tmp_path / "r.bvh", "--rate", 30)
    assert rc == 0, err
    assert io.read_bvh(tmp_path / "r.bvh").frames == 0
    rc, _, err = cli(capsys, "convert", path, tmp_path / "q.csv", "--to", "quat")
    assert rc == 1 and "no valid rows left" in err
