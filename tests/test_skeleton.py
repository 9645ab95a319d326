"""quatarray.skeleton: forward kinematics and resampling of whole clips, against an
independent reference (a small BVH parser here, scipy rotations, a plain Python
loop down the hierarchy)."""

import itertools
import os
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import quatarray as qa
from quatarray import io
from quatarray.io import sample_path
from quatarray.skeleton import Clip

ORDERS = ["".join(p) for p in itertools.permutations("XYZ")]


# --------------------------------------------------------------------------
# an independent reference


def parse_reference(path):
    """(joints [(name, parent, offset, channels, is_end)], frame_time, motion (F, C)) by plain tokens."""
    tok = open(path).read().split()
    i = 0
    joints, stack = [], []
    while tok[i] != "MOTION":
        w = tok[i]
        if w in ("ROOT", "JOINT") or (w == "End" and tok[i + 1] == "Site"):
            end = w == "End"
            name = (joints[stack[-1]][0] + "_End") if end else tok[i + 1]
            joints.append([name, stack[-1] if stack else -1, None, (), end])
            i += 2
        elif w == "{":
            stack.append(len(joints) - 1)
            i += 1
        elif w == "}":
            stack.pop()
            i += 1
        elif w == "OFFSET":
            joints[stack[-1]][2] = [float(x) for x in tok[i + 1:i + 4]]
            i += 4
        elif w == "CHANNELS":
            k = int(tok[i + 1])
            joints[stack[-1]][3] = tuple(tok[i + 2:i + 2 + k])
            i += 2 + k
        else:
            i += 1
    frames = int(tok[i + 2])
    frame_time = float(tok[i + 5])
    vals = np.array(tok[i + 6:], dtype=float).reshape(frames, -1)
    return joints, frame_time, vals


def reference_world(path):
    """World rotations (scipy Rotations per joint) and positions (F, J, 3)."""
    joints, _, vals = parse_reference(path)
    F = len(vals)
    col = 0
    Rw, Pw = [], []
    for name, parent, offset, chans, end in joints:
        t = np.tile(offset, (F, 1))
        order = ""
        angles = []
        for c in chans:
            if c.endswith("position"):
                t[:, "XYZ".index(c[0])] = vals[:, col]
            else:
                order += c[0]
                angles.append(vals[:, col])
            col += 1
        R = Rotation.from_euler(order, np.column_stack(angles), degrees=True) if order else Rotation.identity(F)
        if parent < 0:
            Rw.append(R)
            Pw.append(t)
        else:
            Rw.append(Rw[parent] * R)
            Pw.append(Pw[parent] + Rw[parent].apply(t))
    return Rw, np.stack(Pw, axis=1), joints


def check_against_reference(path, clip=None):
    clip = io.read_bvh(path) if clip is None else clip
    Rw, Pw, joints = reference_world(path)
    assert clip.joints == [j[0] for j in joints]
    assert list(clip.parents) == [j[1] for j in joints]
    q, p = clip.world()
    scale = max(1.0, np.abs(Pw).max())
    np.testing.assert_allclose(p, Pw, rtol=0, atol=1e-12 * scale)
    for j, R in enumerate(Rw):
        assert qa.distance(q[:, j], R.as_quat(scalar_first=True)).max() < 1e-12
    return clip


# --------------------------------------------------------------------------
# files written here (the writer is a plain format string: independent of write_bvh)


