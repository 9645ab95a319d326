"""Angular velocity and acceleration of the spline curves, as analytic derivatives.

The rates are those of :class:`scipy.spatial.transform.RotationSpline`: body
frame (the moving frame's axes), radians per time unit. For a unit quaternion
curve X(u) the body rate is Ω = 2·vec(X* X') (so X' = ½ X ⊗ (0, Ω)) and the
body acceleration is Γ = Ω' = 2·vec(X* X''); in time t = t_n + u·h they are
ω = Ω/h and α = Γ/h².

Every curve here is built from great-arc slerps, so the derivatives follow
from three rules of the rotation group (rotation vectors r, right Jacobian
J(r) with J(r)·r' the body rate of Exp(r), and N(r, r') = J(r)'·r' its
quadratic term, scipy's ``_angular_acceleration_nonlinear_term``):

- product P = X ⊗ Y: Ω_P = R_Y^T Ω_X + Ω_Y and
  Γ_P = R_Y^T Γ_X − Ω_Y × (R_Y^T Ω_X) + Γ_Y;
- relative rotation D = X* ⊗ Y: Ω_D = Ω_Y − R_D^T Ω_X and
  Γ_D = Γ_Y − R_D^T Γ_X + Ω_D × (R_D^T Ω_X);
- logarithm r = Log D: r' = J(r)⁻¹ Ω_D and r'' = J(r)⁻¹ (Γ_D − N(r, r')).

A slerp of moving ends s = slerp(A, B, w) = A ⊗ Exp(w·Log(A* ⊗ B)) (the plain
great arc, no hemisphere flip) then has Ω_s, Γ_s from those of A and B and of
the weight w(u) (:func:`slerp_rates`). A slerp on a fixed arc turns at a
constant body rate, its rotation vector r = Log(p* ⊗ q), and Γ = 0.
The methods' curves (in u of one segment):

- ``slerp``: one fixed arc; ω = r/h, α = 0.
- ``nlerp``: n = c/|c| with the chord c = (1 − u)p + uq: Ω = 2·vec(c* c')/|c|²,
  Γ = −Ω·(|c|²)'/|c|².
- ``bezier`` (de Casteljau): level 1 the three fixed arcs q_n → a_n → b_{n+1}
  → q_{n+1}; level 2 and 3 slerps of moving ends with w = u (w' = 1, w'' = 0).
- ``squad``: the fixed arcs q_n → q_{n+1} and s_n → s_{n+1}, then a slerp of
  moving ends with w = 2u(1 − u) (w' = 2 − 4u, w'' = −4).

The functions of the rotation angle n = |r| in J, J⁻¹ and N are evaluated
from sin(n/2), cos(n/2), in closed form above n = 0.25 and as their Taylor
series to n¹⁰ below (where the closed forms cancel); no other transcendental is
needed beyond those of the curve's value (one atan2 per arc, one sincos).
"""

import numpy as np

from ._elements import cross, qconj, qmul, qrotate_raw, vadd, vdot, vscale, vsub
from ._jit import element, like, select
from ._trig import atan2, sincos

SMALL2 = 0.0625  # n² below which the series are used (n < 0.25: their terms to n¹⁰ are exact to 1e-17 there)
TINY2 = 1e-6  # n² below which sin(n/2)/n takes its series (it does not cancel: only 0/0 is avoided)


@element
def unrotate(q, v):
    """R_q^T v: v turned by the unit quaternion q⁻¹ = q*."""
    return qrotate_raw(qconj(q), v, like(q[0], 1.0))


@element
def _series(n2, a0, a1, a2, a3, a4, a5):
    """a0 + a1 n² + … + a5 n¹⁰ (Horner in n²)."""
    return like(n2, a0) + n2 * (like(n2, a1) + n2 * (like(n2, a2) + n2 * (like(n2, a3) + n2 * (
        like(n2, a4) + n2 * like(n2, a5)))))


@element
def jac_coeffs(n2, s, c):
    """(k1, k2) of the rotation vector r with |r|² = n2, given s = sin(|r|/2),
    c = cos(|r|/2): J(r) = I − k1[r]× + k2[r]×², k1 = (1 − cos n)/n², k2 = (n − sin n)/n³."""
    one = like(n2, 1.0)
    small = n2 < like(n2, SMALL2)
    m2 = select(small, one, n2)  # no 0/0 in the closed forms (their results are not used)
    n = np.sqrt(m2)
    k1 = like(n2, 2.0) * s * s / m2
    k2 = (n - like(n2, 2.0) * s * c) / (m2 * n)
    k1s = _series(n2, 0.5, -1.0 / 24.0, 1.0 / 720.0, -1.0 / 40320.0, 1.0 / 3628800.0, -1.0 / 479001600.0)
    k2s = _series(n2, 1.0 / 6.0, -1.0 / 120.0, 1.0 / 5040.0, -1.0 / 362880.0, 1.0 / 39916800.0, -1.0 / 6227020800.0)
    return select(small, k1s, k1), select(small, k2s, k2)


