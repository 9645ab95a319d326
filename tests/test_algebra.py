"""quatarray.algebra against scipy and independent formulas."""

import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

import quatarray as qa

R = lambda q: Rotation.from_quat(np.asarray(q, float), scalar_first=True)  # noqa: E731

# no subnormals: a quaternion whose largest component is subnormal gives nan by
# design (README; test_any_scale_algebra checks it on purpose)
finite = st.floats(-10, 10, allow_nan=False, allow_subnormal=False, width=64)
quat = arrays(np.float64, 4, elements=finite)


def ref_mul(p, q):
    """Hamilton product from the 4×4 left-matrix form (independent of the kernel)."""
    w, x, y, z = np.moveaxis(p, -1, 0)
    L = np.stack(
        [
            np.stack([w, -x, -y, -z], -1),
            np.stack([x, w, -z, y], -1),
            np.stack([y, z, w, -x], -1),
            np.stack([z, -y, x, w], -1),
        ],
        -2,
    )
    return np.einsum("...ij,...j->...i", L, q)


def test_basis_products():
    one, i, j, k = np.eye(4)
    assert np.array_equal(qa.multiply(i, j), k)
    assert np.array_equal(qa.multiply(j, k), i)
    assert np.array_equal(qa.multiply(k, i), j)
    for u in (i, j, k):
        assert np.array_equal(qa.multiply(u, u), -one)
    assert np.array_equal(qa.multiply(qa.multiply(i, j), k), -one)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_multiply_matches_scipy_composition(rng, dtype):
    p, q = qa.random(1000, rng), qa.random(1000, rng)
    got = qa.multiply(p.astype(dtype), q.astype(dtype))
    assert got.dtype == dtype
    want = (R(p) * R(q)).as_quat(scalar_first=True)
    tol = 1e-6 if dtype == np.float32 else 1e-14
    assert np.allclose(qa.distance(got.astype(float), want), 0, atol=10 * tol)
    assert np.allclose(got, ref_mul(p, q), atol=tol)


def test_multiply_broadcasting(rng):
    p = rng.standard_normal((5, 1, 4))
    q = rng.standard_normal((3, 4))
    got = qa.multiply(p, q)
    assert got.shape == (5, 3, 4)
    assert np.allclose(got, ref_mul(p, q[None]))
    one = qa.multiply(p[0, 0], q)  # (4,) with (N, 4)
    assert one.shape == (3, 4) and np.allclose(one, ref_mul(p[0, 0], q))
    assert qa.multiply(p[0, 0], q[0]).shape == (4,)
    assert qa.multiply(np.empty((0, 4)), q[0]).shape == (0, 4)


def test_dtype_rules(rng):
    q32 = qa.random(4, rng, dtype=np.float32)
    q64 = q32.astype(np.float64)
    assert qa.multiply(q32, q32).dtype == np.float32
    assert qa.multiply(q32, q64).dtype == np.float64
    assert qa.multiply([[1, 0, 0, 0]], [[0, 1, 0, 0]]).dtype == np.float64
    assert qa.multiply(np.ones((2, 4), int), np.ones(4, bool)).dtype == np.float64
    assert qa.power(q32, 0.5).dtype == np.float32  # a Python scalar never upcasts
    assert qa.power(q32, np.float64(0.5)).dtype == np.float64
    with pytest.raises(TypeError, match="`q`"):
        qa.normalize(np.ones(4, complex))
    with pytest.raises(TypeError, match="`p`"):
        qa.multiply(np.array(["a", "b", "c", "d"]), q64)


@pytest.mark.parametrize(
    "f", [qa.conjugate, qa.inverse, qa.normalize, qa.exp, qa.log, qa.canonical, qa.norm, qa.angle]
)
def test_bad_shape_message(f):
    with pytest.raises(ValueError, match=r"Expected `q` to have shape \(\.\.\., 4\), got \(10, 3\)\."):
        f(np.zeros((10, 3)))


def test_broadcast_error_names_arguments():
    with pytest.raises(ValueError, match="`p`.*`q`.*broadcast"):
        qa.multiply(np.zeros((3, 4)), np.zeros((5, 4)))


def test_out_and_aliasing(rng):
    p, q = qa.random(100, rng), qa.random(100, rng)
    want = qa.multiply(p, q)
    out = np.empty_like(p)
    assert qa.multiply(p, q, out=out) is out and np.array_equal(out, want)
    p2 = p.copy()
    qa.multiply(p2, q, out=p2)  # out is the first input
    assert np.array_equal(p2, want)
    q2 = q.copy()
    qa.multiply(p, q2, out=q2)  # out is the second input
    assert np.array_equal(q2, want)
    # partial overlap: out is a shifted view of the input; no row may read a written row
    a = qa.random(11, rng)
    want = qa.multiply(a[:-1], a[0])
    qa.multiply(a[:-1], a[0], out=a[1:])
    assert np.array_equal(a[1:], want)
    # a non-contiguous out
    big = np.zeros((100, 8))
    qa.multiply(p, q, out=big[:, ::2])
    assert np.array_equal(big[:, ::2], qa.multiply(p, q))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("variant", ["serial", "parallel"])
