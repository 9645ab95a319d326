"""Vectorisable sin/cos and atan for the interpolation kernels.

libm's ``sin`` and ``atan2`` are opaque calls, so a loop that uses them runs
one element at a time. These are branch-free polynomial versions (every
choice is a select), which LLVM turns into SIMD code when they sit inside a
row loop. Accuracy in float64: within about one ulp of the correctly rounded
result (the fdlibm kernels, tested in ``tests/test_trig.py``).

``sincos(x)``
    (sin x, cos x); Cody–Waite reduction x − k·π/2 with π/2 split into
    pieces (below), then the fdlibm polynomials on [−π/4, π/4]. inf and nan
    give nan; sin(−0) gives +0 (keeping the sign of zero would cost about
    8% of a sincos loop). Accurate range (:func:`sincos_limit`):

    - float64: |x| ≤ 10⁶, within 2 ulp of sin and cos, also next to the
      multiples of π/2 where the result is tiny (down to ~10⁻¹⁸): fdlibm's
      three 33-bit pieces ``pio2_1..3`` (k·piece exact for |k| < 2²⁰) and
      the tail ``pio2_3t``.
    - float32: |x| ≤ 2¹⁵ = 32768, within 2.5 ulp of the float64 sin and cos
      of the float32 argument (measured on every float32 of the range:
      2.44 ulp; 0.75 ulp on [−π/4, π/4]), also next to the multiples of π/2
      (the closest float32 is 4·10⁻⁹ away, at 161·π/2). π/2 is split into
      float32 pieces of 8, 9, 9 and 24 significant bits (Cephes ``sinf``
      style, finer): k·piece is exact for the first three while |k| < 2¹⁵,
      and the remainder comes out within 0.8 ulp.

    Beyond the range the reduction loses accuracy (for float32 quickly:
    k·piece is no longer exact); callers that may meet such arguments
    check :func:`sincos_limit` and fall back to libm.
``half_arc(a, b)``
    atan2(a, b) for a, b ≥ 0 (a result in [0, π/2]); used for the half
    angle of an arc from the chord lengths |p − q| and |p + q|.
``atan2(y, x)``
    atan2 in all four quadrants, with libm's signed zeros and ±π (nan in,
    nan out; ``atan2(±inf, ±inf)`` gives nan); within 2 ulp in float64.
``sincos_limit(x)``
    The largest |x| for which ``sincos`` is accurate to the rounding of x's
    float type: 10⁶ for float64, 32768 for float32 (callers with larger
    arguments fall back to libm).

Constants go through :func:`quatarray._jit.like`, so float32 stays float32
(the float32 results are then accurate to float32 rounding; for ``sincos``
only up to ``sincos_limit``).
"""

import numpy as np

from ._jit import element, float_bits, fmuladd, like, select

# fdlibm __kernel_sin / __kernel_cos on [-π/4, π/4]
S1 = -1.66666666666666324348e-01
S2 = 8.33333333332248946124e-03
S3 = -1.98412698298579493134e-04
S4 = 2.75573137070700676789e-06
S5 = -2.50507602534068634195e-08
S6 = 1.58969099521155010221e-10
C1 = 4.16666666666666019037e-02
C2 = -1.38888888888741095749e-03
C3 = 2.48015872894767294178e-05
C4 = -2.75573143513906633035e-07
C5 = 2.08757232129817482790e-09
C6 = -1.13596475577881948265e-11

# π/2 in three 33-bit pieces and a 53-bit tail (fdlibm pio2_1, pio2_2, pio2_3,
# pio2_3t) and 2/π
PIO2_1 = 1.57079632673412561417e00
PIO2_2 = 6.07710050630396597660e-11
PIO2_3 = 2.02226624871116645580e-21
PIO2_4 = 8.47842766036889956997e-32
INVPIO2 = 6.36619772367581382433e-01
R_MAX = 1.0  # above π/4 + the float32 rounding of k: the largest reduced argument of sincos (a clamp)

