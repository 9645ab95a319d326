"""quatarray.io.bvh: read_bvh / write_bvh of whole clips."""

import time

import numpy as np
import pytest
from test_skeleton import ORDERS, pos_ch, rot_ch, six_orders_file

import quatarray as qa
from quatarray import io
from quatarray.io import sample_path
from quatarray.io.bvh import exact_euler


def roundtrip(clip, path):
    io.write_bvh(path, clip)
    back = io.read_bvh(path)
    assert back.joints == clip.joints and list(back.parents) == list(clip.parents)
    assert back.channels == clip.channels and back.orders == clip.orders and list(back.ends) == list(clip.ends)
    np.testing.assert_array_equal(back.offsets, clip.offsets)
    assert qa.distance(back.rotations, clip.rotations).max(initial=0.0) < 1e-9
    np.testing.assert_allclose(back.world()[1], clip.world()[1], rtol=0, atol=1e-9)
    return back


def test_roundtrip_real_files(data_dir, tmp_path):
    for name in ("mocapbank_walk.bvh", "free_mocap.bvh"):
        clip = io.read_bvh(data_dir / name)
        back = roundtrip(clip, tmp_path / name)
        assert back.frame_time == clip.frame_time
        np.testing.assert_array_equal(back.translations, clip.translations)


def test_roundtrip_sample_and_written_file(tmp_path, rng):
    roundtrip(io.read_bvh(sample_path()), tmp_path / "walk.bvh")
    clip = io.read_bvh(six_orders_file(str(tmp_path / "six.bvh"), rng))
    roundtrip(clip, tmp_path / "six_back.bvh")
    roundtrip(clip.resample(rate=73.0), tmp_path / "six_73.bvh")


@pytest.mark.parametrize("order", ORDERS)
def test_exact_euler_random_locked_and_near_lock(order, rng):
    n = 600
    a = rng.uniform(-180, 180, (n, 3))
    a[:, 1] = rng.uniform(-90, 90, n)
    dist = np.concatenate([np.zeros(100), 10 ** rng.uniform(-8, -6, 300)])  # rad from lock
    a[:400, 1] = rng.choice([-1, 1], 400) * (90 - np.degrees(dist))
    q = qa.from_euler(order, a, degrees=True)
    ang = exact_euler(q, order)
    assert qa.distance(qa.from_euler(order, ang), q).max() < 1e-14
    assert np.abs(ang).max() <= np.pi and np.abs(ang[:, 1]).max() <= np.pi / 2
    # scipy's snapped angles (what a plain as_euler would write) lose ~1e-7 rad near lock
    plain = qa.as_euler(q, order, suppress_warnings=True)
    assert qa.distance(qa.from_euler(order, plain), q).max() > 1e-9


def test_write_locked_frames_round_trip(tmp_path, rng):
    """Every joint of a 6-order skeleton at and near gimbal lock, written and read back."""
    path = six_orders_file(str(tmp_path / "six.bvh"), rng, frames=60)
    clip = io.read_bvh(path)
    rot = clip.rotations.copy()
    for j, order in enumerate(clip.orders):
        if order:
            a = rng.uniform(-180, 180, (60, 3))
            a[:, 1] = rng.choice([-1, 1], 60) * (90 - np.degrees(np.r_[np.zeros(20), 10 ** rng.uniform(-8, -6, 40)]))
            rot[:, j] = qa.from_euler(order, a, degrees=True)
    roundtrip(clip.replace(rotations=rot), tmp_path / "locked.bvh")


def test_end_sites_and_orders():
    clip = io.read_bvh(sample_path())
    assert len(clip.joints) == 24 and clip.ends.sum() == 5
    assert clip.orders[0] == "ZXY" and clip.orders[7] == ""
    assert clip.channels[7] == () and clip.parents[7] == 6
    # End Site: fixed offset, identity rotation
    np.testing.assert_array_equal(clip.translations[:, 7], np.broadcast_to(clip.offsets[7], (455, 3)))
    np.testing.assert_array_equal(clip.rotations[:, 7], np.broadcast_to([1.0, 0, 0, 0], (455, 4)))
    # the root's translation is its position channels, a child's its OFFSET
    np.testing.assert_array_equal(clip.translations[0, 0], [-44.0003, 93.5663, 229.0256])
    np.testing.assert_array_equal(clip.translations[:, 1], np.broadcast_to(clip.offsets[1], (455, 3)))
    np.testing.assert_allclose(clip.times[:3], [0, 0.033333, 0.066666])


def test_agrees_with_stream_reader():
    """Each joint as read by the one-joint stream reader."""
    clip = io.read_bvh(sample_path())
    for j in (0, 5, 13):
        c = io.concat(list(io.open_stream(sample_path(), fmt="bvh", joint=clip.joints[j])))
        assert qa.distance(c.data, clip.rotations[:, j]).max() < 1e-15