@element
def inv_coeff(n2, s, c):
    """ki of J(r)⁻¹ = I + ½[r]× + ki[r]×², ki = (1 − (n/2)cot(n/2))/n² (n² = n2,
    s, c = sin, cos of n/2)."""
    one = like(n2, 1.0)
    small = n2 < like(n2, SMALL2)
    m2 = select(small, one, n2)
    ki = (one - like(n2, 0.5) * np.sqrt(m2) * c / select(small, one, s)) / m2
    kis = _series(n2, 1.0 / 12.0, 1.0 / 720.0, 1.0 / 30240.0, 1.0 / 1209600.0, 1.0 / 47900160.0,
                  691.0 / 1307674368000.0)
    return select(small, kis, ki)


@element
def acc_coeffs(n2, s, c):
    """(j1, j2) of N(r, r') = (r·r')(j1 r×r' + j2 r×(r×r')) + k2 r'×(r×r') (scipy's
    nonlinear term): j1 = (−n sin n − 2(cos n − 1))/n⁴, j2 = (−2n + 3 sin n − n cos n)/n⁵."""
    one = like(n2, 1.0)
    small = n2 < like(n2, SMALL2)
    m2 = select(small, one, n2)
    n = np.sqrt(m2)
    two = like(n2, 2.0)
    s2 = s * s
    sc = s * c
    j1 = (like(n2, 4.0) * s2 - two * n * sc) / (m2 * m2)
    j2 = (like(n2, 6.0) * sc - like(n2, 3.0) * n + two * n * s2) / (m2 * m2 * n)
    j1s = _series(n2, 1.0 / 12.0, -1.0 / 180.0, 1.0 / 6720.0, -1.0 / 453600.0, 1.0 / 47900160.0, -1.0 / 7264857600.0)
    j2s = _series(n2, -1.0 / 60.0, 1.0 / 1260.0, -1.0 / 60480.0, 1.0 / 4989600.0, -1.0 / 622702080.0,
                  1.0 / 108972864000.0)
    return select(small, j1s, j1), select(small, j2s, j2)


@element
def angle_coeffs(n2, n, s, c):
    """(k1, k2, ki, im2): :func:`jac_coeffs` and :func:`inv_coeff` of the rotation vector r
    with |r|² = n2 and |r| = n both given (no square root), s, c = sin, cos of n/2, with
    one division for 1/n² (im2, 1 below the series' threshold: for :func:`acc_coeffs_of`)
    and one for cot(n/2) = c/s, where those two compute four (the rate loops wait on the
    divider)."""
    one = like(n2, 1.0)
    two = like(n2, 2.0)
    small = n2 < like(n2, SMALL2)
    m2 = select(small, one, n2)  # no 0/0 in the closed forms (their results are not used)
    nn = select(small, one, n)
    im2 = one / m2
    k1 = two * s * s * im2
    k2 = (nn - two * s * c) * im2 * (nn * im2)  # /(n² n): 1/n = n/n²
    ki = (one - like(n2, 0.5) * nn * c / select(small, one, s)) * im2
    k1s = _series(n2, 0.5, -1.0 / 24.0, 1.0 / 720.0, -1.0 / 40320.0, 1.0 / 3628800.0, -1.0 / 479001600.0)
    k2s = _series(n2, 1.0 / 6.0, -1.0 / 120.0, 1.0 / 5040.0, -1.0 / 362880.0, 1.0 / 39916800.0, -1.0 / 6227020800.0)
    kis = _series(n2, 1.0 / 12.0, 1.0 / 720.0, 1.0 / 30240.0, 1.0 / 1209600.0, 1.0 / 47900160.0,
                  691.0 / 1307674368000.0)
    return select(small, k1s, k1), select(small, k2s, k2), select(small, kis, ki), im2


