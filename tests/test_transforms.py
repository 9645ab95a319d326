"""VQS and VQM transforms ("The VQM-Group and its Applications").

Oracles: scipy's Rotation for R(q), numpy 4×4 homogeneous matrices, and the
paper's formulas written out independently with numpy.
"""

import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import quatarray as qa
from quatarray import VQM, VQS

SEEDS = st.integers(0, 2**32 - 1)
SIZES = st.integers(1, 12)


def R(q):
    """Rotation matrices of (possibly non-unit) quaternions, via scipy."""
    q = np.asarray(q, dtype=np.float64)
    return Rotation.from_quat(q.reshape(-1, 4), scalar_first=True).as_matrix().reshape(q.shape[:-1] + (3, 3))


def rand_vqs(rng, n, dtype=np.float64):
    v = rng.normal(size=(n, 3)) * 3
    q = rng.normal(size=(n, 4)) * rng.uniform(0.5, 2, (n, 1))  # non-unit on purpose
    s = rng.uniform(0.3, 3, n)
    return VQS(v.astype(dtype), q.astype(dtype), s.astype(dtype))


def rand_vqm(rng, n, dtype=np.float64):
    v = rng.normal(size=(n, 3)) * 3
    q = rng.normal(size=(n, 4)) * rng.uniform(0.5, 2, (n, 1))
    m = np.eye(3) * rng.uniform(0.5, 2, (n, 3, 1)) + 0.3 * rng.normal(size=(n, 3, 3))
    return VQM(v.astype(dtype), q.astype(dtype), m.astype(dtype))


def linear(t):
    """The linear part M of a transform (s I for VQS), float64."""
    if isinstance(t, VQS):
        return t.s[..., None, None] * np.eye(3)
    return np.asarray(t.M, dtype=np.float64)


def oracle_apply(t, p):
    """R(q) (M p) + v with scipy's R and numpy's matmul."""
    mp = np.einsum("...ij,...j->...i", linear(t), p)
    return np.einsum("...ij,...j->...i", R(t.q), mp) + t.v


def homogeneous(t):
    """[[R M, v], [0, 0, 0, 1]] built from scipy's R."""
    shape = t.shape
    h = np.zeros(shape + (4, 4))
    h[..., :3, :3] = R(t.q) @ linear(t)
    h[..., :3, 3] = t.v
    h[..., 3, 3] = 1
    return h


def close(a, b, tol=1e-10):
    np.testing.assert_allclose(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64), rtol=tol, atol=tol)


# --------------------------------------------------------------------------
# the paper's worked examples (the paper writes [x, y, z, w]; here (w, x, y, z))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_paper_vqs_example(dtype):
    q_paper_xyzw = np.array([0, 1, 0, 0], dtype)  # 180° about y
    T = VQS(np.ones(3, dtype), q_paper_xyzw[[3, 0, 1, 2]], 3)
    out = T.apply(np.array([-1, 2, -1], dtype))
    assert out.dtype == dtype
    close(out, [4, 7, 4], 1e-6)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_paper_vqm_example(dtype):
    T = VQM(np.ones(3, dtype), np.array([0, 0, 1, 0], dtype), np.diag([2, 1, 2]).astype(dtype))
    out = T.apply(np.array([-1, 2, -1], dtype))
    assert out.dtype == dtype
    close(out, [3, 3, 3], 1e-6)


def test_paper_examples_through_matrices_and_inverse():
    T = VQS([1, 1, 1], [0, 0, 1, 0], 3)
    h = T.as_matrix()
    close(h @ [-1, 2, -1, 1], [4, 7, 4, 1])
    close(T.inverse().apply([4, 7, 4]), [-1, 2, -1])
    U = VQM([1, 1, 1], [0, 0, 1, 0], np.diag([2, 1, 2]))
    close(U.as_matrix() @ [-1, 2, -1, 1], [3, 3, 3, 1])
    close(U.inverse().apply([3, 3, 3]), [-1, 2, -1])


# --------------------------------------------------------------------------
# apply


@pytest.mark.parametrize("make", [rand_vqs, rand_vqm])
def test_apply_matches_oracle(make, rng):
    t = make(rng, 50)
    p = rng.normal(size=(50, 3))
    close(t.apply(p), oracle_apply(t, p))


