"""Tests for quatarray.io: readers, writers and the row checks."""

import os
from io import StringIO

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from quatarray import io
from quatarray.io import Chunk, Cleaner, DataError, UsageError


def unit(rng, n, dtype=np.float64):
    q = rng.standard_normal((n, 4))
    return (q / np.linalg.norm(q, axis=1)[:, None]).astype(dtype)


def read_all(reader, on_invalid="error", ordered=False):
    clean = Cleaner(reader, on_invalid, ordered=ordered)
    chunks = [clean(ch) for ch in reader]
    chunks = [c for c in chunks if len(c)]
    return io.concat(chunks), clean


def write(path, text):
    path.write_text(text)
    return str(path)


def fr(v):
    return repr(float(v))


def same_rotation(a, b, atol=1e-9):
    d = np.abs(np.sum(np.asarray(a) * np.asarray(b), axis=-1))
    return np.allclose(d, 1, atol=atol)


# --------------------------------------------------------------------------
# npy


def test_npy_reader_chunks_and_memmap(tmp_path, rng):
    q = unit(rng, 1000)
    p = tmp_path / "q.npy"
    np.save(p, q)
    r = io.open_stream(p, chunk=128)
    assert (r.format, r.rows, r.has_time, r.has_pos) == ("npy", 1000, False, False)
    chunks = list(r)
    assert [len(c) for c in chunks] == [128] * 7 + [104]
    assert isinstance(chunks[1].data, np.memmap)  # mapped, not loaded
    assert not chunks[1].data.flags.writeable
    assert chunks[3].row0 == 384
    np.testing.assert_array_equal(io.concat(chunks).data, q)


def test_npy_layout_dtype_and_matrices(tmp_path, rng):
    q = unit(rng, 50, np.float32)
    np.save(tmp_path / "xyzw.npy", q[:, [1, 2, 3, 0]])
    got, _ = read_all(io.open_stream(tmp_path / "xyzw.npy", layout="xyzw", chunk=16))
    assert got.data.dtype == np.float32
    np.testing.assert_array_equal(got.data, q)
    np.save(tmp_path / "int.npy", np.tile([1, 0, 0, 0], (3, 1)))
    got, _ = read_all(io.open_stream(tmp_path / "int.npy"))
    assert got.data.dtype == np.float64
    m = Rotation.from_quat(q.astype(float), scalar_first=True).as_matrix()
    np.save(tmp_path / "m.npy", m)
    got, _ = read_all(io.open_stream(tmp_path / "m.npy", chunk=7))
    assert same_rotation(got.data, q.astype(float), 1e-6)
    np.save(tmp_path / "f.npy", np.asfortranarray(q))
    got, _ = read_all(io.open_stream(tmp_path / "f.npy", chunk=8))
    np.testing.assert_array_equal(got.data, q)


@pytest.mark.parametrize(
    "arr, msg",
    [
        (np.zeros((5, 3)), r"expected quaternions of shape \(N, 4\).*got \(5, 3\)"),
        (np.zeros((5, 4), complex), "expected an array of real numbers"),
        (np.zeros((0, 4)), "empty file"),
    ],
)
def test_npy_bad(tmp_path, arr, msg):
    np.save(tmp_path / "bad.npy", arr)
    with pytest.raises(DataError, match=msg):
        io.open_stream(tmp_path / "bad.npy")


def test_npy_truncated_and_garbage(tmp_path):
    p = tmp_path / "t.npy"
    np.save(p, np.zeros((100, 4)))
    with open(p, "r+b") as f:
        f.truncate(500)
    with pytest.raises(DataError, match="truncated"):
        io.open_stream(p)
    g = write(tmp_path / "g.npy", "not numpy")
    with pytest.raises(DataError, match="not a valid .npy"):
        io.open_stream(g)


def test_npy_writer_incremental(tmp_path, rng):
    out = tmp_path / "o.npy"
    m = rng.standard_normal((25, 3, 3)).astype(np.float32)
    with io.open_writer(out, ["r"] * 9, core=(3, 3)) as w:
        for a in range(0, 25, 10):
            w.write(m[a : a + 10])
    back = np.load(out)
    assert back.dtype == np.float32
    np.testing.assert_array_equal(back, m)
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]
    with io.open_writer(tmp_path / "e.npy", ["qw", "qx", "qy", "qz"]) as w:
        pass
    assert np.load(tmp_path / "e.npy").shape == (0, 4)


# --------------------------------------------------------------------------
# text formats


def test_csv_named_columns_any_order(tmp_path, rng):
    q = unit(rng, 20)
    t = np.cumsum(rng.uniform(0.1, 0.2, 20))
    lines = ["qz,time,qx,X,qw,y,z,qy,extra"] + [
        f"{fr(q[i,3])},{fr(t[i])},{fr(q[i,1])},{i},{fr(q[i,0])},{2*i},{3*i},{fr(q[i,2])},foo" for i in range(20)
    ]
    p = write(tmp_path / "s.csv", "\n".join(lines) + "\n")
    r = io.open_stream(p, chunk=4)
    assert r.format == "csv" and r.has_time and r.has_pos
    got, _ = read_all(r)
    np.testing.assert_array_equal(got.data, q)  # full precision, reordered to wxyz
    np.testing.assert_array_equal(got.t, t)
    np.testing.assert_array_equal(got.pos, np.arange(20)[:, None] * [1, 2, 3])