def test_out_is_an_input_everywhere(rng, dtype, variant):
    """``out=`` an input itself gives the bits of a new array, for every element-wise
    function whose result has an input's shape, contiguous or strided, far rows
    included; serial calls take the loops that know it (RowLoop.into)."""
    from quatarray import _jit, algebra

    n = 300
    p, q = (qa.random(n, rng) * rng.uniform(0.5, 2, (n, 1))).astype(dtype), qa.random(n, rng).astype(dtype)
    p[::7] *= 1e30  # far rows: the second pass reads the input where the first pass left it
    t = rng.random(n).astype(dtype)
    cases = {
        "multiply 0": (qa.multiply, (p, q), 0), "multiply 1": (qa.multiply, (p, q), 1),
        "conjugate": (qa.conjugate, (p,), 0), "inverse": (qa.inverse, (p,), 0),
        "normalize": (qa.normalize, (p,), 0), "exp": (qa.exp, (0.1 * q,), 0), "log": (qa.log, (p,), 0),
        "power": (qa.power, (q, t), 0), "canonical": (qa.canonical, (p,), 0),
        "rotate": (qa.rotate, (p, rng.normal(size=(n, 3)).astype(dtype)), 1),
        "slerp": (qa.slerp, (q, qa.random(n, rng).astype(dtype), t), 0),
    }
    with _jit.variant(variant):
        for name, (f, args, k) in cases.items():
            want = f(*args)
            for strided in (False, True):
                a = args[k].copy()
                if strided:
                    big = np.zeros(a.shape[:-1] + (2 * a.shape[-1],), dtype)
                    big[..., ::2] = a
                    a = big[..., ::2]
                got = f(*[a if j == k else x for j, x in enumerate(args)], out=a)
                assert got is a and np.array_equal(a, want, equal_nan=True), (name, strided)
    if variant == "serial":
        assert algebra._multiply._into and algebra._normalize.first._into


@pytest.mark.parametrize(
    "bad, msg",
    [
        (np.empty((100, 3)), "shape"),
        (np.empty((100, 4), np.float32), "dtype"),
        ([0.0] * 4, "numpy array"),
    ],
)
def test_bad_out(rng, bad, msg):
    with pytest.raises(ValueError, match=msg):
        qa.multiply(qa.random(100, rng), qa.random(100, rng), out=bad)


def test_read_only_out_refused(rng):
    out = np.empty((3, 4))
    out.flags.writeable = False
    with pytest.raises(ValueError, match="writeable"):
        qa.conjugate(qa.random(3, rng), out=out)


def test_read_only_memmap_and_strided_inputs(tmp_path, rng):
    q = qa.random(50, rng)
    np.save(tmp_path / "q.npy", q)
    m = np.load(tmp_path / "q.npy", mmap_mode="r")
    assert np.array_equal(qa.normalize(m), qa.normalize(q))
    assert np.array_equal(qa.multiply(m, m), qa.multiply(q, q))
    wide = np.zeros((50, 8))
    wide[:, 1::2] = q
    assert np.array_equal(qa.conjugate(wide[:, 1::2]), qa.conjugate(q))
    assert np.array_equal(qa.multiply(q[::-1], q[::-1]), qa.multiply(q, q)[::-1])
    assert np.array_equal(m, q)  # inputs untouched


def test_conjugate_inverse_norm_normalize(rng):
    q = rng.standard_normal((200, 4)) * 3
    n = np.linalg.norm(q, axis=1)
    assert np.allclose(qa.norm(q), n, rtol=1e-15)
    assert np.allclose(qa.normalize(q), q / n[:, None], rtol=1e-15)
    assert np.array_equal(qa.conjugate(q), q * [1, -1, -1, -1])
    assert np.allclose(qa.inverse(q), q * [1, -1, -1, -1] / n[:, None] ** 2)
    assert np.allclose(qa.multiply(q, qa.inverse(q)), [1, 0, 0, 0], atol=1e-14)
    assert np.allclose(qa.dot(q, q), n**2)
    assert isinstance(qa.norm([1, 0, 0, 0]), np.floating)