def test_read_large_clip_in_seconds(tmp_path, rng):
    """100 000 frames × 30 joints (96 channels)."""
    J = 30
    chain = None
    for k in range(J - 1):
        chain = (f"j{k}", [0.0, 1.0, 0.0], rot_ch("ZXY"), [chain] if chain else [])
    motion = np.round(rng.uniform(-180, 180, (100_000, 6 + 3 * (J - 1))), 4)
    path = str(tmp_path / "big.bvh")
    # written with numpy (the test's own writer formats row by row: too slow here)
    with open(path, "w") as f:
        f.write("HIERARCHY\nROOT hips\n{\n OFFSET 0 0 0\n CHANNELS 6 " + " ".join(pos_ch() + rot_ch("ZXY")) + "\n")
        stack = [chain]
        lines = []

        def emit(node):
            name, off, chans, kids = node
            lines.extend([f"JOINT {name}", "{", f"OFFSET {off[0]} {off[1]} {off[2]}",
                          f"CHANNELS 3 {' '.join(chans)}"])
            for kk in kids:
                emit(kk)
            lines.append("}")

        emit(stack[0])
        f.write("\n".join(lines) + "\n}\nMOTION\nFrames: 100000\nFrame Time: 0.01\n")
        np.savetxt(f, motion, fmt="%.4f")
    t = time.perf_counter()
    clip = io.read_bvh(path)
    took = time.perf_counter() - t
    assert clip.rotations.shape == (100_000, J, 4)
    np.testing.assert_array_equal(clip.translations[:, 0], motion[:, :3])
    assert took < 15, took  # a few seconds on a loaded 2-core machine


# --------------------------------------------------------------------------
# bad files


GOOD = """HIERARCHY
ROOT hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT knee
  {
    OFFSET 0 -1 0
    CHANNELS 3 Xrotation Yrotation Zrotation
    End Site
    {
      OFFSET 0 -1 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.1
0 1 2 10 20 30 1 2 3
0 1 2 11 21 31 4 5 6
"""


def bad(tmp_path, text):
    path = tmp_path / "bad.bvh"
    path.write_text(text)
    with pytest.raises(io.DataError) as exc:
        io.read_bvh(path)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(str(path))
    return msg[len(str(path)):]


def test_good_small_file(tmp_path):
    path = tmp_path / "good.bvh"
    path.write_text(GOOD)
    clip = io.read_bvh(path)
    assert clip.joints == ["hips", "knee", "knee_End"] and clip.orders == ["ZXY", "XYZ", ""]
    assert qa.distance(clip.rotations[1, 1], qa.from_euler("XYZ", [4, 5, 6], degrees=True)) < 1e-15


@pytest.mark.parametrize("text, where, what", [
    (GOOD.replace("    CHANNELS 3 Xrotation Yrotation Zrotation\n", ""), ":6:", "has no CHANNELS"),
    (GOOD.replace("0 1 2 11 21 31 4 5 6", "0 1 2 11 21 31 4 5"), ":20:", "expected 9 numbers, got 8"),
    (GOOD.replace("0 1 2 10 20 30 1 2 3", "0 1 2 10 20 30 1 2 3 4"), ":19:", "expected 9 numbers, got 10"),
    (GOOD.replace("Frames: 2", "Frames: 3"), ":17:", "'Frames:' says 3 frames, the file holds 2"),
    (GOOD + "0 1 2 11 21 31 4 5 6\n", ":17:", "'Frames:' says 2 frames, the file holds 3"),
    (GOOD.replace("11 21 31 4", "11 21 x31 4"), ":20:", "not a number: 'x31'"),
    (GOOD.replace("11 21 31 4", "11 21 3.1e 4"), ":20:", "not a number: '3.1e'"),
    (GOOD.replace("Xrotation Yrotation Zrotation", "Xrotation Xrotation Zrotation"), ":9:", "each axis at most once"),
    (GOOD.replace("CHANNELS 3 Xrotation", "CHANNELS 4 Xrotation"), ":9:", "says 4 channels, lists 3"),
    (GOOD.replace("    OFFSET 0 -1 0\n    CHANNELS", "    CHANNELS"), ":6:", "has no OFFSET"),
    (GOOD.replace("}\nMOTION", "MOTION"), ":15:", "missing '}'"),
    (GOOD.replace("11 21 31", "11 21 1e12"), ":20:", "out of range"),
    (GOOD.replace("11 21 31 4", "11 21 31 6_0"), ":20:", "not a number: '6_0'"),  # Python's float reads 60
    (GOOD.replace("0 1 2 10 20", "0 1 2 1\u0661 20"), ":19:", "not a number"),  # an Arabic-Indic digit
    (GOOD.replace("OFFSET 0 -1 0\n    CHANNELS", "OFFSET 0 -1_0 0\n    CHANNELS"), ":8:", "not a number: '-1_0'"),
    (GOOD.replace("Frame Time: 0.1", "Frame Time: 0_1"), ":18:", "bad frame time '0_1'"),
    (GOOD.replace("Frames: 2", "Frames: 0"), ":17:", "'Frames:' says 0 frames, the file holds 2"),
    (GOOD.replace("Xrotation Yrotation Zrotation", "Xrotation Zposition Zposition"), ":9:", "each axis at most once"),
], ids=["no-channels", "short-frame", "long-frame", "frames-more", "frames-fewer", "word", "bad-exponent",
        "repeated-axis", "channel-count", "no-offset", "unclosed", "huge-angle", "underscore", "other-digits",
        "offset-underscore", "frame-time-underscore", "frames-zero-but-some", "repeated-position"])