@pytest.mark.parametrize("make", [rand_vqs, rand_vqm])
def test_apply_one_transform_to_many_points(make, rng):
    t = make(rng, 1)[0]
    assert t.shape == ()
    p = rng.normal(size=(200, 3))
    out = t.apply(p)
    assert out.shape == (200, 3)
    close(out, oracle_apply(t, p))
    # the same transform broadcast as a batch takes the per-row path: same answer
    tb = type(t)(np.broadcast_to(t.v, (200, 3)), t.q, t.s if isinstance(t, VQS) else t.M)
    close(tb.apply(p), out, 1e-12)
    # a (1,) batch keeps its axis; a single point gives (3,)
    assert make(rng, 1).apply(p).shape == (200, 3)
    assert t.apply(p[0]).shape == (3,)


def test_apply_broadcasting(rng):
    t = rand_vqm(rng, 4)
    p = rng.normal(size=(5, 3))
    out = t[:, None].apply(p)
    assert out.shape == (4, 5, 3)
    for i in range(4):
        close(out[i], oracle_apply(t[i], p))
    # N transforms, one point
    close(t.apply(p[0]), oracle_apply(t, np.broadcast_to(p[0], (4, 3))))
    with pytest.raises(ValueError, match="`points` .*broadcast.*transform shape"):
        t.apply(p)
    with pytest.raises(ValueError, match=r"Expected `points` to have shape \(\.\.\., 3\), got \(4, 2\)"):
        t.apply(np.zeros((4, 2)))


def test_apply_out_aliasing_readonly_strided(rng):
    t = rand_vqs(rng, 30)
    p = rng.normal(size=(30, 3))
    expected = oracle_apply(t, p)
    ro = p.copy()
    ro.flags.writeable = False
    close(t.apply(ro), expected)
    wide = np.zeros((30, 6))
    wide[:, ::2] = p
    close(t.apply(wide[:, ::2]), expected)
    out = np.empty((30, 3))
    assert t.apply(p, out=out) is out
    close(out, expected)
    buf = p.copy()
    t.apply(buf, out=buf)  # in place
    close(buf, expected)
    one = t[3]
    buf = p.copy()
    one.apply(buf, out=buf)  # in place, single-transform path
    close(buf, oracle_apply(one, p))
    with pytest.raises(ValueError, match="out"):
        t.apply(p, out=np.empty((30, 3), np.float32))


# --------------------------------------------------------------------------
# group laws (property tests on random batches)


@settings(max_examples=30, deadline=None)
@given(seed=SEEDS, n=SIZES, vqm=st.booleans())
def test_composition_equals_applying_twice(seed, n, vqm):
    rng = np.random.default_rng(seed)
    make = rand_vqm if vqm else rand_vqs
    a, b = make(rng, n), make(rng, n)
    p = rng.normal(size=(n, 3))
    c = a @ b
    assert type(c) is type(a) and c.shape == (n,)
    close(c.apply(p), a.apply(b.apply(p)), 1e-9)
    close(a.compose(b).as_matrix(), homogeneous(a) @ homogeneous(b), 1e-9)


@settings(max_examples=30, deadline=None)
@given(seed=SEEDS, n=SIZES, vqm=st.booleans())
def test_associativity_identity_inverse(seed, n, vqm):
    rng = np.random.default_rng(seed)
    make = rand_vqm if vqm else rand_vqs
    a, b, c = make(rng, n), make(rng, n), make(rng, n)
    x, y = (a @ b) @ c, a @ (b @ c)
    close(x.v, y.v, 1e-9)
    close(x.q, y.q, 1e-9)  # the product of quaternions: same sign, same norm
    close(x._x, y._x, 1e-9)
    e = type(a).identity(n)
    for z in (e @ a, a @ e):
        close(z.v, a.v, 1e-12)
        close(z.q, a.q, 1e-12)
        close(z._x, a._x, 1e-12)
    ident = homogeneous(type(a).identity(n))
    for z in (a @ a.inverse(), a.inverse() @ a):
        close(z.as_matrix(), ident, 1e-9)
        close(qa.normalize(z.q), qa.identity(n), 1e-9)
        close(z.v, 0, 1e-9)