def test_degenerate_numbers_do_not_raise():
    z = np.zeros(4)
    assert np.isnan(qa.inverse(z)).all()
    assert np.isnan(qa.normalize(z)).all()
    assert qa.norm(z) == 0
    nan = np.full(4, np.nan)
    for f in (qa.conjugate, qa.inverse, qa.normalize, qa.exp, qa.log):
        assert np.isnan(f(nan)).any()
    assert np.isnan(qa.angle(nan))
    assert np.isnan(qa.multiply(nan, [1, 0, 0, 0])).all()
    assert qa.log(z)[0] == -np.inf


def test_exp_log(rng):
    q = rng.standard_normal((500, 4))
    assert np.allclose(qa.exp(qa.log(q)), q, atol=1e-13)
    # exp of a pure quaternion θu is the rotation by 2θ about u
    r = rng.standard_normal((500, 3))
    pure = np.concatenate([np.zeros((500, 1)), r / 2], axis=1)
    want = Rotation.from_rotvec(r).as_quat(scalar_first=True)
    assert np.allclose(qa.distance(qa.exp(pure), want), 0, atol=1e-12)
    # tiny vector parts stay accurate
    tiny = np.array([0.0, 1e-20, 0, 0])
    assert np.allclose(qa.exp(tiny), [1, 1e-20, 0, 0], rtol=1e-15, atol=0)
    assert np.allclose(qa.log([1.0, 1e-20, 0, 0]), [0, 1e-20, 0, 0], rtol=1e-15, atol=0)
    assert np.allclose(qa.log([-2.0, 0, 0, 0]), [np.log(2), np.pi, 0, 0])
    # log of a unit quaternion is pure with |u| = half the angle
    u = qa.random(100, rng)
    lg = qa.log(u)
    assert np.allclose(lg[:, 0], 0, atol=1e-15)
    assert np.allclose(2 * np.linalg.norm(lg[:, 1:], axis=1), np.arccos(np.clip(u[:, 0], -1, 1)) * 2, atol=1e-7)


def test_power(rng):
    q = qa.random(200, rng)
    assert np.allclose(qa.power(q, 2), qa.multiply(q, q), atol=1e-14)
    assert np.allclose(qa.power(q, 0), [1, 0, 0, 0])
    assert np.allclose(qa.power(q, 1), q, atol=1e-14)
    assert np.allclose(qa.multiply(qa.power(q, 0.5), qa.power(q, 0.5)), q, atol=1e-14)
    # for w >= 0, q^t is the rotation about q's axis by t times q's angle
    t = rng.uniform(-2, 2, 200)
    want = Rotation.from_rotvec(R(q).as_rotvec() * t[:, None]).as_quat(scalar_first=True)
    assert np.allclose(qa.distance(qa.power(qa.canonical(q), t), want), 0, atol=1e-12)
    tt = rng.uniform(0, 1, 200)
    qc = qa.canonical(q)  # w >= 0: the rotation angle of q^t is t times q's angle
    assert np.allclose(qa.angle(qa.power(qc, tt)), tt * qa.angle(qc), atol=1e-12)
    many = qa.power(q[0], np.linspace(0, 1, 7))  # one q, M exponents
    assert many.shape == (7, 4)


def test_canonical_matches_scipy(rng):
    q = qa.random(500, rng)
    q[:10, 0] = 0  # w == 0 ties
    q[:5, 1] = 0
    q[:2, 2] = 0
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    for s in (1, -1):
        got = qa.canonical(s * q)
        assert np.allclose(got, R(s * q).as_quat(canonical=True, scalar_first=True), rtol=0, atol=1e-15)
    assert np.array_equal(qa.canonical([0, 0, 0, -2.0]), [0, 0, 0, 2.0])


def test_angle_and_distance(rng):
    q = qa.random(500, rng)
    assert np.allclose(qa.angle(q), R(q).magnitude(), atol=1e-14)
    assert np.allclose(qa.angle(-3 * q), R(q).magnitude(), atol=1e-14)
    assert qa.angle(qa.identity()) == 0
    assert np.isclose(qa.angle([0, 1, 0, 0]), np.pi)
    # tiny angles: no arccos round-off
    tiny = Rotation.from_rotvec([[1e-9, 0, 0], [0, 3e-15, 0]]).as_quat(scalar_first=True)
    assert np.allclose(qa.angle(tiny), [1e-9, 3e-15], rtol=1e-12, atol=0)
    p = qa.random(500, rng)
    want = (R(p).inv() * R(q)).magnitude()
    assert np.allclose(qa.distance(p, q), want, atol=1e-13)
    assert np.allclose(qa.distance(p, -q), want, atol=1e-13)
    assert np.allclose(qa.distance(q, -q), 0, atol=1e-15)
    # the branch-free atan2 in every quadrant of (|u|, |w|): as libm's to 2 ulp
    a = np.concatenate([q, q * [1e-3, 1, 1, 1], q * [1, 1e-3, 1e-3, 1e-3]])
    ref = 2 * np.arctan2(np.linalg.norm(a[:, 1:], axis=1), np.abs(a[:, 0]))
    assert np.all(np.abs(qa.angle(a) - ref) <= 2 * np.spacing(ref))
    assert np.isnan(qa.angle(np.zeros(4))) and np.isnan(qa.angle([-0.0, 0, 0, 0]))  # no rotation (issue 14.7)
    assert np.isnan(qa.angle([np.nan, 0, 0, 0])) and np.isnan(qa.angle([0, 0, np.nan, 0]))


