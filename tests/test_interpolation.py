"""quatarray.interpolation against scipy, mpmath and an independent Bézier implementation."""

import mpmath
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation, Slerp

import quatarray as qa
from quatarray import interpolation as I

R = lambda q: Rotation.from_quat(np.asarray(q, float), scalar_first=True)  # noqa: E731


def same_rot(a, b, atol):
    return np.allclose(qa.distance(np.asarray(a, float), np.asarray(b, float)), 0, atol=atol)


# ---------------------------------------------------------------------------
# a deliberately simple, independent implementation of the contract's formulas


def ref_slerp(p, q, t):
    """Textbook slerp with arccos-free angle via numpy, one pair at a time."""
    p, q = np.asarray(p, float), np.asarray(q, float)
    th = 2 * np.arctan2(np.linalg.norm(p - q), np.linalg.norm(p + q))
    if th == 0:
        return (1 - t) * p + t * q
    return (np.sin((1 - t) * th) * p + np.sin(t * th) * q) / np.sin(th)


def ref_double(p, q):
    return 2 * np.dot(p, q) * q - p


def ref_bisect(p, q):
    return (p + q) / np.linalg.norm(p + q)


def ref_controls(keys):
    k = len(keys)
    ext = [ref_double(keys[1], keys[0])] + list(keys) + [ref_double(keys[-2], keys[-1])]
    a, b = [], []
    for n in range(k):
        qm, qn, qp = ext[n], ext[n + 1], ext[n + 2]
        ah = ref_bisect(ref_double(qm, qn), qp)
        an = ref_slerp(qn, ah, 1 / 3)
        a.append(an)
        b.append(ref_double(an, qn))
    return np.array(a), np.array(b)


def ref_bezier(q0, a, b, q1, t):
    p01, p12, p23 = ref_slerp(q0, a, t), ref_slerp(a, b, t), ref_slerp(b, q1, t)
    return ref_slerp(ref_slerp(p01, p12, t), ref_slerp(p12, p23, t), t)


def smooth_keys(rng, k, step=0.3):
    q = qa.from_rotvec(np.cumsum(rng.standard_normal((k, 3)) * step, axis=0))
    return qa.unflip(q)


# ---------------------------------------------------------------------------
# lerp, nlerp, double, bisect


def test_lerp_nlerp(rng):
    p, q = qa.random(50, rng), qa.random(50, rng)
    t = rng.uniform(-0.5, 1.5, 50)
    assert np.allclose(qa.lerp(p, q, t), (1 - t)[:, None] * p + t[:, None] * q, atol=1e-15)
    flip = np.where(np.sum(p * q, -1) < 0, -1.0, 1.0)[:, None]
    want = (1 - t)[:, None] * p + t[:, None] * q * flip
    assert np.allclose(qa.nlerp(p, q, t), want / np.linalg.norm(want, axis=-1, keepdims=True), atol=1e-15)
    raw = (1 - t)[:, None] * p + t[:, None] * q
    assert np.allclose(qa.nlerp(p, q, t, shortest=False), raw / np.linalg.norm(raw, axis=-1, keepdims=True))
    # more rows than one block of the row loop (1024)
    p, q, t = qa.random(3000, rng), qa.random(3000, rng), rng.random(3000)
    raw = (1 - t)[:, None] * p + t[:, None] * q
    assert np.allclose(qa.nlerp(p, q, t, shortest=False), raw / np.linalg.norm(raw, axis=-1, keepdims=True))
    assert np.allclose(qa.lerp(p, q, t), raw, atol=1e-15)


def test_double_bisect(rng):
    p, q = qa.random(20, rng), qa.random(20, rng)
    assert np.allclose(qa.double(p, q), [ref_double(a, b) for a, b in zip(p, q)], atol=1e-15)
    assert np.allclose(qa.bisect(p, q), [ref_bisect(a, b) for a, b in zip(p, q)], atol=1e-15)
    assert np.allclose(qa.double(qa.double(p, q), q), p, atol=1e-14)  # a reflection


# ---------------------------------------------------------------------------
# slerp