# π/2 for float32 in pieces of 8, 9, 9 and 24 significant bits (π/2 truncated
# to 10 bits three times over, the zero bits skipped, then the rest rounded):
# k·PIO2F_1..3 are exact in float32 for |k| < 2¹⁵, and the four together
# carry π/2 to about 2⁻⁵⁸ (relative).
PIO2F_1 = 1.5703125
PIO2F_2 = 4.8351287841796875e-04
PIO2F_3 = 3.1385570764541626e-07
PIO2F_4 = 6.07710062827671e-11

# fdlibm atan on |x| < 7/16
AT0 = 3.33333333333329318027e-01
AT1 = -1.99999999998764832476e-01
AT2 = 1.42857142725034663711e-01
AT3 = -1.11111104054623557880e-01
AT4 = 9.09088713343650656196e-02
AT5 = -7.69187620504482999495e-02
AT6 = 6.66107313738753120669e-02
AT7 = -5.83357013379057348645e-02
AT8 = 4.97687799461593236017e-02
AT9 = -3.65315727442169155270e-02
AT10 = 1.62858201153657823623e-02

PIO4_HI = 7.85398163397448278999e-01  # fdlibm atanhi[3]
PIO4_LO = 3.06161699786838301793e-17  # fdlibm atanlo[3]
TAN_PI8 = 0.41421356237309503


@element
def reduce_pio2(x, k):
    """x − k·π/2 (Cody–Waite): three pieces of π/2 in float64 (k·piece exact for
    |k| < 2²⁰), four in float32 (exact for |k| < 2¹⁵, the differences exact
    (Sterbenz) where they cancel), as fused multiply-adds; the float type picks the
    pieces at compile time."""
    p = select(float_bits(x) == 32, (PIO2F_1, PIO2F_2, PIO2F_3, PIO2F_4), (PIO2_1, PIO2_2, PIO2_3, PIO2_4))
    r = fmuladd(-k, like(x, p[0]), x)  # the last piece matters only within ~1e-9 of a multiple of π/2 (float64)
    r = fmuladd(-k, like(x, p[1]), r)
    r = fmuladd(-k, like(x, p[2]), r)
    r = fmuladd(-k, like(x, p[3]), r)
    return r


@element
def sincos(x):
    """(sin x, cos x), branch-free; accurate for |x| ≤ :func:`sincos_limit`."""
    k = np.rint(x * like(x, INVPIO2))
    r = reduce_pio2(x, k)
    # Beyond sincos_limit the reduction is inexact; there |r| may leave [-π/4, π/4],
    # where the polynomials diverge (1e22 for float32 x = 1e6). Clamped (nan kept),
    # sin² + cos² = 1 holds for every x: the angle is as uncertain as x's rounding.
    r = select(r > like(x, R_MAX), like(x, R_MAX), r)
    r = select(r < like(x, -R_MAX), like(x, -R_MAX), r)
    z = r * r
    # sin(r) = r + r z (S1 + z P), cos(r) = 1 - z/2 + z² Q (fdlibm's split keeps it exact)
    # (Horner's scheme in fused multiply-adds: see quatarray._jit.fmuladd)
    ps = fmuladd(z, fmuladd(z, fmuladd(z, fmuladd(z, like(x, S6), like(x, S5)), like(x, S4)), like(x, S3)), like(x, S2))
    s = fmuladd(r * z, fmuladd(z, ps, like(x, S1)), r)
    pc = fmuladd(z, fmuladd(z, fmuladd(z, like(x, C6), like(x, C5)), like(x, C4)), like(x, C3))
    pc = z * fmuladd(z, fmuladd(z, pc, like(x, C2)), like(x, C1))
    hz = like(x, 0.5) * z
    w = like(x, 1.0) - hz
    c = w + fmuladd(z, pc, (like(x, 1.0) - w) - hz)
    # quadrant k mod 4, in floating point (no float -> int conversion of inf/nan);
    # every choice is a single-condition select so the loop stays vectorisable
    m = k - like(x, 4.0) * np.floor(k * like(x, 0.25))
    h = m * like(x, 0.5)
    odd = h != np.floor(h)
    sn = select(odd, c, s)
    cs = select(odd, s, c)
    sn = select(m >= like(x, 2.0), -sn, sn)
    cs = select(abs(m - like(x, 1.5)) < like(x, 1.0), -cs, cs)
    return sn, cs