@pytest.mark.parametrize("layout", ["wxyz", "xyzw"])
def test_csv_headerless_layouts(tmp_path, rng, layout):
    q = unit(rng, 6)
    cols = q if layout == "wxyz" else q[:, [1, 2, 3, 0]]
    t = np.arange(6) * 0.5
    p = write(tmp_path / "h.csv", "\n".join(",".join(map(fr, [t[i], *cols[i]])) for i in range(6)))
    got, _ = read_all(io.open_stream(p, layout=layout))
    np.testing.assert_array_equal(got.data, q)
    np.testing.assert_array_equal(got.t, t)


def test_csv_vectors(tmp_path):
    p = write(tmp_path / "v.csv", "x,y,z\n1,2,3\n4,5,6\n")
    got, _ = read_all(io.open_stream(p, kind="vector"))
    np.testing.assert_array_equal(got.data, [[1, 2, 3], [4, 5, 6]])
    p = write(tmp_path / "v2.csv", "1 2 3\n4 5 6\n")
    got, _ = read_all(io.open_stream(p, kind="vector"))
    np.testing.assert_array_equal(got.data, [[1, 2, 3], [4, 5, 6]])


def test_tum_comments_scalar_last(tmp_path):
    p = write(
        tmp_path / "traj.txt",
        "# ground truth\n# timestamp tx ty tz qx qy qz qw\n"
        "1305031098.6659 1.0 2.0 3.0 0 0 0.7071067811865476 0.7071067811865476\n"
        "1305031098.6759 1.5 2.5 3.5 0 0 0 1\n",
    )
    r = io.open_stream(p)
    assert (r.format, r.layout) == ("tum", "xyzw")
    got, _ = read_all(r)
    np.testing.assert_allclose(got.data, [[0.7071067811865476, 0, 0, 0.7071067811865476], [1, 0, 0, 0]])
    assert got.t[0] == 1305031098.6659
    np.testing.assert_array_equal(got.pos, [[1, 2, 3], [1.5, 2.5, 3.5]])


def test_euroc_nanoseconds(tmp_path):
    head = "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], v [m]\n"
    p = write(tmp_path / "gt.csv", head + "1403715524907143168,1,2,3,1,0,0,0,9\n1403715524912143104,1,2,3,0,1,0,0,9\n")
    r = io.open_stream(p)
    assert r.format == "euroc"
    got, _ = read_all(r)
    # seconds rounded once from the exact integer nanoseconds
    assert got.t[0] == 1403715524 + 0.907143168
    assert got.t[1] - got.t[0] == pytest.approx(0.004999936, abs=1e-6)
    np.testing.assert_array_equal(got.data, [[1, 0, 0, 0], [0, 1, 0, 0]])


def test_kitti_matrix_rows(tmp_path, rng):
    q = unit(rng, 5)
    m = Rotation.from_quat(q, scalar_first=True).as_matrix()
    tr = rng.standard_normal((5, 3))
    rows = np.concatenate([m, tr[:, :, None]], axis=2).reshape(5, 12)
    p = write(tmp_path / "poses.txt", "\n".join(" ".join(f"{v:.12e}" for v in r) for r in rows) + "\n")
    r = io.open_stream(p)
    assert r.format == "kitti" and r.has_pos and not r.has_time
    got, _ = read_all(r)
    assert same_rotation(got.data, q)
    np.testing.assert_allclose(got.pos, tr, rtol=1e-11)


def test_parquet_roundtrip(tmp_path, rng):
    q = unit(rng, 30)
    t = np.linspace(0, 1, 30)
    pos = rng.standard_normal((30, 3))
    out = tmp_path / "s.parquet"
    with io.open_writer(out, ["qw", "qx", "qy", "qz"], time=True, pos=True) as w:
        w.write(q[:10], t[:10], pos[:10])
        w.write(q[10:], t[10:], pos[10:])
    got, _ = read_all(io.open_stream(out, chunk=8))
    np.testing.assert_array_equal(got.data, q)
    np.testing.assert_array_equal(got.t, t)
    np.testing.assert_array_equal(got.pos, pos)


def test_csv_writer_full_precision_and_names(tmp_path, rng):
    q = unit(rng, 10)
    t = 1.0e9 + rng.uniform(0, 1, 10)
    out = tmp_path / "o.csv"
    with io.open_writer(out, ["qw", "qx", "qy", "qz"], time=True) as w:
        w.write(q, t)
    text = out.read_text().splitlines()
    assert text[0] == "t,qw,qx,qy,qz"
    back = np.loadtxt(out, delimiter=",", skiprows=1)
    np.testing.assert_array_equal(back[:, 0], t)
    np.testing.assert_array_equal(back[:, 1:], q)


def test_tum_writer(tmp_path):
    out = tmp_path / "o.txt"
    with io.open_writer(out, ["qw", "qx", "qy", "qz"], time=True, pos=True) as w:
        w.write(np.array([[1.0, 0, 0, 0]]), np.array([2.5]), np.array([[1.0, 2, 3]]))
    assert out.read_text().splitlines() == ["# timestamp tx ty tz qx qy qz qw", "2.5 1 2 3 0 0 0 1"]
    with pytest.raises(UsageError, match="TUM"):
        io.open_writer(tmp_path / "x.txt", ["qw", "qx", "qy", "qz"])


