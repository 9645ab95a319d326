"""spline(..., order=1|2): angular velocity and acceleration of every method's curve."""

import mpmath
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import quatarray as qa
from quatarray import _rates

METHODS = ["bezier", "slerp", "nlerp", "squad", "cubic"]


def smooth_keys(rng, k, step=0.3):
    return qa.from_rotvec(np.cumsum(rng.standard_normal((k, 3)) * step, axis=0))


def off_knots(rng, times, m, margin=1e-3):
    """m times inside the segments, at least `margin` from every key time (the rates of
    the C¹ methods are continuous there, not differentiable; slerp's jump)."""
    n = rng.integers(0, len(times) - 1, m)
    u = rng.uniform(margin, 1 - margin, m)
    return times[n] + u * (times[n + 1] - times[n])


def fd_rate(times, keys, nt, method, h):
    """Body angular velocity of the spline by a central difference of its values:
    the rotation vector of q(t − h)* ⊗ q(t + h) over 2h."""
    a = qa.spline(times, keys, nt - h, method=method)
    b = qa.spline(times, keys, nt + h, method=method)
    return qa.as_rotvec(qa.multiply(qa.conjugate(a), b)) / (2 * h)


@pytest.mark.parametrize("method", METHODS)
def test_rates_are_derivatives_of_the_curve(rng, method):
    times = np.cumsum(rng.choice([0.3, 1.0, 2.5], 12))
    keys = smooth_keys(rng, 12, 0.5) * rng.choice([-1, 1], 12)[:, None]
    nt = off_knots(rng, times, 300)
    h = 1e-5
    w = qa.spline(times, keys, nt, method=method, order=1)
    assert w.shape == (300, 3) and w.dtype == np.float64
    np.testing.assert_allclose(w, fd_rate(times, keys, nt, method, h), rtol=0, atol=2e-8 * (1 + np.abs(w).max()))
    a = qa.spline(times, keys, nt, method=method, order=2)
    fa = (qa.spline(times, keys, nt + h, method=method, order=1)
          - qa.spline(times, keys, nt - h, method=method, order=1)) / (2 * h)
    np.testing.assert_allclose(a, fa, rtol=0, atol=2e-8 * (1 + np.abs(a).max()))
    # the body rate, not the space rate: angular_velocity(frame="body") of dense samples
    dense = np.linspace(nt[0] - 1e-4, nt[0] + 1e-4, 3)
    av = qa.angular_velocity(qa.spline(times, keys, dense, method=method), dense, frame="body")[1]
    np.testing.assert_allclose(w[0], av, rtol=0, atol=1e-6 * (1 + np.abs(w[0]).max()))


@pytest.mark.parametrize("method", ["bezier", "squad", "nlerp"])
def test_rates_large_turns(rng, method):
    """Keys far apart (arcs of up to ~120° on S³ in the de Casteljau chain)."""
    times = np.cumsum(rng.uniform(0.5, 1.5, 8))
    keys = qa.unflip(qa.random(8, rng=7))
    nt = off_knots(rng, times, 200)
    h = 1e-6
    w = qa.spline(times, keys, nt, method=method, order=1)
    np.testing.assert_allclose(w, fd_rate(times, keys, nt, method, h), rtol=0, atol=1e-6 * (1 + np.abs(w).max()))
    a = qa.spline(times, keys, nt, method=method, order=2)
    fa = (qa.spline(times, keys, nt + h, method=method, order=1)
          - qa.spline(times, keys, nt - h, method=method, order=1)) / (2 * h)
    np.testing.assert_allclose(a, fa, rtol=0, atol=1e-5 * (1 + np.abs(a).max()))


@pytest.mark.parametrize("method", ["bezier", "squad", "cubic"])
def test_rates_continuous_across_keys(rng, method):
    """bezier (time-scaled controls) and cubic are C¹ in time on uneven keys; squad on even ones."""
    k = 10
    times = np.arange(k, dtype=float) if method == "squad" else np.cumsum(rng.choice([0.2, 1.0, 3.0], k))
    keys = smooth_keys(rng, k, 0.4)
    eps = 1e-9
    left = qa.spline(times, keys, times[1:-1] - eps, method=method, order=1)
    right = qa.spline(times, keys, times[1:-1] + eps, method=method, order=1)
    np.testing.assert_allclose(left, right, rtol=0, atol=1e-6)