def write_text_bvh(path, roots, motion, frame_time=0.04):
    """roots: nested (name, offset, channels, children) tuples; children may be "end" offsets."""
    lines = ["HIERARCHY"]

    def emit(node, depth, kind):
        ind = "  " * depth
        if kind == "End":
            lines.extend([f"{ind}End Site", f"{ind}{{", f"{ind}  OFFSET {' '.join(map(repr, node))}", f"{ind}}}"])
            return
        name, offset, chans, kids = node
        lines.extend([f"{ind}{kind} {name}", f"{ind}{{", f"{ind}  OFFSET {' '.join(map(repr, offset))}",
                      f"{ind}  CHANNELS {len(chans)} {' '.join(chans)}"])
        for k in kids:
            emit(k, depth + 1, "End" if isinstance(k[0], float) else "JOINT")
        lines.append(f"{ind}}}")

    for r in roots:
        emit(r, 0, "ROOT")
    lines += ["MOTION", f"Frames: {len(motion)}", f"Frame Time: {frame_time!r}"]
    lines += [" ".join(repr(float(x)) for x in row) for row in motion]
    open(path, "w").write("\n".join(lines) + "\n")


def rot_ch(order):
    return [f"{a}rotation" for a in order]


def pos_ch(axes="XYZ"):
    return [f"{a}position" for a in axes]


def six_orders_file(path, rng, frames=40):
    """One chain per Euler order, position channels on children (all, some, shuffled), two roots."""
    chain = None
    for k, order in enumerate(ORDERS):
        chans = rot_ch(order)
        if k == 2:
            chans = pos_ch("ZX") + chans  # a child with only two position channels
        if k == 4:
            chans = chans[:1] + pos_ch("YXZ") + chans[1:]  # interleaved
        chain = (f"j{k}", [float(k), 1.5, -0.5], chans, [chain] if chain else [(0.0, 2.0, 0.0)])
    root1 = ("hips", [0.0, 0.0, 0.0], pos_ch() + rot_ch("ZYX"), [chain, ("tail", [0.0, -1.0, -1.0], rot_ch("XZY"), [])])
    root2 = ("prop", [3.0, 0.0, 1.0], rot_ch("YXZ") + pos_ch("Y"), [(0.5, 0.5, 0.5)])
    motion = rng.uniform(-170, 170, (frames, count_channels([root1, root2])))
    write_text_bvh(path, [root1, root2], motion)
    return path


def count_channels(nodes):
    return sum(len(n[2]) + count_channels(n[3]) for n in nodes if not isinstance(n[0], float))


@pytest.fixture
def six(tmp_path, rng):
    return six_orders_file(str(tmp_path / "six.bvh"), rng)


# --------------------------------------------------------------------------
# forward kinematics


def test_world_real_files(data_dir):
    for name in ("mocapbank_walk.bvh", "free_mocap.bvh"):
        check_against_reference(str(data_dir / name))


def test_world_bundled_sample():
    clip = check_against_reference(sample_path())
    assert clip.ends.sum() == 5 and clip.joints[7] == "LeftWrist_End"


def test_world_six_orders_child_positions_two_roots(six):
    clip = check_against_reference(six)
    assert sorted(set(clip.orders) - {""}) == sorted(ORDERS)
    assert list(clip.parents).count(-1) == 2
    assert len(clip.positional()) == 4


def test_world_float_kernel_matches_per_joint_numpy(rng):
    """The numba kernel against the batched-over-frames numpy pass of the same maths."""
    clip = random_clip(rng, frames=50, joints=12)
    q, p = clip.world()
    qw, pw = numpy_world(clip)
    assert qa.distance(q, qw).max() < 1e-12
    np.testing.assert_allclose(p, pw, atol=1e-12)


def random_clip(rng, frames, joints):
    parents = [-1] + [int(rng.integers(0, j)) for j in range(1, joints)]
    rot = qa.normalize(rng.standard_normal((frames, joints, 4)))
    off = rng.standard_normal((joints, 3))
    trans = np.broadcast_to(off, (frames, joints, 3)).copy()
    trans[:, 0] = rng.standard_normal((frames, 3))
    chans = [tuple(pos_ch() + rot_ch("ZXY"))] + [tuple(rot_ch("ZXY"))] * (joints - 1)
    return Clip([f"j{j}" for j in range(joints)], parents, off, chans, rot, trans, 1 / 30)