@settings(max_examples=20, deadline=None)
@given(seed=SEEDS, n=SIZES)
def test_compose_components_are_the_papers_product(seed, n):
    rng = np.random.default_rng(seed)
    a, b = rand_vqm(rng, n), rand_vqm(rng, n)
    c = a @ b
    ra, rb = R(a.q), R(b.q)
    close(c.v, np.einsum("nij,nj->ni", ra @ a.M, b.v) + a.v, 1e-9)
    close(R(c.q), ra @ rb, 1e-9)
    close(c.M, np.swapaxes(rb, -1, -2) @ a.M @ rb @ b.M, 1e-9)
    # quaternion of the composite is q_a q_b (not only the same rotation)
    close(c.q, qa.multiply(a.q, b.q), 1e-12)
    # VQS: the scale multiplies
    s, t = rand_vqs(rng, n), rand_vqs(rng, n)
    close((s @ t).s, s.s * t.s, 1e-12)


def test_mixed_vqs_vqm_compose_to_vqm(rng):
    a, b = rand_vqs(rng, 6), rand_vqm(rng, 6)
    p = rng.normal(size=(6, 3))
    for x, y in ((a, b), (b, a)):
        z = x @ y
        assert isinstance(z, VQM)
        close(z.apply(p), x.apply(y.apply(p)), 1e-9)
    close(a.as_vqm().as_matrix(), a.as_matrix(), 1e-12)


def test_compose_broadcasting(rng):
    a = rand_vqs(rng, 3)
    b = rand_vqs(rng, 4)
    c = a[:, None] @ b
    assert c.shape == (3, 4)
    close(c.as_matrix(), homogeneous(a)[:, None] @ homogeneous(b)[None], 1e-9)
    one = a[0]
    close((one @ b).as_matrix(), homogeneous(one) @ homogeneous(b), 1e-9)
    with pytest.raises(ValueError, match="broadcast"):
        a @ b
    with pytest.raises(TypeError):
        a @ np.eye(4)
    with pytest.raises(TypeError):
        np.eye(4) @ a
    with pytest.raises(TypeError, match="VQS or VQM"):
        a.compose(np.eye(4))


# --------------------------------------------------------------------------
# homogeneous matrices


@pytest.mark.parametrize("make", [rand_vqs, rand_vqm])
def test_as_matrix_matches_oracle(make, rng):
    t = make(rng, 20)
    h = t.as_matrix()
    assert h.shape == (20, 4, 4)
    close(h, homogeneous(t))
    p = rng.normal(size=(20, 3))
    close(np.einsum("nij,nj->ni", h[:, :3, :3], p) + h[:, :3, 3], t.apply(p))


def test_vqs_from_matrix_roundtrip(rng):
    t = rand_vqs(rng, 40)
    u = VQS.from_matrix(t.as_matrix())
    assert u.shape == (40,)
    close(u.s, t.s)
    close(u.v, t.v)
    close(qa.distance(u.q, t.q), 0, 1e-7)
    close(u.as_matrix(), t.as_matrix())
    # leading shape kept; affine (3, 4) accepted
    h = t.as_matrix().reshape(4, 10, 4, 4)
    assert VQS.from_matrix(h).shape == (4, 10)
    close(VQS.from_matrix(h[..., :3, :]).as_matrix(), h)


def test_vqm_from_matrix_polar(rng):
    t = rand_vqm(rng, 40)
    h = t.as_matrix()
    u = VQM.from_matrix(h)
    close(u.as_matrix(), h, 1e-9)
    close(u.M, np.swapaxes(u.M, -1, -2), 0)  # symmetric exactly
    # positive definite where det A > 0; one negative eigenvalue for reflections
    negative = (np.linalg.eigvalsh(u.M) < 0).sum(axis=1)
    assert negative.tolist() == (np.linalg.det(h[:, :3, :3]) < 0).astype(int).tolist()
    assert 0 < negative.sum() < 40  # both cases occur in this sample
    # a symmetric positive definite M comes back as it was
    m = np.eye(3) * [2.0, 1.0, 0.5] + 0.1
    w = VQM([1, 2, 3], qa.from_rotvec([0.3, -0.2, 1.0]), m)
    x = VQM.from_matrix(w.as_matrix())
    close(x.M, m, 1e-12)
    close(qa.distance(x.q, w.q), 0, 1e-7)