def test_bad_files_one_line_naming_the_line(tmp_path, text, where, what):
    msg = bad(tmp_path, text)
    assert msg.startswith(where) and what in msg, msg


def test_bad_file_without_motion(tmp_path):
    assert "no MOTION section" in bad(tmp_path, GOOD.split("MOTION")[0])


def test_write_refuses_what_bvh_cannot_hold(tmp_path):
    path = tmp_path / "good.bvh"
    path.write_text(GOOD)
    clip = io.read_bvh(path)
    tr = clip.translations.copy()
    tr[:, 1, 0] += 1.0  # the knee moves along x: it has no position channel
    with pytest.raises(ValueError, match="no position channel"):
        io.write_bvh(tmp_path / "out.bvh", clip.replace(translations=tr))
    assert not (tmp_path / "out.bvh").exists()


# --------------------------------------------------------------------------
# issue 36: nested End Sites, hinges, BOM and CR, names, 0 frames


NESTED = GOOD.replace("""    End Site
    {
      OFFSET 0 -1 0
    }""", """    End Site
    {
      OFFSET 0 -1 0
      End Site
      {
        OFFSET 0 0 -0.25
      }
    }""")


def test_nested_end_sites_written_as_read(tmp_path):
    """An End Site inside an End Site (read as <name>_End_End) is written back, not dropped."""
    path = tmp_path / "nested.bvh"
    path.write_text(NESTED)
    clip = io.read_bvh(path)
    assert clip.joints == ["hips", "knee", "knee_End", "knee_End_End"] and list(clip.parents) == [-1, 0, 1, 2]
    back = roundtrip(clip, tmp_path / "back.bvh")
    np.testing.assert_array_equal(back.offsets[3], [0, 0, -0.25])
    assert (tmp_path / "back.bvh").read_text().count("End Site") == 2
    roundtrip(clip.resample(rate=25), tmp_path / "resampled.bvh")


HINGES = GOOD.replace("CHANNELS 3 Xrotation Yrotation Zrotation", "CHANNELS 1 Xrotation").replace(
    " 1 2 3\n", "\n").replace(" 4 5 6\n", " 50\n").replace("0 1 2 10 20 30\n", "0 1 2 10 20 30 -170\n").replace(
    """  JOINT knee""", """  JOINT wrist
  {
    OFFSET 1 0 0
    CHANNELS 2 Zrotation Yrotation
  }
  JOINT knee""").replace("0 1 2 10 20 30 -170", "0 1 2 10 20 30 15 -25 -170").replace(
    "0 1 2 11 21 31 50", "0 1 2 11 21 31 179 89 50")


def test_hinge_joints_round_trip(tmp_path):
    """CHANNELS 1 Xrotation (a hinge) and CHANNELS 2: read as rotations about those axes,
    written with their own channels and read back; a resampled clip too."""
    path = tmp_path / "hinges.bvh"
    path.write_text(HINGES)
    clip = io.read_bvh(path)
    assert clip.orders == ["ZXY", "ZY", "X", ""] and clip.channels[2] == ("Xrotation",)
    assert qa.distance(clip.rotations[:, 2], qa.from_euler("X", [[-170], [50]], degrees=True)).max() < 1e-15
    assert qa.distance(clip.rotations[:, 1], qa.from_euler("ZY", [[15, -25], [179, 89]], degrees=True)).max() < 1e-15
    back = roundtrip(clip, tmp_path / "back.bvh")
    text = (tmp_path / "back.bvh").read_text()
    assert "CHANNELS 1 Xrotation\n" in text and "CHANNELS 2 Zrotation Yrotation\n" in text
    np.testing.assert_array_equal(back.translations, clip.translations)
    for method in ("bezier", "cubic"):
        roundtrip(clip.resample(rate=30, method=method), tmp_path / f"{method}.bvh")


