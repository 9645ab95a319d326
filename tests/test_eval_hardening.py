"""Trajectory evaluation hardened (issue 36, items 7-9 and 15-19): ``quatarray eval`` and its
readers against evo (pairs, interpolation), mpmath (UTM-sized coordinates) and bad inputs."""

import copy

import numpy as np
import pytest

import quatarray as qa
from quatarray import trajectory as T

evo = pytest.importorskip("evo", reason="evo (the test extra) is needed to compare with it")
from evo.core import filters, lie_algebra  # noqa: E402

# ---- item 8: RPE pairs by path length, rounded as evo rounds the step lengths ----

# integer steps whose length is a whole number: on a decimal grid the running length lands on delta
_WHOLE = np.array([(a, b, c) for a in range(-6, 7) for b in range(-6, 7) for c in range(-6, 7)
                   if (a, b, c) != (0, 0, 0) and round((a * a + b * b + c * c) ** 0.5) ** 2 == a * a + b * b + c * c])


def _grid_path(rng, n):
    """(positions, delta): a walk on a decimal grid whose steps have lengths k * scale, delta too."""
    if rng.random() < 0.5:
        steps = _WHOLE[rng.integers(len(_WHOLE), size=n - 1)]
        scale = float(rng.choice([0.1, 0.3, 0.7, 0.01]))
        ints = np.concatenate([np.zeros((1, 3), int), np.cumsum(steps, axis=0)]) + rng.integers(-50, 50, size=3)
        return ints * scale, float(rng.integers(1, 8)) * scale
    steps = rng.integers(-2, 3, size=(n - 1, 3)) * rng.choice([0.1, 0.25, 0.3, 1.0, 0.7])
    pos = np.concatenate([np.zeros((1, 3)), np.cumsum(steps, axis=0)]) + rng.choice([0, 3.7, 100.0])
    return pos, float(rng.choice([0.5, 1.0, 1.5, 2.0, 3.0]))


@pytest.mark.parametrize("all_pairs", [False, True])
def test_rpe_pairs_in_metres_equal_evo_on_grid_paths(all_pairs):
    rng = np.random.default_rng(36)
    differ = []
    for k in range(1500):
        pos, delta = _grid_path(rng, 40)
        theirs = filters.filter_pairs_by_path([lie_algebra.se3(np.eye(3), x) for x in pos], delta, 0.1 * delta,
                                              all_pairs)
        try:
            i, j = T.pairs(T.poses(None, pos, qa.identity(len(pos))), delta, "m", all_pairs)
            ours = list(zip(i.tolist(), j.tolist()))
        except ValueError:  # no pair: evo gives an empty list
            ours = []
        if ours != theirs:
            differ.append(k)
    assert differ == []


# ---- item 9: UTM-sized coordinates: errors about the alignment's origins, exact ----

mpmath = pytest.importorskip("mpmath")
UTM = np.array([4.5e6, 1.0e7, 312.0])  # northing-sized offsets (m)


def _utm_case(rng, n=120, offset=UTM):
    """(ref, est): a reference near `offset`, an estimate in its own frame (a similarity of it), noisy."""
    t = np.arange(n) * 0.1
    local = np.c_[300 * np.sin(0.05 * t), 200 * np.cos(0.03 * t), 5 * np.sin(0.2 * t)] + rng.normal(size=(n, 3))
    ref = T.poses(t, local + offset, qa.random(n, rng=rng))
    q = qa.from_rotvec([0.2, -0.4, 1.1])
    pos = 0.8 * qa.rotate(np.tile(q, (n, 1)), local) + [7.0, -3.0, 1.0] + rng.normal(scale=0.02, size=(n, 3))
    pos[::7] += rng.normal(scale=1e-4, size=(pos[::7].shape))  # some errors far smaller than the others
    est = T.poses(t, pos, qa.multiply(np.tile(q, (n, 1)), ref.q))
    return ref, est


def _exact_ape(ref, est, with_scale):
    """Umeyama's fit and the APE (translation) in 40-digit arithmetic (mpmath) of the float inputs."""
    mp = mpmath.mp
    with mpmath.workdps(40):
        x = [[mp.mpf(float(v)) for v in row] for row in est.pos]
        y = [[mp.mpf(float(v)) for v in row] for row in ref.pos]
        n = len(x)
        mx = [mp.fsum(r[k] for r in x) / n for k in range(3)]
        my = [mp.fsum(r[k] for r in y) / n for k in range(3)]
        xc = [[r[k] - mx[k] for k in range(3)] for r in x]
        yc = [[r[k] - my[k] for k in range(3)] for r in y]
        cov = mp.matrix(3, 3)
        for i in range(3):
            for j in range(3):
                cov[i, j] = mp.fsum(a[i] * b[j] for a, b in zip(yc, xc)) / n
        u, d, vt = mp.svd_r(cov)
        sign = mp.matrix([[1, 0, 0], [0, 1, 0], [0, 0, 1 if mp.det(u) * mp.det(vt) > 0 else -1]])
        r = u * sign * vt
        sx = mp.fsum(v * v for a in xc for v in a) / n
        s = (d[0] + d[1] + sign[2, 2] * d[2]) / sx if with_scale else mp.mpf(1)
        out = []
        for a, b in zip(xc, yc):
            e = [s * mp.fsum(r[i, k] * a[k] for k in range(3)) - b[i] for i in range(3)]
            out.append(float(mp.sqrt(mp.fsum(v * v for v in e))))
        return np.array(out), float(s)