def test_slerp_rate_is_the_segment_rotation_vector(rng):
    times = np.cumsum(rng.uniform(0.2, 2.0, 9))
    keys = qa.unflip(smooth_keys(rng, 9, 0.6))
    nt = off_knots(rng, times, 100)
    n = np.searchsorted(times, nt, side="right") - 1
    want = qa.as_rotvec(qa.multiply(qa.conjugate(keys[n]), keys[n + 1])) / (times[n + 1] - times[n])[:, None]
    np.testing.assert_allclose(qa.spline(times, keys, nt, method="slerp", order=1), want, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(qa.spline(times, keys, nt, method="slerp", order=2), 0)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_rates_at_keys_ends_and_dtypes(rng, method, dtype):
    times = np.cumsum(rng.uniform(0.5, 1.5, 6))
    keys = smooth_keys(rng, 6).astype(dtype)
    for order in (1, 2):
        r = qa.spline(times, keys, times, method=method, order=order)  # both ends and every key
        assert r.dtype == dtype and r.shape == (6, 3) and np.isfinite(r).all()
        ref = qa.spline(times, keys.astype(np.float64), times, method=method, order=order)
        tol = 1e-13 if dtype == np.float64 else 3e-4
        np.testing.assert_allclose(r, ref, rtol=0, atol=tol * (1 + np.abs(ref).max()))
    nt = rng.uniform(times[0], times[-1], (4, 5))
    assert qa.spline(times, keys, nt, method=method, order=1).shape == (4, 5, 3)
    assert qa.spline(times, keys, np.empty(0), method=method, order=2).shape == (0, 3)
    np.testing.assert_array_equal(qa.spline(times, keys, nt, method=method, order=0),
                                  qa.spline(times, keys, nt, method=method))


def test_identical_keys_give_zero_rates():
    keys = np.tile(qa.from_rotvec([0.1, 0.2, 0.3]), (5, 1))
    keys[2] *= -1
    t = np.arange(5.0)
    nt = np.linspace(0, 4, 41)
    for method in METHODS:
        for order in (1, 2):
            np.testing.assert_allclose(qa.spline(t, keys, nt, method=method, order=order), 0, atol=1e-15)


@pytest.mark.parametrize("order", [3, -1, 1.5, True, False, "1", None, np.float64(1.0)])
def test_bad_order(rng, order):
    keys = smooth_keys(rng, 4)
    for method in METHODS:
        with pytest.raises(ValueError, match=r"Expected `order` to be 0, 1 or 2, got"):
            qa.spline(np.arange(4.0), keys, [0.5], method=method, order=order)


def test_numpy_integer_order(rng):
    keys = smooth_keys(rng, 4)
    np.testing.assert_array_equal(qa.spline(np.arange(4.0), keys, [0.5], order=np.int64(1)),
                                  qa.spline(np.arange(4.0), keys, [0.5], order=1))


# ---- the angle functions of J, J⁻¹ and N: series below n = 0.25, closed forms above


def _exact(n):
    n = mpmath.mpf(n)
    s, c = mpmath.sin(n), mpmath.cos(n)
    return [(1 - c) / n**2, (n - s) / n**3, (1 - n / 2 * mpmath.cot(n / 2)) / n**2,
            (-n * s - 2 * (c - 1)) / n**4, (-2 * n + 3 * s - n * c) / n**5]


@pytest.mark.parametrize("n", [1e-9, 1e-4, 0.01, 0.2499, 0.2501, 0.6, 1.5, 3.0, 5.0])
def test_angle_coefficients(n):
    mpmath.mp.dps = 100
    s, c = np.sin(n / 2), np.cos(n / 2)
    n2 = n * n
    got = [*_rates.jac_coeffs(n2, s, c), _rates.inv_coeff(n2, s, c), *_rates.acc_coeffs(n2, s, c)]
    for g, want in zip(got, _exact(n)):
        assert abs(g - float(want)) <= 1e-11 * abs(float(want)), (n, g, float(want))


# ---- properties


@settings(max_examples=25, deadline=None)
@given(k=st.integers(2, 9), seed=st.integers(0, 2**31), method=st.sampled_from(METHODS), order=st.sampled_from([1, 2]))
def test_batch_equals_loop(k, seed, method, order):
    rng = np.random.default_rng(seed)
    times = np.cumsum(rng.uniform(0.1, 2.0, k))
    keys = qa.random(k, rng=seed) * rng.choice([-1, 1], k)[:, None]
    nt = rng.uniform(times[0], times[-1], 7)
    batch = qa.spline(times, keys, nt, method=method, order=order)
    loop = np.array([qa.spline(times, keys, [x], method=method, order=order)[0] for x in nt])
    np.testing.assert_allclose(batch, loop, rtol=0, atol=1e-12 * (1 + np.abs(loop).max()))


@settings(max_examples=25, deadline=None)
@given(k=st.integers(2, 9), seed=st.integers(0, 2**31), method=st.sampled_from(["bezier", "slerp", "squad", "cubic"]),
       even=st.booleans())
def test_constant_rate_keys(k, seed, method, even):
    """Keys q0 ⊗ Exp(ω t_k): order 1 is ω (body frame) everywhere, order 2 is 0 (uneven
    times: slerp and cubic; bezier's and squad's controls are on the arc only for even ones)."""
    rng = np.random.default_rng(seed)
    if not even and method in ("bezier", "squad"):
        even = True
    times = 0.7 * np.arange(k) if even else np.cumsum(rng.uniform(0.2, 1.5, k))
    omega = rng.uniform(-1, 1, 3)
    omega *= rng.uniform(0.01, 1.0) / max(np.linalg.norm(omega), 1e-3)  # at most 1 rad per time unit
    q0 = qa.random(rng=seed)
    keys = qa.multiply(q0, qa.from_rotvec(np.outer(times, omega)))
    nt = rng.uniform(times[0], times[-1], 20)
    np.testing.assert_allclose(qa.spline(times, keys, nt, method=method, order=1), np.broadcast_to(omega, (20, 3)),
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(qa.spline(times, keys, nt, method=method, order=2), 0, atol=1e-11)


@pytest.mark.needs_simd
@pytest.mark.skipif(__import__("os").environ.get("NUMBA_DISABLE_JIT") == "1", reason="inspects compiled code")
@pytest.mark.parametrize("method", ["bezier", "squad"])
@pytest.mark.parametrize("order", [1, 2])
def test_rate_loops_vectorise_over_a_segments_samples(rng, method, order):
    """Sorted samples run many to a segment, and the rate loop over them must be SIMD
    code: the slerps of moving ends are inlined, not called (the Bézier order=2 loop
    with its three slerp_acc as calls ran 3.5× slower on sorted samples)."""
    import re

    import numba

    from quatarray import splines

    times = np.arange(5.0)
    qa.spline(times, smooth_keys(rng, 5), np.linspace(0, 4, 50), method=method, order=order)
    loop = splines._RATES[(method, order)].serial
    # the float64 signature of the call above (other tests in this process may have
    # compiled the loop for float32 first: its vectors are of float)
    sig = next(s for s in loop.signatures if s[2].dtype == numba.float64)
    fresh = numba.njit(cache=False, error_model="numpy")(loop.py_func)  # cached code has no IR to see
    fresh.compile(sig)
    assert re.search(r"= fmul (?:\w+ )*<\d+ x double>", fresh.inspect_llvm(sig)), "the rate loop did not vectorise"


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_rates_in_pieces_and_tiles_equal_the_whole_table(rng, dtype, monkeypatch):
    """Sorted new times over many keys take the rates piece by piece (each piece's own
    table) and the Bézier rates come in SIMD tiles of samples from any segments: both
    give the whole table's numbers (unsorted new times, the same times reversed) bit
    for bit, for every table method and both orders, with segments of one sample, of
    a few and of many, and the key times themselves."""
    from quatarray import splines

    monkeypatch.setattr(splines, "PIECES_MIN_KEYS", 2)
    k = 600
    times = np.cumsum(rng.uniform(0.2, 2.0, k))
    keys = (smooth_keys(rng, k, 0.4) * rng.choice([-1, 1], k)[:, None]).astype(dtype)
    counts = rng.choice([0, 1, 2, 3, 4, 5, 9, 70], k - 1)
    new = np.concatenate([times[n] + (times[n + 1] - times[n]) * rng.uniform(0, 1, c)
                          for n, c in enumerate(counts)] + [times])
    new = np.sort(new)
    called = []
    pieces = dict(splines._RATE_PIECES)
    for key in pieces:
        monkeypatch.setitem(splines._RATE_PIECES, key, lambda *a, key=key: called.append(key) or pieces[key](*a))
    for method in ("bezier", "slerp", "nlerp", "squad"):
        for order in (1, 2):
            got = qa.spline(times, keys, new, method=method, order=order)
            assert got.dtype == dtype and np.isfinite(got).all()
            whole = qa.spline(times, keys, new[::-1], method=method, order=order)[::-1]
            np.testing.assert_array_equal(got, whole)
    assert called == [(m, o) for m in ("bezier", "slerp", "nlerp", "squad") for o in (1, 2)]