def numpy_world(clip):
    J = len(clip.joints)
    q = np.empty_like(clip.rotations)
    p = np.empty_like(clip.translations)
    for j in range(J):
        a = clip.parents[j]
        if a < 0:
            q[:, j], p[:, j] = clip.rotations[:, j], clip.translations[:, j]
        else:
            q[:, j] = qa.multiply(q[:, a], clip.rotations[:, j])
            p[:, j] = p[:, a] + qa.rotate(q[:, a], clip.translations[:, j])
    return q, p


def test_world_cold_compile_time(tmp_path):
    """The FK kernel compiles from a fresh cache in about a second of CPU time."""
    code = (
        "import time, numpy as np\n"
        "from quatarray.skeleton import Clip, _world\n"
        "rot = np.zeros((4, 3, 4)); rot[..., 0] = 1; tr = np.zeros((4, 3, 3))\n"
        "c = Clip(['a', 'b', 'c'], [-1, 0, 1], np.zeros((3, 3)), [('Zrotation', 'Xrotation', 'Yrotation')] * 3,"
        " rot, tr, 0.1)\n"
        "t = time.process_time(); c.world(); print(time.process_time() - t)\n"
    )
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert float(out.stdout) < 3.0, out.stdout  # measured about 0.85 s


# --------------------------------------------------------------------------
# resample


def test_resample_at_key_times_reproduces_clip(six):
    clip = io.read_bvh(six)
    same = clip.resample(times=clip.times)
    assert qa.distance(same.rotations, clip.rotations).max() < 1e-12
    np.testing.assert_allclose(same.translations, clip.translations, rtol=0, atol=1e-12)
    np.testing.assert_allclose(same.world()[1], clip.world()[1], rtol=0, atol=1e-10)


def test_resample_rate_matches_spline_and_interp(six):
    clip = io.read_bvh(six)
    r = clip.resample(rate=100, method="slerp")
    assert r.frame_time == 0.01 and r.frames == int(round(clip.times[-1] * 100)) + 1
    for j in range(len(clip.joints)):
        if clip.orders[j]:
            ref = qa.spline(clip.times, clip.rotations[:, j], r.times, method="slerp")
            assert qa.distance(r.rotations[:, j], ref).max() < 1e-14
        for a in range(3):
            np.testing.assert_allclose(r.translations[:, j, a],
                                       np.interp(r.times, clip.times, clip.translations[:, j, a]), atol=1e-12)
    # the resampled clip writes and reads back (every joint, its own orders)
    assert r.world()[1].shape == (r.frames, len(clip.joints), 3)


@pytest.mark.parametrize("one_pass", [True, False])
@pytest.mark.parametrize("method", ["bezier", "slerp", "nlerp", "squad", "cubic"])
def test_resample_equals_spline_per_joint_bitwise(six, rng, method, one_pass, monkeypatch):
    """All joints in one pass (or joint by joint, for small clips) give exactly what
    spline gives each joint alone: even times at a rate, uneven key times, new times
    in any order, joints that skip."""
    from quatarray import skeleton

    monkeypatch.setattr(skeleton, "LANES_MIN_SAMPLES", 0 if one_pass else 10**12)
    clip = io.read_bvh(six)
    uneven = clip.replace(times=np.cumsum(rng.uniform(0.005, 0.05, clip.frames)))
    new = np.unique(rng.uniform(uneven.times[0], uneven.times[-1], 3 * clip.frames))  # uneven, increasing
    for c, kw in ((clip, dict(rate=75)), (uneven, dict(times=new))):
        r = c.resample(method=method, **kw)
        for j in range(len(c.joints)):
            if c.orders[j]:
                ref = qa.spline(c.times, c.rotations[:, j], r.times, method=method)
                assert np.array_equal(r.rotations[:, j], ref), (method, c.joints[j])
            else:
                const = np.broadcast_to(qa.normalize(c.rotations[0, j]), (r.frames, 4))
                assert np.array_equal(r.rotations[:, j], const)
    # the one-pass kernels take new times in any order (a clip refuses them: its frames are in time order)
    shuffled = rng.permutation(new)
    cols = [j for j in range(len(clip.joints)) if clip.orders[j]]
    out = np.zeros((shuffled.size, len(clip.joints), 4))
    (skeleton.resample_streams if one_pass else skeleton.resample_each)(
        uneven.times, shuffled, uneven.rotations, cols, method, out)
    for j in cols:
        assert np.array_equal(out[:, j], qa.spline(uneven.times, uneven.rotations[:, j], shuffled, method=method))