def test_cumprod(rng):
    q = qa.random((6, 5), rng)
    got = qa.cumprod(q)
    acc = q[0]
    for i in range(6):
        if i:
            acc = qa.multiply(acc, q[i])
        assert np.allclose(got[i], acc, atol=1e-14)
    along1 = qa.cumprod(q, axis=1)
    assert np.allclose(along1, np.swapaxes(qa.cumprod(np.swapaxes(q, 0, 1)), 0, 1))
    assert np.allclose(qa.cumprod(q, axis=-1), along1)
    assert qa.cumprod(q.astype(np.float32)).dtype == np.float32
    with pytest.raises(ValueError, match="axis"):
        qa.cumprod(q, axis=2)
    with pytest.raises(ValueError, match="`q`"):
        qa.cumprod(np.zeros(4))


def test_identity_and_random():
    assert np.array_equal(qa.identity(), [1, 0, 0, 0])
    assert qa.identity((2, 3)).shape == (2, 3, 4)
    assert qa.identity(5, np.float32).dtype == np.float32
    with pytest.raises(TypeError):
        qa.identity(dtype=int)
    a = qa.random(10_000, rng=7)
    assert np.array_equal(a, qa.random(10_000, rng=7))
    assert np.allclose(np.linalg.norm(a, axis=1), 1)
    assert qa.random().shape == (4,) and qa.random(3, dtype=np.float32).dtype == np.float32
    # Haar measure: rotation angles have density (1 − cos θ)/π, mean π/2 + 2/π
    assert abs(qa.angle(a).mean() - (np.pi / 2 + 2 / np.pi)) < 0.02
    # every axis direction equally likely
    assert np.all(np.abs(a[:, 1:].mean(axis=0)) < 0.02)


def test_mean_matches_scipy(rng):
    q = qa.random(300, rng)
    base = Rotation.from_rotvec([0.3, 0.2, 0.1]).as_quat(scalar_first=True)
    q = qa.multiply(base, qa.power(qa.canonical(q), 0.1))
    w = rng.uniform(0, 1, 300)
    for weights in (None, w):
        want = R(q).mean(weights=weights).as_quat(scalar_first=True)
        got = qa.mean(q, weights)
        assert np.allclose(qa.distance(got, want), 0, atol=1e-12)
        flips = q * np.where(rng.uniform(size=300) < 0.5, -1, 1)[:, None]
        assert np.allclose(qa.distance(qa.mean(flips * 2.5, weights), want), 0, atol=1e-12)
    with pytest.raises(ValueError, match="weights"):
        qa.mean(q, -w)
    with pytest.raises(ValueError, match="weights"):
        qa.mean(q, w[:3])


# ---------------------------------------------------------------- properties