@element
def acc_coeffs_of(n2, n, s, c, im2):
    """:func:`acc_coeffs` given |r| = n and im2 of :func:`angle_coeffs` (no division)."""
    small = n2 < like(n2, SMALL2)
    nn = select(small, like(n2, 1.0), n)
    two = like(n2, 2.0)
    s2 = s * s
    sc = s * c
    i4 = im2 * im2
    j1 = (like(n2, 4.0) * s2 - two * nn * sc) * i4
    j2 = (like(n2, 6.0) * sc - like(n2, 3.0) * nn + two * nn * s2) * i4 * (nn * im2)
    j1s = _series(n2, 1.0 / 12.0, -1.0 / 180.0, 1.0 / 6720.0, -1.0 / 453600.0, 1.0 / 47900160.0, -1.0 / 7264857600.0)
    j2s = _series(n2, -1.0 / 60.0, 1.0 / 1260.0, -1.0 / 60480.0, 1.0 / 4989600.0, -1.0 / 622702080.0,
                  1.0 / 108972864000.0)
    return select(small, j1s, j1), select(small, j2s, j2)


@element
def jac(r, k1, k2, v):
    """J(r)·v = v − k1 r×v + k2 r×(r×v)."""
    a = cross(r, v)
    b = cross(r, a)
    return (v[0] - k1 * a[0] + k2 * b[0], v[1] - k1 * a[1] + k2 * b[1], v[2] - k1 * a[2] + k2 * b[2])


@element
def jac_inv(r, ki, v):
    """J(r)⁻¹·v = v + ½ r×v + ki r×(r×v)."""
    a = cross(r, v)
    b = cross(r, a)
    h = like(ki, 0.5)
    return (v[0] + h * a[0] + ki * b[0], v[1] + h * a[1] + ki * b[1], v[2] + h * a[2] + ki * b[2])


@element
def jac_dot(r, rd, j1, j2, k2):
    """N(r, r') = J(r)'·r': the body acceleration of Exp(r) is J(r) r'' + N(r, r')."""
    dp = vdot(r, rd)
    cp = cross(r, rd)
    ccp = cross(r, cp)
    dccp = cross(rd, cp)
    return (dp * (j1 * cp[0] + j2 * ccp[0]) + k2 * dccp[0], dp * (j1 * cp[1] + j2 * ccp[1]) + k2 * dccp[1],
            dp * (j1 * cp[2] + j2 * ccp[2]) + k2 * dccp[2])


@element
def arc_rotvec(p, th, v):
    """Rotation vector Log(p* ⊗ q) of the fixed arc p cos uθ + v sin uθ (v the unit
    tangent at p): 2θ·vec(p* ⊗ v), the arc's constant body rate per unit u."""
    d = qmul(qconj(p), v)
    f = like(th, 2.0) * th
    return (f * d[1], f * d[2], f * d[3])


@element
def log_arc(a, b):
    """(r, n2, s, c) of D = a* ⊗ b on the plain great arc: r = Log D (|r| = 2θ, θ ∈ [0, π]
    the arc's angle on S³), n2 = |r|², s = sin θ, c = cos θ (from D itself)."""
    d = qmul(qconj(a), b)
    dv = (d[1], d[2], d[3])
    un = np.sqrt(vdot(dv, dv))
    th = atan2(un, d[0])
    zero = like(un, 0.0)
    f = select(un > zero, like(un, 2.0) * th / un, like(un, 2.0))
    nd = np.sqrt(d[0] * d[0] + un * un)
    return vscale(dv, f), like(un, 4.0) * th * th, un / nd, d[0] / nd


@element
def log_arc_n(a, b):
    """:func:`log_arc` and |r| = 2θ: (r, n2, n, s, c), s and c with one division."""
    d = qmul(qconj(a), b)
    dv = (d[1], d[2], d[3])
    un = np.sqrt(vdot(dv, dv))
    th = atan2(un, d[0])
    zero = like(un, 0.0)
    two = like(un, 2.0)
    f = select(un > zero, two * th / un, two)
    ind = like(un, 1.0) / np.sqrt(d[0] * d[0] + un * un)
    return vscale(dv, f), like(un, 4.0) * th * th, two * th, un * ind, d[0] * ind


@element
def qexp_half_n(y, ny2, ny, hs, hc):
    """:func:`qexp_half` given |y| = ny (no square root)."""
    small = ny2 < like(ny2, TINY2)
    f = hs / select(small, like(ny2, 1.0), ny)
    fs = like(ny2, 0.5) - ny2 * (like(ny2, 1.0 / 48.0) - ny2 * like(ny2, 1.0 / 3840.0))
    f = select(small, fs, f)
    return (hc, f * y[0], f * y[1], f * y[2])


