"""align_vectors and rotation_between against scipy's Rotation.align_vectors."""

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import quatarray as qa

Rotation = pytest.importorskip("scipy.spatial.transform").Rotation


def scipy_align(a, b, w=None, sens=False):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = Rotation.align_vectors(a, b, w, return_sensitivity=sens)
    return (res[0].as_quat(scalar_first=True),) + tuple(res[1:])


def check(a, b, w=None, atol=1e-10):
    q, rssd = qa.align_vectors(a, b, w)
    qs, rs = scipy_align(a, b, w)
    assert qa.distance(q, qs) < atol
    np.testing.assert_allclose(rssd, rs, atol=2e-7, rtol=1e-9)  # an exact fit: sqrt of a rounding-level ssd
    return q


@pytest.mark.parametrize("n", [2, 3, 5, 40])
def test_random_weighted_noisy(rng, n):
    for _ in range(20):
        b = rng.standard_normal((n, 3))
        q0 = qa.random(rng=rng)
        a = qa.rotate(q0, b) + 0.1 * rng.standard_normal((n, 3))
        w = rng.random(n) * 3
        q, rssd, sens = qa.align_vectors(a, b, w, return_sensitivity=True)
        qs, rs, ss = scipy_align(a, b, w, sens=True)
        np.testing.assert_allclose(q, qs, atol=1e-12)  # scipy's sign too
        np.testing.assert_allclose(rssd, rs, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(sens, ss, rtol=1e-8, atol=1e-10)


def test_scipy_docstring_example():
    a = [[0, 1, 0], [0, 1, 1], [0, 1, 1]]
    b = [[1, 0, 0], [1, 1.1, 0], [1, 0.9, 0]]
    q, rssd, sens = qa.align_vectors(a, b, return_sensitivity=True)
    np.testing.assert_allclose(qa.as_matrix(q), [[0, 0, 1], [1, 0, 0], [0, 1, 0]], atol=1e-12)
    np.testing.assert_allclose(rssd, 0.141421356237308, atol=1e-12)
    np.testing.assert_allclose(sens, [[0.2, 0, 0], [0, 1.5, 1], [0, 1, 1]], atol=1e-12)


def test_no_reflection_issue_10444(rng):
    x = np.array([[0.89299824, -0.44372674, 0.0752378], [0.60221789, -0.47564102, -0.6411702]])
    y = np.array([[0.02386536, -0.82176463, 0.5693271], [-0.27654929, -0.95191427, -0.1318321]])
    q, rssd = qa.align_vectors(x, y)
    np.testing.assert_allclose(qa.rotate(q, y), x, atol=1e-6)
    assert rssd < 1e-7
    # mirrored sets: the best orthogonal map is a reflection; we return the best rotation
    for _ in range(20):
        b = rng.standard_normal((6, 3))
        a = b * [1, 1, -1]
        q = check(a, b)
        assert np.linalg.det(qa.as_matrix(q)) > 0


def test_one_pair_and_infinite_weight_issue_17542(rng):
    # one pair: the shortest arc (scipy's special case)
    for _ in range(50):
        a, b = rng.standard_normal(3) * 3, rng.standard_normal(3)
        q = check(a, b)
        np.testing.assert_allclose(qa.rotate(q, b / np.linalg.norm(b)), a / np.linalg.norm(a), atol=1e-12)
    # one infinite weight: that pair exactly, the rest about it
    for n in (2, 3, 6):
        for _ in range(20):
            a, b = rng.standard_normal((n, 3)), rng.standard_normal((n, 3))
            w = rng.random(n)
            k = rng.integers(n)
            w[k] = np.inf
            q = check(a, b, w)
            u = qa.rotate(q, b[k])
            np.testing.assert_allclose(u / np.linalg.norm(u), a[k] / np.linalg.norm(a[k]), atol=1e-12)
    # scipy's align-constrain example
    q, rssd = qa.align_vectors([[0.0, 1, 0], [0, 1, 1]], [[1, 0, 0], [1, 2, 0]], weights=[np.inf, 1])
    np.testing.assert_allclose(qa.as_matrix(q), [[0, 0, 1], [1, 0, 0], [0, 1, 0]], atol=1e-12)
    assert abs(rssd - 1.0) < 1e-12


def test_parallel_and_antiparallel():
    for a, b in [([1.0, 0, 0], [0, 1, 0]), ([1, 0, 0], [1, 0, 0]), ([1, 0, 0], [-1, 0, 0]),
                 ([0, 1, 0], [0, -1, 0]), ([0, 0, 1], [0, 0, -1]), ([1, 2, 3], [-2, -4, -6])]:
        check(a, b, atol=1e-12)
        check([a, [0.3, -0.1, 0.2]], [b, [0.1, 0.5, -0.3]], [np.inf, 1], atol=1e-12)
    # near antiparallel: as the large finite weight
    rs = qa.from_rotvec(qa.as_rotvec(qa.random(20, rng=0)) * 1e-4)
    for dq in rs:
        a = np.array([qa.rotate(dq, [1.0, 0, 0]), [0, 1, 0]])
        b = np.array([[-1.0, 0, 0], [0, 1, 0]])
        q1, _ = qa.align_vectors(a, b, [np.inf, 1])
        q2, _ = qa.align_vectors(a, b, [1e10, 1])
        assert qa.distance(q1, q2) < 1e-7
        check(a, b, [np.inf, 1])


def test_degenerate_sets():
    # collinear: not unique; scipy warns, the rssd is the optimum and the fit is optimal
    a = np.array([[1.0, 0, 0], [2, 0, 0], [-1, 0, 0]])
    b = np.array([[0.0, 1, 0], [0, 2, 0], [0, -1, 0]])
    with pytest.warns(UserWarning, match="not uniquely"):
        q, rssd = qa.align_vectors(a, b)
    np.testing.assert_allclose(rssd, scipy_align(a, b)[1], atol=1e-7)  # sqrt of a rounding-level ssd
    np.testing.assert_allclose(qa.rotate(q, b), a, atol=1e-12)
    # coplanar (rank 2): unique
    a = np.array([[1.0, 0, 0], [0, 1, 0], [1, 1, 0]])
    check(a, qa.rotate(qa.random(rng=3), a))
    # all weights zero, zero vectors
    check(np.ones((3, 3)), np.ones((3, 3)) * 2, np.zeros(3))
    check(np.zeros((3, 3)), np.ones((3, 3)))


def test_errors():
    with pytest.raises(ValueError, match="at most one infinite"):
        qa.align_vectors(np.ones((3, 3)), np.eye(3), [np.inf, np.inf, 1])
    with pytest.raises(ValueError, match="zero length primary"):
        qa.align_vectors([0, 0, 0], [1, 0, 0])
    with pytest.raises(ValueError, match="sensitivity"):
        qa.align_vectors([1, 0, 0], [0, 1, 0], return_sensitivity=True)
    with pytest.raises(ValueError, match="non-negative"):
        qa.align_vectors(np.eye(3), np.eye(3), [1, -1, 1])
    with pytest.raises(ValueError, match=r"Expected `b` to have shape \(\.\.\., n, 3\)"):
        qa.align_vectors(np.eye(3), np.ones((3, 2)))
    with pytest.raises(ValueError, match="same number"):
        qa.align_vectors(np.eye(3), np.eye(3)[:2])
    with pytest.raises(ValueError, match=r"index \(1, 0\)"):
        w = np.ones((2, 2, 3))
        w[1, 0, :2] = np.inf
        qa.align_vectors(np.ones((2, 2, 3, 3)), np.eye(3), w)


def test_batch_broadcast_dtype(rng):
    a = rng.standard_normal((4, 1, 7, 3))
    b = rng.standard_normal((5, 7, 3))
    w = rng.random(7)
    q, rssd, sens = qa.align_vectors(a, b, w, return_sensitivity=True)
    assert q.shape == (4, 5, 4) and rssd.shape == (4, 5) and sens.shape == (4, 5, 3, 3)
    for i in range(4):
        for j in range(5):
            qs, rs = scipy_align(a[i, 0], b[j], w)
            assert qa.distance(q[i, j], qs) < 1e-10
            np.testing.assert_allclose(rssd[i, j], rs, rtol=1e-10)
    q32, r32 = qa.align_vectors(a.astype(np.float32), b.astype(np.float32), w)
    assert q32.dtype == r32.dtype == np.float32
    assert np.all(qa.distance(q32.astype(float), q) < 1e-5)
    assert qa.align_vectors(a.astype(np.float32), b)[0].dtype == np.float64
    # read-only, strided input is left alone
    ro = np.asfortranarray(a)
    ro.flags.writeable = False
    np.testing.assert_array_equal(qa.align_vectors(ro, b, w)[0], q)


@settings(max_examples=40, deadline=None)
@given(
    arrays(np.float64, st.tuples(st.integers(1, 3), st.integers(1, 5), st.just(3)),
           elements=st.floats(-10, 10, width=32)),
    st.integers(0, 2**32 - 1),
    st.booleans(),
)
def test_batch_is_loop_of_single_calls(a, seed, inf):
    rng = np.random.default_rng(seed)
    b = a + rng.standard_normal(a.shape)
    w = rng.random(a.shape[:-1]) + 0.1
    if inf:
        w[:, 0] = np.inf
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            q, rssd = qa.align_vectors(a, b, w)
        except ValueError:  # a zero primary vector somewhere
            return
        for k in range(a.shape[0]):
            qk, rk = qa.align_vectors(a[k], b[k], w[k])
            np.testing.assert_array_equal(q[k], qk)
            np.testing.assert_array_equal(rssd[k], rk)


def test_rotation_between(rng):
    u = rng.standard_normal((200, 3))
    v = rng.standard_normal((200, 3)) * 5
    q = qa.rotation_between(u, v)
    np.testing.assert_allclose(qa.rotate(q, u / np.linalg.norm(u, axis=1, keepdims=True)),
                               v / np.linalg.norm(v, axis=1, keepdims=True), atol=1e-12)
    np.testing.assert_allclose(qa.angle(q), np.arccos(np.clip(
        np.sum(u * v, 1) / np.linalg.norm(u, axis=1) / np.linalg.norm(v, axis=1), -1, 1)), atol=1e-7)
    assert np.all(q[:, 0] >= 0)
    for i in range(20):
        assert qa.distance(q[i], scipy_align(v[i], u[i])[0]) < 1e-12
    # antiparallel: the documented axis, perpendicular to v
    for v1, axis in [([0, 0, -1], [0, 1, 0]), ([1, 0, 0], [0, 0, -1]), ([0, 2, 0], [0, 0, 1]),
                     ([1, 2, 3], [0, -3, 2])]:
        v1 = np.array(v1, float)
        q1 = qa.rotation_between(-v1, v1)
        axis = np.array(axis) / np.linalg.norm(axis)
        np.testing.assert_allclose(q1, np.r_[0, axis], atol=1e-15)
    assert np.isnan(qa.rotation_between([0, 0, 0], [1, 0, 0])).all()
    assert np.isnan(qa.rotation_between([1, 0, 0], [0, 0, 0])).all()
    np.testing.assert_array_equal(qa.rotation_between([1, 0, 0], [3, 0, 0]), [1, 0, 0, 0])
    # broadcasting, float32, out=
    assert qa.rotation_between(u[:, None], v[None, :5]).shape == (200, 5, 4)
    q32 = qa.rotation_between(u.astype(np.float32), v.astype(np.float32))
    assert q32.dtype == np.float32 and np.all(qa.distance(q32.astype(float), q) < 1e-5)
    out = np.empty((200, 4))
    assert qa.rotation_between(u, v, out=out) is out
    np.testing.assert_array_equal(out, q)


def test_nan_and_inf_inputs_give_nan(rng):
    # a nan anywhere in a problem: nan for that problem (not the identity), the others unchanged
    a = rng.standard_normal((3, 4, 3))
    b = qa.rotate(qa.random(3, rng=rng)[:, None], a)
    q_ok, r_ok, s_ok = qa.align_vectors(a, b, return_sensitivity=True)
    for arr, idx in [("a", (1, 2, 0)), ("b", (1, 0, 1)), ("w", (1, 3))]:
        a2, b2, w2 = a.copy(), b.copy(), np.ones((3, 4))
        {"a": a2, "b": b2, "w": w2}[arr][idx] = np.nan
        q, r, sens = qa.align_vectors(a2, b2, w2, return_sensitivity=True)
        assert np.isnan(q[1]).all() and np.isnan(r[1]) and np.isnan(sens[1]).all()
        np.testing.assert_array_equal(q[[0, 2]], q_ok[[0, 2]])
        np.testing.assert_array_equal(r[[0, 2]], r_ok[[0, 2]])
    q, r = qa.align_vectors([[np.nan, 0, 0], [0, 1, 0]], [[1, 0, 0], [0, 1, 0]])
    assert np.isnan(q).all() and np.isnan(r)
    q, r = qa.align_vectors([[np.inf, 0, 0], [0, 1, 0]], [[1, 0, 0], [0, 1, 0]])
    assert np.isnan(q).all()


def test_collinear_sets_always_warn(rng):
    # exactly collinear a or b: the optimum is not unique; every such problem warns (scipy's
    # 1e-16 test, below the rounding of its SVD, misses some), and the fit is still optimal
    for i in range(200):
        u, v = rng.standard_normal(3), rng.standard_normal(3)
        f = rng.standard_normal(int(rng.integers(2, 6)))
        a, b = f[:, None] * u, (f * rng.uniform(0.5, 2, f.size))[:, None] * v
        with pytest.warns(UserWarning, match="not uniquely"):
            q, rssd = qa.align_vectors(a, b)
        np.testing.assert_allclose(rssd, scipy_align(a, b)[1], atol=1e-6)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # and a generic set does not warn
        qa.align_vectors(rng.standard_normal((500, 3, 3)), rng.standard_normal((500, 3, 3)))


def test_float32_near_antiparallel_is_unit_and_accurate(rng):
    # the shortest arc is computed in float64: float32 results are the float64 ones rounded
    u = rng.standard_normal((20_000, 3))
    v = -u + rng.standard_normal(u.shape) * 10 ** rng.uniform(-5, 0, (20_000, 1))
    u32, v32 = u.astype(np.float32), v.astype(np.float32)
    q32 = qa.rotation_between(u32, v32)
    q64 = qa.rotation_between(u32.astype(float), v32.astype(float))
    assert q32.dtype == np.float32
    assert np.abs(np.linalg.norm(q32.astype(float), axis=1) - 1).max() < 3e-7
    assert qa.distance(q32.astype(float), q64).max() < 1e-6
    one = qa.align_vectors(v32[:50, None], u32[:50, None])[0]  # one pair per problem: the same arc
    assert one.dtype == np.float32 and qa.distance(one.astype(float), q64[:50]).max() < 1e-6
    # the example the float32 arithmetic got 5.4e-5 rad wrong (norm 1.00012)
    u1, v1 = np.float32([0.24333124, -0.7858214, 0.5492702]), np.float32([-0.2426596, 0.7865856, -0.5490437])
    assert qa.distance(qa.rotation_between(u1, v1).astype(float), qa.rotation_between(u1 * 1.0, v1 * 1.0)) < 1e-6
    # near a half turn and at exactly one, against scipy in float64 (within what rounding in
    # the cross product of the inputs makes of the axis: ε/(π − θ))
    for i in range(300):
        q = qa.rotation_between(u[i], v[i])
        assert qa.distance(q, scipy_align(v[i], u[i])[0]) < 1e-13 + 1e-15 / (np.pi - qa.angle(q))
    np.testing.assert_array_equal(qa.rotation_between([0.0, 0, 1], [0, 0, -1]), [0, 0, 1, 0])  # w exactly 0


def test_any_magnitude(rng):
    # vectors scaled by powers of ten from 1e-300 to 1e300: the same rotation, rssd and
    # sensitivity scaled (B, |a|², the singular values are formed on the problem scaled
    # by a power of two; scipy's products overflow or underflow beyond about 1e±150)
    b0 = rng.standard_normal((5, 3))
    a0 = qa.rotate(qa.from_rotvec([0.3, 0.2, 0.1]), b0) + 0.01 * rng.standard_normal((5, 3))
    q0, r0, s0 = qa.align_vectors(a0, b0, return_sensitivity=True)
    w = np.r_[np.inf, np.ones(5)]
    qi, ri = qa.align_vectors(np.r_[a0[:1], a0], np.r_[b0[:1], b0], w)
    for sc in [1e-300, 1e-200, 1e-100, 1e100, 1e200, 1e300]:
        q, r, sens = qa.align_vectors(a0 * sc, b0 * sc, return_sensitivity=True)
        assert qa.distance(q, q0) < 1e-15 and abs(r / sc / r0 - 1) < 1e-10
        if 1e-150 < sc < 1e150:  # beyond, the sensitivity itself (∝ 1/sc²) is out of range
            np.testing.assert_allclose(sens * sc * sc, s0, rtol=1e-12)
        q, r = qa.align_vectors(np.r_[a0[:1], a0] * sc, np.r_[b0[:1], b0] * sc, w)
        assert qa.distance(q, qi) < 1e-15 and abs(r / sc / ri - 1) < 1e-12
        q = qa.rotation_between(b0 * sc, a0 * sc)
        assert np.all(qa.distance(q, qa.rotation_between(b0, a0)) < 1e-15)
    # a half turn's axis far below the square root of the smallest float: still unit
    for t in [1e-150, 1e-160, 1e-300]:
        q = qa.rotation_between([-1.0, 0, 0], [1, t, 0])
        assert abs(np.linalg.norm(q) - 1) < 3e-16 and abs(q[3] + 1) < 3e-16 and 0 < q[0] <= t
    np.testing.assert_allclose(qa.rotation_between([1e200, 0, 0], [0, 1e200, 0]), [2**-0.5, 0, 0, 2**-0.5])


def test_magnitudes_far_apart_within_a_problem():
    # a and b of different magnitudes (each set scaled by its own power of two), a tiny
    # primary, tiny other pairs under a huge primary: the rotations scipy finds where its
    # products do not underflow, and the rssd of the unscaled problem
    h = 2**-0.5
    q, r = qa.align_vectors([[1e200, 0, 0], [0, 1e200, 0]], [[0, 1e-200, 0], [-1e-200, 0, 0]])
    np.testing.assert_allclose(np.abs(q), [h, 0, 0, h], atol=1e-15)
    np.testing.assert_allclose(r, 2**0.5 * 1e200, rtol=1e-12)
    q, r = qa.align_vectors([[1e-200, 0, 0], [0, 1, 0]], [[0, 1e-200, 0], [-1, 0, 0]], [np.inf, 1])
    np.testing.assert_allclose(q, [h, 0, 0, -h], atol=1e-15)
    q, r = qa.align_vectors([[1e-150, 0, 0], [0, 1e150, 0]], [[0, 1e-150, 0], [-1e150, 0, 0]], [np.inf, 1])
    np.testing.assert_allclose(q, [h, 0, 0, -h], atol=1e-15)
    q, r = qa.align_vectors([[1e150, 0, 0], [0, 1e-150, 0]], [[1e150, 0, 0], [0, 0, 1e-150]], [np.inf, 1])
    np.testing.assert_allclose(q, [h, -h, 0, 0], atol=1e-15)
    assert r < 1e-160
    q, r = qa.align_vectors([1e-200, 0, 0], [0, 1e200, 0])  # one pair: the shortest arc
    np.testing.assert_allclose(q, [h, 0, 0, -h], atol=1e-15)
    np.testing.assert_allclose(r, 1e200, rtol=1e-12)
    rng = np.random.default_rng(3)
    b0 = rng.standard_normal((5, 3))
    a0 = qa.rotate(qa.from_rotvec([0.3, 0.2, 0.1]), b0) + 0.01 * rng.standard_normal((5, 3))
    q0, r0 = qa.align_vectors(a0, b0)
    for sa, sb in [(1e160, 1e-160), (1e200, 1e-200), (1e-250, 1e250)]:
        q, r = qa.align_vectors(a0 * sa, b0 * sb)
        assert qa.distance(q, q0) < 1e-15 and np.isfinite(r)


@pytest.mark.parametrize("sc", [1e-308, 1e-310, 1e-315])
def test_subnormal_vectors(rng, sc):
    # issue 36.4: vectors whose largest component is subnormal gave the identity with rssd 0. The
    # oracle: scipy on the same (subnormal) vectors times 2^1000, an exact scaling into its range
    up = 2.0**1000
    b0 = rng.standard_normal((3, 6, 3))
    a0 = qa.rotate(qa.random((3, 1), rng), b0) + 0.05 * rng.standard_normal((3, 6, 3))
    big = max(np.abs(a0).max(), np.abs(b0).max())
    a0, b0 = a0 / big, b0 / big
    a, b = a0 * sc, b0 * sc
    assert np.abs(a).max() < np.finfo(float).tiny and np.abs(b).max() < np.finfo(float).tiny
    ulp = np.finfo(float).smallest_subnormal
    q, r = qa.align_vectors(a, b)
    for k in range(3):
        qs, rs = scipy_align(a[k] * up, b[k] * up)
        assert qa.distance(q[k], qs) < 1e-12
        assert abs(r[k] - rs / up) <= 1e-9 * rs / up + 2 * ulp  # the rssd of the scaled problem (as check())
        # and near scipy's answer for the unscaled vectors (the subnormals keep fewer digits)
        assert qa.distance(q[k], scipy_align(a0[k], b0[k])[0]) < 1e-14 + 100 * ulp / sc
    # a only, b only, an infinite weight (the primary-pair path), one pair
    w = np.r_[np.inf, np.ones(5)]
    for a1, ua, b1, ub, w1 in ((a[0], up, b0[0], 1, None), (a0[0], 1, b[0], up, None), (a[0], up, b[0], up, w),
                               (a[0, :1], up, b[0, :1], up, None)):
        q, r = qa.align_vectors(a1, b1, w1)
        qs, rs = scipy_align(a1 * ua, b1 * ub, w1)
        assert qa.distance(q, qs) < 1e-12
        if ua == ub:  # both subnormal: the rssd of the scaled problem (a subnormal number: its own rounding)
            assert abs(r - rs / up) <= 1e-9 * rs / up + 2 * ulp
        else:  # one set subnormal, the other normal: the residual is that of the normal set
            want = np.sqrt(np.sum((a1 - qa.rotate(q, b1)) ** 2))
            assert abs(r - want) <= 1e-12 * want
    # float32 vectors below float32's normal range are normal float64 numbers: aligned as well
    q32 = qa.align_vectors((a0 * 1e-40).astype(np.float32), (b0 * 1e-40).astype(np.float32))[0]
    assert q32.dtype == np.float32 and np.all(qa.distance(q32, qa.align_vectors(a0, b0)[0]) < 1e-3)