def test_resample_needs_rate_or_times(six):
    clip = io.read_bvh(six)
    with pytest.raises(ValueError):
        clip.resample()
    with pytest.raises(ValueError):
        clip.resample(times=[clip.times[-1] + 1])


def test_tree_lists_orders(six):
    lines = io.read_bvh(six).tree()
    assert lines[0] == "hips  ZYX + XYZ position"
    assert any(line.strip() == "j2  YXZ + ZX position" for line in lines)
    assert lines[-2:] == ["prop  YXZ + Y position", "  prop_End  end site"]


# --------------------------------------------------------------------------
# issue 36: new times that repeat or go back, clips of 0 and 1 frames, hinges


@pytest.mark.parametrize("times", [[0.5, 0.4], [0.2, 0.3, 0.3, 0.4], [0.3, 0.2, 0.1], [0.1, np.nan]])
def test_resample_refuses_times_that_repeat_or_go_back(six, times):
    """A clip's frames are in time order: new times that repeat or decrease (which gave
    a frame time of 0 or less, a BVH that read_bvh refuses, a repr that raised) are
    refused, naming the first."""
    clip = io.read_bvh(six)
    with pytest.raises(ValueError, match=r"strictly increasing, got times\[\d\] = .* after times\[\d\]"):
        clip.resample(times=times)


def test_frame_time_must_be_positive_and_repr_never_raises(six):
    clip = io.read_bvh(six)
    for bad in (0.0, -0.1, np.nan, np.inf):
        with pytest.raises(ValueError, match="frame_time"):
            clip.replace(frame_time=bad)
    r = clip.resample(times=[0.0, 0.01, 0.03])
    assert r.frame_time == 0.015 and repr(r).endswith("3 frames at 66.6667 fps>")
    clip.frame_time = 0.0  # set after construction: repr still says what it is, write_bvh refuses it
    assert repr(clip).endswith("frames at frame time 0.0>")
    with pytest.raises(ValueError, match="positive, finite `frame_time`"):
        io.write_bvh(os.path.join(os.path.dirname(six), "out.bvh"), clip)
    assert not os.path.exists(os.path.join(os.path.dirname(six), "out.bvh"))
    clip.frame_time = None
    assert "frame time None" in repr(clip)


def _frames(clip, a, b):
    return clip.replace(rotations=clip.rotations[a:b], translations=clip.translations[a:b], times=clip.times[a:b])


@pytest.mark.parametrize("method", ["bezier", "cubic"])
def test_resample_one_frame_clip_holds_still(six, method):
    """One frame spans one instant: any rate gives that frame once; new times at that
    instant give it again; new times elsewhere are outside the span."""
    clip = io.read_bvh(six)
    one = _frames(clip, 3, 4)
    for r in (one.resample(rate=120, method=method), one.resample(times=[one.times[0]], method=method)):
        assert r.frames == 1 and r.times[0] == one.times[0]
        assert qa.distance(r.rotations, one.rotations).max() < 1e-15
        np.testing.assert_array_equal(r.translations, one.translations)
        np.testing.assert_allclose(r.world()[1], one.world()[1], rtol=0, atol=1e-12)
    assert one.resample(rate=120).frame_time == 1 / 120
    with pytest.raises(ValueError, match="within"):
        one.resample(times=[one.times[0] + 0.01])


