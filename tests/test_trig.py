"""Tests for quatarray._trig's branch-free sincos and its accurate range.

References: numpy's float64 sin/cos of the (exact) float32 argument for
float32 results, mpmath for float64 results. Errors are in ulps of the
correctly rounded result in the result's type, so the points next to the
multiples of π/2 (tiny results) are the hard ones. Measured over every
float32 with |x| ≤ 32768 (a separate, 3-minute scan): sin 2.44 ulp, cos 2.36
ulp at most; the tests below hold the kernels to 2.5 ulp (float32) and 2 ulp
(float64).
"""

import os

import mpmath
import numpy as np
import pytest
from numba import njit, types

import quatarray as qa
from quatarray import _trig

LIM32 = _trig.sincos_limit(np.float32(1.0))
LIM64 = _trig.sincos_limit(1.0)
JIT = os.environ.get("NUMBA_DISABLE_JIT") != "1"


@njit(error_model="numpy")
def sincos_loop(x, s, c):
    for i in range(x.shape[0]):
        s[i], c[i] = _trig.sincos(x[i])


@njit(error_model="numpy")
def sincos_one(x):
    return _trig.sincos(x)


@njit
def limit_of(x):
    return _trig.sincos_limit(x)


def run(x):
    s, c = np.empty_like(x), np.empty_like(x)
    with np.errstate(invalid="ignore"):  # plain-Python pass: inf − inf warns
        sincos_loop(x, s, c)
    return s, c


def ulps32(got, x):
    """Error of float32 results in float32 ulps of sin/cos of the float32 argument."""
    xd = x.astype(np.float64)
    out = []
    for g, ref in ((got[0], np.sin(xd)), (got[1], np.cos(xd))):
        unit = np.spacing(np.abs(ref).astype(np.float32)).astype(np.float64)
        out.append(np.abs(g.astype(np.float64) - ref) / unit)
    return out


def near_half_pi_multiples32(kmax, step=1):
    """The float32 values closest to k·π/2 for 1 ≤ k ≤ kmax, and their neighbours."""
    k = np.arange(1, kmax + 1, step)
    x = (k * (np.pi / 2)).astype(np.float32)
    x = np.concatenate([x, np.nextafter(x, np.float32(0)), np.nextafter(x, np.float32(np.inf))])
    return np.concatenate([x, -x])


# --------------------------------------------------------------------------
# the documented range


def test_limits_documented_values():
    assert LIM32 == 32768.0 and LIM64 == 1e6
    assert _trig.SINCOS_LIMIT_32 == LIM32 and _trig.SINCOS_LIMIT_64 == LIM64
    # the compiled overload agrees, in x's type
    assert limit_of(np.float32(2.0)) == LIM32 and limit_of(2.0) == LIM64
    # the float32 pieces: k·piece exact for |k| < 2**15 needs at most 9 significant bits
    for piece in (_trig.PIO2F_1, _trig.PIO2F_2, _trig.PIO2F_3):
        m = np.frexp(piece)[0] * 2.0**9
        assert m == np.round(m) and np.float32(piece) == piece
    assert np.float32(_trig.PIO2F_4) == _trig.PIO2F_4
    assert LIM32 * _trig.INVPIO2 + 1 < 2**15  # every k of the range is within that bound
    total = sum(mpmath.mpf(p) for p in (_trig.PIO2F_1, _trig.PIO2F_2, _trig.PIO2F_3, _trig.PIO2F_4))
    assert abs(total - mpmath.pi / 2) < mpmath.mpf(2) ** -58


# --------------------------------------------------------------------------
# float32


def test_float32_stays_float32():
    s, c = sincos_one(np.float32(1.25))
    if JIT:
        sig = sincos_one.nopython_signatures
        assert any(g.args == (types.float32,) and g.return_type == types.UniTuple(types.float32, 2) for g in sig)
        # no float64 inside the float32 function (a bare float constant would promote it)
        key = next(k for k in sincos_one.signatures if k == (types.float32,))
        ir = sincos_one.inspect_llvm(key)
        bodies = [d for d in ir.split("define ")[1:] if "cpython" not in d.split("(")[0]]
        assert bodies and not any("double" in d for d in bodies)
    elif int(np.__version__.split(".")[0]) >= 2:  # plain Python: numpy 1's scalars promote to float64 (no NEP 50)
        assert isinstance(s, np.float32) and isinstance(c, np.float32)
    assert abs(float(s) - np.sin(1.25)) < 1.2e-7 and abs(float(c) - np.cos(1.25)) < 1.2e-7
    s, c = run(np.linspace(-3, 3, 7, dtype=np.float32))
    assert s.dtype == np.float32 and c.dtype == np.float32