def test_writer_abort_leaves_nothing(tmp_path):
    out = tmp_path / "o.csv"
    out.write_text("precious")
    with pytest.raises(RuntimeError):
        with io.open_writer(out, ["qw", "qx", "qy", "qz"]) as w:
            w.write(np.ones((3, 4)))
            raise RuntimeError("boom")
    assert out.read_text() == "precious"
    assert sorted(os.listdir(tmp_path)) == ["o.csv"]


def test_check_output(tmp_path):
    a = tmp_path / "a.npy"
    a.write_bytes(b"x")
    with pytest.raises(UsageError, match="is the input"):
        io.check_output(a, [a], force=True)
    with pytest.raises(UsageError, match="is the input"):
        io.check_output(tmp_path / "." / "a.npy", [str(a)], force=True)
    with pytest.raises(UsageError, match="--force"):
        io.check_output(a, [tmp_path / "b.npy"])
    io.check_output(a, [tmp_path / "b.npy"], force=True)
    with pytest.raises(UsageError, match="does not exist"):
        io.check_output(tmp_path / "no" / "o.npy")
    with pytest.raises(UsageError, match="extension"):
        io.open_writer(tmp_path / "o.dat", ["qw"])


# --------------------------------------------------------------------------
# bad text files: the first bad line is named


@pytest.mark.parametrize(
    "text, msg",
    [
        ("t,qw,qx,qy,qz\n0,1,0,0,0\n1,1,0,0\n", r"f\.csv:3: expected 5 fields, got 4"),
        ("t,qw,qx,qy,qz\n0,1,0,0,0\n\n1,1,x1,0,0\n", r"f\.csv:4: not a number: 'x1' in column qx"),
        ("t,qw,qx,qy,qz\n0,1,0,0,0\n1,1,,0,0\n", r"f\.csv:3: empty field in column qx|f\.csv:3: quaternion is not finite"),
        ("t,qw,qx,qy,qz\n0,1,0,0,0\n1,0,0,0,0\n", r"f\.csv:3: zero quaternion"),
        ("t,qw,qx,qy,qz\n0,1,0,0,0\n1,inf,0,0,0\n", r"f\.csv:3: quaternion is not finite"),
        ("t,qw,qx,qy,qz\nnan,1,0,0,0\n", r"f\.csv:2: time is not a finite number"),
        ("", r"f\.csv: empty file"),
        ("t,qw,qx,qy,qz\n", r"f\.csv: empty file"),
        ("t,qw,qx,qy\n0,1,0,0\n", r"f\.csv:1: missing column qz"),
        ("1,0,0\n", r"f\.csv:1: expected 4 \(quaternion\).*got 3"),
    ],
)
def test_bad_csv(tmp_path, text, msg):
    p = write(tmp_path / "f.csv", text)
    with pytest.raises(DataError, match=msg):
        read_all(io.open_stream(p, name="f.csv"))


def test_tum_comment_lines_anywhere(tmp_path):
    p = write(
        tmp_path / "traj.txt",
        "# head\n1 0 0 0 0 0 0 1\n# a note recorded mid-stream\n2 0 0 0 0 0 1 0\n  # indented\n3 0 0 0 1 0 0 0\n",
    )
    got, clean = read_all(io.open_stream(p))
    np.testing.assert_array_equal(got.t, [1, 2, 3])
    np.testing.assert_allclose(got.data, [[1, 0, 0, 0], [0, 0, 0, 1], [0, 1, 0, 0]])
    # a comment is not a bad row: the same file with a broken line still names that line
    bad = write(tmp_path / "b.txt", "1 0 0 0 0 0 0 1\n# note\n2 0 0 0 0 0 1\n")
    with pytest.raises(DataError, match=r"b\.txt:3: expected 8 numbers, got 7"):
        read_all(io.open_stream(bad, name="b.txt"))


def test_bad_tum_line(tmp_path):
    p = write(tmp_path / "t.txt", "# c\n1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n")
    with pytest.raises(DataError, match=r"t\.txt:3: expected 8 numbers, got 7"):
        read_all(io.open_stream(p, name="t.txt"))


def test_drop_counts(tmp_path):
    p = write(
        tmp_path / "f.csv",
        "t,qw,qx,qy,qz\n0,1,0,0,0\n1,1,0,0\n2,1,abc,0,0\n3,0,0,0,0\n4,nan,0,0,0\n5,2,0,0,0\n5,1,0,0,0\n4,1,0,0,0\n6,1,0,0,0\n",
    )
    got, clean = read_all(io.open_stream(p, on_invalid="drop", chunk=2), "drop", ordered=True)
    np.testing.assert_array_equal(got.t, [0, 5, 6])
    np.testing.assert_array_equal(got.data, [[1, 0, 0, 0]] * 3)  # the (2, 0, 0, 0) row is normalised
    assert clean.reader.skipped == 1 and clean.dropped == 5
    assert clean.max_dev == 1.0
    import io as _io

    err = _io.StringIO()
    clean.report(err)
    assert "dropped 6 invalid rows" in err.getvalue()
    assert "normalised 1 non-unit quaternion (largest | |q| - 1 | = 1)" in err.getvalue()