@pytest.mark.parametrize("shortest", [True, False])
def test_slerp_matches_scipy(rng, shortest):
    p, q = qa.random(300, rng), qa.random(300, rng)
    t = rng.random(300)
    got = qa.slerp(p, q, t, shortest=shortest)
    want = np.array([Slerp([0, 1], R([a, b]))(s).as_quat(scalar_first=True) for a, b, s in zip(p, q, t)])
    assert same_rot(got, want, 1e-14) == shortest  # scipy always takes the short way
    assert np.allclose(np.linalg.norm(got, axis=-1), 1, atol=1e-15)
    if not shortest:  # the long arc of unit p → q, as written
        assert np.allclose(got, [ref_slerp(a, b, s) for a, b, s in zip(p, q, t)], atol=1e-14)


def test_slerp_exact_ends_and_extrapolation(rng):
    p, q = qa.random(100, rng), qa.random(100, rng)
    q = np.where((np.sum(p * q, -1) < 0)[:, None], -q, q)  # same hemisphere: t=1 gives q itself
    assert np.array_equal(qa.slerp(p, q, 0.0), p)
    assert np.array_equal(qa.slerp(p, q, 1.0), q)
    assert np.array_equal(qa.slerp(p, -q, 1.0), q)  # shortest flips −q back to q
    assert np.array_equal(qa.slerp(p, -q, 1.0, shortest=False), -q)
    # extrapolation stays on the arc: slerp(p, q, 2) = q (p⁻¹ q)
    two = qa.slerp(p, q, 2.0)
    assert np.allclose(two, qa.multiply(q, qa.multiply(qa.conjugate(p), q)), atol=1e-14)
    assert np.allclose(qa.slerp(p, q, -1.0), qa.multiply(p, qa.multiply(qa.conjugate(q), p)), atol=1e-14)