def test_resample_zero_frame_clip(six):
    clip = io.read_bvh(six)
    none = _frames(clip, 0, 0)
    r = none.resample(rate=30)
    assert r.frames == 0 and r.rotations.shape == (0, len(clip.joints), 4) and r.frame_time == 1 / 30
    assert none.resample(times=[]).frames == 0
    with pytest.raises(ValueError, match="without frames"):
        none.resample(times=[0.0])


HINGE = """HIERARCHY
ROOT hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT knee
  {
    OFFSET 0 -1 0
    CHANNELS 1 Xrotation
    End Site
    {
      OFFSET 0 -1 0
    }
  }
  JOINT wrist
  {
    OFFSET 1 0 0
    CHANNELS 2 Yrotation Xrotation
    End Site
    {
      OFFSET 0.5 0 0
    }
  }
}
MOTION
Frame Time: 0.1
"""


def hinge_file(path, rng, frames=30):
    motion = np.column_stack([rng.uniform(-1, 1, (frames, 3)), np.cumsum(rng.uniform(-20, 20, (frames, 6)), axis=0)])
    text = HINGE.replace("MOTION\n", f"MOTION\nFrames: {frames}\n")
    with open(path, "w") as f:
        f.write(text + "\n".join(" ".join(repr(float(x)) for x in row) for row in motion) + "\n")
    return path


def test_hinge_joints_read_against_reference(tmp_path, rng):
    """A knee with one rotation channel, a wrist with two: read as rotations about those
    axes (the independent reader with scipy agrees)."""
    clip = check_against_reference(hinge_file(str(tmp_path / "hinge.bvh"), rng))
    assert clip.orders == ["ZXY", "X", "", "YX", ""]


@pytest.mark.parametrize("method", ["bezier", "slerp", "squad", "cubic"])
def test_resample_keeps_hinges_on_their_axes(tmp_path, rng, method):
    """A hinge's resampled rotations turn about its axis (as spline gives them, up to
    rounding); a 2-axis joint's are taken back to its two axes (near the spline's)."""
    from quatarray.skeleton import few_axes_angles

    clip = io.read_bvh(hinge_file(str(tmp_path / "hinge.bvh"), rng))
    r = clip.resample(rate=47, method=method)
    knee = qa.spline(clip.times, clip.rotations[:, 1], r.times, method=method)
    assert qa.distance(r.rotations[:, 1], knee).max() < 1e-14
    assert np.abs(r.rotations[:, 1, 2:]).max() == 0 or np.abs(r.rotations[:, 1, 2:]).max() < 1e-16
    wrist = qa.spline(clip.times, clip.rotations[:, 3], r.times, method=method)
    back = qa.from_euler("YX", few_axes_angles(r.rotations[:, 3], "YX"))
    assert qa.distance(back, r.rotations[:, 3]).max() < 1e-14  # on its axes
    assert qa.distance(r.rotations[:, 3], wrist).max() < 0.2  # and near the spline (keys 20° apart)
    at_keys = clip.resample(times=clip.times, method=method)
    assert qa.distance(at_keys.rotations, clip.rotations).max() < 1e-12


def test_few_axes_angles_exact_for_what_the_axes_make(rng):
    from quatarray.skeleton import few_axes_angles

    for order in ("X", "Y", "Z", "XY", "YX", "XZ", "ZX", "YZ", "ZY"):
        a = rng.uniform(-np.pi, np.pi, (500, len(order)))
        q = qa.from_euler(order, a)
        got = few_axes_angles(q, order)
        assert qa.distance(qa.from_euler(order, got), q).max() < 1e-14
        if len(order) == 1:  # the angle itself, up to the turn
            np.testing.assert_allclose(np.cos(got - a), 1, atol=1e-12)
        ref = Rotation.from_euler(order, a).as_matrix()  # independent: scipy's matrices
        np.testing.assert_allclose(Rotation.from_euler(order, got).as_matrix(), ref, rtol=0, atol=1e-12)