def test_vqm_from_matrix_reflection_and_singular():
    h = np.diag([-1.0, 2.0, 3.0, 1.0])  # a reflection times a scale
    u = VQM.from_matrix(h)
    close(u.as_matrix(), h, 1e-12)
    close(qa.angle(u.q), 0, 1e-12)  # the rotation nearest to A
    close(u.M, np.diag([-1.0, 2.0, 3.0]), 1e-12)
    r = qa.from_rotvec([0.2, 0.5, -0.3])
    h2 = VQM([1, 2, 3], r, np.diag([2.0, -0.5, 1.0])).as_matrix()
    u2 = VQM.from_matrix(h2)
    close(u2.as_matrix(), h2, 1e-12)
    close(qa.distance(u2.q, r), 0, 1e-7)
    close(u2.M, np.diag([2.0, -0.5, 1.0]), 1e-12)
    sing = np.diag([1.0, 0.0, 2.0, 1.0])  # a projection: from_matrix works, inverse refuses
    p = VQM.from_matrix(sing)
    close(p.as_matrix(), sing, 1e-12)
    with pytest.raises(ValueError, match="`M` to be invertible"):
        p.inverse()


def test_from_matrix_errors():
    with pytest.raises(ValueError, match="non-uniform scale"):
        VQS.from_matrix(np.diag([1.0, 2.0, 1.0, 1.0]))
    bad = np.stack([np.eye(4), np.eye(4), np.diag([1.0, 1.0, 3.0, 1.0])])
    with pytest.raises(ValueError, match="row 2 has a non-uniform scale"):
        VQS.from_matrix(bad)
    with pytest.raises(ValueError, match="reflection"):
        VQS.from_matrix(np.diag([-1.0, 1.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="zero linear part"):
        VQS.from_matrix(np.diag([0.0, 0.0, 0.0, 1.0]))
    proj = np.eye(4)
    proj[3, 0] = 0.5
    with pytest.raises(ValueError, match=r"last row \(0, 0, 0, 1\)"):
        VQM.from_matrix(proj)
    with pytest.raises(ValueError, match=r"`m4` to have shape \(\.\.\., 4, 4\)"):
        VQS.from_matrix(np.eye(3))
    # tolerance is adjustable
    nearly = np.diag([1.0, 1.0 + 1e-5, 1.0, 1.0])
    with pytest.raises(ValueError):
        VQS.from_matrix(nearly)
    assert abs(float(VQS.from_matrix(nearly, rtol=1e-4).s) - 1) < 1e-5


def test_from_matrix_float32(rng):
    t = rand_vqs(rng, 10, np.float32)
    h = t.as_matrix()
    assert h.dtype == np.float32
    u = VQS.from_matrix(h)
    assert u.dtype == np.float32 and u.q.dtype == np.float32 and u.s.dtype == np.float32
    close(u.as_matrix(), h, 1e-5)
    w = VQM.from_matrix(rand_vqm(rng, 10, np.float32).as_matrix())
    assert w.dtype == np.float32 and w.M.dtype == np.float32


# --------------------------------------------------------------------------
# inverse


def test_inverse_formulas(rng):
    t = rand_vqs(rng, 10)
    i = t.inverse()
    close(i.s, 1 / t.s)
    close(i.q, qa.inverse(t.q))
    close(i.as_matrix(), np.linalg.inv(homogeneous(t)), 1e-9)
    m = rand_vqm(rng, 10)
    close(m.inverse().as_matrix(), np.linalg.inv(homogeneous(m)), 1e-9)


def test_singular_inverse_names_row(rng):
    m = np.tile(np.eye(3), (4, 1, 1))
    m[2] = [[1, 2, 3], [4, 5, 6], [7, 8, 9]]  # det 0 in exact arithmetic, ~1e-16 in float
    t = VQM(np.zeros(3), [1, 0, 0, 0], m)
    with pytest.raises(ValueError, match="row 2 is singular"):
        t.inverse()
    t2 = VQM(np.zeros(3), [1, 0, 0, 0], m.reshape(2, 2, 3, 3))
    with pytest.raises(ValueError, match=r"index \(1, 0\) is singular"):
        t2.inverse()
    with pytest.raises(ValueError, match="invertible; the single input is singular"):
        VQM(M=np.zeros((3, 3))).inverse()


# --------------------------------------------------------------------------
# interpolation


def test_interpolate_vqs_endpoints_and_elerp(rng):
    a, b = rand_vqs(rng, 8), rand_vqs(rng, 8)
    i0, i1 = qa.interpolate(a, b, 0.0), qa.interpolate(a, b, 1.0)
    close(i0.v, a.v, 0)
    close(i1.v, b.v, 0)
    close(i0.s, a.s, 0)
    close(i1.s, b.s, 0)
    close(qa.distance(i0.q, a.q), 0, 1e-7)
    close(qa.distance(i1.q, b.q), 0, 1e-7)
    close(qa.norm(i0.q), 1, 1e-12)
    h = qa.interpolate(VQS(s=1), VQS(s=4), 0.5)
    assert float(h.s) == 2.0
    ts = np.array([0.25, 0.5, 0.75])
    h = qa.interpolate(VQS(s=1.0), VQS(s=16.0), ts)
    close(h.s, [2, 4, 8], 1e-12)
    close(qa.interpolate(a, b, 0.3).s, a.s * (b.s / a.s) ** 0.3, 1e-12)


def test_interpolate_rotation_is_slerp_and_translation_is_lerp(rng):
    a, b = rand_vqs(rng, 8), rand_vqs(rng, 8)
    t = rng.uniform(0, 1, 8)
    h = qa.interpolate(a, b, t)
    close(h.v, (1 - t)[:, None] * a.v + t[:, None] * b.v, 1e-12)
    # scipy oracle: the rotation moves along the shorter arc by the fraction t
    ra, rb = Rotation.from_quat(a.q, scalar_first=True), Rotation.from_quat(b.q, scalar_first=True)
    rel = (ra.inv() * rb).as_rotvec()
    expected = ra * Rotation.from_rotvec(rel * t[:, None])
    close(qa.distance(h.q, expected.as_quat(scalar_first=True)), 0, 1e-7)


def test_interpolate_broadcast_and_vqm(rng):
    a, b = rand_vqm(rng, 1)[0], rand_vqm(rng, 1)[0]
    ts = np.linspace(0, 1, 7)
    h = qa.interpolate(a, b, ts)
    assert isinstance(h, VQM) and h.shape == (7,)
    close(h.M, (1 - ts)[:, None, None] * a.M + ts[:, None, None] * b.M, 1e-12)
    close(h[0].M, a.M, 0)
    close(h[-1].M, b.M, 0)
    m = qa.interpolate(VQS(s=2.0), VQM(M=np.diag([4.0, 2.0, 2.0])), 0.5)
    assert isinstance(m, VQM)
    close(m.M, np.diag([3.0, 2.0, 2.0]), 1e-12)
    with pytest.raises(ValueError, match="broadcast"):
        qa.interpolate(rand_vqs(rng, 3), rand_vqs(rng, 3), np.zeros(4))
    with pytest.raises(TypeError, match="`b` to be a VQS or VQM"):
        qa.interpolate(a, np.eye(4), 0.5)


def test_interpolate_float32(rng):
    a, b = rand_vqs(rng, 5, np.float32), rand_vqs(rng, 5, np.float32)
    h = qa.interpolate(a, b, 0.5)
    assert h.dtype == h.q.dtype == h.s.dtype == np.float32
    close(h.s, np.sqrt(a.s.astype(float) * b.s), 1e-5)


# --------------------------------------------------------------------------
# float32 throughout


@pytest.mark.parametrize("make", [rand_vqs, rand_vqm])
def test_float32_stays_float32(make, rng):
    a, b = make(rng, 20, np.float32), make(rng, 20, np.float32)
    p = rng.normal(size=(20, 3)).astype(np.float32)
    for x in (a @ b, a.inverse(), type(a).identity(3, dtype=np.float32)):
        assert x.dtype == x.v.dtype == x.q.dtype == x._x.dtype == np.float32
    assert a.apply(p).dtype == np.float32
    assert a[0].apply(p).dtype == np.float32
    assert a.as_matrix().dtype == np.float32
    close((a @ b).apply(p), a.apply(b.apply(p)), 2e-4)
    a64 = a.astype(np.float64)
    close(a.apply(p), a64.apply(p.astype(np.float64)), 2e-5)
    # mixed: float64 points with a float32 transform give float64
    assert a.apply(p.astype(np.float64)).dtype == np.float64
    # Python scalars don't upcast
    assert VQS(np.zeros(3, np.float32), np.array([1, 0, 0, 0], np.float32), 2).dtype == np.float32


def test_float32_kernels_have_float32_signatures(rng):
    """No float64 variable inside the float32 kernels (constants go through `like`)."""
    import io

    from quatarray import transforms as tr

    if not hasattr(tr._compose_vqm.serial, "nopython_signatures"):
        pytest.skip("JIT disabled")
    a = rand_vqm(rng, 4, np.float32)
    s = rand_vqs(rng, 4, np.float32)
    a @ a, a.inverse(), s @ s, s.inverse(), a.apply(a.v), s.as_matrix()
    for kern in (tr._compose_vqm, tr._inverse_vqm, tr._compose_vqs, tr._inverse_vqs, tr._apply_vqm, tr._matrix_vqs):
        k = kern.serial
        sigs = [g for g in k.nopython_signatures if all(str(x.dtype) == "float32" for x in g.args)]
        assert sigs, kern.__name__
        buf = io.StringIO()
        k.inspect_types(file=buf, signature=sigs[0].args)
        wide = [ln for ln in buf.getvalue().splitlines() if ln.rstrip().endswith(":: float64") and "const(float" not in ln]
        assert not wide, (kern.__name__, wide[:3])


# --------------------------------------------------------------------------
# validation


def test_validation_errors():
    with pytest.raises(ValueError, match=r"Expected `v` to have shape \(\.\.\., 3\), got \(2,\)"):
        VQS([1, 2], [1, 0, 0, 0], 1)
    with pytest.raises(ValueError, match=r"Expected `q` to have shape \(\.\.\., 4\), got \(3,\)"):
        VQS([1, 2, 3], [1, 0, 0], 1)
    with pytest.raises(ValueError, match=r"Expected `M` to have shape \(\.\.\., 3, 3\), got \(3,\)"):
        VQM([1, 2, 3], [1, 0, 0, 0], [1, 1, 1])
    q = np.tile([1.0, 0, 0, 0], (5, 1))
    q[3] = 0
    with pytest.raises(ValueError, match="`q` to be non-zero; row 3 is the zero quaternion"):
        VQS(np.zeros(3), q, 1)
    with pytest.raises(ValueError, match="zero quaternion"):
        VQM(q=[0, 0, 0, 0])
    s = np.ones((2, 3))
    s[1, 2] = -1
    with pytest.raises(ValueError, match=r"`s` to be positive; index \(1, 2\) has s = -1"):
        VQS(s=s)
    with pytest.raises(ValueError, match="`s` to be positive"):
        VQS(s=0)
    with pytest.raises(ValueError, match="leading dimensions of `v` .* to broadcast"):
        VQS(np.zeros((3, 3)), np.ones((4, 4)), 1)
    with pytest.raises(TypeError, match="`q`"):
        VQS(q=np.ones(4, complex))
    with pytest.raises(TypeError, match="dtype"):
        VQS.identity(2, dtype=np.int32)


# --------------------------------------------------------------------------
# the container


def test_container_is_immutable_and_copies(rng):
    v = rng.normal(size=(4, 3))
    t = VQS(v, [1, 0, 0, 0], 2.0)
    v[0] = 99  # the container holds its own copy
    assert t.v[0, 0] != 99
    for a in (t.v, t.q, t.s):
        assert not a.flags.writeable
        with pytest.raises(ValueError):
            a[...] = 0
    with pytest.raises(AttributeError, match="immutable"):
        t.s = 3
    with pytest.raises(AttributeError):
        t.foo = 3
    assert t.q.shape == (4, 4) and t.s.shape == (4,)  # parts broadcast to the common shape
    t2 = VQS(v, [1, 0, 0, 0], np.full(4, 2.0), copy=False)
    assert t2.v.base is v or np.shares_memory(t2.v, v)


def test_container_array_surface(rng):
    t = rand_vqm(rng, 6)
    assert (t.shape, t.ndim, t.size, len(t), t.dtype) == ((6,), 1, 6, 6, np.float64)
    assert [x.shape for x in t] == [()] * 6
    close(t[2].M, t.M[2], 0)
    assert t[1:4].shape == (3,)
    assert t[[0, 5]].shape == (2,)
    assert t[t.v[:, 0] > 0].shape == ((t.v[:, 0] > 0).sum(),)
    u = VQS(np.zeros((2, 3, 3)), [1, 0, 0, 0], 1)
    assert u.shape == (2, 3)
    assert u[1].shape == (3,) and u[:, 0].shape == (2,) and u[..., 1].shape == (2,)
    assert u[None].shape == (1, 2, 3) and u[1, 2].shape == ()
    with pytest.raises(IndexError):
        u[0, 0, 0]
    with pytest.raises(IndexError):
        t[6]
    single = t[0]
    with pytest.raises(TypeError):
        len(single)
    with pytest.raises(IndexError):
        single[0]
    r = repr(VQS([1, 1, 1], [0, 0, 1, 0], 3))
    assert r.startswith("VQS(") and "v=array([1., 1., 1.])" in r and "s=array(3.)" in r
    assert "M=array(" in repr(t)
    back = pickle.loads(pickle.dumps(t))
    assert type(back) is VQM
    close(back.as_matrix(), t.as_matrix(), 0)


def test_identity_and_defaults():
    e = VQS.identity()
    assert e.shape == () and float(e.s) == 1.0
    close(e.as_matrix(), np.eye(4), 0)
    assert VQM.identity((2, 3)).shape == (2, 3)
    close(VQM.identity(5).as_matrix(), np.tile(np.eye(4), (5, 1, 1)), 0)
    assert VQS.identity(3, dtype=np.float32).dtype == np.float32
    close(VQS(v=[1, 2, 3]).apply([1, 1, 1]), [2, 3, 4], 0)
    close(VQM().as_matrix(), np.eye(4), 0)


# --------------------------------------------------------------------------
# real data: KITTI poses are rigid (s = 1) homogeneous matrices


def test_kitti_poses(data_dir):
    rows = np.loadtxt(data_dir / "kitti_00_poses.txt")[:2000]
    p34 = rows.reshape(-1, 3, 4)
    h = np.zeros((len(p34), 4, 4))
    h[:, :3] = p34
    h[:, 3, 3] = 1
    t = VQS.from_matrix(p34)
    close(t.s, 1, 1e-5)
    close(t.as_matrix(), h, 1e-5)  # the file has ~6 significant digits
    # relative motion between consecutive frames: T_i⁻¹ T_{i+1}
    rel = t[:-1].inverse() @ t[1:]
    close(rel.as_matrix(), np.linalg.inv(h[:-1]) @ h[1:], 1e-5)
    # chaining the relative motions recovers the last pose
    acc = t[0]
    for k in range(0, 50):
        acc = acc @ rel[k]
    close(acc.as_matrix(), h[50], 1e-5)
    # interpolating halfway between frames lands between their positions
    mid = qa.interpolate(t[:-1], t[1:], 0.5)
    close(mid.v, 0.5 * (t.v[:-1] + t.v[1:]), 1e-12)


# --------------------------------------------------------------------------
# degenerate numbers and sizes


def test_nan_propagates_and_empty_batches():
    n = VQS([np.nan, 0, 0], [1, 0, 0, 0], 2.0)
    assert np.isnan(n.apply([1, 2, 3])[0])
    assert np.isnan(n.inverse().v).any()
    m = VQM(M=np.full((3, 3), np.nan))
    assert np.isnan(m.apply([1, 2, 3])).all()
    assert np.isnan(m.inverse().M).all()  # nan, not a "singular" error
    assert np.isnan(VQS.from_matrix(np.full((4, 4), np.nan)).s)
    e = VQS(np.zeros((0, 3)), [1, 0, 0, 0], 1)
    assert e.shape == (0,) and len(e) == 0
    assert e.apply(np.zeros((0, 3))).shape == (0, 3)
    assert (e @ e).shape == e.inverse().shape == (0,)
    assert e.as_matrix().shape == (0, 4, 4)
    assert VQM.from_matrix(np.zeros((0, 4, 4))).shape == (0,)


def test_interpolate_sign_of_q_does_not_matter(rng):
    a, b = rand_vqs(rng, 6), rand_vqs(rng, 6)
    b_neg = VQS(b.v, -b.q, b.s)
    t = np.linspace(0, 1, 6)
    x, y = qa.interpolate(a, b, t), qa.interpolate(a, b_neg, t)
    close(qa.distance(x.q, y.q), 0, 1e-7)
    p = rng.normal(size=(6, 3))
    close(x.apply(p), y.apply(p), 1e-9)


def test_vqs_refuses_nan_scale_and_masked():
    # issue 14.10: s = nan was accepted
    for s in (np.nan, [1.0, np.nan]):
        with pytest.raises(ValueError, match="Expected `s` to be positive"):
            VQS(s=s)
    with pytest.raises(TypeError, match="`v`.*masked"):
        VQS(v=np.ma.masked_array(np.zeros(3)))
    assert VQS(q=np.array([1, 0, 0, 0], ">f4")).q.dtype == np.float32
