"""Whole clips: forward kinematics and resampling of 10⁵ frames × 30 joints.

``world``: :meth:`quatarray.skeleton.Clip.world` (one numba kernel over frames ×
joints) against the same forward kinematics in numpy with scipy rotations,
batched over frames, one joint at a time down the hierarchy (the way it is
written without quatarray). ``resample``: :meth:`Clip.resample` to twice the
rate (Bézier rotations, linear translations); items are joint-samples.

Run: ``pytest benchmarks/test_skeleton.py --benchmark-only``. Targets (issue 17):
world ≥ 20× the numpy/scipy pass; resample ≥ 10 M joint-samples/s.
"""

import numpy as np
import pytest
from conftest import run

import quatarray as qa
from quatarray.skeleton import Clip

Rotation = pytest.importorskip("scipy.spatial.transform").Rotation

FRAMES, JOINTS = 100_000, 30
_CLIP = {}


def clip():
    """A smooth random clip: a tree of 30 joints, ZXY channels, root positions."""
    if not _CLIP:
        rng = np.random.default_rng(17)
        parents = [-1] + [int(rng.integers(max(0, j - 4), j)) for j in range(1, JOINTS)]
        chans = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")] + \
            [("Zrotation", "Xrotation", "Yrotation")] * (JOINTS - 1)
        angles = np.cumsum(rng.normal(0, 2, (FRAMES, JOINTS, 3)), axis=0)
        rot = qa.from_euler("ZXY", angles, degrees=True)
        off = rng.standard_normal((JOINTS, 3)) * 10
        trans = np.broadcast_to(off, (FRAMES, JOINTS, 3)).copy()
        trans[:, 0] = np.cumsum(rng.normal(0, 0.1, (FRAMES, 3)), axis=0)
        _CLIP["c"] = Clip([f"j{j}" for j in range(JOINTS)], parents, off, chans, rot, trans, 1 / 100)
    return _CLIP["c"]


def numpy_world(c):
    """Forward kinematics in numpy + scipy: one joint at a time, all frames at once."""
    rw, pw = [], []
    for j in range(len(c.joints)):
        r = Rotation.from_quat(c.rotations[:, j], scalar_first=True)
        t = c.translations[:, j]
        p = c.parents[j]
        if p < 0:
            rw.append(r)
            pw.append(t)
        else:
            rw.append(rw[p] * r)
            pw.append(pw[p] + rw[p].apply(t))
    return np.stack([r.as_quat(scalar_first=True) for r in rw], axis=1), np.stack(pw, axis=1)


@pytest.mark.benchmark(group="clip-world-100000x30")
@pytest.mark.parametrize("lib", ["quatarray", "numpy-scipy"])
def test_world(benchmark, lib):
    c = clip()
    fn = c.world if lib == "quatarray" else (lambda: numpy_world(c))
    fn()
    q, p = run(benchmark, fn, FRAMES * JOINTS, slow=lib != "quatarray")
    np.testing.assert_allclose(p, c.world()[1], atol=1e-9)


@pytest.mark.benchmark(group="clip-resample-2x-100000x30")
@pytest.mark.parametrize("lib", ["quatarray"])
def test_resample(benchmark, lib):
    c = clip()
    c.resample(rate=200)
    out = run(benchmark, lambda: c.resample(rate=200), (2 * FRAMES - 1) * JOINTS, slow=True)
    assert out.frames == 2 * FRAMES - 1