@pytest.mark.parametrize("align", ["se3", "sim3"])
def test_utm_offsets_ape_is_exact(rng, align, tmp_path):
    ref, est = _utm_case(rng)
    exact, s = _exact_ape(ref, est, align == "sim3")
    r = T.evaluate(ref, est, "ape", align=align, relation="trans")
    assert r.alignment.s == pytest.approx(s, rel=1e-12)
    np.testing.assert_allclose(r.errors, exact, rtol=1e-10, atol=0)
    for k, v in (("min", exact.min()), ("max", exact.max()), ("rmse", np.sqrt(np.mean(exact ** 2)))):
        assert r.stats[k] == pytest.approx(v, rel=1e-10), k
    # the chunked pass over pose arrays gives the same numbers
    from quatarray.evaluate import PoseFile, run_chunked

    for name, p in (("ref", ref), ("est", est)):
        np.save(tmp_path / f"{name}.npy", np.c_[p.t, p.pos, p.q])
    c = run_chunked(PoseFile.open(str(tmp_path / "ref.npy")), PoseFile.open(str(tmp_path / "est.npy")), "ape",
                    align, "trans", 1, False, None, 0.01, 0.0, 17)
    np.testing.assert_allclose(np.sort(c.errors), np.sort(exact), rtol=1e-10, atol=0)
    # the aligned estimate lies on the reference as well as float positions there can
    moved = T.align(ref, est, align)[0]
    np.testing.assert_allclose(np.linalg.norm(moved.pos - ref.pos, axis=1), exact, rtol=0, atol=4e-9)


@pytest.mark.parametrize("align", ["se3", "sim3"])
def test_near_origin_equals_evo_and_exact(rng, align):
    """Where evo is exact (coordinates near the origin), quatarray equals it and the exact numbers."""
    from evo.core import metrics
    from evo.core.trajectory import PoseTrajectory3D

    ref, est = _utm_case(rng, offset=np.zeros(3))
    exact, _ = _exact_ape(ref, est, align == "sim3")
    r = T.evaluate(ref, est, "ape", align=align, relation="trans")
    np.testing.assert_allclose(r.errors, exact, rtol=1e-10)
    er = PoseTrajectory3D(ref.pos, ref.q, ref.t)
    ee = PoseTrajectory3D(est.pos, est.q, est.t)
    ee.align(er, correct_scale=align == "sim3")
    m = metrics.APE(metrics.PoseRelation.translation_part)
    m.process_data((er, ee))
    np.testing.assert_allclose(r.errors, m.error, rtol=1e-9)
    for k, v in m.get_all_statistics().items():
        assert r.stats[k] == pytest.approx(v, rel=1e-9), k


@pytest.mark.parametrize("metric", ["ape", "rpe"])
@pytest.mark.parametrize("relation", ["trans", "full"])
def test_utm_offsets_do_not_change_the_errors(rng, metric, relation):
    """Moving the reference by 10⁷ m (exactly: the offset is subtracted without rounding)
    changes no error beyond rounding of the motion's own size."""
    ref, est = _utm_case(rng)
    near = ref.replace(pos=ref.pos - UTM)
    assert np.array_equal(near.pos + UTM, ref.pos)
    a = T.evaluate(ref, est, metric, align="sim3", relation=relation)
    b = T.evaluate(near, est, metric, align="sim3", relation=relation)
    np.testing.assert_allclose(a.errors, b.errors, rtol=1e-10)


# ---- item 16: tiny motions are aligned (a relative test), degenerate ones named ----


@pytest.mark.parametrize("span", [1e-6, 1e-8, 1e-12, 1e-30, 1e30])
def test_tiny_and_huge_motions_are_aligned(rng, span):
    x = rng.normal(size=(50, 3)) * span
    q = qa.from_rotvec([0.1, 0.2, 0.3])
    y = 2.0 * qa.rotate(np.tile(q, (50, 1)), x) + 3.0 * span
    a = T.umeyama(x, y)
    assert a.s == pytest.approx(2.0, rel=1e-12)
    np.testing.assert_allclose(a.r, qa.as_matrix(q), atol=1e-12)
    ref, est = T.poses(None, y, qa.identity(50)), T.poses(None, x, qa.identity(50))
    r = T.evaluate(ref, est, align="sim3")
    assert r.stats["max"] <= 1e-12 * span


@pytest.mark.parametrize("what, pos, message", [
    ("line", lambda rng: np.outer(rng.normal(size=30), [1.0, 2.0, 3.0]) * 1e-9,
     r"the positions lie on a line \(the covariance's second singular value is .* of its first, at most 1e-12\)"),
    ("equal est", lambda rng: np.full((30, 3), 1e-9), r"all positions are equal in the estimate"),
])
def test_degenerate_motions_say_what_is_wrong(rng, what, pos, message):
    x = pos(rng)
    y = x + rng.normal(size=x.shape) * 1e-12 if what != "line" else 2 * x
    with pytest.raises(ValueError, match=message):
        T.umeyama(x, y)
    with pytest.raises(ValueError, match=r"all positions are equal in the reference"):
        T.umeyama(rng.normal(size=(30, 3)), np.ones((30, 3)))