@settings(max_examples=60, deadline=None)
@given(quat, quat)
def test_norm_is_multiplicative(p, q):
    assert np.isclose(qa.norm(qa.multiply(p, q)), qa.norm(p) * qa.norm(q), rtol=1e-12, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(quat, quat, quat)
def test_associative(p, q, r):
    lhs = qa.multiply(qa.multiply(p, q), r)
    rhs = qa.multiply(p, qa.multiply(q, r))
    assert np.allclose(lhs, rhs, rtol=1e-12, atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(quat)
def test_inverse_property(q):
    if qa.norm(q) > 1e-3:
        assert np.allclose(qa.multiply(q, qa.inverse(q)), [1, 0, 0, 0], atol=1e-12)
        assert np.allclose(qa.multiply(qa.inverse(q), q), [1, 0, 0, 0], atol=1e-12)
    assert np.allclose(qa.conjugate(qa.conjugate(q)), q)


@settings(max_examples=60, deadline=None)
@given(quat, quat)
def test_conjugate_reverses_products(p, q):
    assert np.allclose(
        qa.conjugate(qa.multiply(p, q)), qa.multiply(qa.conjugate(q), qa.conjugate(p)), atol=1e-9
    )


def test_scans_of_empty_streams():
    assert qa.cumprod(np.empty((0, 4))).shape == (0, 4)
    assert qa.cumprod(np.empty((3, 0, 4)), axis=1).shape == (3, 0, 4)


# ---------------------------------------------------------------- hardening (issue 14)


class _Sub(np.ndarray):
    """An ndarray subclass whose reshape(-1) stays 2-D, like np.matrix."""

    def reshape(self, *shape, **kw):
        return np.asarray(self).reshape(1, -1).view(type(self))


def out_cases(rng):
    """(name, call with out=, result shape) for the element-wise functions with ``out=``
    outside quatarray.interpolation."""
    q, p = qa.random(1000, rng), qa.random(1000, rng)
    v = rng.normal(size=(1000, 3))
    m = qa.as_matrix(q)
    u = qa.as_su2(q)
    T = qa.VQS(v, q, rng.uniform(1, 2, 1000))
    return [
        ("multiply", lambda out: qa.multiply(p, q, out=out), (1000, 4)),
        ("conjugate", lambda out: qa.conjugate(q, out=out), (1000, 4)),
        ("inverse", lambda out: qa.inverse(q, out=out), (1000, 4)),
        ("normalize", lambda out: qa.normalize(q, out=out), (1000, 4)),
        ("exp", lambda out: qa.exp(q, out=out), (1000, 4)),
        ("log", lambda out: qa.log(q, out=out), (1000, 4)),
        ("power", lambda out: qa.power(q, 0.3, out=out), (1000, 4)),
        ("canonical", lambda out: qa.canonical(q, out=out), (1000, 4)),
        ("rotate", lambda out: qa.rotate(q, v, out=out), (1000, 3)),
        ("as_matrix", lambda out: qa.as_matrix(q, out=out), (1000, 3, 3)),
        ("from_matrix", lambda out: qa.from_matrix(m, out=out), (1000, 4)),
        ("from_matrix_valid", lambda out: qa.from_matrix(m, assume_valid=True, out=out), (1000, 4)),
        ("as_rotvec", lambda out: qa.as_rotvec(q, out=out), (1000, 3)),
        ("from_rotvec", lambda out: qa.from_rotvec(v, out=out), (1000, 4)),
        ("from_axis_angle", lambda out: qa.from_axis_angle(v, v[:, 0], out=out), (1000, 4)),
        ("as_xyzw", lambda out: qa.as_xyzw(q, out=out), (1000, 4)),
        ("from_xyzw", lambda out: qa.from_xyzw(q, out=out), (1000, 4)),
        ("as_left_matrix", lambda out: qa.as_left_matrix(q, out=out), (1000, 4, 4)),
        ("as_right_matrix", lambda out: qa.as_right_matrix(q, out=out), (1000, 4, 4)),
        ("from_su2", lambda out: qa.from_su2(u, out=out), (1000, 4)),
        ("VQS.apply", lambda out: T.apply(v, out=out), (1000, 3)),
    ]


@pytest.mark.filterwarnings("ignore:the matrix subclass:PendingDeprecationWarning")
@pytest.mark.parametrize("kind", ["matrix", "subclass"])
def test_out_subclasses_filled_in_bounds(rng, kind):
    # issue 14.1: np.matrix (2-D only) and subclasses whose reshape stays 2-D
    for name, call, shape in out_cases(rng):
        want = call(None)
        if kind == "matrix":
            if len(shape) != 2:
                continue
            out = np.matrix(np.zeros(shape))
        else:
            out = np.zeros(shape).view(_Sub)
        assert call(out) is out, name
        assert np.array_equal(np.asarray(out), want), name


def test_masked_arrays_refused(rng):
    # issue 14.11: a mask would be ignored by the kernels, so masked input is refused
    q = np.ma.masked_array(qa.random(5, rng), mask=False)
    for f in (qa.normalize, qa.norm, qa.as_matrix, qa.mean, lambda a: qa.as_euler(a, "xyz"), qa.cumprod):
        with pytest.raises(TypeError, match="`q`.*masked"):
            f(q)
    with pytest.raises(TypeError, match="`p`.*masked"):
        qa.multiply(q, q.data)
    with pytest.raises(ValueError, match="`out`"):
        qa.conjugate(q.data, out=np.ma.masked_array(np.zeros((5, 4))))


@pytest.mark.parametrize("order", [">", "<"])
def test_any_byte_order_keeps_float32(rng, order):
    # issue 14.11: '>f4' (and '<f4') in → native float32 out; float16 → float32
    q = qa.random(7, rng)
    for dt, want in ((order + "f4", np.float32), (order + "f8", np.float64), ("f2", np.float32)):
        a = q.astype(dt)
        for f in (qa.normalize, qa.norm, qa.as_matrix, qa.as_rotvec, qa.mean, qa.cumprod, qa.angle):
            r = f(a)
            assert r.dtype == want and r.dtype.isnative, (f, dt)
        assert qa.multiply(a, a).dtype == want and qa.power(a, 0.5).dtype == want
        assert qa.rotate(a, np.ones(3, dt)).dtype == want
        assert qa.as_euler(a, "xyz").dtype == want
        assert np.allclose(qa.normalize(a), qa.normalize(q), atol=1e-3)


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda: qa.identity(2.5), "shape"),
        (lambda: qa.identity((2, 2.5)), "shape"),
        (lambda: qa.identity(True), "shape"),
        (lambda: qa.identity("3"), "shape"),
        (lambda: qa.random(2.5), "n"),
        (lambda: qa.random(True), "n"),
        (lambda: qa.random((2, None)), "n"),
        (lambda: qa.cumprod(np.ones((3, 4)), axis=1.0), "axis"),
        (lambda: qa.cumprod(np.ones((3, 4)), axis="0"), "axis"),
        (lambda: qa.cumprod(np.ones((3, 4)), axis=None), "axis"),
        (lambda: qa.cumprod(np.ones((3, 4)), axis=True), "axis"),
        (lambda: qa.unflip(np.ones((3, 4)), axis=1.0), "axis"),
        (lambda: qa.unflip(np.ones((3, 4)), axis="0"), "axis"),
        (lambda: qa.unflip(np.ones((3, 4)), axis=None), "axis"),
    ],
)
def test_bad_integer_arguments_named(call, name):
    # issue 14.10
    with pytest.raises(TypeError, match=f"Expected `{name}` to be"):
        call()


