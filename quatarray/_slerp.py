"""Per-element interpolation math: one or a few quaternions (4-tuples) and a
parameter in, a quaternion out, inlined into the row loops of
:mod:`quatarray.interpolation` and :mod:`quatarray.splines` so they vectorise.
Like :mod:`quatarray._elements` they never allocate, validate or raise and keep
the float type of their arguments.

Every slerp here is p cos tθ + v sin tθ on the great arc from p: θ =
2·atan2(|p − q|, |p + q|) (accurate for identical, nearly identical and
antipodal pairs, never an arccos) and v the unit tangent at p towards q, kept
unit and orthogonal to p, so the result is unit for every pair and every t
(see :func:`arc`). The trigonometry is the branch-free polynomial code of
:mod:`quatarray._trig`, so the row loops run as SIMD code. t = 0 and t = 1
give p and q exactly. θ = 0 gives p; an exactly antipodal pair with
``shortest=False`` (no unique arc) follows p ⊗ (cos tπ, sin tπ, 0, 0), the
convention of :func:`quatarray.power`.
"""

import numpy as np

from ._elements import qconj, qdot, qmul
from ._jit import element, float_bits, fmuladd, like, select
from ._trig import atan2, half_arc, sincos

TIE_64 = 2.0**-46  # the tie band of flip_rule: 64 ulp of 1
TIE_32 = 2.0**-17


@element
def tie_band(x):
    """TIE of x's float type (see the module docstring)."""
    return like(x, select(float_bits(x) == 32, TIE_32, TIE_64))


@element
def flip_rule(p, q, d, tol, tol_v):
    """(flip, chain) for q after p, given d (p·q, or 4p·q = |p + q|² − |p − q|²), tol
    the tie band on d's scale and tol_v on p·q's (TIE·(|p|² + |q|²)/2: what a
    component of D = p* ⊗ q may be and still count as 0).

    flip: q goes into p's hemisphere: d < −tol, or a tie (|d| ≤ tol) whose D has
    a negative first non-negligible x, y, z (scipy's canonical rule for w = 0).
    Negating p or q negates d and D, so negates flip.
    chain: false only where nothing decides (a zero or nan row): flip is then
    false whatever the signs, so a sign carried along a stream stops there."""
    dv = qmul(qconj(p), q)
    x, y, z = dv[1], dv[2], dv[3]
    bx = abs(x) > tol_v
    by = abs(y) > tol_v
    f = select(bx, x, select(by, y, z))
    zero = like(d, 0.0)
    below = d < -tol
    flip = below | ((abs(d) <= tol) & (f < zero))
    chain = below | (d > tol) | bx | by | (abs(z) > tol_v)
    return flip, chain


@element
def unflip_sign(p, q):
    """What :func:`quatarray.unflip` does to q after p (as it stands): −1 negate (p·q < 0,
    or the tie rule of :func:`flip_rule`), 1 keep, 0 keep whatever the signs (a zero or
    nan row: a sign carried along the stream stops there). Negating p or q negates a
    non-zero sign."""
    tol = tie_band(p[0]) * like(p[0], 0.5) * (qdot(p, p) + qdot(q, q))
    flip, chain = flip_rule(p, q, qdot(q, p), tol, tol)
    one = like(p[0], 1.0)
    return select(chain, select(flip, -one, one), like(p[0], 0.0))