def test_write_refuses_a_hinge_turning_off_its_axis(tmp_path):
    path = tmp_path / "hinges.bvh"
    path.write_text(HINGES)
    clip = io.read_bvh(path)
    rot = clip.rotations.copy()
    rot[1, 2] = qa.from_euler("XY", [50, 1e-6], degrees=True)  # the knee turns a little about y
    with pytest.raises(ValueError, match=r"'knee' has rotation channels about X only, but its rotation in frame 1"):
        io.write_bvh(tmp_path / "out.bvh", clip.replace(rotations=rot))
    assert not (tmp_path / "out.bvh").exists()


@pytest.mark.parametrize("encode", [
    lambda t: b"\xef\xbb\xbf" + t.encode(),  # a byte-order mark
    lambda t: t.replace("\n", "\r").encode(),  # old Mac line ends
    lambda t: t.replace("\n", "\r\n").encode(),  # Windows
    lambda t: b"\xef\xbb\xbf" + t.replace("\n", "\r").encode(),
], ids=["bom", "cr", "crlf", "bom-cr"])
def test_bom_and_line_ends(tmp_path, encode):
    path = tmp_path / "good.bvh"
    path.write_bytes(encode(GOOD))
    clip = io.read_bvh(path)
    path.write_text(GOOD)
    ref = io.read_bvh(path)
    assert clip.joints == ref.joints and np.array_equal(clip.rotations, ref.rotations)
    np.testing.assert_array_equal(clip.translations, ref.translations)


def test_line_numbers_with_cr_line_ends(tmp_path):
    path = tmp_path / "bad.bvh"
    path.write_bytes(GOOD.replace("11 21 31 4", "11 21 x31 4").replace("\n", "\r").encode())
    with pytest.raises(io.DataError, match=r":20: not a number: 'x31'"):
        io.read_bvh(path)


@pytest.mark.parametrize("name", ["", " ", "left\nknee", "knee ", " knee", "left  knee", "left\tknee", "a\rb",
                                  "knee {", "\ud800"])
def test_write_refuses_names_it_cannot_read_back(tmp_path, name):
    path = tmp_path / "good.bvh"
    path.write_text(GOOD)
    clip = io.read_bvh(path)
    with pytest.raises(ValueError, match=r"Joint 1 has the name .* which BVH cannot hold"):
        io.write_bvh(tmp_path / "out.bvh", clip.replace(joints=["hips", name, "knee_End"]))
    assert not (tmp_path / "out.bvh").exists()
    ok = clip.replace(joints=["hips", "left knée", "left knée_End"])  # single spaces, any letters: read back
    assert roundtrip(ok, tmp_path / "ok.bvh").joints[1] == "left knée"


def test_zero_frame_clip_round_trips(tmp_path):
    """``Frames: 0`` is a hierarchy without motion: read as a clip of 0 frames, written back."""
    path = tmp_path / "empty.bvh"
    path.write_text(GOOD.split("0 1 2 10")[0].replace("Frames: 2", "Frames: 0"))
    clip = io.read_bvh(path)
    assert clip.frames == 0 and clip.rotations.shape == (0, 3, 4) and clip.frame_time == 0.1
    assert clip.world()[1].shape == (0, 3, 3)
    back = roundtrip(clip, tmp_path / "back.bvh")
    assert back.frames == 0 and "Frames: 0\n" in (tmp_path / "back.bvh").read_text()
    # without "Frames: 0" an empty MOTION block is still refused (frames were lost)
    path.write_text(GOOD.split("0 1 2 10")[0].replace("Frames: 2\n", ""))
    with pytest.raises(io.DataError, match="no frames"):
        io.read_bvh(path)


def test_stream_reader_reads_hinges(tmp_path):
    """The one-joint stream reader (info, convert, resample of a BVH's joint) reads a
    joint of 1 or 2 rotation channels as read_bvh does."""
    path = tmp_path / "hinges.bvh"
    path.write_text(HINGES)
    clip = io.read_bvh(path)
    for j, euler in ((1, "ZY"), (2, "X")):
        reader = io.open_stream(path, fmt="bvh", joint=clip.joints[j])
        c = io.concat(list(reader))
        assert reader.layout == f"euler {euler} (intrinsic, degrees)" and reader.seq is None
        assert qa.distance(c.data, clip.rotations[:, j]).max() < 1e-15
    path.write_text(HINGES.replace("CHANNELS 1 Xrotation", "CHANNELS 0"))
    with pytest.raises(io.DataError, match="has 0 rotation channels, need 1, 2 or 3"):
        io.open_stream(path, fmt="bvh", joint="knee")