def test_negative_and_array_sizes():
    # issue 14.10: negative sizes refused by name; a 0-d integer array is a size, as in numpy
    for call, name in ((lambda: qa.random(-1), "n"), (lambda: qa.identity((2, -1)), "shape")):
        with pytest.raises(ValueError, match=f"Expected `{name}` to be a non-negative"):
            call()
    assert qa.random(np.array(3), rng=0).shape == (3, 4)
    assert qa.identity(np.int8(2)).shape == (2, 4)
    assert qa.identity(np.array([2, 3])).shape == (2, 3, 4)
    assert qa.cumprod(np.ones((2, 3, 4)), axis=np.array(1)).shape == (2, 3, 4)


def test_mean_zero_weights_and_bad_rows(rng):
    # issue 14.9: all-zero weights gave a 180° turn (scipy: the identity); a zero,
    # nan or inf row or weight raised LinAlgError
    q = qa.random(6, rng)
    want = R(q).mean(weights=np.zeros(6)).as_quat(scalar_first=True)
    assert np.array_equal(qa.mean(q, np.zeros(6)), want) and np.array_equal(want, [1, 0, 0, 0])
    assert qa.mean(q.astype(np.float32), np.zeros(6)).dtype == np.float32
    for bad in (0.0, np.nan, np.inf):
        b = q.copy()
        b[3] = bad
        with pytest.raises(ValueError, match=r"Expected `q` to be finite and non-zero; row 3"):
            qa.mean(b)
        with pytest.raises(ValueError, match=r"`q`.*index \(1, 0\)"):
            qa.mean(b.reshape(2, 3, 4))
    for bad in (np.nan, np.inf):
        w = np.ones(6)
        w[2] = bad
        with pytest.raises(ValueError, match=r"Expected `weights` to be finite; row 2"):
            qa.mean(q, w)
    with pytest.raises(ValueError, match=r"Expected `weights` to be non-negative; row 4"):
        qa.mean(q, [1, 1, 1, 1, -1, 1])
    # any scale (issue 14.5)
    for scale in (1e-160, 1e160, 1e300):
        assert np.allclose(qa.distance(qa.mean(q * scale), qa.mean(q)), 0, atol=1e-14)