@element
def arc(p, q, shortest):
    """(θ, v, f) of the great arc from unit p to unit (1 − f)·q: slerp = p cos tθ + v sin tθ.

    f = 2 when `shortest` is 1.0 and :func:`flip_rule` flips q (p·q < 0, or the
    tie rule), else 0 (`shortest` is a float
    flag: a runtime boolean in the loop keeps LLVM from vectorising); the flip
    costs nothing: |p ∓ q| just swap. θ = 2 atan2(|p − sq|, |p + sq|) ∈ [0, π]
    from the chords a = |p − sq|, b = |p + sq|; v is the unit tangent at p
    towards sq: sq − p cos θ (cos θ = (b² − a²)/(a² + b²)), made orthogonal to
    p once more and normalised (never divided by sin θ). Near θ = π (b of a few
    ulp) its direction is only as certain as p + sq, but it stays a unit
    tangent, so slerp stays unit for every pair and every t.
    Where no tangent is left (identical or antipodal ends) v = p ⊗ i: an
    antipodal pair follows p ⊗ (cos tπ, sin tπ, 0, 0), as :func:`quatarray.power`.
    """
    dw, dx, dy, dz = p[0] - q[0], p[1] - q[1], p[2] - q[2], p[3] - q[3]
    sw, sx, sy, sz = p[0] + q[0], p[1] + q[1], p[2] + q[2], p[3] + q[3]
    d2 = fmuladd(dw, dw, dx * dx) + fmuladd(dy, dy, dz * dz)
    s2 = fmuladd(sw, sw, sx * sx) + fmuladd(sy, sy, sz * sz)
    # 4 p·q = |p+q|² − |p−q|², the tie band on the scale of 2(|p|² + |q|²) = s2 + d2
    tol = tie_band(d2) * (s2 + d2)
    flip = flip_rule(p, q, s2 - d2, tol, like(d2, 0.25) * tol)[0] & (shortest > like(d2, 0.0))
    m2 = select(flip, s2, d2)
    p2 = select(flip, d2, s2)
    # 2 when flipped, else 0, converted from the boolean (a select or copysign
    # feeding the weights stops LLVM's vectoriser)
    sgn = like(d2, 2.0) * flip
    one = like(d2, 1.0)
    a = np.sqrt(m2)
    b = np.sqrt(p2)
    two = like(a, 2.0)
    th = two * half_arc(a, b)
    c = (p2 - m2) / (m2 + p2)  # cos θ
    k = one - sgn  # ±1: the sign of q on the arc
    v0 = k * q[0] - c * p[0]
    v1 = k * q[1] - c * p[1]
    v2 = k * q[2] - c * p[2]
    v3 = k * q[3] - c * p[3]
    e = p[0] * v0 + p[1] * v1 + p[2] * v2 + p[3] * v3
    v0, v1, v2, v3 = v0 - e * p[0], v1 - e * p[1], v2 - e * p[2], v3 - e * p[3]
    n2 = v0 * v0 + v1 * v1 + v2 * v2 + v3 * v3
    nv = one / np.sqrt(n2)
    v = (v0 * nv, v1 * nv, v2 * nv, v3 * nv)
    st = two * a * b / (m2 + p2)  # sin θ
    # no tangent left (|v| ≤ sin θ / 2: rounding only): identical ends (any unit
    # tangent: sin tθ = 0) or antipodal ones, also p + sq parallel to p (sq a
    # scaled −p)
    v = select(n2 <= like(a, 0.25) * st * st, (-p[1], p[0], p[3], -p[2]), v)
    return th, v, sgn