def test_float32_special_values():
    x = np.array([0.0, -0.0, 1e-30, -1e-30, 1e-45, np.nan, np.inf, -np.inf], np.float32)
    s, c = run(x)
    # ±0 and tiny: sin x = x, cos x = 1 (sin(−0) is +0: documented)
    np.testing.assert_array_equal(s[:5], x[:5])
    np.testing.assert_array_equal(c[:5], 1.0)
    assert np.isnan(s[5:]).all() and np.isnan(c[5:]).all()  # nan and ±inf: nan, no exception


def test_float32_near_multiples_of_half_pi_small():
    # the hard points: results down to 4e-9 (k = 161), needing ~50 bits of π/2
    x = np.concatenate([near_half_pi_multiples32(200), near_half_pi_multiples32(int(LIM32 / (np.pi / 2)), 997)])
    es, ec = ulps32(run(x), x)
    assert es.max() <= 2.5 and ec.max() <= 2.5


@pytest.mark.slow
def test_float32_near_every_multiple_of_half_pi():
    x = near_half_pi_multiples32(int(LIM32 / (np.pi / 2)))
    x = x[np.abs(x) <= LIM32]
    es, ec = ulps32(run(x), x)
    assert es.max() <= 2.5 and ec.max() <= 2.5
    # at 8192 the old float32 reduction (one float32 piece of π/2) was 5e-4 off
    big = np.abs(x) > 8000
    assert np.abs(run(x[big])[0] - np.sin(x[big].astype(np.float64))).max() < 1e-7


def test_float32_grid_small():
    x = np.concatenate([np.linspace(-4, 4, 2001, dtype=np.float32), np.linspace(-LIM32, LIM32, 2001, dtype=np.float32)])
    es, ec = ulps32(run(x), x)
    assert es.max() <= 2.5 and ec.max() <= 2.5


@pytest.mark.slow
def test_float32_dense_grids_and_random():
    rng = np.random.default_rng(11)
    parts = [
        np.linspace(-np.pi, np.pi, 10001, dtype=np.float32),
        np.linspace(-LIM32, LIM32, 10001, dtype=np.float32),
        # every float32 in windows at the ends of [−π/4, π/4], at 1, 8192 and the limit
        *(
            (np.float32(a) + np.arange(-5000, 5000) * np.spacing(np.float32(a))).astype(np.float32)
            for a in (np.pi / 4, 3 * np.pi / 4, 1.0, 8192.0, LIM32 - 5000 * np.spacing(np.float32(LIM32)))
        ),
        rng.uniform(-LIM32, LIM32, 10000).astype(np.float32),
        # log-uniform magnitudes from 1e-8 to the limit, both signs
        (rng.choice([-1.0, 1.0], 10000) * np.exp(rng.uniform(np.log(1e-8), np.log(LIM32), 10000))).astype(np.float32),
    ]
    x = np.concatenate(parts)
    x = x[np.abs(x) <= LIM32]
    es, ec = ulps32(run(x), x)
    assert es.max() <= 2.5 and ec.max() <= 2.5
    # and within the fast polynomial's own interval [−π/4, π/4] under 1 ulp
    core = np.abs(x) <= np.pi / 4
    assert es[core].max() < 1 and ec[core].max() < 1


# --------------------------------------------------------------------------
# float64 against mpmath


def ulps64_mp(got, x, fn):
    ref = [fn(mpmath.mpf(float(v))) for v in x]
    err = np.array([float(abs(mpmath.mpf(float(g)) - r)) for g, r in zip(got, ref)])
    return err / np.spacing(np.abs(np.array([float(r) for r in ref])))


@pytest.fixture(scope="module")
def mp300():
    old = mpmath.mp.prec
    mpmath.mp.prec = 300
    yield
    mpmath.mp.prec = old


def near_half_pi_multiples64(ks):
    out = []
    for k in ks:
        x = float(int(k) * mpmath.pi / 2)  # the closest double to k·π/2
        out += [x, np.nextafter(x, 0), np.nextafter(x, np.inf)]
    out = np.array(out)
    return np.concatenate([out, -out])