def test_slerp_broadcasting_out_and_readonly(rng):
    p, q = qa.random(2, rng)
    t = np.linspace(0, 1, 7)
    r = qa.slerp(p, q, t)
    assert r.shape == (7, 4)
    assert np.allclose(r, [qa.slerp(p, q, s) for s in t], atol=0)
    ps, qs = qa.random((3, 1), rng), qa.random(5, rng)
    assert qa.slerp(ps, qs, 0.3).shape == (3, 5, 4)
    a = qa.random(10, rng)
    a.flags.writeable = False
    b = qa.random(10, rng)[::-1]  # non-contiguous
    want = qa.slerp(a, b, 0.4)
    out = b.copy()
    assert qa.slerp(a, out, 0.4, out=out) is out and np.allclose(out, want, atol=0)
    tr = np.empty((4, 10)).T  # non-contiguous out
    qa.slerp(a, b, 0.4, out=tr)
    assert np.array_equal(tr, want)
    with pytest.raises(ValueError):
        qa.slerp(a, b, 0.4, out=np.empty((10, 4), np.float32))
    with pytest.raises(ValueError, match="`q`"):
        qa.slerp(a, b[:, :3], 0.5)
    with pytest.raises(TypeError):
        qa.slerp(a, b, 1j)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_slerp_rows_do_not_depend_on_the_batch(rng, dtype):
    """The three-pass slerp loop (blocks of SLERP_BLOCK rows inside blocks of ROWS):
    a row's result is the same, bit for bit, alone, at any place in a batch (SIMD
    part or remainder of a pass), in the serial and the parallel variant and with
    `out` one of the inputs; exact ends, identical and antipodal pairs included."""
    from quatarray import _jit

    n = 2 * I.ROWS + I.SLERP_BLOCK + 37
    p, q = qa.random(n, rng, dtype), qa.random(n, rng, dtype)
    t = rng.uniform(-0.5, 1.5, n).astype(dtype)
    t[::7], t[3::11] = 1, 0
    q[5::13] = p[5::13]
    q[6::17] = -p[6::17]
    with _jit.variant("serial"):
        want = qa.slerp(p, q, t)
        assert np.array_equal(np.concatenate([qa.slerp(p[i:i + 1], q[i:i + 1], t[i:i + 1]) for i in range(0, n, 97)]), want[::97])
        assert np.array_equal(qa.slerp(p[1:], q[1:], t[1:]), want[1:])  # every row moved to another lane and block
        pp = p.copy()
        assert np.array_equal(qa.slerp(pp, q, t, out=pp), want)
    with _jit.variant("parallel"):
        assert np.array_equal(qa.slerp(p, q, t), want)
    one, zero = t == 1, t == 0
    assert np.all(np.all(want[one] == q[one], axis=1) | np.all(want[one] == -q[one], axis=1))  # exact ends
    assert np.array_equal(want[zero], p[zero])


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("shortest", [True, False])
def test_slerp_streamed_rows_are_the_cached_ones(rng, monkeypatch, dtype, shortest):
    """The variant for a caller's large `out` (non-temporal stores, ``_slerp_stream``)
    gives the rows of the plain loop bit for bit, rare pairs and exact ends included,
    serial and parallel, into a given array and into `p` or `q` as `out`; a new output
    and a misaligned `out` take the plain loop."""
    from quatarray import _access, _jit

    n = 3 * I.SLERP_BLOCK + 29
    p, q = qa.random(n, rng, dtype), qa.random(n, rng, dtype)
    t = rng.uniform(-0.5, 1.5, n).astype(dtype)
    t[::7], t[3::11] = 1, 0
    q[5::13], q[6::17] = p[5::13], -p[6::17]
    want = qa.slerp(p, q, t, shortest)
    calls = []
    monkeypatch.setattr(_access, "STREAM_MIN_BYTES", 0)
    monkeypatch.setattr(I, "_slerp_stream", _counted(I._slerp_stream, calls))
    for name in ("serial", "parallel"):
        with _jit.variant(name):
            assert np.array_equal(qa.slerp(p, q, t, shortest), want)  # a new output: not streamed
            assert np.array_equal(qa.slerp(p, q, t, shortest, out=np.empty_like(p)), want)
            pp, qq = p.copy(), q.copy()
            assert np.array_equal(qa.slerp(pp, q, t, shortest, out=pp), want)
            assert np.array_equal(qa.slerp(p, qq, t, shortest, out=qq), want)
    assert len(calls) == 6
    raw = np.empty(want.nbytes + 16, np.uint8)
    off = (-raw.ctypes.data) % 16 + want.itemsize
    out = raw[off:off + want.nbytes].view(dtype).reshape(want.shape)
    assert np.array_equal(qa.slerp(p, q, t, shortest, out=out), want)
    # an `out` the loop cannot write itself goes through a new temporary: not streamed
    for out in (np.empty((n, 8), dtype)[:, ::2], np.asfortranarray(np.empty_like(p))):
        assert np.array_equal(qa.slerp(p, q, t, shortest, out=out), want)
    assert len(calls) == 6


def _counted(loop, calls):
    def run(*args):
        calls.append(1)
        return loop(*args)

    return run


def test_slerp_float32(rng):
    p, q = qa.random(100, rng, np.float32), qa.random(100, rng, np.float32)
    r = qa.slerp(p, q, 0.3)
    assert r.dtype == np.float32
    assert np.allclose(r, qa.slerp(p.astype(float), q.astype(float), 0.3), atol=2e-6)
    assert qa.slerp(p, q.astype(float), 0.3).dtype == np.float64
    sig = getattr(I._slerp.serial, "nopython_signatures", None)  # None without the JIT
    assert sig is None or any("float64" not in str(s) for s in sig)  # a pure float32 specialisation


def test_slerp_degenerate_pairs():
    p = np.array([0.5, 0.5, 0.5, 0.5])
    t = np.linspace(0, 1, 11)
    assert np.allclose(qa.slerp(p, p, t), p, atol=1e-16)  # identical
    assert np.allclose(qa.slerp(p, -p, t), p, atol=1e-16)  # antipodal, shortest: constant
    anti = qa.slerp(p, -p, t, shortest=False)  # antipodal, no unique arc: the power convention
    want = qa.multiply(p, np.stack([np.cos(np.pi * t), np.sin(np.pi * t), 0 * t, 0 * t], -1))
    assert np.allclose(anti, want, atol=1e-15)
    nan = qa.slerp([np.nan, 0, 0, 0], p, 0.5)
    assert np.isnan(nan).all()