@element
def arc_fast(p, q, shortest):
    """(θ, v, f, rare): :func:`arc` for the common pairs, with a cheaper tangent, and
    whether the pair is a rare one that needs :func:`arc` itself.

    With s = p + sq and d = p − sq (sq = ±q as :func:`arc` flips it), m2 = |d|²,
    p2 = |s|², the tangent at p towards sq is (m2 s − p2 d)/(2ab) (a = |d|, b = |s|;
    orthogonal to p and of norm |q| exactly, for unit p). Its terms never cancel
    (near θ = 0 both are of order a², near θ = π/2 of order 1), so it is orthogonal
    to p within a few ulp without the projection of :func:`arc`, and one Newton step
    makes it unit (no square root), for every pair with θ ≤ π/2 (all pairs of ``shortest=True``) and up
    to θ = 2 atan 4 (152°). The rare ones (then not resolved here): θ beyond that
    (b < a/4: the nearly antipodal pairs of ``shortest=False``, where s is only as
    certain as its rounding, which leaves the tangent off orthogonal to p by ε/b:
    it must be projected), identical ends (m2 = 0), ties (|p·q| within the tie
    band: the rule of :func:`flip_rule`) and nan."""
    dw, dx, dy, dz = p[0] - q[0], p[1] - q[1], p[2] - q[2], p[3] - q[3]
    sw, sx, sy, sz = p[0] + q[0], p[1] + q[1], p[2] + q[2], p[3] + q[3]
    d2 = fmuladd(dw, dw, dx * dx) + fmuladd(dy, dy, dz * dz)
    s2 = fmuladd(sw, sw, sx * sx) + fmuladd(sy, sy, sz * sz)
    zero = like(d2, 0.0)
    diff = s2 - d2  # 4 p·q
    flip = diff * shortest < zero
    m2 = select(flip, s2, d2)
    p2 = select(flip, d2, s2)
    # θ > 2 atan 4 (152°: b < a/4, only with shortest=False), identical ends, ties, nan
    rare = ~(like(d2, 16.0) * p2 >= m2) | ~(m2 > zero) | ((abs(diff) <= tie_band(d2) * (s2 + d2)) & (shortest > zero))
    sgn = like(d2, 2.0) * flip
    a = np.sqrt(m2)
    b = np.sqrt(p2)
    th = like(a, 2.0) * half_arc(a, b)
    # s and d of sq are d and s of q, swapped and d negated when q is flipped, so
    # m2 s − p2 d is ±(d2 s − s2 d): the sign goes into w (no select per component)
    w = (like(a, 1.0) - sgn) / (like(a, 2.0) * a * b)
    v = (fmuladd(d2, sw, -s2 * dw) * w, fmuladd(d2, sx, -s2 * dx) * w, fmuladd(d2, sy, -s2 * dy) * w,
         fmuladd(d2, sz, -s2 * dz) * w)
    # |v| = 1 within a few ulp (the roundings of a, b and w): one Newton step of the
    # normalisation, v (3 − |v|²)/2, brings it within one, without a square root
    n2 = fmuladd(v[0], v[0], v[1] * v[1]) + fmuladd(v[2], v[2], v[3] * v[3])
    f = like(a, 1.5) - like(a, 0.5) * n2
    return th, (v[0] * f, v[1] * f, v[2] * f, v[3] * f), sgn, rare


@element
def fixed_arc(p, q):
    """(θ, v) of the plain great arc from p to q as a spline's table holds it: :func:`arc_fast`,
    or :func:`arc` for its rare pairs, both computed and one selected (for SIMD loops; a
    scalar loop branches instead, with the same result)."""
    zero = like(p[0], 0.0)
    th, v, _, rare = arc_fast(p, q, zero)
    th_x, v_x, _ = arc(p, q, zero)
    return select(rare, th_x, th), select(rare, v_x, v)


@element
def slerp4(p, q, t, shortest=0.0):
    """Great-arc interpolation of unit p and q at t (`shortest` 1.0: flip q into p's
    hemisphere): p cos tθ + v sin tθ on the arc of :func:`arc`, one sincos. Exact at
    t = 0 (sincos(0) = (0, 1)) and t = 1 (±q)."""
    th, v, sgn = arc(p, q, shortest)
    s, c = sincos(t * th)
    r = (c * p[0] + s * v[0], c * p[1] + s * v[1], c * p[2] + s * v[2], c * p[3] + s * v[3])
    k = like(t, 1.0) - sgn
    return select(t == like(t, 1.0), (k * q[0], k * q[1], k * q[2], k * q[3]), r)


@element(how="call")
def slerp_call(p, q, t):
    """:func:`slerp4` (plain great arc) as a called function, compiled once.

    The public Bézier and squad row loops call it six and three times per
    row; inlining every copy made those kernels take about half a minute to
    compile (the spline's segment loops are the fast path for resampling).
    """
    return slerp4(p, q, t, like(t, 0.0))


@element
def bezier4(q0, a, b, q1, t):
    """Spherical cubic Bézier by de Casteljau: six slerps."""
    p01 = slerp_call(q0, a, t)
    p12 = slerp_call(a, b, t)
    p23 = slerp_call(b, q1, t)
    return slerp_call(slerp_call(p01, p12, t), slerp_call(p12, p23, t), t)


@element
def squad4(q0, s0, s1, q1, t):
    """Shoemake's squad: slerp(slerp(q0, q1, t), slerp(s0, s1, t), 2t(1 − t))."""
    h = like(t, 2.0) * t * (like(t, 1.0) - t)
    return slerp_call(slerp_call(q0, q1, t), slerp_call(s0, s1, t), h)


@element
def double4(p, q):
    """Shoemake's Double: 2(p·q)q − p."""
    d2 = like(p[0], 2.0) * qdot(p, q)
    return (d2 * q[0] - p[0], d2 * q[1] - p[1], d2 * q[2] - p[2], d2 * q[3] - p[3])