@element
def atan_small(x):
    """atan(x) for |x| ≤ 7/16 (fdlibm)."""
    z = x * x
    w = z * z
    s1 = fmuladd(w, fmuladd(w, fmuladd(w, like(x, AT10), like(x, AT8)), like(x, AT6)), like(x, AT4))
    s1 = z * fmuladd(w, fmuladd(w, s1, like(x, AT2)), like(x, AT0))
    s2 = fmuladd(w, fmuladd(w, fmuladd(w, like(x, AT9), like(x, AT7)), like(x, AT5)), like(x, AT3))
    s2 = w * fmuladd(w, s2, like(x, AT1))
    return fmuladd(-x, s1 + s2, x)


@element
def half_arc(a, b):
    """atan2(a, b) for a, b ≥ 0, in [0, π/2], branch-free.

    With lo = min(a, b), hi = max(a, b) the ratio lo/hi is in [0, 1]; above
    tan(π/8) it is reduced with atan(x) = π/4 + atan((x − 1)/(x + 1)), and
    a > b reflects the result about π/4 (atan2(a, b) = π/2 − atan2(b, a)).
    """
    swap = a > b
    lo = select(swap, b, a)
    hi = select(swap, a, b)
    big = lo > like(a, TAN_PI8) * hi
    num = select(big, lo - hi, lo)
    den = select(big, lo + hi, hi)
    x = num / den
    r = atan_small(x)
    # π/4 and π/2 in two parts so the sums keep the full precision
    zero = like(a, 0.0)
    off_hi = select(big, like(a, PIO4_HI), zero)
    off_lo = select(big, like(a, PIO4_LO), zero)
    y = off_hi + (r + off_lo)
    refl = (like(a, 2.0 * PIO4_HI) - y) + like(a, 2.0 * PIO4_LO)
    return select(swap, refl, y)


@element
def atan2(y, x):
    """atan2(y, x) in all four quadrants, branch-free (same reduction as
    :func:`half_arc`, then the quadrant).

    With lo = min(|x|, |y|), hi = max(|x|, |y|): atan2(|y|, |x|) is
    k·π/4 ± atan(u) with |u| ≤ tan(π/8); k·π/4 is added in two parts.
    """
    zero = like(x, 0.0)
    one = like(x, 1.0)
    ax = abs(x)
    ay = abs(y)
    swap = ay > ax
    lo = select(swap, ax, ay)
    hi = select(swap, ay, ax)
    big = lo > like(x, TAN_PI8) * hi
    num = select(big, lo - hi, lo)
    den = select(big, lo + hi, hi)
    u = num / den
    u = select((hi == zero) & (lo == zero), zero, u)  # atan2(±0, ±0); nan stays nan
    r = atan_small(u)
    # r, π/2 − r (|y| > |x|), π/2 + r (and x < 0), π − r (x < 0); each ± π/4 when big
    neg = np.copysign(one, x) < zero
    s = select(swap != neg, -one, one)
    k = select(swap, like(x, 2.0), select(neg, like(x, 4.0), zero)) + select(big, s, zero)
    return np.copysign(k * like(x, PIO4_HI) + (s * r + k * like(x, PIO4_LO)), y)


# sincos's reduction is exact for |k| < 2**20 in float64 and |k| < 2**15 in
# float32 (|x| < 2**15·π/2); the limits leave a margin and are round numbers.
# Measured: float32 within 2.44 ulp on every float32 with |x| ≤ 2**15,
# float64 within 1 ulp next to the multiples of π/2 (tests/test_trig.py).
SINCOS_LIMIT_64 = 1.0e6
SINCOS_LIMIT_32 = 32768.0


@element
def sincos_limit(x):
    """The largest |x| for which :func:`sincos` is accurate to x's float rounding."""
    return like(x, select(float_bits(x) == 32, SINCOS_LIMIT_32, SINCOS_LIMIT_64))