def test_float64_adversarial_within_2_ulp(mp300):
    # next to k·π/2 the result is down to ~1e-18: needs π/2 to ~150 bits (four pieces)
    ks = np.unique(np.concatenate([np.arange(1, 120), np.geomspace(120, LIM64 / (np.pi / 2), 60).astype(np.int64), [58, 1308, 654]]))
    x = near_half_pi_multiples64(ks)
    x = x[np.abs(x) <= LIM64]
    s, c = run(x)
    assert ulps64_mp(s, x, mpmath.sin).max() <= 2
    assert ulps64_mp(c, x, mpmath.cos).max() <= 2
    assert s[0] == 1.0 and c[np.argmin(np.abs(x - np.pi / 2))] == np.cos(np.pi / 2)  # 6.12e-17, exactly libm's


def test_float64_random_within_2_ulp(mp300):
    rng = np.random.default_rng(12)
    x = np.concatenate([rng.uniform(-4, 4, 300), rng.uniform(-LIM64, LIM64, 300), np.exp(rng.uniform(-40, np.log(LIM64), 300))])
    s, c = run(x)
    assert ulps64_mp(s, x, mpmath.sin).max() <= 2
    assert ulps64_mp(c, x, mpmath.cos).max() <= 2


def test_float64_special_values():
    x = np.array([0.0, -0.0, 1e-300, 5e-324, np.nan, np.inf, -np.inf])
    s, c = run(x)
    np.testing.assert_array_equal(s[:4], x[:4])
    np.testing.assert_array_equal(c[:4], 1.0)
    assert np.isnan(s[4:]).all() and np.isnan(c[4:]).all()


# --------------------------------------------------------------------------
# end to end: the public functions that use sincos


def test_from_rotvec_float32_large_angles():
    # exact float32 rotation angles up to 2·limit: the half angle is exact and only
    # sincos is left (the old float32 reduction was ~1e-5 off at 1000 rad)
    ang = np.concatenate([np.arange(1, 300, dtype=np.float64), np.geomspace(300, 2 * LIM32, 200).round()])
    v = np.zeros((ang.size, 3))
    v[:, 2] = ang
    got = qa.from_rotvec(v.astype(np.float32))
    assert got.dtype == np.float32
    assert np.abs(got - qa.from_rotvec(v)).max() < 2.5e-7


def test_from_euler_float32_fast_range_matches_float64():
    # sincos_limit decides which rows from_euler gives to libm: the fast rows must be
    # as accurate as libm's (half angles up to the limit, just inside it, and beyond)
    rng = np.random.default_rng(13)
    a = rng.uniform(-2 * LIM32, 2 * LIM32, (300, 3)).astype(np.float32)
    a[:20] = np.float32(2 * LIM32) * rng.choice([-1, 1], (20, 3)).astype(np.float32)
    a[20:40] = np.nextafter(a[:20], np.float32(0))
    a[40:60] *= np.float32(3)  # beyond: libm
    got = qa.from_euler("zyx", a)
    assert got.dtype == np.float32
    assert np.abs(got - qa.from_euler("zyx", a.astype(np.float64))).max() < 4e-7


@pytest.mark.parametrize("t", [50.0, -50.0])
def test_slerp_float32_far_outside_unit_interval(t):
    # a 3-radian pair at t = ±50: the sine arguments reach ±75 rad. The float32 angle
    # θ of the arc is itself rounded, and the weights scale its error by |t|, so the
    # bound is a few float32 epsilons times (1 + |t|·θ).
    rng = np.random.default_rng(14)
    p = qa.random(500, rng)
    axis = rng.standard_normal((500, 3))
    q = qa.multiply(p, qa.from_rotvec(3.0 * axis / np.linalg.norm(axis, axis=1, keepdims=True)))
    p32, q32 = p.astype(np.float32), q.astype(np.float32)
    tt = np.full(500, t, np.float32)
    got = qa.slerp(p32, q32, tt)
    assert got.dtype == np.float32
    want = qa.slerp(p32.astype(np.float64), q32.astype(np.float64), tt.astype(np.float64))
    eps = np.finfo(np.float32).eps
    assert np.abs(got - want).max() < 4 * eps * (1 + abs(t) * 1.5)
    # the results stay unit quaternions to float32 accuracy
    assert np.abs(np.linalg.norm(got.astype(np.float64), axis=1) - 1).max() < 1e-5