@element
def slerp_rates(a, wa, b, wb, w, dw):
    """(s, Ω_s, y, k's of Exp(y), r, r', ki) of s = slerp(a, b, w) on the plain great arc,
    given a, b and their body rates wa, wb per unit u, and w, w' = dw.
    s = a ⊗ Exp(y), y = w r, r = Log(a* ⊗ b). The angles |r| = 2θ and |y| = |w|·|r|
    are known (no square roots) and the coefficients share their divisions
    (:func:`angle_coeffs`)."""
    r, n2, n, s_, c_ = log_arc_n(a, b)
    k1, k2, ki, im2 = angle_coeffs(n2, n, s_, c_)
    wd = vsub(wb, unrotate(qmul(qconj(a), b), wa))  # Ω_D
    rd = jac_inv(r, ki, wd)
    y = vscale(r, w)
    yd = vadd(vscale(r, dw), vscale(rd, w))
    ny2 = w * w * n2
    ny = abs(w) * n
    hs, hc = sincos(like(w, 0.5) * ny)  # half the angle |y| = |w|·|r|
    e = qexp_half_n(y, ny2, ny, hs, hc)
    ky1, ky2, _kyi, imy2 = angle_coeffs(ny2, ny, hs, hc)
    wy = jac(y, ky1, ky2, yd)
    ws = vadd(unrotate(e, wa), wy)
    return qmul(a, e), ws, (r, rd, wd, n2, n, s_, c_, k2, ki, im2, y, yd, ny2, ny, hs, hc, ky1, ky2, imy2, e, wy)


@element
def qexp_half(y, ny2, hs, hc):
    """Exp(y) = (cos(n/2), sin(n/2) y/n), n = |y|, given hs, hc = sin, cos of n/2."""
    small = ny2 < like(ny2, TINY2)
    n = np.sqrt(select(small, like(ny2, 1.0), ny2))
    # sin(n/2)/n: series below the threshold (and exactly 1/2 at 0)
    f = hs / n
    fs = like(ny2, 0.5) - ny2 * (like(ny2, 1.0 / 48.0) - ny2 * like(ny2, 1.0 / 3840.0))
    f = select(small, fs, f)
    return (hc, f * y[0], f * y[1], f * y[2])


@element(how="trace")  # branches on None (no acceleration given), not on a number
def slerp_acc(a, wa, ga, b, wb, gb, w, dw, ddw):
    """(s, Ω_s, Γ_s) of s = slerp(a, b, w) given a, b, their body rates wa, wb and
    accelerations ga, gb per unit u, and w, w', w''. ``ga = gb = None`` (ends on
    fixed arcs: no acceleration) and ``ddw = None`` (w'' = 0) leave out those terms
    (from a traced caller, :func:`slerp_acc_fixed`), the same values but for the
    sign of a zero."""
    s, ws, x = slerp_rates(a, wa, b, wb, w, dw)
    r, rd, wd, n2, n, s_, c_, k2, ki, im2, y, yd, ny2, ny, hs, hc, ky1, ky2, imy2, e, wy = x
    d = qmul(qconj(a), b)
    z = unrotate(d, wa)
    gd = cross(wd, z) if ga is None else vadd(vsub(gb, unrotate(d, ga)), cross(wd, z))  # Γ_D
    j1, j2 = acc_coeffs_of(n2, n, s_, c_, im2)
    rdd = jac_inv(r, ki, vsub(gd, jac_dot(r, rd, j1, j2, k2)))
    ydd = vscale(rd, like(w, 2.0) * dw)
    if ddw is not None:
        ydd = vadd(vscale(r, ddw), ydd)
    ydd = vadd(ydd, vscale(rdd, w))
    yj1, yj2 = acc_coeffs_of(ny2, ny, hs, hc, imy2)
    gy = vadd(jac(y, ky1, ky2, ydd), jac_dot(y, yd, yj1, yj2, ky2))
    za = unrotate(e, wa)
    gs = vsub(gy, cross(wy, za)) if ga is None else vadd(vsub(unrotate(e, ga), cross(wy, za)), gy)
    return s, ws, gs


@element
def slerp_acc_fixed(a, wa, b, wb, w, dw, ddw):
    """:func:`slerp_acc` of ends on fixed arcs (their accelerations zero): the
    Bézier chain's second level and squad's outer slerp."""
    return slerp_acc(a, wa, None, b, wb, None, w, dw, ddw)