def test_ordered_times_error_names_line(tmp_path):
    p = write(tmp_path / "f.csv", "t,qw,qx,qy,qz\n0,1,0,0,0\n1,1,0,0,0\n1,1,0,0,0\n")
    with pytest.raises(DataError, match=r"f\.csv:4: repeated time 1\.0"):
        read_all(io.open_stream(p, name="f.csv", chunk=2), ordered=True)
    q = Chunk(np.tile([1.0, 0, 0, 0], (4, 1)), np.array([0.0, 1, 2, 1.5]))
    r = io.open_stream(p)
    with pytest.raises(DataError, match="decreasing time 1.5"):
        Cleaner(r, ordered=True)(q)


def test_cleaner_float32_tolerance(tmp_path, rng):
    q = unit(rng, 100, np.float32)
    np.save(tmp_path / "q.npy", q)
    r = io.open_stream(tmp_path / "q.npy")
    got, clean = read_all(r)
    assert clean.normalised == 0 and got.data.dtype == np.float32


# --------------------------------------------------------------------------
# bvh


BVH = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Knee
  {
    OFFSET 0 -1 0
    CHANNELS 3 Yrotation Xrotation Zrotation
    End Site
    {
      OFFSET 0 -1 0
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.5
1 2 3 10 20 30 5 6 7
4 5 6 -40 50 170 8 9 10
7 8 9 90 0 -90 11 12 13
"""


def test_bvh_root_and_joint(tmp_path):
    p = write(tmp_path / "m.bvh", BVH)
    r = io.open_stream(p)
    assert (r.format, r.joint, r.seq, r.has_pos) == ("bvh", "Hips", "ZXY", True)
    got, _ = read_all(r)
    ang = np.array([[10, 20, 30], [-40, 50, 170], [90, 0, -90]], float)
    assert same_rotation(got.data, Rotation.from_euler("ZXY", ang, degrees=True).as_quat(scalar_first=True))
    np.testing.assert_array_equal(got.t, [0, 0.5, 1.0])
    np.testing.assert_array_equal(got.pos, [[1, 2, 3], [4, 5, 6], [7, 8, 9]])
    k = io.open_stream(p, joint="Knee")
    assert k.seq == "YXZ" and not k.has_pos
    got, _ = read_all(k)
    ang = np.array([[5, 6, 7], [8, 9, 10], [11, 12, 13]], float)
    assert same_rotation(got.data, Rotation.from_euler("YXZ", ang, degrees=True).as_quat(scalar_first=True))
    with pytest.raises(UsageError, match="no joint 'Elbow'"):
        io.open_stream(p, joint="Elbow")


def test_bvh_bad_frames(tmp_path):
    p = write(tmp_path / "m.bvh", BVH.replace("4 5 6 -40", "4 5 -40").replace("11 12 13", "11 x 13"))
    with pytest.raises(DataError, match=r"m\.bvh:20: expected 9 numbers, got 8"):
        read_all(io.open_stream(p, name="m.bvh"))
    got, clean = read_all(io.open_stream(p, on_invalid="drop"), "drop")
    assert len(got) == 1 and clean.reader.skipped == 2
    with pytest.raises(DataError, match="no MOTION"):
        io.open_stream(write(tmp_path / "n.bvh", BVH.split("MOTION")[0]))


# --------------------------------------------------------------------------
# times for resample --times


def test_read_times(tmp_path):
    np.save(tmp_path / "t.npy", np.array([0.0, 0.5]))
    np.testing.assert_array_equal(io.read_times(tmp_path / "t.npy"), [0, 0.5])
    p = write(tmp_path / "t.txt", "# times\n0.25\n0.75\n")
    np.testing.assert_array_equal(io.read_times(p), [0.25, 0.75])
    p = write(tmp_path / "s.csv", "t,qw,qx,qy,qz\n1,1,0,0,0\n2,1,0,0,0\n")
    np.testing.assert_array_equal(io.read_times(p), [1, 2])
    p = write(tmp_path / "b.txt", "0.25\nabc\n")
    with pytest.raises(DataError, match=r"b\.txt:2: not a number"):
        io.read_times(p, name="b.txt")


def test_read_times_locates_each_time(tmp_path):
    p = write(tmp_path / "t.txt", "# times\n\n0.25\n# gap\n0.75\n")
    t, where = io.read_times(p, name="t.txt", locate=True)
    assert list(t) == [0.25, 0.75] and where(0) == "t.txt:3" and where(1) == "t.txt:5"
    p = write(tmp_path / "s.tum", "# tum\n1 0 0 0 0 0 0 1\n2 0 0 0 0 0 0 1\n")
    t, where = io.read_times(p, name="s.tum", locate=True)
    assert list(t) == [1, 2] and where(1) == "s.tum:3"


@pytest.mark.parametrize("content", [b"garbage" * 10, None])
def test_read_times_garbage_npy(tmp_path, content):
    p = tmp_path / "t.npy"
    if content is None:
        np.save(p, np.array([{"a": 1}, 2], dtype=object), allow_pickle=True)
    else:
        p.write_bytes(content)
    with pytest.raises(DataError, match=r"t\.npy: not a valid \.npy float array") as exc:
        io.read_times(p, name="t.npy")
    assert "pickle" not in str(exc.value)


# --------------------------------------------------------------------------
# the real recordings


REAL = {
    "euroc_v102_groundtruth.csv": ("euroc", 16702, True, True),
    "tum_freiburg1_xyz_groundtruth.txt": ("tum", 3000, True, True),
    "tum_freiburg2_desk_groundtruth.txt": ("tum", 20957, True, True),
    "kitti_00_poses.txt": ("kitti", 4541, False, True),
    "mocapbank_walk.bvh": ("bvh", 455, True, True),
    "free_mocap.bvh": ("bvh", 69, True, True),
}


@pytest.mark.parametrize("name", sorted(REAL))
def test_real_files_read(data_dir, name):
    fmt, rows, has_t, has_pos = REAL[name]
    r = io.open_stream(data_dir / name, chunk=4096)
    assert (r.format, r.has_time, r.has_pos) == (fmt, has_t, has_pos)
    got, clean = read_all(r)
    assert len(got) == rows and clean.dropped == 0
    np.testing.assert_allclose(np.linalg.norm(got.data, axis=1), 1, atol=1e-12)


def test_real_tum_values(data_dir):
    got, _ = read_all(io.open_stream(data_dir / "tum_freiburg1_xyz_groundtruth.txt"))
    raw = np.loadtxt(data_dir / "tum_freiburg1_xyz_groundtruth.txt")
    np.testing.assert_array_equal(got.t, raw[:, 0])
    np.testing.assert_array_equal(got.pos, raw[:, 1:4])
    ref = raw[:, [7, 4, 5, 6]] / np.linalg.norm(raw[:, 4:8], axis=1)[:, None]
    np.testing.assert_allclose(got.data, ref, atol=1e-15)


def test_real_euroc_values(data_dir):
    got, _ = read_all(io.open_stream(data_dir / "euroc_v102_groundtruth.csv"))
    raw = np.loadtxt(data_dir / "euroc_v102_groundtruth.csv", delimiter=",", usecols=range(8))
    ns = np.loadtxt(data_dir / "euroc_v102_groundtruth.csv", delimiter=",", usecols=0, dtype=np.int64)
    np.testing.assert_array_equal(got.t, (ns // 10**9) + (ns % 10**9) * 1e-9)
    np.testing.assert_array_equal(got.pos, raw[:, 1:4])
    assert same_rotation(got.data, raw[:, 4:8] / np.linalg.norm(raw[:, 4:8], axis=1)[:, None], 1e-12)


def test_real_kitti_matches_scipy(data_dir):
    got, _ = read_all(io.open_stream(data_dir / "kitti_00_poses.txt"))
    raw = np.loadtxt(data_dir / "kitti_00_poses.txt").reshape(-1, 3, 4)
    ref = Rotation.from_matrix(raw[:, :, :3]).as_quat(scalar_first=True)
    assert same_rotation(got.data, ref, 1e-9)
    np.testing.assert_array_equal(got.pos, raw[:, :, 3])


def test_real_bvh_root_matches_scipy(data_dir):
    path = data_dir / "mocapbank_walk.bvh"
    got, _ = read_all(io.open_stream(path))
    lines = path.read_text().splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.startswith("Frame Time")) + 1
    motion = np.array([ln.split() for ln in lines[start:] if ln.strip()], float)
    ref = Rotation.from_euler("ZXY", motion[:, 3:6], degrees=True).as_quat(scalar_first=True)
    assert same_rotation(got.data, ref, 1e-12)
    np.testing.assert_allclose(got.t, np.arange(455) * 0.033333)


def test_euroc_bad_timestamp_error_and_drop(tmp_path):
    head = "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z []\n"
    p = write(tmp_path / "gt.csv", head + "1000000000,1,2,3,1,0,0,0\n10x0,1,2,3,1,0,0,0\n3000000000,1,2,3,0,1,0,0\n")
    with pytest.raises(DataError, match=r"gt\.csv:3: not an integer: '10x0' in column timestamp"):
        read_all(io.open_stream(p, name="gt.csv"))
    got, clean = read_all(io.open_stream(p, on_invalid="drop"), "drop")
    np.testing.assert_array_equal(got.t, [1.0, 3.0])
    assert clean.dropped == 1


def test_kitti_not_a_rotation(tmp_path):
    rows = ["1 0 0 0 0 1 0 0 0 0 1 0", "1 0 0 0 0 1 0 0 0 0 -1 0"]
    p = write(tmp_path / "k.txt", "\n".join(rows) + "\n")
    with pytest.raises(DataError, match=r"k\.txt:2: not a rotation matrix \(determinant -1\)"):
        read_all(io.open_stream(p, name="k.txt"))
    got, clean = read_all(io.open_stream(p, on_invalid="drop"), "drop")
    assert len(got) == 1 and clean.dropped == 1


# --------------------------------------------------------------------------
# hardening (issue 14): inputs other tools read


TUM_ROWS = [
    [1305031098.6659, 1.0, 2.0, 3.0, 0.0, 0.0, 0.7071067811865476, 0.7071067811865476],
    [1305031098.6759, 1.5, -2.5, 3.5, 0.0, 0.0, 0.0, 1.0],
    [1305031098.6859, 1.5, 2.5, 3.5, 0.5, 0.5, 0.5, 0.5],
]


def tum_text(rows, sep=" ", lead="", trail=""):
    return "".join(lead + sep.join(repr(v) for v in r) + trail + "\n" for r in rows)


def tum_want(rows):
    a = np.array(rows)
    return a[:, 0], a[:, 1:4], a[:, [7, 4, 5, 6]]


@pytest.mark.parametrize(
    "text",
    [
        tum_text(TUM_ROWS, lead="  "),
        tum_text(TUM_ROWS, sep="   "),
        tum_text(TUM_ROWS, trail="  "),
        tum_text(TUM_ROWS, trail="\t"),
        tum_text(TUM_ROWS, sep=" \t "),
        tum_text(TUM_ROWS, trail=" \r"),
        "# aligned\n" + "".join(" ".join(f"{v!r:>20}" for v in r) + "\n" for r in TUM_ROWS),
        "  # indented comment\n\n" + tum_text(TUM_ROWS[:1]) + "   \n" + tum_text(TUM_ROWS[1:], lead="\t"),
    ],
    ids=["leading", "runs", "trailing", "trailing-tab", "mixed", "crlf-space", "aligned", "comments-blanks"],
)
def test_tum_any_whitespace_separates(tmp_path, text):
    p = write(tmp_path / "traj.txt", text)
    np.testing.assert_array_equal(np.loadtxt(p), TUM_ROWS)  # what numpy reads, we read
    r = io.open_stream(p)
    assert r.format == "tum"
    got, _ = read_all(r)
    t, pos, q = tum_want(TUM_ROWS)
    np.testing.assert_array_equal(got.t, t)
    np.testing.assert_array_equal(got.pos, pos)
    np.testing.assert_allclose(got.data, q, atol=1e-15)


def test_whitespace_errors_still_name_the_line(tmp_path):
    rows = ["   " + "   ".join(f"{v!r:>18}" for v in r) + "  " for r in TUM_ROWS]
    rows[2] = rows[2].rsplit(" ", 3)[0]  # a short row
    p = write(tmp_path / "t.txt", "# c\n\n" + "\n".join(rows) + "\n")
    with pytest.raises(DataError, match=r"t\.txt:5: expected 8 numbers, got 7"):
        read_all(io.open_stream(p, name="t.txt"))
    rows = tum_text(TUM_ROWS, lead=" ", sep="  ").replace("0.5 ", "x ", 1)
    with pytest.raises(DataError, match=r"t\.txt:3: not a number: 'x'"):
        read_all(io.open_stream(write(tmp_path / "t.txt", rows), name="t.txt"))


def test_kitti_aligned_columns(tmp_path, rng):
    q = unit(rng, 4)
    m = Rotation.from_quat(q, scalar_first=True).as_matrix()
    rows = np.concatenate([m, rng.standard_normal((4, 3, 1))], axis=2).reshape(4, 12)
    text = "".join(" " + "  ".join(f"{v: .12e}" for v in r) + " \t\n" for r in rows)
    r = io.open_stream(write(tmp_path / "poses.txt", text))
    assert r.format == "kitti"
    got, _ = read_all(r)
    assert same_rotation(got.data, q)


BOM = "\ufeff"
F_TUM = ["timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"]


def test_byte_order_mark(tmp_path, rng):
    p = write(tmp_path / "traj.txt", BOM + "# timestamp tx ty tz qx qy qz qw\n" + tum_text(TUM_ROWS))
    got, _ = read_all(io.open_stream(p))
    np.testing.assert_array_equal(got.t, tum_want(TUM_ROWS)[0])
    p = write(tmp_path / "bare.txt", BOM + tum_text(TUM_ROWS))  # the mark before the first number
    got, _ = read_all(io.open_stream(p))
    np.testing.assert_array_equal(got.t, tum_want(TUM_ROWS)[0])
    m = Rotation.from_quat(unit(rng, 2), scalar_first=True).as_matrix()
    rows = np.concatenate([m, np.zeros((2, 3, 1))], axis=2).reshape(2, 12)
    p = write(tmp_path / "poses.txt", BOM + "\n".join(" ".join(f"{v:.12e}" for v in r) for r in rows) + "\n")
    assert len(read_all(io.open_stream(p))[0]) == 2
    head = "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z []\n"
    p = write(tmp_path / "gt.csv", BOM + head + "1403715524907143168,1,2,3,1,0,0,0\n")
    r = io.open_stream(p)
    assert r.format == "euroc" and read_all(r)[0].t[0] == 1403715524 + 0.907143168
    p = write(tmp_path / "s.csv", BOM + "t,qw,qx,qy,qz\n0,1,0,0,0\n")
    assert read_all(io.open_stream(p))[0].data.tolist() == [[1, 0, 0, 0]]


@pytest.mark.parametrize("sep", [" ", ","])
def test_hash_header_without_space_is_tum(tmp_path, sep):
    p = write(tmp_path / "traj.txt", "#" + sep.join(F_TUM) + "\n" + tum_text(TUM_ROWS, sep=sep))
    r = io.open_stream(p)
    assert (r.format, r.layout) == ("tum", "xyzw") and not r.notes
    got, _ = read_all(r)
    t, pos, q = tum_want(TUM_ROWS)
    np.testing.assert_array_equal(got.pos, pos)
    np.testing.assert_allclose(got.data, q, atol=1e-15)


def test_comment_header_names_columns(tmp_path):
    p = write(tmp_path / "s.csv", "# t,qx,qy,qz,qw\n0,0,0,1,0\n1,1,0,0,0\n")
    r = io.open_stream(p)
    assert r.layout == "named columns" and not r.notes
    np.testing.assert_array_equal(read_all(r)[0].data, [[0, 0, 0, 1], [0, 1, 0, 0]])
    # a comment that is no header for these rows stays a comment
    p = write(tmp_path / "c.csv", "# recorded,by,a,robot,today\n0,1,0,0,0\n")
    assert io.open_stream(p).layout == "wxyz"


def test_quoted_header_names(tmp_path):
    p = write(tmp_path / "s.csv", '"t","qx","qy","qz","qw"\n0,0,0,1,0\n"1","1","0","0","0"\n')
    got, _ = read_all(io.open_stream(p))
    np.testing.assert_array_equal(got.t, [0, 1])
    np.testing.assert_array_equal(got.data, [[0, 0, 0, 1], [0, 1, 0, 0]])
    p = write(tmp_path / "r.csv", "t,qw,qx,qy,qw\n0,1,0,0,0\n")
    with pytest.raises(DataError, match=r"r\.csv:1: repeated column name 'qw' in the header"):
        io.open_stream(p, name="r.csv")


def test_headerless_layout_is_said(tmp_path):
    rows = "\n".join(",".join(repr(v) for v in r) for r in TUM_ROWS) + "\n"
    p = write(tmp_path / "c.csv", rows)
    r = io.open_stream(p, name="c.csv")
    assert r.notes == ["c.csv: no column names: read as t x y z qw qx qy qz (scalar first); "
                       "choose with --layout xyzw or --format tum"]
    for kw in ({"layout": "xyzw"}, {"fmt": "tum"}):  # the two ways to read TUM numbers with commas
        r = io.open_stream(p, **kw)
        assert not r.notes
        np.testing.assert_allclose(read_all(r)[0].data, tum_want(TUM_ROWS)[2], atol=1e-15)
    r = io.open_stream(write(tmp_path / "s.txt", tum_text(TUM_ROWS)), name="s.txt")
    assert r.format == "tum" and r.notes == []  # the TUM format's own layout is no guess (issue 36)
    r = io.open_stream(tmp_path / "s.txt", layout="wxyz")  # the same numbers, scalar first
    np.testing.assert_allclose(read_all(r)[0].data, np.array(TUM_ROWS)[:, 4:], atol=1e-15)
    err = StringIO()
    c = Cleaner(io.open_stream(p, name="c.csv"))
    c.report(err)
    assert err.getvalue().startswith("c.csv: no column names")


def test_layout_on_named_columns_is_ignored(tmp_path):
    p = write(tmp_path / "s.csv", "t,qw,qx,qy,qz\n0,0,1,0,0\n")
    r = io.open_stream(p, layout="xyzw", name="s.csv")
    assert r.notes == ["s.csv: --layout xyzw ignored: the file names its columns"]
    np.testing.assert_array_equal(read_all(r)[0].data, [[0, 1, 0, 0]])


@pytest.mark.parametrize("says, cut", [(1000, 0), (2, 0), (3, 1)], ids=["too-few", "too-many", "cut-short"])
def test_bvh_frame_count_checked(tmp_path, says, cut):
    text = BVH.replace("Frames: 3", f"Frames: {says}")
    if cut:
        text = text[: text.rindex("7 8 9 90")]  # the last frame lost
    p = write(tmp_path / "m.bvh", text)
    held = 3 - cut
    with pytest.raises(DataError, match=rf"^m\.bvh:17: 'Frames:' says {says} frames, the file holds {held}$"):
        read_all(io.open_stream(p, name="m.bvh"))
    got, clean = read_all(io.open_stream(p, name="m.bvh", on_invalid="drop"), "drop")
    assert len(got) == held
    err = StringIO()
    clean.report(err)
    assert err.getvalue() == f"m.bvh:17: 'Frames:' says {says} frames, the file holds {held}; read those {held}\n"


def test_bvh_huge_angles_refused(tmp_path):
    p = write(tmp_path / "m.bvh", BVH.replace("-40 50 170", "-40 1e308 170"))
    with pytest.raises(DataError, match=r"^m\.bvh:20: angle 1e\+308 out of range \(\|angle\| > 1e\+09 degrees"):
        read_all(io.open_stream(p, name="m.bvh"))
    got, clean = read_all(io.open_stream(p, on_invalid="drop"), "drop")
    np.testing.assert_array_equal(got.t, [0, 1])
    assert clean.dropped == 1


def report_of(reader, **kw):
    got, clean = read_all(reader, **kw)
    err = StringIO()
    clean.report(err)
    return got, err.getvalue()


def test_real_text_precision_not_reported(data_dir, tmp_path):
    for name in ("tum_freiburg1_xyz_groundtruth.txt", "tum_freiburg2_desk_groundtruth.txt", "kitti_00_poses.txt"):
        got, err = report_of(io.open_stream(data_dir / name))
        assert err == "", name
        np.testing.assert_allclose(np.linalg.norm(got.data, axis=1), 1, atol=1e-15)  # still normalised
    # one row put off its rotation by more than its 7 digits explain
    lines = (data_dir / "kitti_00_poses.txt").read_text().splitlines()
    f = lines[100].split()
    f[0] = f"{float(f[0]) * 1.001:.6e}"
    lines[100] = " ".join(f)
    p = write(tmp_path / "k.txt", "\n".join(lines) + "\n")
    _, err = report_of(io.open_stream(p, name="k.txt"))
    assert err == ("k.txt: projected 1 non-orthonormal rotation matrix (largest |R^T R - I| = 0.00195)\n")
    lines = (data_dir / "tum_freiburg1_xyz_groundtruth.txt").read_text().splitlines()
    f = lines[10].split()
    f[7] = f"{float(f[7]) * 1.01:.4f}"
    lines[10] = " ".join(f)
    p = write(tmp_path / "t.txt", "\n".join(lines) + "\n")
    _, err = report_of(io.open_stream(p, name="t.txt"))
    assert err.startswith("t.txt: normalised 1 non-unit quaternion (largest | |q| - 1 | = 0.00")


def test_nine_decimal_text_float32_noise_not_reported(tmp_path, rng):
    q = unit(rng, 50).astype(np.float32).astype(np.float64) * (1 + 1.1e-7)
    p = write(tmp_path / "t.txt", "".join(f"{i} 0 0 0 " + " ".join(f"{v:.9f}" for v in r[[1, 2, 3, 0]]) + "\n"
                                          for i, r in enumerate(q)))
    got, err = report_of(io.open_stream(p))
    assert "normalised" not in err
    np.testing.assert_allclose(np.linalg.norm(got.data, axis=1), 1, atol=1e-15)
    p = write(tmp_path / "u.txt", open(p).read().replace(f"{q[3, 0]:.9f}\n", f"{q[3, 0] * 1.001:.9f}\n"))
    assert "normalised 1 non-unit quaternion" in report_of(io.open_stream(p))[1]


def test_npy_matrices_not_orthonormal_reported(tmp_path, rng):
    m = Rotation.from_quat(unit(rng, 10), scalar_first=True).as_matrix()
    np.save(tmp_path / "m.npy", m)
    assert report_of(io.open_stream(tmp_path / "m.npy"))[1] == ""
    m[[2, 5]] *= np.array([1.01, 1.0001])[:, None, None]
    np.save(tmp_path / "m.npy", m)
    got, err = report_of(io.open_stream(tmp_path / "m.npy", name="m.npy"))
    assert err == "m.npy: projected 2 non-orthonormal rotation matrices (largest |R^T R - I| = 0.0201)\n"
    assert same_rotation(got.data[2], Rotation.from_matrix(m[2] / 1.01).as_quat(scalar_first=True))


@pytest.mark.parametrize("scale", [1e308, 1e-200, -1e300])
def test_huge_and_tiny_quaternions_read_correctly(tmp_path, rng, scale):
    q = unit(rng, 3)
    raw = q.copy()
    raw[1] = np.array([1.0, 1, 1, 1]) * scale
    np.save(tmp_path / "q.npy", raw)
    got, err = report_of(io.open_stream(tmp_path / "q.npy", name="q.npy"))
    np.testing.assert_allclose(got.data, np.vstack([q[0], np.sign(scale) * np.full(4, 0.5), q[2]]), atol=1e-15)
    assert err.startswith("q.npy: normalised 1 non-unit quaternion (largest | |q| - 1 | = ")
    if scale == 1e308:
        assert err.endswith("= > 1.8e+308)\n")
    p = write(tmp_path / "z.csv", "qw,qx,qy,qz\n0,0,0,0\n")
    with pytest.raises(DataError, match=r"z\.csv:2: zero quaternion"):
        read_all(io.open_stream(p, name="z.csv"))


@pytest.mark.parametrize(
    "raw, msg",
    [
        (b"t,qw,qx,qy,qz\n0,1,0,0,0\n1,\x1b[31m\x00x,0,0,0\n",
         r"^b\.csv:3: not a number: '\\x1b\[31m\\x00x' in column qw$"),
        (b"1 0 0 0 0 0 0 1\n2 0 0 0 0 0 0 \x07" + b"z" * 200 + b"\n",
         r"^b\.csv:2: not a number: '\\x07z{55}…' in column qw$"),
        (b"\x00\x01\x02\xff,\x1b[2J" + b"y" * 100 + b"\n1,2\n",
         r"the header has \\x00\\x01\\x02\\xff, \\x1b\[2Jy+…\)$"),
    ],
    ids=["control", "long", "header"],
)
def test_binary_bytes_escaped_in_messages(tmp_path, raw, msg):
    (tmp_path / "b.csv").write_bytes(raw)
    with pytest.raises(DataError, match=msg) as info:
        read_all(io.open_stream(tmp_path / "b.csv", name="b.csv"))
    assert str(info.value).isprintable() and len(str(info.value)) < 160
