"""quatarray.conversions against scipy's Rotation and independent formulas
(round trips and the shape, dtype and input rules include the functions of
quatarray.layouts)."""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

import quatarray as qa
from quatarray._validate import origin

R = lambda q: Rotation.from_quat(np.asarray(q, float), scalar_first=True)  # noqa: E731
SQ = lambda r: r.as_quat(scalar_first=True)  # noqa: E731

finite = st.floats(-10, 10, allow_nan=False, width=64)
quat = arrays(np.float64, 4, elements=finite)
vec = arrays(np.float64, 3, elements=st.floats(-3, 3, allow_nan=False, width=64))
TOL = {np.float32: 2e-6, np.float64: 1e-14}

# 180° about each axis, about random axes, tiny angles, identity
EYE = np.eye(4)
HALF_TURNS = np.array([[0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1], [0, -1, 0, 0], [0, 0, -1, 0],
                       [0, 0.6, -0.8, 0], [0, 0, 0.6, -0.8], [0, -0.48, 0.6, 0.64]])  # fmt: skip


def same_rotation(a, b, atol):
    """Quaternions a and b (any sign) describe the same rotation."""
    return np.all(np.abs(np.abs(np.sum(a * b, -1)) - 1) <= atol)


def edge_quats(rng):
    axes = rng.standard_normal((4, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    random_half = np.concatenate([np.zeros((4, 1)), axes], 1)
    tiny = np.concatenate([np.ones((4, 1)), 0.5e-12 * axes], 1)
    return np.concatenate([EYE[:1], -EYE[:1], HALF_TURNS, random_half, tiny, -tiny])


# ---------------------------------------------------------------- matrices


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_as_matrix_matches_scipy(rng, dtype):
    q = qa.random(2000, rng)
    got = qa.as_matrix(q.astype(dtype))
    assert got.dtype == dtype and got.shape == (2000, 3, 3)
    want = R(q).as_matrix()
    assert np.allclose(got, want, atol=10 * TOL[dtype])
    assert np.allclose(qa.as_matrix(-q), want, atol=1e-14)  # q and −q
    e = edge_quats(rng)
    assert np.allclose(qa.as_matrix(e), R(e).as_matrix(), atol=1e-15)


def test_as_matrix_non_unit_equals_rotate(rng):
    q = rng.standard_normal((500, 4)) * rng.uniform(1e-3, 1e3, (500, 1))
    v = rng.standard_normal((500, 3))
    m = qa.as_matrix(q)
    assert np.allclose(np.einsum("nij,nj->ni", m, v), qa.rotate(q, v), atol=1e-13)
    assert np.allclose(m, R(q).as_matrix(), atol=1e-14)
    assert np.isnan(qa.as_matrix([0, 0, 0, 0])).all()
    assert np.isnan(qa.as_matrix([np.nan, 0, 0, 0])).all()


@settings(max_examples=60, deadline=None)
@given(quat)
def test_as_matrix_orthonormal_det_one(q):
    assume(np.linalg.norm(q) > 1e-3)
    m = qa.as_matrix(q)
    assert np.allclose(m @ m.T, np.eye(3), atol=1e-13)
    assert np.isclose(np.linalg.det(m), 1.0, atol=1e-13)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_from_matrix_matches_scipy_with_sign(rng, dtype):
    q = np.concatenate([qa.random(2000, rng), edge_quats(rng)])
    m = R(q).as_matrix()
    want = SQ(Rotation.from_matrix(m))
    got = qa.from_matrix(m.astype(dtype))
    assert got.dtype == dtype
    # same sign as scipy (not canonical): Shepperd's branch decides it
    assert np.allclose(got, want, atol=10 * TOL[dtype])
    got = qa.from_matrix(m.astype(dtype), assume_valid=True)
    assert np.allclose(got, SQ(Rotation.from_matrix(m, assume_valid=True)), atol=10 * TOL[dtype])


def test_from_matrix_sign_is_not_canonical():
    # largest diagonal entry m00 > trace: x comes out positive and w negative, as scipy
    q = qa.normalize([-0.1, 0.9, 0.3, 0.2])
    m = qa.as_matrix(q)
    got = qa.from_matrix(m)
    assert got[1] > 0 and got[0] < 0
    assert np.allclose(got, SQ(Rotation.from_matrix(m)), atol=1e-15)


def _scipy_projects_onto_nearest_rotation():
    """scipy's from_matrix of a non-orthogonal matrix is the nearest rotation (polar
    decomposition) from scipy 1.15; before, Markley's method gives another rotation."""
    g = np.random.default_rng(0).standard_normal((3, 3))
    g *= np.sign(np.linalg.det(g))
    u, _, vt = np.linalg.svd(g)
    return np.allclose(Rotation.from_matrix(g).as_matrix(), u @ vt, atol=1e-12)


def test_from_matrix_projects_onto_the_nearest_rotation(rng):
    # the projection is the nearest rotation: a rotation back is itself
    assert np.allclose(qa.from_matrix(np.diag([3.0, 2.0, 1.0])), [1, 0, 0, 0])
    g = rng.standard_normal((200, 3, 3))
    g[np.linalg.det(g) < 0] *= -1
    u, _, vt = np.linalg.svd(g)
    assert np.allclose(qa.as_matrix(qa.from_matrix(g)), u @ vt, atol=1e-9)


def test_from_matrix_projects_non_orthogonal_like_scipy(rng):
    if not _scipy_projects_onto_nearest_rotation():
        import scipy

        pytest.skip(f"the oracle is scipy's projection onto the nearest rotation (scipy 1.15 on); scipy {scipy.__version__} here")
    m = R(qa.random(1000, rng)).as_matrix()
    noisy = m + 1e-3 * rng.standard_normal(m.shape)
    scaled = m * rng.uniform(0.5, 2, (1000, 1, 1))
    gauss = rng.standard_normal((1000, 3, 3))
    gauss[np.linalg.det(gauss) < 0] *= -1
    gauss = gauss[np.linalg.cond(gauss) < 1e4]
    slightly = m * (1 + 5e-7)  # within scipy's rtol: not projected, by scipy and by us
    for a in (noisy, scaled, gauss, slightly):
        want = SQ(Rotation.from_matrix(a))
        assert np.allclose(qa.from_matrix(a), want, atol=1e-11)
    f32 = qa.from_matrix(noisy.astype(np.float32))
    assert f32.dtype == np.float32
    assert same_rotation(f32, SQ(Rotation.from_matrix(noisy)), 1e-5)


def test_from_matrix_rejects_non_positive_determinant(rng):
    m = R(qa.random(10, rng)).as_matrix()
    m[7] = -m[7]
    with pytest.raises(ValueError, match=r"`m`.*row 7 has determinant -1"):
        qa.from_matrix(m)
    m[7] = 0
    with pytest.raises(ValueError, match=r"row 7 has determinant 0"):
        qa.from_matrix(m)
    with pytest.raises(ValueError, match=r"index \(1, 2\)"):
        qa.from_matrix(m.reshape(2, 5, 3, 3))
    with pytest.raises(ValueError, match=r"the single input has determinant -1"):
        qa.from_matrix(-np.eye(3))
    m[7] = np.diag([1.0, 1.0, -1.0])  # a reflection
    with pytest.raises(ValueError, match="determinant"):
        qa.from_matrix(m)
    with origin((100, 20)), pytest.raises(ValueError, match=r"index \(101, 22\)"):
        qa.from_matrix(m.reshape(2, 5, 3, 3))  # inside a block of a larger array (quatarray.dask)
    with origin((100,)), pytest.raises(ValueError, match=r"row 107 has"):
        qa.from_matrix(m)
    assert qa.from_matrix(m[:7]).shape == (7, 4)
    # non-finite matrices propagate as nan, they do not raise
    bad = np.full((3, 3), np.nan)
    assert np.isnan(qa.from_matrix(bad)).all()
    bad = np.eye(3)
    bad[0, 0] = np.inf
    assert np.isnan(qa.from_matrix(bad)).all()


# ---------------------------------------------------------------- rotation vectors


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_as_rotvec_matches_scipy(rng, dtype):
    q = np.concatenate([qa.random(2000, rng), edge_quats(rng)])
    got = qa.as_rotvec(q.astype(dtype))
    assert got.dtype == dtype
    want = R(q).as_rotvec()
    assert np.allclose(got, want, atol=20 * TOL[dtype])
    assert np.all(np.linalg.norm(qa.as_rotvec(q), axis=-1) <= np.pi * (1 + 4e-16))
    assert np.allclose(qa.as_rotvec(q, degrees=True), R(q).as_rotvec(degrees=True), atol=1e-12)


def test_as_rotvec_edges(rng):
    e = edge_quats(rng)
    # 180° rotations: the same direction as scipy (its canonical sign)
    assert np.allclose(qa.as_rotvec(e), R(e).as_rotvec(), atol=1e-15, rtol=0)
    assert np.allclose(qa.as_rotvec(-e), R(e).as_rotvec(), atol=1e-15, rtol=0)
    # tiny angles: relative accuracy, no arccos
    r = np.array([1e-12, -2e-12, 3e-13])
    q = np.concatenate([[1.0], r / 2])
    assert np.allclose(qa.as_rotvec(q), r, rtol=1e-15, atol=0)
    assert np.allclose(qa.as_rotvec(7 * q), r, rtol=1e-15, atol=0)  # non-unit
    assert np.array_equal(qa.as_rotvec(qa.identity()), [0, 0, 0])
    assert np.isnan(qa.as_rotvec([0, 0, 0, 0])).all()
    assert np.isnan(qa.as_rotvec([np.nan, 0, 0, 1])).all()


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_from_rotvec_matches_scipy(rng, dtype):
    r = np.concatenate([rng.standard_normal((2000, 3)) * 2, [[1e-12, 0, 0], [0, 0, 0], [0, np.pi, 0]]])
    got = qa.from_rotvec(r.astype(dtype))
    assert got.dtype == dtype
    assert np.allclose(got, SQ(Rotation.from_rotvec(r)), atol=10 * TOL[dtype])
    assert np.allclose(qa.from_rotvec(r * 57.3, degrees=True), SQ(Rotation.from_rotvec(r * 57.3, degrees=True)))
    big = r * 1e5  # long vectors: the polynomial sine/cosine's range reduction
    assert np.allclose(qa.from_rotvec(big), SQ(Rotation.from_rotvec(big)), atol=1e-9)


def test_from_rotvec_tiny_and_degenerate():
    r = np.array([3e-12, -1e-12, 2e-13])
    assert np.allclose(qa.from_rotvec(r)[1:], r / 2, rtol=1e-15, atol=0)
    assert qa.from_rotvec(r)[0] == 1.0
    assert np.array_equal(qa.from_rotvec([0, 0, 0]), [1, 0, 0, 0])
    assert np.isnan(qa.from_rotvec([np.nan, 0, 0])).all()
    assert np.isnan(qa.from_rotvec([np.inf, 0, 0])).all()


# ---------------------------------------------------------------- axis-angle


def test_axis_angle_against_rotvec(rng):
    q = np.concatenate([qa.random(1000, rng), edge_quats(rng)[2:]])
    axis, ang = qa.as_axis_angle(q)
    assert np.allclose(np.linalg.norm(axis, axis=-1), 1, atol=1e-15)
    assert np.all((ang >= 0) & (ang <= np.pi))
    assert np.allclose(axis * ang[:, None], R(q).as_rotvec(), atol=1e-14)
    axis_d, ang_d = qa.as_axis_angle(q, degrees=True)
    assert np.array_equal(axis_d, axis) and np.allclose(ang_d, np.degrees(ang))
    back = qa.from_axis_angle(axis, ang)
    assert same_rotation(back, q, 1e-14)
    assert same_rotation(qa.from_axis_angle(axis, ang_d, degrees=True), q, 1e-14)


def test_axis_angle_edges():
    axis, ang = qa.as_axis_angle([[1, 0, 0, 0], [-3, 0, 0, 0]])
    assert np.array_equal(axis, [[1, 0, 0], [1, 0, 0]]) and np.array_equal(ang, [0, 0])
    axis, ang = qa.as_axis_angle([0, 0, -1, 0])
    assert np.array_equal(axis + 0, [0, 1, 0]) and ang == np.pi
    axis, ang = qa.as_axis_angle([1, 1e-13, 0, 0])
    assert np.allclose(axis, [1, 0, 0]) and np.isclose(ang, 2e-13, rtol=1e-15)
    axis, ang = qa.as_axis_angle([0, 0, 0, 0])
    assert np.isnan(axis).all() and np.isnan(ang)
    axis, ang = qa.as_axis_angle([np.nan, 1, 0, 0])
    assert np.isnan(ang)


def test_from_axis_angle(rng):
    axis = rng.standard_normal((500, 3)) * rng.uniform(1e-3, 1e3, (500, 1))
    ang = rng.uniform(-7, 7, 500)
    want = SQ(Rotation.from_rotvec(axis / np.linalg.norm(axis, axis=1, keepdims=True) * ang[:, None]))
    assert np.allclose(qa.from_axis_angle(axis, ang), want, atol=1e-14)
    # one axis, many angles (broadcasting), and float32
    got = qa.from_axis_angle(np.float32([0, 0, 1]), np.linspace(0, np.pi, 5, dtype=np.float32))
    assert got.dtype == np.float32 and got.shape == (5, 4)
    assert np.allclose(got[-1], [0, 0, 0, 1], atol=1e-7)
    assert qa.from_axis_angle([1, 0, 0], 1.0).shape == (4,)
    f32 = qa.from_axis_angle(np.float32([0, 0, 1]), 90, degrees=True)  # a Python angle never upcasts
    assert f32.dtype == np.float32 and np.allclose(f32, [np.sqrt(0.5), 0, 0, np.sqrt(0.5)])
    assert qa.from_rotvec(np.float32([0, 0, 90]), degrees=True).dtype == np.float32
    assert qa.as_rotvec(np.float32([1, 0, 0, 1]), degrees=True).dtype == np.float32
    assert qa.as_axis_angle(np.float32([1, 0, 0, 1]), degrees=True)[1].dtype == np.float32
    with pytest.raises(ValueError, match=r"`axis`.*row 2"):
        qa.from_axis_angle([[1, 0, 0], [0, 1, 0], [0, 0, 0]], 1.0)
    with pytest.raises(ValueError, match=r"`axis`.*index \(1, 0\)"):
        qa.from_axis_angle(np.zeros((2, 1, 3)) + [[[1, 0, 0]], [[0, 0, 0]]], 1.0)
    assert np.isnan(qa.from_axis_angle([np.nan, 0, 0], 1.0)).all()
    assert np.isnan(qa.from_axis_angle([np.inf, 0, 0], 1.0)[:2]).all()


# ---------------------------------------------------------------- round trips


@settings(max_examples=60, deadline=None)
@given(quat)
def test_round_trips(q):
    assume(np.linalg.norm(q) > 1e-3)
    u = q / np.linalg.norm(q)
    assert same_rotation(qa.from_matrix(qa.as_matrix(q)), u, 1e-13)
    assert same_rotation(qa.from_matrix(qa.as_matrix(q), assume_valid=True), u, 1e-13)
    assert same_rotation(qa.from_rotvec(qa.as_rotvec(q)), u, 1e-13)
    assert same_rotation(qa.from_rotvec(qa.as_rotvec(q, True), True), u, 1e-13)
    assert same_rotation(qa.from_axis_angle(*qa.as_axis_angle(q)), u, 1e-13)
    assert np.array_equal(qa.from_xyzw(qa.as_xyzw(q)), q)
    assert same_rotation(qa.from_scipy(qa.to_scipy(q)), u, 1e-15)


@settings(max_examples=60, deadline=None)
@given(vec)
def test_rotvec_round_trip(r):
    back = qa.as_rotvec(qa.from_rotvec(r))
    if np.linalg.norm(r) < np.pi - 1e-6:
        assert np.allclose(back, r, atol=1e-13)
    assert np.allclose(qa.as_matrix(qa.from_rotvec(back)), qa.as_matrix(qa.from_rotvec(r)), atol=1e-13)


# ---------------------------------------------------------------- shapes, dtypes, out, inputs


def test_broadcasting_shapes(rng):
    q = qa.random((2, 5), rng)
    m = qa.as_matrix(q)
    assert m.shape == (2, 5, 3, 3)
    assert np.array_equal(qa.from_matrix(m), qa.from_matrix(m.reshape(10, 3, 3)).reshape(2, 5, 4))
    assert qa.as_rotvec(q).shape == (2, 5, 3)
    assert qa.from_rotvec(qa.as_rotvec(q)).shape == (2, 5, 4)
    axis, ang = qa.as_axis_angle(q)
    assert axis.shape == (2, 5, 3) and ang.shape == (2, 5)
    assert qa.from_axis_angle(axis[:, :1], ang).shape == (2, 5, 4)
    assert qa.as_left_matrix(q).shape == (2, 5, 4, 4) and qa.as_su2(q).shape == (2, 5, 2, 2)
    assert qa.as_matrix(q[0, 0]).shape == (3, 3) and qa.from_matrix(np.eye(3)).shape == (4,)
    assert qa.as_rotvec(np.empty((0, 4))).shape == (0, 3)
    assert isinstance(qa.as_axis_angle(q[0, 0])[1], float | np.floating)


def test_out(rng):
    q = qa.random(20, rng)
    o = np.empty((20, 3, 3))
    assert qa.as_matrix(q, out=o) is o and np.array_equal(o, qa.as_matrix(q))
    o4 = np.empty((20, 4))
    assert qa.from_matrix(o, out=o4) is o4 and np.array_equal(o4, qa.from_matrix(o))
    assert qa.from_matrix(o, assume_valid=True, out=o4) is o4
    o3 = np.empty((20, 3))
    assert qa.as_rotvec(q, out=o3) is o3 and np.array_equal(o3, qa.as_rotvec(q))
    assert qa.from_rotvec(o3, out=o4) is o4 and np.array_equal(o4, qa.from_rotvec(o3))
    assert qa.from_axis_angle(o3, 1.0, out=o4) is o4
    with pytest.raises(ValueError, match="out"):
        qa.as_matrix(q, out=np.empty((20, 3, 3), np.float32))
    with pytest.raises(ValueError, match="out"):
        qa.as_rotvec(q, out=np.empty((20, 4)))


def test_read_only_memmap_and_strided(tmp_path, rng):
    q = qa.random(300, rng)
    path = tmp_path / "q.npy"
    np.save(path, q)
    mm = np.load(path, mmap_mode="r")
    assert not mm.flags.writeable
    assert np.array_equal(qa.as_matrix(mm), qa.as_matrix(q))
    assert np.array_equal(qa.as_rotvec(mm), qa.as_rotvec(q))
    m = qa.as_matrix(q)
    np.save(tmp_path / "m.npy", m)
    mmm = np.load(tmp_path / "m.npy", mmap_mode="r")
    assert np.array_equal(qa.from_matrix(mmm), qa.from_matrix(m))
    big = np.zeros((300, 8))
    big[:, ::2] = q  # strided view
    assert np.array_equal(qa.as_matrix(big[:, ::2]), qa.as_matrix(q))
    assert np.array_equal(qa.from_matrix(np.swapaxes(np.swapaxes(m, 1, 2).copy(), 1, 2)), qa.from_matrix(m))
    assert np.array_equal(mm, q)  # inputs untouched


def test_bad_shapes_and_dtypes():
    with pytest.raises(ValueError, match=r"Expected `q` to have shape \(\.\.\., 4\), got \(10, 3\)\."):
        qa.as_matrix(np.zeros((10, 3)))
    with pytest.raises(ValueError, match=r"Expected `m` to have shape \(\.\.\., 3, 3\), got \(10, 3, 4\)\."):
        qa.from_matrix(np.zeros((10, 3, 4)))
    with pytest.raises(ValueError, match=r"Expected `r` to have shape \(\.\.\., 3\), got \(4,\)\."):
        qa.from_rotvec([1, 2, 3, 4])
    with pytest.raises(ValueError, match=r"`axis`"):
        qa.from_axis_angle([1, 0], 1.0)
    with pytest.raises(ValueError, match="broadcast"):
        qa.from_axis_angle(np.ones((3, 3)), np.ones(4))
    with pytest.raises(TypeError, match="`q`"):
        qa.as_rotvec(np.zeros((2, 4), complex))
    with pytest.raises(TypeError, match="`m`"):
        qa.from_matrix(np.zeros((3, 3), object))
    # integers and lists become float64
    assert qa.as_matrix([1, 0, 0, 0]).dtype == np.float64
    assert qa.from_rotvec(np.zeros(3, np.int32)).dtype == np.float64


def test_parallel_variants_report_the_first_bad_row(rng):
    """The multi-threaded loops (used from QUATARRAY_PARALLEL_MIN_ROWS rows) reduce
    the first bad row across threads and give the serial results."""
    from quatarray import conversions as C

    m = qa.as_matrix(qa.random(3000, rng))
    m[[2500, 1700, 2900]] *= -1
    out_p, out_s = np.empty((3000, 4)), np.empty((3000, 4))
    assert C._from_matrix.parallel(m, out_p) == 1700 == C._from_matrix.serial(m, out_s)
    assert np.array_equal(out_p, out_s, equal_nan=True)
    axis = rng.standard_normal((3000, 3))
    axis[[2999, 1234]] = 0
    ang = rng.standard_normal(3000)
    assert C._from_axis_angle.parallel(axis, ang, out_p) == 1234 == C._from_axis_angle.serial(axis, ang, out_s)
    assert np.array_equal(out_p, out_s, equal_nan=True)


# ---------------------------------------------------------------- hardening (issue 14)


def test_big_endian_float32_conversions(rng):
    # issue 14.11: '>f4' in any function gives native float32
    q = qa.random(5, rng).astype(">f4")
    for r in (qa.as_matrix(q), qa.from_matrix(qa.as_matrix(q).astype(">f4")), qa.as_rotvec(q),
              qa.from_rotvec(np.ones((5, 3), ">f4")), qa.as_axis_angle(q)[0], qa.as_left_matrix(q),
              qa.from_axis_angle(np.ones((5, 3), ">f4"), np.ones(5, ">f4")), qa.as_xyzw(q)):
        assert r.dtype == np.float32 and r.dtype.isnative
    assert qa.as_su2(q).dtype == np.complex64


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_any_scale_conversions(rng, dtype):
    # issue 14.5: 1e160·q gave the identity matrix and a zero rotation vector,
    # 1e-160·q nan, from_matrix(1e120·R) nan
    tol = 1e-12 if dtype == np.float64 else 2e-6
    scales = (1e-300, 1e-160, 1e160, 1e300) if dtype == np.float64 else (1e-37, 1e-30, 1e30, 1e37)
    q0 = np.concatenate([qa.random(20, rng), [[np.cos(np.pi / 4), 0, np.sin(np.pi / 4), 0]]]).astype(dtype)
    v = rng.normal(size=(21, 3)).astype(dtype)
    m0 = qa.as_matrix(q0)
    for s in scales:
        s = dtype(s)
        q = q0 * s
        assert np.allclose(qa.as_matrix(q), m0, atol=tol)
        assert np.allclose(qa.rotate(q, v), qa.rotate(q0, v), atol=10 * tol)
        assert np.allclose(qa.rotate(q[-1], v), qa.rotate(q0[-1], v), atol=10 * tol)
        assert np.allclose(qa.as_rotvec(q), qa.as_rotvec(q0), atol=tol)
        for a, b in zip(qa.as_axis_angle(q), qa.as_axis_angle(q0)):
            assert np.allclose(a, b, atol=tol)
        assert np.allclose(qa.as_euler(q, "ZYX", suppress_warnings=True), qa.as_euler(q0, "ZYX", suppress_warnings=True), atol=tol)
        assert np.allclose(qa.as_euler(q, "zxz"), qa.as_euler(q0, "zxz"), atol=tol)
        assert np.allclose(qa.distance(qa.from_matrix(m0 * s), q0), 0, atol=10 * tol)
        T = qa.VQS(v, q, 2.0)
        assert np.allclose(T.apply(v), qa.VQS(v, q0, 2.0).apply(v), atol=10 * tol)
        assert np.allclose((T @ T.inverse()).apply(v), v, atol=100 * tol)
    with pytest.raises(ValueError, match="determinant"):
        qa.from_matrix(np.zeros((3, 3)))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_huge_angles_give_unit_quaternions(rng, dtype):
    # issue 14.6: from_rotvec / from_axis_angle at 1e18 rad gave |q| ≈ 2e15
    ang = np.array([1e18, -3e7, 7e5, 1e30 if dtype == np.float64 else 1e19, 4e6], dtype)
    axis = qa.normalize(np.concatenate([rng.normal(size=(5, 3)), np.zeros((5, 1))], 1))[:, :3].astype(dtype)
    for q in (qa.from_rotvec(axis * ang[:, None]), qa.from_axis_angle(axis, ang)):
        assert q.dtype == dtype
        assert np.allclose(qa.norm(q), 1, atol=1e-6)
        if dtype == np.float64:  # (float32 products axis·angle round differently from scipy's)
            want = Rotation.from_rotvec(axis * ang[:, None]).as_quat(scalar_first=True)
            assert np.allclose(qa.distance(q, want), 0, atol=1e-8)
    assert np.isnan(qa.from_rotvec([np.inf, 0, 0])).all()


# ---------------------------------------------------------------- modified Rodrigues parameters and Gibbs vectors


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
