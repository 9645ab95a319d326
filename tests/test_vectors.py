"""quatarray.vectors.rotate against scipy's Rotation.apply."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

import quatarray as qa


def test_worked_example():
    # rotating (0, 1, 1) by 90° about y gives (1, 1, 0)
    q = [np.cos(np.pi / 4), 0, np.sin(np.pi / 4), 0]
    assert np.allclose(qa.rotate(q, [0, 1, 1]), [1, 1, 0], atol=1e-15)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_matches_scipy_apply(rng, dtype):
    q = qa.random(2000, rng)
    v = rng.standard_normal((2000, 3))
    got = qa.rotate(q.astype(dtype), v.astype(dtype))
    assert got.dtype == dtype
    want = Rotation.from_quat(q, scalar_first=True).apply(v)
    assert np.allclose(got, want, atol=1e-5 if dtype == np.float32 else 1e-14)
    assert np.allclose(qa.rotate(-q, v), want, atol=1e-14)  # q and −q: same rotation


def test_non_unit_quaternions_need_no_normalising(rng):
    q = qa.random(500, rng)
    v = rng.standard_normal((500, 3))
    scale = rng.uniform(1e-3, 1e3, (500, 1))
    assert np.allclose(qa.rotate(q * scale, v), qa.rotate(q, v), atol=1e-12)
    assert np.isnan(qa.rotate([0, 0, 0, 0], [1, 2, 3])).all()


def test_edge_rotations():
    v = np.array([1.0, 2.0, 3.0])
    assert np.array_equal(qa.rotate(qa.identity(), v), v)
    assert np.allclose(qa.rotate([0, 1, 0, 0], v), [1, -2, -3])  # 180° about x
    assert np.allclose(qa.rotate([0, 0, 0, 1], v), [-1, -2, 3])  # 180° about z
    tiny = Rotation.from_rotvec([0, 0, 1e-12]).as_quat(scalar_first=True)
    assert np.allclose(qa.rotate(tiny, [1, 0, 0]), [1, 1e-12, 0], rtol=1e-12, atol=1e-24)
    assert np.isnan(qa.rotate([np.nan, 0, 0, 0], v)).all()


def test_broadcasting_and_out(rng):
    q = qa.random((4, 1), rng)
    v = rng.standard_normal((5, 3))
    got = qa.rotate(q, v)
    assert got.shape == (4, 5, 3)
    assert np.allclose(got[2, 3], qa.rotate(q[2, 0], v[3]))
    one_q = qa.rotate(q[0, 0], v)
    assert one_q.shape == (5, 3)
    vv = v.copy()
    assert qa.rotate(q[0, 0], vv, out=vv) is vv and np.array_equal(vv, one_q)
    with pytest.raises(ValueError, match=r"Expected `v` to have shape \(\.\.\., 3\), got \(5, 4\)\."):
        qa.rotate(q, np.zeros((5, 4)))
    with pytest.raises(ValueError, match="out"):
        qa.rotate(q[0, 0], v, out=np.empty((5, 4)))


@settings(max_examples=60, deadline=None)
@given(
    arrays(np.float64, 4, elements=st.floats(-5, 5)).filter(lambda q: np.linalg.norm(q) > 1e-2),
    arrays(np.float64, 3, elements=st.floats(-100, 100)),
)
def test_preserves_length_and_composes(q, v):
    r = qa.rotate(q, v)
    assert np.isclose(np.linalg.norm(r), np.linalg.norm(v), rtol=1e-12, atol=1e-9)
    p = np.array([0.5, -0.5, 0.5, 0.5])
    assert np.allclose(qa.rotate(qa.multiply(p, q), v), qa.rotate(p, r), atol=1e-9)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_one_rotation_many_vectors(rng, dtype):
    # a single q takes the matrix path; it must agree with scipy and the row-wise path
    q = qa.random(rng=rng) * 3.0  # non-unit on purpose
    v = rng.standard_normal((1000, 3))
    got = qa.rotate(q.astype(dtype), v.astype(dtype))
    assert got.dtype == dtype and got.shape == (1000, 3)
    want = Rotation.from_quat(q, scalar_first=True).apply(v)
    assert np.allclose(got, want, atol=1e-5 if dtype == np.float32 else 1e-14)
    assert np.allclose(qa.rotate(np.tile(q, (1000, 1)), v), want, atol=1e-14)
    assert qa.rotate(q, np.empty((0, 3))).shape == (0, 3)
    assert np.isnan(qa.rotate(np.zeros(4), v[:3])).all()


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("variant", ["serial", "parallel"])
def test_far_rows_with_out_and_out_v(rng, dtype, variant):
    # rows far from unit scale (and zero, nan) are redone by the second pass, also
    # when `out` is `v` (its own loop, which must leave those rows holding v)
    from quatarray import _jit

    big, small = (1e30, 1e-30) if dtype == np.float32 else (1e200, 1e-200)
    q0 = qa.random(300, rng).astype(dtype)
    v = rng.standard_normal((300, 3)).astype(dtype)
    q = q0.copy()
    q[7] *= dtype(big)
    q[150] *= dtype(small)
    q[200], q[201] = 0, np.nan
    with _jit.variant(variant):
        want = qa.rotate(q0, v)
        got = qa.rotate(q, v)
        into = v.copy()
        assert qa.rotate(q, into, out=into) is into
        out = np.empty_like(v)
        qa.rotate(q, v, out=out)
    near = np.ones(300, bool)
    near[[200, 201]] = False
    tol = 1e-5 if dtype == np.float32 else 1e-14
    assert np.allclose(got[near], want[near], atol=tol) and np.isnan(got[~near]).all()
    np.testing.assert_array_equal(into, got)
    np.testing.assert_array_equal(out, got)


def test_old_import_path():
    # the module was quatarray.rotation: that path is the same module object
    import quatarray.rotation
    import quatarray.vectors
    from quatarray.rotation import rotate

    assert quatarray.rotation is quatarray.vectors
    assert rotate is qa.rotate is quatarray.vectors.rotate
