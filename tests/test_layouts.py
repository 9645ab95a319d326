"""quatarray.layouts against scipy's Rotation and independent formulas."""

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


def test_old_import_path():
    # quatarray.representations held the layouts and MRP and Gibbs vectors: its names still import,
    # the same objects as in quatarray.layouts and (MRP, Gibbs) quatarray.conversions
    import quatarray.conversions as C
    import quatarray.layouts as L
    import quatarray.representations as old
    from quatarray.representations import (
        as_gibbs, as_left_matrix, as_mrp, as_right_matrix, as_su2, as_xyzw,
        from_gibbs, from_mrp, from_scipy, from_su2, from_xyzw, to_scipy,
    )  # fmt: skip

    assert (as_xyzw, from_xyzw, to_scipy, from_scipy, as_left_matrix, as_right_matrix, as_su2, from_su2) == (
        L.as_xyzw, L.from_xyzw, L.to_scipy, L.from_scipy, L.as_left_matrix, L.as_right_matrix, L.as_su2, L.from_su2)
    assert (as_mrp, from_mrp, as_gibbs, from_gibbs) == (C.as_mrp, C.from_mrp, C.as_gibbs, C.from_gibbs)
    assert as_mrp is qa.as_mrp and as_xyzw is qa.as_xyzw
    layouts = {name for name, mod in qa._WHERE.items() if mod == "layouts"}
    assert set(old.__all__) == layouts | {"as_mrp", "from_mrp", "as_gibbs", "from_gibbs"}
    # the old module's other names: layouts' own, and the moved MRP and Gibbs code
    assert old.left_matrix is L.left_matrix and old._as_su2 is L._as_su2
    assert old.qmrp is C.qmrp and old.gibbs_quat is C.gibbs_quat and old._from_mrp is C._from_mrp
    with pytest.raises(AttributeError, match="representations.*as_matrix"):
        old.as_matrix  # noqa: B018 - never a name of the old module
