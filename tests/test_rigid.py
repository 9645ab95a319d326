"""The pose kernels of quatarray.rigid: dual quaternions, exponential coordinates,
ScLERP, powers, means and the pose spline.

Oracles: scipy's RigidTransform (every conversion, single and stacked),
pytransform3d (dual-quaternion ScLERP, exponential coordinates and screw
parameters, one pose at a time), mpmath (SE(3) exp and log in 40 digits for
tiny, ordinary and near-half-turn angles), and hypothesis properties.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
import scipy  # noqa: E402

if tuple(int(x) for x in scipy.__version__.split(".")[:2]) < (1, 17):  # the declared floor has scipy 1.11
    pytest.skip(f"the oracle is scipy 1.17's classes; scipy {scipy.__version__} here", allow_module_level=True)

from scipy.spatial.transform import RigidTransform as T
from scipy.spatial.transform import Rotation

import quatarray as qa

pt = pytest.importorskip("pytransform3d.transformations")

SEEDS = st.integers(0, 2**32 - 1)


def poses(rng, n, scale=3.0, dtype=np.float64):
    q = qa.random(n, rng=rng)
    t = rng.normal(size=(n, 3)) * scale
    return q.astype(dtype), t.astype(dtype)


def scipy_tf(q, t):
    q = np.asarray(q, np.float64)
    return T.from_components(np.asarray(t, np.float64), Rotation.from_quat(q, scalar_first=True))


def matrix(q, t):
    return qa.pose_as_matrix(np.asarray(q, np.float64), np.asarray(t, np.float64))


def same_rotation(p, q, atol):
    """p = ±q row by row."""
    p, q = np.asarray(p, np.float64), np.asarray(q, np.float64)
    d = np.minimum(np.abs(p - q).max(-1), np.abs(p + q).max(-1))
    assert d.max() <= atol, d.max()


# --------------------------------------------------------------------------
# scipy as the oracle, single and stacked


@pytest.mark.parametrize("n", [None, 1, 40])
def test_conversions_match_scipy(n):
    rng = np.random.default_rng(1)
    q, t = poses(rng, 40 if n is None else n)
    if n is None:
        q, t = q[0], t[0]
    tf = scipy_tf(q, t)
    np.testing.assert_allclose(qa.pose_as_matrix(q, t), tf.as_matrix(), atol=1e-14)
    qm, tm = qa.pose_from_matrix(tf.as_matrix())
    np.testing.assert_allclose(qm, tf.rotation.as_quat(scalar_first=True), atol=1e-14)
    np.testing.assert_allclose(tm, tf.translation, atol=1e-14)
    ref = tf.as_dual_quat(scalar_first=True)
    dq = qa.as_dual_quat(q, t)
    same_rotation(dq[..., :4], ref[..., :4], 1e-14)
    sign = np.sign(np.sum(dq[..., :4] * ref[..., :4], axis=-1))[..., None]
    np.testing.assert_allclose(dq * sign, ref, atol=1e-13)
    np.testing.assert_allclose(qa.as_dual_quat(q, t, scalar_first=False) * sign, tf.as_dual_quat(), atol=1e-13)
    np.testing.assert_allclose(qa.as_exp_coords(q, t), tf.as_exp_coords(), atol=1e-12)
    e = tf.as_exp_coords() * 1.7
    np.testing.assert_allclose(matrix(*qa.from_exp_coords(e)), T.from_exp_coords(e).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(matrix(*qa.pose_inverse(q, t)), tf.inv().as_matrix(), atol=1e-13)
    v = rng.normal(size=(40, 3))
    np.testing.assert_allclose(qa.pose_apply(q, t, v), tf.apply(v), atol=1e-13)
    np.testing.assert_allclose(qa.pose_apply(q, t, v, inverse=True), tf.apply(v, inverse=True), atol=1e-13)


def test_from_dual_quat_normalises_as_scipy():
    rng = np.random.default_rng(2)
    dq = rng.normal(size=(50, 8)) * rng.uniform(0.01, 100, (50, 1))  # non-unit, dual part not orthogonal
    dq[0, :4] = 0  # a zero real part: the identity rotation
    for first in (True, False):
        q, t = qa.from_dual_quat(dq, scalar_first=first)
        ref = T.from_dual_quat(dq, scalar_first=first)
        np.testing.assert_allclose(matrix(q, t), ref.as_matrix(), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1, atol=1e-15)


def test_compose_broadcasts_and_matches_scipy():
    rng = np.random.default_rng(3)
    q1, t1 = poses(rng, 15)
    q2, t2 = poses(rng, 15)
    a, b = scipy_tf(q1.reshape(5, 1, 3, 4)[:, :, 0], t1.reshape(5, 1, 3, 3)[:, :, 0]), scipy_tf(q2[:4], t2[:4])
    q, t = qa.pose_compose(q1.reshape(5, 1, 3, 4)[:, :, 0], t1.reshape(5, 1, 3, 3)[:, :, 0], q2[:4], t2[:4])
    assert q.shape == (5, 4, 4) and t.shape == (5, 4, 3)
    np.testing.assert_allclose(matrix(q, t), (a * b).as_matrix(), atol=1e-13)


@pytest.mark.parametrize("a", [0.0, 1.0, -1.0, 0.5, 2.5, -0.3])
def test_power_matches_scipy_exp_coords(a):
    rng = np.random.default_rng(4)
    q, t = poses(rng, 60)
    tf = scipy_tf(q, t)
    # scipy's `**` is exp(n·log T) (its documented definition), computed here from its
    # own exp coordinates: its cython `**` strays from that by up to ~1e-7 on some rows
    ref = T.from_exp_coords(tf.as_exp_coords() * a).as_matrix()
    np.testing.assert_allclose(matrix(*qa.pose_power(q, t, a)), ref, atol=1e-12)
    np.testing.assert_allclose(matrix(*qa.pose_power(q, t, a)), (tf**a).as_matrix(), atol=1e-6)


def test_power_against_mpmath_where_scipy_strays():
    mp = pytest.importorskip("mpmath")
    rng = np.random.default_rng(1)
    q, t = qa.random(1000, rng=1), rng.normal(size=(1000, 3))
    tf = scipy_tf(q, t)
    err = np.abs((tf**0.3).as_matrix() - matrix(*qa.pose_power(q, t, 0.3))).max((1, 2))
    i = int(np.argmax(err))
    mp.mp.dps = 30
    ref = np.array(mp.expm(0.3 * mp.logm(mp.matrix(tf[i].as_matrix().tolist()))).tolist(), dtype=float)
    np.testing.assert_allclose(matrix(*qa.pose_power(q[i], t[i], 0.3)), ref, atol=2e-15)


def test_mean_matches_scipy():
    rng = np.random.default_rng(5)
    q, t = poses(rng, 24)
    w = rng.random(24)
    tf = scipy_tf(q, t)
    for kw in ({}, {"weights": w}):
        qm, tm = qa.pose_mean(q, t, **kw)
        np.testing.assert_allclose(matrix(qm, tm), tf.mean(**kw).as_matrix(), atol=1e-13)
    q3, t3 = q.reshape(4, 6, 4), t.reshape(4, 6, 3)
    qm, tm = qa.pose_mean(q3, t3, axis=1)
    np.testing.assert_allclose(matrix(qm, tm), scipy_tf(q3, t3).mean(axis=1).as_matrix(), atol=1e-13)


def test_pose_from_matrix_refuses_a_bad_last_row():
    m = np.tile(np.eye(4), (3, 1, 1))
    m[2, 3, 0] = 1e-9
    with pytest.raises(ValueError, match=r"last row of transformation matrix `m`.*row 2"):
        qa.pose_from_matrix(m)
    with pytest.raises(ValueError, match=r"\(\.\.\., 4\)"):
        qa.pose_compose(np.ones(3), np.zeros(3), np.ones(4), np.zeros(3))


# --------------------------------------------------------------------------
# pytransform3d: dual-quaternion ScLERP, exponential coordinates, screw parameters


def pt_dq(q, t):
    return pt.dual_quaternion_from_pq(np.concatenate([t, q]))


def test_sclerp_matches_pytransform3d():
    rng = np.random.default_rng(6)
    q0, t0 = poses(rng, 30)
    q1, t1 = poses(rng, 30)
    s = rng.uniform(-0.5, 1.5, 30)  # extrapolation too
    q, t = qa.sclerp(q0, t0, q1, t1, s)
    for i in range(30):
        a = q1[i] * np.sign(np.dot(q0[i], q1[i]))  # pytransform3d goes the way the signs say: the short one
        ref = pt.dual_quaternion_sclerp(pt_dq(q0[i], t0[i]), pt_dq(a, t1[i]), s[i])
        p, tt = pt.pq_from_dual_quaternion(ref)[3:], pt.pq_from_dual_quaternion(ref)[:3]
        same_rotation(q[i], p, 1e-12)
        np.testing.assert_allclose(t[i], tt, atol=1e-12)


def test_exp_coords_and_screw_parameters_match_pytransform3d():
    rng = np.random.default_rng(7)
    q, t = poses(rng, 20)
    e = qa.as_exp_coords(q, t)
    for i in range(20):
        h = pt.transform_from_pq(np.concatenate([t[i], q[i]]))
        np.testing.assert_allclose(e[i], pt.exponential_coordinates_from_transform(h), atol=1e-12)
        # screw parameters (point on the axis, direction, pitch, angle) read off φ and u
        qs, s_axis, pitch, theta = pt.screw_parameters_from_dual_quaternion(pt_dq(q[i], t[i]))
        phi, u = e[i, :3], e[i, 3:]
        ang = np.linalg.norm(phi)
        w = phi / ang
        v = u / ang
        if theta > np.pi:  # pytransform3d's angle is in [0, 2π): the same screw the other way
            theta, s_axis, pitch = 2 * np.pi - theta, -s_axis, pitch * theta / (2 * np.pi - theta)
        np.testing.assert_allclose(ang, theta, atol=1e-12)
        np.testing.assert_allclose(w, s_axis, atol=1e-12)
        np.testing.assert_allclose(np.dot(w, v), pitch, atol=1e-10)
        # the axis point: v = −w × q_s + pitch·w
        np.testing.assert_allclose(v, -np.cross(w, qs) + pitch * w, atol=1e-10)


# --------------------------------------------------------------------------
# mpmath: SE(3) exp and log in high precision, tiny to half-turn angles


def mp_exp(e, mp):
    """(R, t) of exponential coordinates by the closed forms, in mpmath."""
    phi = [mp.mpf(float(x)) for x in e[:3]]
    u = [mp.mpf(float(x)) for x in e[3:]]
    th = mp.sqrt(sum(x * x for x in phi))
    K = mp.matrix([[0, -phi[2], phi[1]], [phi[2], 0, -phi[0]], [-phi[1], phi[0], 0]])
    K2 = K * K
    if th == 0:
        R, V = mp.eye(3), mp.eye(3)
    else:
        R = mp.eye(3) + mp.sin(th) / th * K + (1 - mp.cos(th)) / th**2 * K2
        V = mp.eye(3) + (1 - mp.cos(th)) / th**2 * K + (th - mp.sin(th)) / th**3 * K2
    return R, V * mp.matrix(u)


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-7, 1e-3, 0.2, 0.2499, 0.2501, 1.0, 3.0, np.pi - 1e-6, np.pi - 1e-9])
def test_exp_and_log_against_mpmath(angle):
    mp = pytest.importorskip("mpmath")
    mp.mp.dps = 40
    rng = np.random.default_rng(8)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    e = np.concatenate([axis * angle, rng.normal(size=3) * 5])
    q, t = qa.from_exp_coords(e)
    R, tt = mp_exp(e, mp)
    np.testing.assert_allclose(qa.as_matrix(q), np.array(R.tolist(), float), atol=4e-16)
    np.testing.assert_allclose(t, np.array(tt.tolist(), float).ravel(), rtol=0, atol=4e-15 * 5)
    # the logarithm of the (rounded) pose gives e back to the rounding of the pose
    back = qa.as_exp_coords(q, t)
    tol = 1e-15 * 20 if angle < 3.1 else 1e-7  # within 1e-6 of a half turn, log is ill-conditioned
    np.testing.assert_allclose(back, e, atol=tol)


def test_half_turns_match_scipy():
    for axis in np.eye(3).tolist() + [[0, 1, 1], [1, 1, 1], [-1, 2, 0]]:
        axis = np.array(axis, float) / np.linalg.norm(axis)
        q = np.concatenate([[0.0], axis])
        t = np.array([1.0, -2.0, 0.5])
        tf = scipy_tf(q, t)
        # exactly at π the rotation vector's sign is free: scipy's follows the rounding of
        # the w it reads off the matrix (±1e-17); both give the pose back
        e, ref = qa.as_exp_coords(q, t), tf.as_exp_coords()
        assert np.allclose(e, ref, atol=1e-14) or np.allclose(e[:3], -ref[:3], atol=1e-14)
        np.testing.assert_allclose(np.linalg.norm(e[:3]), np.pi, atol=1e-15)
        np.testing.assert_allclose(matrix(*qa.from_exp_coords(e)), tf.as_matrix(), atol=1e-14)
        np.testing.assert_allclose(T.from_exp_coords(e).as_matrix(), tf.as_matrix(), atol=1e-14)
        # just short of a half turn the log is unique again
        qn = qa.normalize(q + [1e-9, 0, 0, 0])
        np.testing.assert_allclose(qa.as_exp_coords(qn, t), scipy_tf(qn, t).as_exp_coords(), atol=1e-9)
        qq, tt = qa.pose_power(q, t, 0.5)
        np.testing.assert_allclose(matrix(*qa.pose_compose(qq, tt, qq, tt)), tf.as_matrix(), atol=1e-14)


# --------------------------------------------------------------------------
# edge cases


def test_identity_and_pure_translation():
    one = np.array([1.0, 0, 0, 0])
    assert np.array_equal(qa.as_exp_coords(one, [0, 0, 0]), np.zeros(6))
    assert np.array_equal(qa.as_exp_coords(one, [1, 2, 3]), [0, 0, 0, 1, 2, 3])
    q, t = qa.from_exp_coords([0, 0, 0, 1, 2, 3])
    assert np.array_equal(q, one) and np.array_equal(t, [1, 2, 3])
    # ScLERP between pure translations: a straight line, no rotation axis needed
    q, t = qa.sclerp(one, [0, 0, 0], one, [2, 4, 6], np.array([0.0, 0.25, 1.0, 1.5]))
    np.testing.assert_array_equal(q, np.tile(one, (4, 1)))
    np.testing.assert_allclose(t, [[0, 0, 0], [0.5, 1, 1.5], [2, 4, 6], [3, 6, 9]], atol=1e-15)
    q, t = qa.pose_power(one, [2, 0, 0], -1.5)
    np.testing.assert_array_equal(t, [-3, 0, 0])


@pytest.mark.parametrize("scale", [1e-300, 1e300])
def test_extreme_translations(scale):
    rng = np.random.default_rng(9)
    q, t = poses(rng, 20, scale=scale)
    tf_t = t / scale
    e = qa.as_exp_coords(q, t)
    ref = qa.as_exp_coords(q, tf_t)
    np.testing.assert_allclose(e[:, 3:] / scale, ref[:, 3:], rtol=1e-13)
    np.testing.assert_array_equal(e[:, :3], ref[:, :3])
    _q2, t2 = qa.from_exp_coords(e)
    np.testing.assert_allclose(t2 / scale, tf_t, rtol=1e-12, atol=1e-12 * np.abs(tf_t).max())
    dq = qa.as_dual_quat(q, t)
    assert np.all(np.isfinite(dq))
    _q3, t3 = qa.from_dual_quat(dq)
    np.testing.assert_allclose(t3 / scale, tf_t, rtol=1e-12, atol=1e-13)
    v = rng.normal(size=(20, 3)) * scale
    np.testing.assert_allclose(qa.pose_apply(q, t, v, inverse=True) / scale,
                               qa.pose_apply(q, tf_t, v / scale, inverse=True), rtol=1e-12, atol=1e-13)
    _q4, t4 = qa.sclerp(q, t, q[::-1], t[::-1], 0.3)
    _q5, t5 = qa.sclerp(q, tf_t, q[::-1], tf_t[::-1], 0.3)
    np.testing.assert_allclose(t4 / scale, t5, rtol=1e-12, atol=1e-12)


def test_tiny_motions():
    rng = np.random.default_rng(10)
    phi = rng.normal(size=(10, 3)) * 1e-9
    u = rng.normal(size=(10, 3)) * 1e-9
    q, t = qa.from_exp_coords(np.concatenate([phi, u], axis=1))
    e = qa.as_exp_coords(q, t)
    np.testing.assert_allclose(e, np.concatenate([phi, u], axis=1), rtol=1e-12, atol=1e-24)
    # ScLERP between poses 1e-9 apart: the straight line to first order
    q0, t0 = poses(rng, 10)
    q1, t1 = qa.pose_compose(q0, t0, q, t)
    qs, ts = qa.sclerp(q0, t0, q1, t1, 0.5)
    qh, th = qa.pose_compose(q0, t0, *qa.from_exp_coords(np.concatenate([phi, u], axis=1) / 2))
    same_rotation(qs, qh, 1e-15)
    np.testing.assert_allclose(ts, th, atol=1e-15)


def test_float32_is_kept():
    rng = np.random.default_rng(11)
    q, t = poses(rng, 30, dtype=np.float32)
    q64, t64 = q.astype(np.float64), t.astype(np.float64)
    checks = [
        (qa.as_dual_quat(q, t), qa.as_dual_quat(q64, t64), 1e-6),
        (qa.as_exp_coords(q, t), qa.as_exp_coords(q64, t64), 2e-5),
        (qa.pose_apply(q, t, t), qa.pose_apply(q64, t64, t64), 1e-5),
        (qa.pose_as_matrix(q, t), qa.pose_as_matrix(q64, t64), 1e-5),
    ]
    for got, ref, tol in checks:
        assert got.dtype == np.float32
        np.testing.assert_allclose(got, ref, atol=tol * 10)
    for f, args in [(qa.from_exp_coords, (qa.as_exp_coords(q, t),)), (qa.from_dual_quat, (qa.as_dual_quat(q, t),)),
                    (qa.pose_power, (q, t, 0.3)), (qa.sclerp, (q, t, q[::-1], t[::-1], np.float32(0.3))),
                    (qa.pose_compose, (q, t, q, t)), (qa.pose_inverse, (q, t))]:
        r = f(*args)
        assert r[0].dtype == np.float32 and r[1].dtype == np.float32
        r64 = f(*[a.astype(np.float64) if isinstance(a, np.ndarray) else a for a in args])
        same_rotation(r[0], r64[0], 2e-6)
        np.testing.assert_allclose(r[1], r64[1], atol=1e-4)


def test_out_may_alias_an_input():
    rng = np.random.default_rng(12)
    q, t = poses(rng, 9)
    v = rng.normal(size=(9, 3))
    ref = qa.pose_apply(q, t, v)
    qa.pose_apply(q, t, v, out=v)
    np.testing.assert_array_equal(v, ref)
    out = np.empty((9, 8))
    assert qa.as_dual_quat(q, t, out=out) is out


# --------------------------------------------------------------------------
# properties


def pose_pair(seed, n=8):
    rng = np.random.default_rng(seed)
    q, t = poses(rng, n)
    return rng, q, t


@settings(max_examples=40, deadline=None)
@given(SEEDS)
def test_exp_of_log_is_the_pose(seed):
    _rng, q, t = pose_pair(seed)
    q2, t2 = qa.from_exp_coords(qa.as_exp_coords(q, t))
    same_rotation(q2, q, 1e-14)
    np.testing.assert_allclose(t2, t, atol=1e-13)


@settings(max_examples=40, deadline=None)
@given(SEEDS)
def test_sclerp_ends(seed):
    rng, q, t = pose_pair(seed)
    q1, t1 = poses(rng, 8)
    for s, (qe, te) in ((0.0, (q, t)), (1.0, (q1, t1))):
        qs, ts = qa.sclerp(q, t, q1, t1, s)
        same_rotation(qs, qe, 1e-14)
        np.testing.assert_allclose(ts, te, atol=1e-13)


@settings(max_examples=40, deadline=None)
@given(SEEDS, st.floats(-3, 3), st.floats(-3, 3))
def test_powers_add(seed, a, b):
    _rng, q, t = pose_pair(seed)
    qa_, ta = qa.pose_power(q, t, a)
    qb, tb = qa.pose_power(q, t, b)
    lhs = matrix(*qa.pose_compose(qa_, ta, qb, tb))
    rhs = matrix(*qa.pose_power(q, t, a + b))
    np.testing.assert_allclose(lhs, rhs, atol=1e-12)


def dq_mul(a, b):
    """Dual-quaternion product (r_a + ε d_a)(r_b + ε d_b), scalar first."""
    ra, da, rb, db = a[..., :4], a[..., 4:], b[..., :4], b[..., 4:]
    return np.concatenate([qa.multiply(ra, rb), qa.multiply(ra, db) + qa.multiply(da, rb)], axis=-1)


@settings(max_examples=40, deadline=None)
@given(SEEDS)
def test_dual_quaternion_product_is_the_pose_product(seed):
    rng, q, t = pose_pair(seed)
    q1, t1 = poses(rng, 8)
    lhs = dq_mul(qa.as_dual_quat(q, t), qa.as_dual_quat(q1, t1))
    rhs = qa.as_dual_quat(*qa.pose_compose(q, t, q1, t1))
    sign = np.sign(np.sum(lhs[:, :4] * rhs[:, :4], axis=1))[:, None]
    np.testing.assert_allclose(lhs * sign, rhs, atol=1e-13)


@settings(max_examples=40, deadline=None)
@given(SEEDS, st.floats(-1, 2))
def test_sclerp_of_pure_rotations_is_slerp(seed, s):
    rng = np.random.default_rng(seed)
    q0, q1 = qa.random(8, rng=rng), qa.random(8, rng=rng)
    zero = np.zeros((8, 3))
    q, t = qa.sclerp(q0, zero, q1, zero, s)
    same_rotation(q, qa.slerp(q0, q1, s), 1e-13)
    np.testing.assert_allclose(t, 0, atol=1e-15)


# --------------------------------------------------------------------------
# the pose spline


def test_pose_spline_rules():
    rng = np.random.default_rng(13)
    times = np.cumsum(rng.uniform(0.5, 1.5, 8))
    q, t = poses(rng, 8)
    q = qa.unflip(q)
    new = np.linspace(times[0], times[-1], 41)
    qs, ts = qa.pose_spline(times, q, t, new, method="slerp")
    same_rotation(qs, qa.spline(times, q, new, method="slerp"), 1e-15)
    np.testing.assert_allclose(ts, np.stack([np.interp(new, times, t[:, j]) for j in range(3)], -1), atol=1e-15)
    qs, ts = qa.pose_spline(times, q, t, new, method="cubic")
    from scipy.interpolate import CubicSpline

    np.testing.assert_allclose(ts, CubicSpline(times, t, bc_type="natural")(new), atol=1e-13)
    qs, ts = qa.pose_spline(times, q, t, new, poses="screw")
    k = np.clip(np.searchsorted(times, new, side="right") - 1, 0, 6)
    s = (new - times[k]) / (times[k + 1] - times[k])
    qr, tr = qa.sclerp(q[k], t[k], q[k + 1], t[k + 1], s)
    same_rotation(qs, qr, 0)
    np.testing.assert_array_equal(ts, tr)
    same_rotation(qs[[0, -1]], q[[0, -1]], 1e-15)  # the keys come back at their times
    np.testing.assert_allclose(ts[[0, -1]], t[[0, -1]], atol=1e-14)
    with pytest.raises(ValueError, match="poses"):
        qa.pose_spline(times, q, t, new, poses="bogus")
    with pytest.raises(ValueError, match="new_times"):
        qa.pose_spline(times, q, t, new + 100)


# --------------------------------------------------------------------------
# the command line: resample --poses screw on a pose stream (TUM layout)


def test_cli_resample_poses_screw(tmp_path):
    from quatarray.app.cli import main

    rng = np.random.default_rng(14)
    times = np.cumsum(rng.uniform(0.05, 0.15, 12))
    q, t = poses(rng, 12)
    q = qa.unflip(q)
    src = tmp_path / "in.txt"
    rows = np.column_stack([times, t, q[:, 1:], q[:, :1]])  # TUM: t tx ty tz qx qy qz qw
    np.savetxt(src, rows, fmt="%.17g", header="timestamp tx ty tz qx qy qz qw")
    out = {}
    for rule in ("linear", "screw"):
        dst = tmp_path / f"{rule}.txt"
        assert main(["resample", str(src), str(dst), "--rate", "50", "--poses", rule, "--no-progress"]) == 0
        out[rule] = np.loadtxt(dst)
    new = out["screw"][:, 0]
    qs, ts = qa.pose_spline(times, q, t, new, poses="screw")
    np.testing.assert_allclose(out["screw"][:, 1:4], ts, atol=1e-12)
    same_rotation(out["screw"][:, [7, 4, 5, 6]], qs, 1e-12)
    lin = np.stack([np.interp(new, times, t[:, j]) for j in range(3)], -1)
    np.testing.assert_allclose(out["linear"][:, 1:4], lin, atol=1e-12)  # the default rule: linear positions
    assert not np.allclose(out["screw"][:, 1:4], lin, atol=1e-6)  # the screw couples them to the rotation
    assert main(["resample", str(src), str(tmp_path / "x.txt"), "--rate", "50", "--poses", "screw",
                 "--scheduler", "local", "--no-progress"]) == 2


@pytest.mark.parametrize("scale", [1e-300, 1e-30, 1e30, 1e300])
def test_quaternions_of_any_scale(scale):
    rng = np.random.default_rng(15)
    q, t = poses(rng, 12)
    v = rng.normal(size=(12, 3))
    big = q * scale
    np.testing.assert_allclose(qa.pose_apply(big, t, v), qa.pose_apply(q, t, v), atol=1e-14)
    np.testing.assert_allclose(qa.pose_apply(big, t, v, inverse=True), qa.pose_apply(q, t, v, inverse=True), atol=1e-14)
    np.testing.assert_allclose(qa.pose_as_matrix(big, t), qa.pose_as_matrix(q, t), atol=1e-15)
    np.testing.assert_allclose(qa.as_dual_quat(big, t), qa.as_dual_quat(q, t), atol=1e-15)
    np.testing.assert_allclose(qa.as_exp_coords(big, t), qa.as_exp_coords(q, t), atol=1e-14)
    for f, args, ref in [(qa.pose_compose, (big, t, big, t), (q, t, q, t)), (qa.pose_inverse, (big, t), (q, t)),
                         (qa.sclerp, (big, t, big[::-1], t[::-1], 0.3), (q, t, q[::-1], t[::-1], 0.3)),
                         (qa.pose_power, (big, t, 0.7), (q, t, 0.7))]:
        a, b = f(*args), f(*ref)
        same_rotation(a[0], b[0], 1e-15)
        np.testing.assert_allclose(a[1], b[1], atol=1e-14)
    dq = qa.as_dual_quat(q, t) * scale
    np.testing.assert_allclose(matrix(*qa.from_dual_quat(dq)), matrix(q, t), atol=1e-14)


def test_real_pose_streams_screw(data_dir, tmp_path):
    """TUM and EuRoC ground truth resampled with --poses screw: the TUM poses are
    sclerp of the keys around each new time; both streams come out unit and continuous."""
    from quatarray.app.cli import main

    for name, rate in (("tum_freiburg1_xyz_groundtruth.txt", 45), ("euroc_v102_groundtruth.csv", 70)):
        dst = tmp_path / (name + ".csv")
        assert main(["resample", str(data_dir / name), str(dst), "--rate", str(rate),
                     "--poses", "screw", "--no-progress"]) == 0
        out = np.genfromtxt(dst, delimiter=",", names=True)
        assert len(out) > 100
        q = np.column_stack([out["qw"], out["qx"], out["qy"], out["qz"]])
        np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1, atol=1e-12)
        assert np.max(qa.distance(q[1:], q[:-1])) < 0.2  # continuous: neighbours close in rotation
        if name.startswith("tum"):
            keys = np.loadtxt(data_dir / name)
            kq = keys[:, [7, 4, 5, 6]]
            qs, ts = qa.pose_spline(keys[:, 0], kq, keys[:, 1:4], out["t"], poses="screw")
            np.testing.assert_allclose(np.column_stack([out["x"], out["y"], out["z"]]), ts, atol=1e-9)
            same_rotation(q, qs, 1e-9)