def _mp_slerp(p, q, t):
    p = [mpmath.mpf(float(x)) for x in p]
    q = [mpmath.mpf(float(x)) for x in q]
    t = mpmath.mpf(float(t))
    if sum(a * b for a, b in zip(p, q)) < 0:
        q = [-x for x in q]
    a = mpmath.sqrt(sum((x - y) ** 2 for x, y in zip(p, q)))
    b = mpmath.sqrt(sum((x + y) ** 2 for x, y in zip(p, q)))
    th = 2 * mpmath.atan2(a, b)
    if th == 0:
        return [(1 - t) * x + t * y for x, y in zip(p, q)]
    s = mpmath.sin(th)
    return [(mpmath.sin((1 - t) * th) * x + mpmath.sin(t * th) * y) / s for x, y in zip(p, q)]


def test_slerp_accuracy_mpmath(rng):
    """Max abs error ≤ 4e-15 against 40 digits on adversarial pairs (inputs taken as exact)."""
    mpmath.mp.dps = 40
    base = qa.random(40, rng)
    axis = rng.standard_normal((40, 3))
    pairs = []
    for eps in (0.0, 1e-15, 1e-12, 1e-8, 1e-4, 0.5, np.pi / 2 - 1e-9, np.pi - 1e-7, np.pi - 1e-12):
        d = qa.from_rotvec(axis / np.linalg.norm(axis, axis=1, keepdims=True) * eps)
        pairs.append((base, qa.multiply(base, d)))  # eps apart (rotation angle)
    pairs.append((base, -base))  # antipodal
    pairs.append((base, qa.random(40, rng)))
    p = np.concatenate([a for a, _ in pairs])
    q = np.concatenate([b for _, b in pairs])
    t = np.tile(np.array([0, 1e-9, 0.1, 1 / 3, 0.5, 0.77, 1 - 1e-12, 1.0]), len(p) // 8 + 1)[: len(p)]
    got = qa.slerp(p, q, t)
    err = max(
        float(max(abs(g - w) for g, w in zip(row, _mp_slerp(a, b, s))))
        for row, a, b, s in zip(got, p, q, t)
    )
    assert err <= 4e-15, err


@settings(max_examples=40, deadline=None)
@given(st.floats(0, 1), st.integers(0, 2**32 - 1))
def test_slerp_constant_speed_property(t, seed):
    p, q = qa.random(2, seed)
    total = float(qa.distance(p, q))  # ≤ π, and the shortest arc covers it
    r = qa.slerp(p, q, t)
    assert np.isclose(float(qa.distance(p, r)), abs(t) * total, atol=1e-12)
    assert np.isclose(float(qa.distance(r, q)), abs(1 - t) * total, atol=1e-12)


# ---------------------------------------------------------------------------
# Bézier, squad, unflip


def test_bezier_controls_match_reference(rng):
    keys = smooth_keys(rng, 12)
    a, b = qa.bezier_controls(keys)
    ra, rb = ref_controls(keys)
    assert np.allclose(a, ra, atol=1e-14) and np.allclose(b, rb, atol=1e-14)
    assert np.allclose(a[0], qa.slerp(keys[0], keys[1], 1 / 3), atol=1e-15)
    assert np.allclose(b[-1], qa.slerp(keys[-1], keys[-2], 1 / 3), atol=1e-15)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_bezier_controls_uneven_times_match_public_functions(rng, dtype):
    """The fused control loop against the docstring's formulas composed from the public
    slerp, double and bisect (uneven times scale the tangent arcs), and F-order input."""
    keys = smooth_keys(rng, 9).astype(dtype)
    t = np.cumsum(rng.uniform(0.2, 3.0, 9))
    h = np.diff(t)
    a, b = qa.bezier_controls(np.asfortranarray(keys), t)
    assert a.dtype == b.dtype == dtype
    for n in range(1, 8):
        q = keys[n]
        a0 = qa.slerp(q, qa.bisect(qa.double(keys[n - 1], q), keys[n + 1]), 1 / 3, shortest=False)
        f_out, f_in = 2 * h[n] / (h[n - 1] + h[n]), 2 * h[n - 1] / (h[n - 1] + h[n])
        tol = 1e-6 if dtype == np.float32 else 1e-15
        np.testing.assert_allclose(a[n], qa.slerp(q, a0, f_out, shortest=False), rtol=0, atol=tol)
        np.testing.assert_allclose(b[n], qa.slerp(q, qa.double(a0, q), f_in, shortest=False), rtol=0, atol=tol)


def test_bezier_matches_reference_and_broadcasts(rng):
    q0, a, b, q1 = smooth_keys(rng, 4)
    t = np.linspace(-0.2, 1.2, 15)
    got = qa.bezier(q0, a, b, q1, t)
    assert got.shape == (15, 4)
    assert np.allclose(got, [ref_bezier(q0, a, b, q1, s) for s in t], atol=1e-14)
    assert np.array_equal(qa.bezier(q0, a, b, q1, 0.0), q0)
    assert np.array_equal(qa.bezier(q0, a, b, q1, 1.0), q1)
    out = np.empty((15, 4))
    assert qa.bezier(q0, a, b, q1, t, out=out) is out


def test_two_keys_bezier_is_slerp(rng):
    keys = smooth_keys(rng, 2, 0.8)
    u = np.linspace(0, 1, 21)
    got = qa.spline([0.0, 1.0], keys, u)
    assert np.allclose(got, qa.slerp(keys[0], keys[1], u), atol=2e-15)


def test_squad(rng):
    keys = smooth_keys(rng, 6)
    s = I.squad_controls(keys)
    t = np.linspace(0, 1, 9)
    got = qa.squad(keys[1], s[1], s[2], keys[2], t)
    h = 2 * t * (1 - t)
    want = [ref_slerp(ref_slerp(keys[1], keys[2], x), ref_slerp(s[1], s[2], x), y) for x, y in zip(t, h)]
    assert np.allclose(got, want, atol=1e-14)
    times = np.arange(6.0)
    sp = qa.spline(times, keys, [1.0, 1.5, 2.0], method="squad")
    assert np.allclose(sp, [keys[1], qa.squad(keys[1], s[1], s[2], keys[2], 0.5), keys[2]], atol=1e-14)


def test_unflip(rng):
    q = smooth_keys(rng, 50, 0.1)
    signs = rng.choice([-1.0, 1.0], 50)
    got = qa.unflip(q * signs[:, None])
    assert np.allclose(got, q * signs[0], atol=0)
    stacked = np.stack([q * signs[:, None], -q], axis=1)  # (50, 2, 4), scan along axis 0
    u = qa.unflip(stacked)
    assert np.allclose(u[:, 0], q * signs[0]) and np.allclose(u[:, 1], -q)
    assert np.allclose(qa.unflip(np.swapaxes(stacked, 0, 1), axis=1), np.swapaxes(u, 0, 1))


def test_angular_velocity_constant_rate_uneven_times(rng):
    times = np.cumsum(rng.uniform(0.01, 0.2, 30))
    w_body = np.array([0.3, -1.1, 0.7])
    q0 = qa.random(rng=rng)
    q = qa.multiply(q0, qa.from_rotvec(np.outer(times, w_body)))  # body-frame constant rate
    q *= rng.choice([-1, 1], 30)[:, None]  # sign flips
    body = qa.angular_velocity(q, times, frame="body")
    assert np.allclose(body, w_body, atol=1e-12)
    space = qa.angular_velocity(q, times)
    assert np.allclose(space, qa.rotate(q, body), atol=1e-12)
    step = (R(q[1:]) * R(q[:-1]).inv()).as_rotvec() / np.diff(times)[:, None]  # scipy oracle
    assert np.allclose(space[0], step[0], atol=1e-12) and np.allclose(space[-1], step[-1], atol=1e-12)
    with pytest.raises(ValueError, match="frame"):
        qa.angular_velocity(q, times, frame="world")
    with pytest.raises(ValueError, match="strictly increasing"):
        qa.angular_velocity(q, times[::-1])


class _Sub(np.ndarray):
    """An ndarray subclass whose reshape(-1) stays 2-D, like np.matrix."""

    def reshape(self, *shape, **kw):
        return np.asarray(self).reshape(1, -1).view(type(self))


@pytest.mark.filterwarnings("ignore:the matrix subclass:PendingDeprecationWarning")
@pytest.mark.parametrize("kind", ["matrix", "subclass"])
def test_out_subclasses_filled_in_bounds(rng, kind):
    # issue 14.1: these used to write past a 2-D-only `out` (segfault)
    p, q, a, b = (qa.random(1000, rng) for _ in range(4))
    t = rng.uniform(0, 1, 1000)
    calls = {
        "lerp": lambda out: qa.lerp(p, q, 0.3, out=out),
        "nlerp": lambda out: qa.nlerp(p, q, t, out=out),
        "slerp": lambda out: qa.slerp(p, q, 0.3, out=out),
        "slerp strided": lambda out: qa.slerp(p[:, ::-1], q, t, out=out),
        "double": lambda out: qa.double(p, q, out=out),
        "bisect": lambda out: qa.bisect(p, q, out=out),
        "bezier": lambda out: qa.bezier(p, a, b, q, t, out=out),
        "squad": lambda out: qa.squad(p, a, b, q, t, out=out),
    }
    for name, call in calls.items():
        want = call(None)
        out = np.matrix(np.zeros((1000, 4))) if kind == "matrix" else np.zeros((1000, 4)).view(_Sub)
        assert call(out) is out, name
        assert np.array_equal(np.asarray(out), want), name
    # a strided subclass out (the copy-back path)
    big = np.zeros((1000, 8)).view(_Sub)
    qa.slerp(p, q, t, out=big[:, ::2])
    assert np.array_equal(np.asarray(big)[:, ::2], qa.slerp(p, q, t))


def test_spline_and_angular_velocity_refuse_bool_times(rng):
    # issue 14.10: bool times gave numpy's "boolean subtract"
    keys = qa.random(2, rng)
    with pytest.raises(TypeError, match="Expected `times` to have a real"):
        qa.spline(np.array([False, True]), keys, [0.5])
    with pytest.raises(TypeError, match="Expected `new_times` to have a real"):
        qa.spline([0.0, 1.0], keys, np.array([True]))
    with pytest.raises(TypeError, match="Expected `times` to have a real"):
        qa.angular_velocity(keys, np.array([False, True]))
    with pytest.raises(TypeError, match="`times`.*masked"):
        qa.spline(np.ma.masked_array([0.0, 1.0]), keys, [0.5])


def test_angular_velocity_int64_nanoseconds_exact():
    # issue 14.8: EuRoC stamps (ns since the epoch, 200 Hz); float64 stamps are 256 ns coarse
    t = 1403636579763555584 + 5_000_000 * np.arange(400, dtype=np.int64)
    t[1::3] += 137  # a little jitter, as real stamps have
    omega = np.array([0.3, -0.5, 0.75])  # rad/s
    q = qa.from_rotvec(np.outer((t - t[0]) * 1e-9, omega))
    w = qa.angular_velocity(q, t) * 1e9
    assert np.max(np.abs(w - omega)) < 1e-9
    wb = qa.angular_velocity(q, t.astype(np.uint64), frame="body") * 1e9
    assert np.max(np.abs(wb - omega)) < 1e-9  # a rotation about ω leaves ω fixed


# --------------------------------------------------------------------------
# hardening (issue 14: 3, 4, 6)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_slerp_unit_for_every_pair(dtype):
    """Nearly antipodal pairs (|p + q| of a few ulp, also q a scaled −p) with
    shortest=False gave norms of 2.65, 706 ...; every pair now gives unit results,
    also inside bezier, bezier_controls and squad."""
    rng = np.random.default_rng(41)
    eps = np.finfo(dtype).eps
    p = qa.random(4000, rng=1).astype(dtype)
    worst = 0.0
    for scale in [0, 1e-16, 1e-15, 1e-13, 1e-10, 1e-7, 1e-6, 1e-3]:
        q = qa.normalize((-p.astype(np.float64) + rng.normal(size=p.shape) * scale).astype(dtype))
        t = rng.uniform(-0.5, 1.5, len(p)).astype(dtype)
        for r in (qa.slerp(p, q, t, shortest=False), qa.bezier(p, q, p, q, t), qa.squad(p, q, -p, q, t),
                  *qa.bezier_controls(np.stack([p[0], q[0], p[1], q[1], -q[1]]))):
            assert r.dtype == dtype
            worst = max(worst, np.abs(qa.norm(r.astype(np.float64)) - 1).max() / eps)
    assert worst <= 4, worst


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_slerp_huge_parameter_stays_unit(dtype):
    """|t·θ| far beyond sincos's range (float32 1e5 … 1e7) gave |q| = 1.5e22."""
    rng = np.random.default_rng(42)
    p, q = qa.random(200, rng=2).astype(dtype), qa.random(200, rng=3).astype(dtype)
    t = (rng.choice([-1, 1], 200) * 10 ** rng.uniform(5, 15 if dtype == np.float64 else 7, 200)).astype(dtype)
    r = qa.slerp(p, q, t)
    assert np.abs(qa.norm(r.astype(np.float64)) - 1).max() <= 4 * np.finfo(dtype).eps


# ---------------------------------------------------------------------------
# the tie rule: pairs a half turn apart on S³ (p·q = 0), issue 36 item 3

# half-turn axes: the coordinate axes (D with exact zeros: scipy's canonical rule
# decides by the first non-zero component) and general ones, either sign
TIE_AXES = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (-1, 0, 0), (0, -1, 0), (0, 0, -1), (0, 0.6, -0.8),
            (-0.6, 0.8, 0), (0.48, -0.6, 0.64), (-2 / 3, 1 / 3, 2 / 3)]


