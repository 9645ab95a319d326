"""quatarray.representations against scipy's Rotation and independent formulas."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

import quatarray as qa

R = lambda q: Rotation.from_quat(np.asarray(q, float), scalar_first=True)  # noqa: E731

quat = arrays(np.float64, 4, elements=st.floats(-10, 10, allow_nan=False, width=64))


def test_xyzw_and_scipy_interop(rng):
    q = qa.random(100, rng)
    a = qa.as_xyzw(q)
    assert np.array_equal(a, q[:, [1, 2, 3, 0]])
    assert np.allclose(a, R(q).as_quat(), atol=1e-15)
    assert np.array_equal(qa.from_xyzw(a), q)
    assert np.allclose(qa.from_xyzw(Rotation.from_quat(a).as_quat()), q, atol=1e-15)
    r = qa.to_scipy(q)
    assert isinstance(r, Rotation) and len(r) == 100
    assert np.allclose(qa.from_scipy(r), q, atol=1e-15)
    assert np.allclose(qa.from_scipy(qa.to_scipy(3 * q[0])), q[0], atol=1e-15)
    assert qa.from_scipy(qa.to_scipy(q.astype(np.float32))).dtype == np.float64
    with pytest.raises(TypeError, match="`rotation`"):
        qa.from_scipy(q)
    with pytest.raises(ValueError, match=r"Expected `q` to have shape \(\.\.\., 4\), got \(3,\)\."):
        qa.to_scipy([1, 0, 0])
    # in place: out aliases the input
    b = q.copy()
    assert qa.as_xyzw(b, out=b) is b and np.array_equal(b, a)
    assert qa.from_xyzw(b, out=b) is b and np.array_equal(b, q)


def test_to_scipy_of_a_stack(rng, monkeypatch):
    """(..., 4) with several leading axes: a Rotation of that shape where scipy has such
    stacks (1.17), else an error naming `q` and the scipy release."""
    from quatarray import _compat

    q = qa.random((2, 3), rng)
    if _compat.scipy_nd_stacks():
        r = qa.to_scipy(q)
        assert r.shape == (2, 3) and np.allclose(qa.from_scipy(r), q, atol=1e-15)
    monkeypatch.setattr(_compat, "_ND_STACKS", [False])
    with pytest.raises(ValueError, match=r"Expected `q` to have shape \(4,\) or \(N, 4\), got \(2, 3, 4\): scipy"):
        qa.to_scipy(q)
    assert len(qa.to_scipy(q[0])) == 3  # (N, 4) as ever


def test_left_right_matrices(rng):
    p, q = rng.standard_normal((200, 4)), rng.standard_normal((200, 4))
    L, Rm = qa.as_left_matrix(q), qa.as_right_matrix(q)
    assert L.shape == Rm.shape == (200, 4, 4)
    assert np.allclose(np.einsum("nij,nj->ni", L, p), qa.multiply(q, p), atol=1e-13)
    assert np.allclose(np.einsum("nij,nj->ni", Rm, p), qa.multiply(p, q), atol=1e-13)
    # they commute (left and right multiplication are independent)
    assert np.allclose(L @ qa.as_right_matrix(p), qa.as_right_matrix(p) @ L, atol=1e-12)
    assert qa.as_left_matrix(q.astype(np.float32)).dtype == np.float32


@settings(max_examples=60, deadline=None)
@given(quat, quat)
def test_su2_is_multiplicative(p, q):
    prod = qa.as_su2(p) @ qa.as_su2(q)
    assert np.allclose(prod, qa.as_su2(qa.multiply(p, q)), atol=1e-11)
    assert np.array_equal(qa.from_su2(qa.as_su2(q)), q)


def test_su2(rng):
    q = qa.random(50, rng)
    u = qa.as_su2(q)
    assert u.dtype == np.complex128 and u.shape == (50, 2, 2)
    assert np.allclose(np.linalg.det(u), 1)
    assert np.allclose(u @ np.conj(np.swapaxes(u, -1, -2)), np.eye(2))  # unitary
    w, x, y, z = q.T
    assert np.array_equal(u[:, 1, 0], -y + 1j * z) and np.array_equal(u[:, 1, 1], w - 1j * x)
    assert qa.as_su2(q.astype(np.float32)).dtype == np.complex64
    assert qa.from_su2(u.astype(np.complex64)).dtype == np.float32
    assert np.array_equal(qa.from_su2(np.eye(2)), [1, 0, 0, 0])  # real input
    # non-contiguous input and the nearest-quaternion average of the two copies
    assert np.array_equal(qa.from_su2(np.swapaxes(np.swapaxes(u, -1, -2), -1, -2)[::2]), q[::2])
    assert np.allclose(qa.from_su2([[1, 0], [0, 0]]), [0.5, 0, 0, 0])
    with pytest.raises(ValueError, match=r"Expected `m` to have shape \(\.\.\., 2, 2\), got \(2, 3\)\."):
        qa.from_su2(np.zeros((2, 3), complex))
    with pytest.raises(TypeError, match="`m`"):
        qa.from_su2(np.array([["a", "b"], ["c", "d"]]))


def test_from_su2_byte_order_ragged_and_masked(rng):
    # issue 14.10 / 14.11
    q = qa.random(5, rng)
    u = qa.as_su2(q)
    for dt, want in ((">c8", np.float32), ("<c8", np.float32), (">c16", np.float64), (">f4", np.float32)):
        m = u.astype(dt) if dt[1] == "c" else u.real.astype(dt)
        r = qa.from_su2(m)
        assert r.dtype == want and r.dtype.isnative, dt
    assert np.allclose(qa.from_su2(u.astype(">c8")), q, atol=1e-6)
    with pytest.raises(TypeError, match="Expected `m` to be an array"):
        qa.from_su2([[[1, 0], [0, 1]], [[1, 0]]])
    with pytest.raises(TypeError, match="`m`.*masked"):
        qa.from_su2(np.ma.masked_array(u))


def test_mrp_vs_scipy(rng):
    from scipy.spatial.transform import Rotation

    q = qa.random(1000, rng=rng) * rng.uniform(0.1, 10, (1000, 1))  # any scale, either sign
    q[:3] = [[0, 1, 0, 0], [0, 0, -1, 0], [1, 0, 0, 0]]  # half turns, identity
    p = qa.as_mrp(q)
    np.testing.assert_allclose(p, Rotation.from_quat(q, scalar_first=True).as_mrp(), atol=1e-15, rtol=1e-13)
    assert np.all(np.linalg.norm(p, axis=-1) <= 1 + 1e-15)
    pp = rng.standard_normal((1000, 3)) * 2  # |p| > 1 too
    np.testing.assert_allclose(qa.from_mrp(pp), Rotation.from_mrp(pp).as_quat(scalar_first=True), atol=1e-15)
    assert np.all(qa.distance(qa.from_mrp(p), q) < 1e-7)  # round trip
    np.testing.assert_allclose(qa.as_mrp(qa.from_mrp(p)), p, atol=1e-15)
    assert np.isnan(qa.as_mrp([0, 0, 0, 0])).all()
    np.testing.assert_allclose(qa.as_mrp([1e-300, 0, 0, 2e-300]), qa.as_mrp([1, 0, 0, 2]))


def test_gibbs(rng):
    q = qa.random(1000, rng=rng)
    g = qa.as_gibbs(q)
    axis, ang = qa.as_axis_angle(q)
    np.testing.assert_allclose(g, np.tan(ang / 2)[:, None] * axis, rtol=1e-9)
    np.testing.assert_allclose(qa.as_gibbs(-3 * q), g, rtol=1e-15)
    assert np.all(qa.distance(qa.from_gibbs(g), q) < 1e-7)
    assert np.all(qa.from_gibbs(g)[:, 0] > 0)
    # half turns: inf along the axis; and back
    np.testing.assert_array_equal(qa.as_gibbs([[0, 0, -1, 0], [0, 1, 1, 0], [0, 0, 0, 1]]),
                                  [[0, np.inf, 0], [np.inf, np.inf, 0], [0, 0, np.inf]])
    np.testing.assert_allclose(qa.from_gibbs([[0, -np.inf, 0], [np.inf, np.inf, 0]]),
                               [[0, 0, -1, 0], [0, 2**-0.5, 2**-0.5, 0]])
    assert np.isnan(qa.as_gibbs([0, 0, 0, 0])).all()
    assert np.isnan(qa.from_gibbs([np.inf, np.nan, 0])).all()
    np.testing.assert_allclose(qa.from_gibbs([1e300, 0, 0]), [0, 1, 0, 0], atol=1e-300)


@pytest.mark.parametrize("fn, core", [("as_mrp", 4), ("from_mrp", 3), ("as_gibbs", 4), ("from_gibbs", 3)])
def test_mrp_gibbs_dtype_out_broadcast(rng, fn, core):
    f = getattr(qa, fn)
    x = qa.random((5, 2), rng=rng)[..., :core].copy()
    res = f(x)
    r32 = f(x.astype(np.float32))
    assert r32.dtype == np.float32 and res.dtype == np.float64
    np.testing.assert_allclose(r32, res, rtol=1e-5, atol=1e-6)
    out = np.empty_like(res)
    assert f(x, out=out) is out
    np.testing.assert_array_equal(out, res)
    np.testing.assert_array_equal(f(x[:, ::-1][:, ::-1]), res)  # strided view
    with pytest.raises(ValueError, match=rf"Expected `\w` to have shape \(\.\.\., {core}\)"):
        f(np.ones((2, 5)))
    with pytest.raises(ValueError):
        f(x, out=np.empty((3, 3)))


@settings(max_examples=200, deadline=None)
@given(quat.filter(lambda q: np.linalg.norm(q) > 1e-3))
def test_mrp_round_trips(q):
    p = qa.as_mrp(q)
    assert np.linalg.norm(p) <= 1 + 1e-15  # the short one of the two MRPs
    assert qa.distance(qa.from_mrp(p), q) < 1e-7
    back = qa.as_mrp(qa.from_mrp(p))
    if np.linalg.norm(p) < 1 - 1e-12:
        np.testing.assert_allclose(back, p, atol=2e-15)
    else:  # a half turn: p and −p are the same rotation, and w = 0 to rounding picks one
        assert qa.distance(qa.from_mrp(back), q) < 1e-7
    np.testing.assert_allclose(p, R(q).as_mrp(), atol=2e-15)


@settings(max_examples=200, deadline=None)
@given(arrays(np.float64, 3, elements=st.floats(-1e3, 1e3, allow_nan=False, width=64)))
def test_gibbs_round_trips(g):
    q = qa.from_gibbs(g)
    assert q[0] > 0
    np.testing.assert_allclose(qa.as_gibbs(q), g, rtol=1e-12, atol=1e-12)
    assert qa.distance(qa.from_gibbs(qa.as_gibbs(q)), q) < 1e-7
