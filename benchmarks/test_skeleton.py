"""Whole clips: forward kinematics and resampling of 10⁵ frames × 30 joints.

``world``: :meth:`quatarray.skeleton.Clip.world` (one numba kernel over frames ×
joints) against the same forward kinematics in numpy with scipy rotations,
batched over frames, one joint at a time down the hierarchy (the way it is
written without quatarray). ``resample``: :meth:`Clip.resample` to twice the
rate (Bézier rotations, linear translations); items are joint-samples;
``quatarray-per-joint-spline`` is the rotations alone, one ``spline`` call per joint
(how resample worked before the multi-stream engine).

Run: ``pytest benchmarks/test_skeleton.py --benchmark-only``. Targets (issue 17):
world ≥ 20× the numpy/scipy pass; resample ≥ 10 M joint-samples/s.
"""

import numpy as np
import pytest
from conftest import run

from quatarray.app.bench import _clip, _numpy_world

Rotation = pytest.importorskip("scipy.spatial.transform").Rotation

FRAMES, JOINTS = 100_000, 30
_CLIP = {}


def clip():
    """A smooth random clip: a tree of 30 joints, ZXY channels, root positions (as ``quatarray bench``)."""
    if not _CLIP:
        _CLIP["c"] = _clip(FRAMES, JOINTS, np.random.default_rng(17))
    return _CLIP["c"]


def numpy_world(c):
    """Forward kinematics in numpy + scipy: one joint at a time, all frames at once."""
    return _numpy_world(c, Rotation)


@pytest.mark.benchmark(group="clip-world-100000x30")
@pytest.mark.parametrize("lib", ["quatarray", "numpy-scipy"])
def test_world(benchmark, lib):
    c = clip()
    fn = c.world if lib == "quatarray" else (lambda: numpy_world(c))
    fn()
    q, p = run(benchmark, fn, FRAMES * JOINTS, slow=lib != "quatarray")
    np.testing.assert_allclose(p, c.world()[1], atol=1e-9)


def per_joint_resample(c, rate):
    """The rotations of ``c.resample(rate=rate)`` one joint at a time through ``spline``
    (how resample worked before the multi-stream engine)."""
    import quatarray as qa

    nt = c.times[0] + np.arange(int(np.floor((c.times[-1] - c.times[0]) * rate + 1e-9)) + 1) / rate
    return np.stack([qa.spline(c.times, c.rotations[:, j], nt) for j in range(len(c.joints))], axis=1)


@pytest.mark.benchmark(group="clip-resample-2x-100000x30")
@pytest.mark.parametrize("lib", ["quatarray", "quatarray-per-joint-spline"])
def test_resample(benchmark, lib):
    c = clip()
    fn = (lambda: c.resample(rate=200)) if lib == "quatarray" else (lambda: per_joint_resample(c, 200))
    fn()
    out = run(benchmark, fn, (2 * FRAMES - 1) * JOINTS, slow=True)
    if lib == "quatarray":
        assert out.frames == 2 * FRAMES - 1