@element
def bisect4(p, q):
    """Shoemake's Bisect: (p + q)/|p + q|."""
    s = (p[0] + q[0], p[1] + q[1], p[2] + q[2], p[3] + q[3])
    n = np.sqrt(qdot(s, s))
    return (s[0] / n, s[1] / n, s[2] / n, s[3] / n)


@element
def controls4(qp, qn, qx, f_out, f_in):
    """(a_n, b_n) of key qn between qp and qx: â = bisect(double(qp, qn), qx),
    a₀ = slerp(qn, â, 1/3), a_n = slerp(qn, a₀, f_out), b_n = slerp(qn, double(a₀, qn), f_in)."""
    zero = like(f_out, 0.0)
    a0 = slerp4(qn, bisect4(double4(qp, qn), qx), like(f_out, 1.0) / like(f_out, 3.0), zero)
    return slerp4(qn, a0, f_out, zero), slerp4(qn, double4(a0, qn), f_in, zero)


@element
def log_unit(d):
    """Log of a unit quaternion as the rotation-vector half (θ u/|u|, θ = atan2(|u|, w)),
    its real part log|d| = 0 dropped; (π, 0, 0) for d = (−1, 0, 0, 0), as :func:`quatarray.log`."""
    un = np.sqrt(d[1] * d[1] + d[2] * d[2] + d[3] * d[3])
    zero = like(un, 0.0)
    some = un > zero
    f = atan2(un, d[0]) / select(some, un, like(un, 1.0))
    pi = select(d[0] < zero, like(un, 3.141592653589793), zero)
    return select(some, (f * d[1], f * d[2], f * d[3]), (pi, zero, zero))


@element
def squad_inner4(qp, qn, qx):
    """Shoemake's squad inner point of unit key qn between qp and qx:
    qn ⊗ exp(−(log(qn* ⊗ qx) + log(qn* ⊗ qp))/4) (the logs of unit quaternions: no real part)."""
    inv = qconj(qn)
    a = log_unit(qmul(inv, qx))
    b = log_unit(qmul(inv, qp))
    h = like(a[0], -0.25)
    x = ((a[0] + b[0]) * h, (a[1] + b[1]) * h, (a[2] + b[2]) * h)
    n = np.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
    s, c = sincos(n)
    zero = like(n, 0.0)
    f = select(n > zero, s / select(n > zero, n, like(n, 1.0)), like(n, 1.0))
    return qmul(qn, (c, f * x[0], f * x[1], f * x[2]))


@element
def lerp4(p, q, s, t):
    """The linear blend s·p + t·q."""
    return (s * p[0] + t * q[0], s * p[1] + t * q[1], s * p[2] + t * q[2], s * p[3] + t * q[3])


@element
def nlerp4(p, q, s, t):
    """The normalised blend (s·p + t·q)/|s·p + t·q|."""
    r = lerp4(p, q, s, t)
    nr = np.sqrt(qdot(r, r))
    return (r[0] / nr, r[1] / nr, r[2] / nr, r[3] / nr)


@element
def arc_slerp(p, q, c, t):
    """slerp(p, q, t) = p cos tθ + v sin tθ on a fixed arc, c = (θ, v) from :func:`quatarray.splines.put_arc`."""
    th, v0, v1, v2, v3 = c
    s, co = sincos(t * th)
    r = (co * p[0] + s * v0, co * p[1] + s * v1, co * p[2] + s * v2, co * p[3] + s * v3)
    return select(t == like(t, 1.0), q, r)  # exact end (t = 0 is exact already: sincos(0) = (0, 1))


@element
def bezier_seg(q0, a, b, q1, c0, c1, c2, t):
    """Segment value at u = t: the level-1 slerps on the three fixed control arcs, then two levels of slerp."""
    p01 = arc_slerp(q0, a, c0, t)
    p12 = arc_slerp(a, b, c1, t)
    p23 = arc_slerp(b, q1, c2, t)
    zero = like(t, 0.0)
    p012 = slerp4(p01, p12, t, zero)
    p123 = slerp4(p12, p23, t, zero)
    return slerp4(p012, p123, t, zero)