SCALES = {np.float64: (1e-300, 1e-160, 1e160, 1e300), np.float32: (1e-37, 1e-30, 1e30, 1e37)}


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_any_scale_algebra(rng, dtype):
    # issue 14.5: 1e160·q gave a zero norm-free identity angle, normalize zeros, 1e-160·q nan
    tol = 1e-12 if dtype == np.float64 else 2e-6
    q0 = np.concatenate([qa.random(20, rng), [[np.cos(np.pi / 4), 0, np.sin(np.pi / 4), 0]]]).astype(dtype)
    p0 = qa.random(21, rng).astype(dtype)
    for s in SCALES[dtype]:
        s = dtype(s)
        q = q0 * s
        assert np.allclose(qa.norm(q) / s, 1, rtol=tol, atol=0)
        assert np.allclose(qa.normalize(q), q0, atol=tol)
        assert np.allclose(qa.inverse(q) * s, qa.conjugate(q0), atol=tol)
        assert np.allclose(qa.angle(q), qa.angle(q0), atol=tol)
        assert np.allclose(qa.distance(q, p0 * s), qa.distance(q0, p0), atol=tol)
        assert np.allclose(qa.distance(q, q0), 0, atol=tol)
        lq, l0 = qa.log(q), qa.log(q0)
        assert np.allclose(lq[:, 1:], l0[:, 1:], atol=tol)
        assert np.allclose(lq[:, 0], np.log(np.float64(s)), rtol=tol)
        assert np.allclose(qa.distance(qa.mean(q), qa.mean(q0)), 0, atol=tol)
    # subnormal scales are out of range: nan, never a wrong finite answer
    if dtype == np.float64:
        tiny = q0 * 1e-315
        for f in (qa.norm, qa.normalize, qa.angle, qa.log):
            assert np.isnan(f(tiny)).all()


def test_zero_quaternion_gives_nan():
    # issue 14.7: distance(0, q), distance(q, 0) and angle(0) gave 0
    z, q = np.zeros(4), qa.from_rotvec([0.1, 0.2, 0.3])
    assert np.isnan(qa.angle(z)) and np.isnan(qa.distance(z, q)) and np.isnan(qa.distance(q, z))
    assert np.isnan(qa.angle(np.zeros((3, 4), np.float32))).all()
    assert qa.norm(z) == 0
    # q⁰ = 1 for every q, as numpy's 0.0**0 (and nan**0)
    for a in (z, np.full(4, np.nan), q):
        assert np.array_equal(qa.power(a, 0), [1, 0, 0, 0])
    assert np.array_equal(qa.power(np.zeros((2, 4), np.float32), [0, 0.5]), [[1, 0, 0, 0], [0, 0, 0, 0]])


_THREADS_SCRIPT = """
import threading, numpy as np, quatarray as qa
from quatarray import algebra
p, q = qa.random(250_000, rng=0), qa.random(250_000, rng=1)
want = np.empty_like(p)
algebra._multiply.serial(p, q, want)
results = [None] * 4
def work(k):
    results[k] = [qa.multiply(p, q) for _ in range(5)]
threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
for t in threads: t.start()
for t in threads: t.join()
import numba
assert numba.threading_layer() == "workqueue", numba.threading_layer()
assert all(np.array_equal(r, want) for rs in results for r in rs)
print("ok")
"""