def ref_flips(p, q):
    """Whether unflip negates q after p (as it stands): p·q < 0, or a tie (|p·q| within
    64 ulp of the rows' size) whose relative rotation p* ⊗ q has a negative first
    non-negligible x, y, z (an independent numpy version of the rule)."""
    p, q = np.asarray(p), np.asarray(q)
    tie = 2.0**-17 if p.dtype == np.float32 else 2.0**-46
    tol = tie * 0.5 * (p @ p + q @ q)
    d = p @ q
    v = p[0] * q[1:] - q[0] * p[1:] - np.cross(p[1:], q[1:])
    big = np.flatnonzero(np.abs(v) > tol)
    return bool(d < -tol or (abs(d) <= tol and big.size and v[big[0]] < 0))


def half_turn(axis):
    return np.array([0.0, *axis])


def canonical_axis(axis):
    """The axis as scipy's canonical rule for w = 0 takes it: first non-zero positive."""
    a = np.asarray(axis, float)
    return -a if a[np.flatnonzero(a)[0]] < 0 else a


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(TIE_AXES), st.floats(-0.5, 1.5))
def test_slerp_tie_is_equivariant(seed, axis, t):
    """slerp(R⊗p, R⊗q, t) = R⊗slerp(p, q, t) for pairs with p·q = 0 (q = p ⊗ (0, u)),
    whatever the sign R⊗p·R⊗q takes by rounding; before the tie rule about 10 % of
    rotations R turned the other way (up to 1.9 rad apart)."""
    rng = np.random.default_rng(seed)
    r = qa.random(64, rng=rng)
    p = qa.random(rng=rng)
    q = qa.multiply(p, half_turn(axis))
    want = qa.multiply(r, qa.slerp(p, q, t))
    got = qa.slerp(qa.multiply(r, p), qa.multiply(r, q), t)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-14)
    got = qa.nlerp(qa.multiply(r, p), qa.multiply(r, q), t)
    np.testing.assert_allclose(got, qa.multiply(r, qa.nlerp(p, q, t)), rtol=0, atol=1e-14)
    # the arc is the one of scipy's rule: the relative rotation turns about the canonical axis
    rel = qa.multiply(qa.conjugate(p), qa.slerp(p, q, t))
    half = t * np.pi / 2
    np.testing.assert_allclose(rel, [np.cos(half), *(np.sin(half) * canonical_axis(axis))], rtol=0, atol=1e-14)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_slerp_tie_ignores_the_rounded_sign(dtype):
    """The same pair with its dot product nudged by rounding either way (a few ulp)
    takes the same arc; t = 1 gives q or −q as the rule says, exactly."""
    eps = np.finfo(dtype).eps
    p = np.array([1.0, 0, 0, 0], dtype)
    for axis in TIE_AXES:
        q = half_turn(axis).astype(dtype)
        rows = [q, q + np.array([4 * eps, 0, 0, 0], dtype), q - np.array([4 * eps, 0, 0, 0], dtype)]
        got = qa.slerp(p, np.array(rows), np.array(0.5, dtype))
        assert got.dtype == dtype
        np.testing.assert_allclose(got, got[[0, 0, 0]], rtol=0, atol=20 * eps)
        sign = 1.0 if (canonical_axis(axis) == np.asarray(axis, float)).all() else -1.0
        assert (qa.slerp(p, q, np.array(1.0, dtype)) == sign * q).all()
        # shortest=False: no flip, the plain great arc to q
        assert (qa.slerp(p, q, np.array(1.0, dtype), shortest=False) == q).all()


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_unflip_tie_is_equivariant(seed):
    """unflip(R ⊗ q) = R ⊗ unflip(q) for streams with half turns between keys, and the
    tie rule's sign is scipy's (the relative rotation's canonical axis)."""
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(TIE_AXES), 12)
    steps = np.array([half_turn(TIE_AXES[i]) for i in idx])
    q = qa.cumprod(np.concatenate([qa.random(1, rng=rng), steps])) * rng.choice([-1.0, 1.0], (13, 1))
    u = qa.unflip(q)
    want = q.copy()
    for i in range(1, len(q)):
        if ref_flips(want[i - 1], want[i]):
            want[i] = -want[i]
    assert np.array_equal(u, want)
    rel = qa.multiply(qa.conjugate(u[:-1]), u[1:])
    np.testing.assert_allclose(rel[:, 1:], [canonical_axis(TIE_AXES[i]) for i in idx], rtol=0, atol=1e-14)
    r = qa.random(rng=rng)
    np.testing.assert_allclose(qa.unflip(qa.multiply(r, q)), qa.multiply(r, u), rtol=0, atol=1e-14)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_slerp_shortest_unit_within_3_ulp(dtype):
    """The pairs kernel's cheap tangent (m2 s − p2 d)/(2ab) for the common pairs (every
    pair of shortest=True): unit within 3 ulp, random, nearly identical and nearly
    antipodal pairs (flipped into nearly identical ones), t inside and outside [0, 1]."""
    rng = np.random.default_rng(3)
    eps = np.finfo(dtype).eps
    p = qa.random(5000, rng=rng).astype(dtype)
    worst = 0.0
    for scale in [None, 0, 1e-16, 1e-12, 1e-8, 1e-4, 1e-2, 0.3]:
        if scale is None:
            q = qa.random(5000, rng=rng).astype(dtype)
        else:
            q = qa.normalize((p.astype(np.float64) + rng.normal(size=p.shape) * scale).astype(dtype))
        for sign in (1, -1):
            t = rng.uniform(-0.5, 1.5, len(p)).astype(dtype)
            r = qa.slerp(p, sign * q, t)
            worst = max(worst, np.abs(qa.norm(r.astype(np.float64)) - 1).max() / eps)
            if dtype == np.float64:
                u = qa.slerp(p, sign * q, t, shortest=False)  # the same arc where p·q > 0
                keep = np.einsum("ij,ij->i", p, sign * q) > 0
                assert np.array_equal(r[keep], u[keep])
                worst = max(worst, np.abs(qa.norm(u) - 1).max() / eps)  # shortest=False: θ up to π
    assert worst <= 3, worst