@pytest.mark.skipif(os.environ.get("NUMBA_DISABLE_JIT") == "1", reason="no threading layer without the JIT")
def test_concurrent_threads_on_workqueue_layer(tmp_path):
    # issue 14.2: 4 threads in parallel kernels aborted the process on workqueue
    import os
    import subprocess
    import sys

    env = dict(os.environ, NUMBA_THREADING_LAYER="workqueue", QUATARRAY_PARALLEL_MIN_ROWS="1000")
    r = subprocess.run([sys.executable, "-c", _THREADS_SCRIPT], env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr[-2000:]


def test_mean_axis_matches_scipy(rng):
    from scipy.spatial.transform import Rotation as R

    # one quaternion: one leading axis of length 1 for `axis`, as a single scipy Rotation
    one = qa.from_rotvec([0.1, -0.2, 0.3])
    for axis in [None, 0, -1, (0,), ()]:
        want = R.from_quat(one, scalar_first=True).mean(axis=axis).as_quat(scalar_first=True)
        got = qa.mean(one, axis=axis)
        assert got.shape == np.shape(want) and qa.distance(got, want).max() < 1e-12
    with pytest.raises(ValueError, match="axis"):
        qa.mean(one, axis=1)

    q = qa.random((3, 4, 5), rng=rng)
    w = rng.random((3, 4, 5))
    r = R.from_quat(q, scalar_first=True)
    for axis in [None, 0, 1, 2, -1, (0, 2), (2, 0), (0, 1, 2), (1, 1), ()]:
        for weights in [None, w, w[0, :, :1]]:
            want = r.mean(weights=weights, axis=axis).as_quat(scalar_first=True)
            got = qa.mean(q, weights, axis=axis)
            assert got.shape == want.shape
            assert np.all(qa.distance(got, want) < 1e-12)
    np.testing.assert_allclose(qa.mean(-q, axis=()), qa.canonical(q))
    np.testing.assert_array_equal(qa.mean(q, np.zeros(5), axis=1), np.tile([1.0, 0, 0, 0], (3, 5, 1)))
    assert qa.mean(q.astype(np.float32), axis=0).dtype == np.float32
    for bad in [3, -4, (0, 3), [0], 1.0]:
        with pytest.raises(ValueError, match="axis"):
            qa.mean(q, axis=bad)
    with pytest.raises(ValueError, match="broadcast"):
        qa.mean(q, np.ones(4))
    with pytest.raises(ValueError, match="at least one"):
        qa.mean(np.ones((3, 0, 4)), axis=1)
    bad = q.copy()
    bad[1, 2, 3] = 0
    with pytest.raises(ValueError, match=r"index \(1, 2, 3\)|row"):
        qa.mean(bad, axis=2)


def test_approx_equal_matches_scipy(rng):
    from scipy.spatial.transform import Rotation as R

    p = qa.random(500, rng=rng)
    q = qa.multiply(p, qa.from_rotvec(rng.standard_normal((500, 3)) * 10.0 ** rng.uniform(-12, -1, (500, 1))))
    q[::3] *= -2  # sign- and scale-blind
    rp, rq = R.from_quat(p, scalar_first=True), R.from_quat(q, scalar_first=True)
    for atol in [None, 1e-9, 1e-6, 1e-3]:
        np.testing.assert_array_equal(qa.approx_equal(p, q, atol), rp.approx_equal(rq, atol))
    np.testing.assert_array_equal(qa.approx_equal(p, q, 0.01, degrees=True), rp.approx_equal(rq, 0.01, degrees=True))
    with pytest.warns(UserWarning, match="atol must be set"):
        qa.approx_equal(p, q, degrees=True)
    assert qa.approx_equal(p[:, None], p[None, :10]).shape == (500, 10)
    assert qa.approx_equal(p[0], p[0]).dtype == np.bool_
    # API.md: distance <= atol (scipy tests <: they differ only at a distance of exactly atol)
    assert qa.approx_equal([1, 0, 0, 0], [-2, 0, 0, 0], atol=0)
    assert qa.approx_equal([1, 0, 0, 0], qa.from_rotvec([0, 0, 0.5]), atol=qa.distance([1, 0, 0, 0], qa.from_rotvec([0, 0, 0.5])))
    assert qa.approx_equal(p.astype(np.float32), p.astype(np.float32), 1e-3).all()


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_same_rotation_is_exactly_zero_apart(rng, dtype):
    # issue 36.1: distance(q, q) and distance(q, -q) were up to 1.6e-16 rad (8e-8 in float32) for
    # about 63 % of rotations, so approx_equal(q, q, atol=0) was False; scipy gives exactly 0
    q0 = qa.random(5000, rng)
    rq = R(q0)
    assert np.all((rq.inv() * rq).magnitude() == 0)  # the oracle's behaviour
    for s in (1.0, 3.7) + SCALES[dtype]:
        q = (q0 * s).astype(dtype)
        for other in (q, -q, dtype(2) * q):
            assert np.all(qa.distance(q, other) == 0), s
            assert np.all(qa.distance(other, q) == 0), s
            assert qa.approx_equal(q, other, atol=0).all(), s
    # the product's vector part cancels exactly for q*⊗q, q⊗q* (multiply and the cumprod scan)
    q = q0.astype(dtype)
    for a, b in ((qa.conjugate(q), q), (q, qa.conjugate(q)), (qa.conjugate(q), -q)):
        assert np.all(qa.multiply(a, b)[:, 1:] == 0)
        assert np.all(qa.cumprod(np.stack([a, b]))[-1, :, 1:] == 0)


def test_approx_equal_float32_as_scipy(rng):
    # issue 36.2: approx_equal(p, p) was False for about half of float32 rotations (their float32
    # distance reached 8e-8 rad, above the default 1e-8); scipy is True for all of them. Rule:
    # float32 rotations are compared in float64, as scipy (which holds them in float64) does.
    p = qa.random(4000, rng, dtype=np.float32)
    assert qa.approx_equal(p, p).all() and qa.approx_equal(p, -p).all() and qa.approx_equal(2 * p, p).all()
    # nearby float32 rotations are decided as scipy decides them, not by float32 rounding
    small = qa.from_rotvec(rng.standard_normal((4000, 3)) * 10.0 ** rng.uniform(-9, -6, (4000, 1)))
    q = qa.multiply(p.astype(np.float64), small).astype(np.float32)
    q[::3] *= -3
    rp, rq = R(p), R(q)
    for atol in (None, 3e-8, 1e-7, 3e-7, 1e-6):
        np.testing.assert_array_equal(qa.approx_equal(p, q, atol), rp.approx_equal(rq, atol))
        np.testing.assert_array_equal(qa.approx_equal(p, q.astype(np.float64), atol), rp.approx_equal(rq, atol))
    assert qa.distance(p, q).dtype == np.float32  # distance itself keeps float32
