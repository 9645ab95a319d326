"""Interpolation of unit quaternions (Shoemake): lerp, slerp, spherical Bézier
curves, squad, and resampling of timestamped key streams.

Quaternions are ``(..., 4)`` arrays in (w, x, y, z) order, Hamilton algebra.
Leading dimensions broadcast like numpy; float32 stays float32, float64 stays
float64, mixed gives float64.

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

import math

import numpy as np

from . import _elements as E
from numba import types
from numba.extending import overload

from ._jit import (CACHE, INLINE_OPTIONS, element, flat_load, flat_store, inline, ir_inline, kernel, like, prange, rowloop,
                   specialise)
from ._trig import half_arc, sincos
from ._validate import as_float, as_times, check_core, elementwise, scan, shape_error

Q = (4,)
BLOCK = 2048  # samples per block of the segment search
# The Bézier samples are gathered, TILE at a time, into a column-major tile of
# their segments' rows and evaluated there as SIMD lanes (see _eval_bezier):
# one copy of the long de Casteljau chain serves runs of any length (a separate
# loop for long runs in one segment was no faster, and doubled its compile time).
TILE = 64
# rows per block of a row loop: prange runs over blocks and the plain inner
# loop is what LLVM vectorises (a prange loop body itself is not vectorised)
ROWS = 1024
NSEG = 31  # floats per row of a spline's segment table: 4 quaternions, 3 arcs

# --------------------------------------------------------------------------
# element functions (inlined so the row loops vectorise)


@inline
def arc(p, q, shortest):
    """(θ, v, f) of the great arc from unit p to unit (1 − f)·q: slerp = p cos tθ + v sin tθ.

    f = 2 when p·q < 0 and `shortest` is 1.0, else 0 (`shortest` is a float
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
    d2 = dw * dw + dx * dx + dy * dy + dz * dz
    s2 = sw * sw + sx * sx + sy * sy + sz * sz
    flip = (s2 - d2) * shortest < like(d2, 0.0)  # 4 p·q = |p+q|² − |p−q|²
    m2 = s2 if flip else d2
    p2 = d2 if flip else s2
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
    if n2 <= like(a, 0.25) * st * st:
        v = (-p[1], p[0], p[3], -p[2])
    return th, v, sgn


@inline
def slerp4(p, q, t, shortest=0.0):
    """Great-arc interpolation of unit p and q at t (`shortest` 1.0: flip q into p's
    hemisphere): p cos tθ + v sin tθ on the arc of :func:`arc`, one sincos. Exact at
    t = 0 (sincos(0) = (0, 1)) and t = 1 (±q)."""
    th, v, sgn = arc(p, q, shortest)
    s, c = sincos(t * th)
    r = (c * p[0] + s * v[0], c * p[1] + s * v[1], c * p[2] + s * v[2], c * p[3] + s * v[3])
    if t == like(t, 1.0):
        k = like(t, 1.0) - sgn
        r = (k * q[0], k * q[1], k * q[2], k * q[3])
    return r


@element
def slerp_call(p, q, t):
    """:func:`slerp4` (plain great arc) as a called function, compiled once.

    The public Bézier and squad row loops call it six and three times per
    row; inlining every copy made those kernels take about half a minute to
    compile (the spline's segment loops are the fast path for resampling).
    """
    return slerp4(p, q, t, like(t, 0.0))


@inline
def bezier4(q0, a, b, q1, t):
    """Spherical cubic Bézier by de Casteljau: six slerps."""
    p01 = slerp_call(q0, a, t)
    p12 = slerp_call(a, b, t)
    p23 = slerp_call(b, q1, t)
    return slerp_call(slerp_call(p01, p12, t), slerp_call(p12, p23, t), t)


@inline
def squad4(q0, s0, s1, q1, t):
    """Shoemake's squad: slerp(slerp(q0, q1, t), slerp(s0, s1, t), 2t(1 − t))."""
    h = like(t, 2.0) * t * (like(t, 1.0) - t)
    return slerp_call(slerp_call(q0, q1, t), slerp_call(s0, s1, t), h)


@inline
def ld4(a, i):
    return (a[i, 0], a[i, 1], a[i, 2], a[i, 3])


# Flat access to the 1-D C-contiguous arrays of the row loops (quaternions as
# (4n,)). Compiled, they read and write the buffer directly (no negative-index
# wraparound), so LLVM can bound the addresses and vectorise the loops; without
# the JIT the plain-Python bodies run.


def ld1(a, i):
    return a[i]


def st1(o, i, v):
    o[i] = v


def ld4flat(a, i):
    return (a[4 * i], a[4 * i + 1], a[4 * i + 2], a[4 * i + 3])


def st4flat(o, i, q):
    o[4 * i], o[4 * i + 1], o[4 * i + 2], o[4 * i + 3] = q


def _flat_ok(a):
    return isinstance(a, types.Array) and a.ndim == 1 and a.layout == "C"


@overload(ld1, jit_options=INLINE_OPTIONS)
def _ld1(a, i):
    if _flat_ok(a):
        return lambda a, i: flat_load(a, i)
    return ld1


@overload(st1, jit_options=INLINE_OPTIONS)
def _st1(o, i, v):
    if _flat_ok(o):
        return lambda o, i, v: flat_store(o, i, v)
    return st1


@overload(ld4flat, jit_options=INLINE_OPTIONS)
def _ld4flat(a, i):
    if _flat_ok(a):
        # "+ 0" keeps LLVM from folding a select of two loaded values into a
        # load through a selected pointer, which the vectoriser cannot bound
        ftype = np.dtype(str(a.dtype)).type  # not like(a, ·): a call with an array stops the vectoriser

        def impl(a, i):
            z = ftype(0.0)
            j = 4 * i
            return (flat_load(a, j) + z, flat_load(a, j + 1) + z, flat_load(a, j + 2) + z, flat_load(a, j + 3) + z)

        return impl
    return ld4flat


@overload(st4flat, jit_options=INLINE_OPTIONS)
def _st4flat(o, i, q):
    if _flat_ok(o):

        def impl(o, i, q):
            j = 4 * i
            flat_store(o, j, q[0])
            flat_store(o, j + 1, q[1])
            flat_store(o, j + 2, q[2])
            flat_store(o, j + 3, q[3])

        return impl
    return st4flat


# The same accessors inlined at numba's typed-IR level, for loops that LLVM does
# not vectorise through the LLVM-inlined ones (the Bézier controls: 10 packed
# instructions instead of 761). Typed-IR inlining costs compile time per call
# site, so only there.
def ld1_ir(a, i):
    return ld1(a, i)


def ld4flat_ir(a, i):
    return ld4flat(a, i)


def st4flat_ir(o, i, q):
    st4flat(o, i, q)


for _stub, _impl in ((ld1_ir, _ld1), (ld4flat_ir, _ld4flat), (st4flat_ir, _st4flat)):
    overload(_stub, inline="always", jit_options={"cache": CACHE})(_impl)


# --------------------------------------------------------------------------
# batched loops. Quaternion outputs are flat (4n,) views (see `_flat`).


@rowloop(rows=2)
def _slerp(p, q, t, shortest, out):
    n = t.shape[0]
    for blk in prange((n + ROWS - 1) // ROWS):
        lo = max(blk * ROWS, 0)  # provably >= 0: no negative-index wraparound, so LLVM vectorises
        for k in range(min(n - lo, ROWS)):
            i = lo + k
            ti = ld1(t, i)
            st4flat(out, i, slerp4(ld4flat(p, i), ld4flat(q, i), ti, shortest))


@rowloop(rows=2)
def _nlerp(p, q, t, shortest, out):
    n = t.shape[0]
    for blk in prange((n + ROWS - 1) // ROWS):
        lo = max(blk * ROWS, 0)  # provably >= 0: no negative-index wraparound, so LLVM vectorises
        for k in range(min(n - lo, ROWS)):
            i = lo + k
            ti = ld1(t, i)
            pi = ld4flat(p, i)
            qi = ld4flat(q, i)
            d = pi[0] * qi[0] + pi[1] * qi[1] + pi[2] * qi[2] + pi[3] * qi[3]
            s = like(ti, 1.0) - ti
            # −t when q is flipped into p's hemisphere; 0 or 2 from the boolean (no select)
            ts = ti - like(ti, 2.0) * (d * shortest < like(ti, 0.0)) * ti
            r = (s * pi[0] + ts * qi[0], s * pi[1] + ts * qi[1], s * pi[2] + ts * qi[2], s * pi[3] + ts * qi[3])
            nr = np.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3])
            st4flat(out, i, (r[0] / nr, r[1] / nr, r[2] / nr, r[3] / nr))


@rowloop(rows=2)
def _lerp(p, q, t, out):
    n = t.shape[0]
    for blk in prange((n + ROWS - 1) // ROWS):
        lo = max(blk * ROWS, 0)  # provably >= 0: no negative-index wraparound, so LLVM vectorises
        for k in range(min(n - lo, ROWS)):
            i = lo + k
            ti = ld1(t, i)
            pi = ld4flat(p, i)
            qi = ld4flat(q, i)
            s = like(ti, 1.0) - ti
            st4flat(out, i, (s * pi[0] + ti * qi[0], s * pi[1] + ti * qi[1],
                             s * pi[2] + ti * qi[2], s * pi[3] + ti * qi[3]))


@inline
def double4(p, q):
    """Shoemake's Double: 2(p·q)q − p."""
    d2 = like(p[0], 2.0) * (p[0] * q[0] + p[1] * q[1] + p[2] * q[2] + p[3] * q[3])
    return (d2 * q[0] - p[0], d2 * q[1] - p[1], d2 * q[2] - p[2], d2 * q[3] - p[3])


@inline
def bisect4(p, q):
    """Shoemake's Bisect: (p + q)/|p + q|."""
    s = (p[0] + q[0], p[1] + q[1], p[2] + q[2], p[3] + q[3])
    n = np.sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2] + s[3] * s[3])
    return (s[0] / n, s[1] / n, s[2] / n, s[3] / n)


@rowloop
def _double(p, q, out):
    n = p.shape[0] // 4
    for blk in prange((n + ROWS - 1) // ROWS):
        lo = max(blk * ROWS, 0)  # provably >= 0: no negative-index wraparound, so LLVM vectorises
        for k in range(min(n - lo, ROWS)):
            i = lo + k
            st4flat(out, i, double4(ld4flat(p, i), ld4flat(q, i)))


@rowloop
def _bisect(p, q, out):
    n = p.shape[0] // 4
    for blk in prange((n + ROWS - 1) // ROWS):
        lo = max(blk * ROWS, 0)  # provably >= 0: no negative-index wraparound, so LLVM vectorises
        for k in range(min(n - lo, ROWS)):
            i = lo + k
            st4flat(out, i, bisect4(ld4flat(p, i), ld4flat(q, i)))


@inline
def controls4(qp, qn, qx, f_out, f_in):
    """(a_n, b_n) of key qn between qp and qx: â = bisect(double(qp, qn), qx),
    a₀ = slerp(qn, â, 1/3), a_n = slerp(qn, a₀, f_out), b_n = slerp(qn, double(a₀, qn), f_in)."""
    zero = like(f_out, 0.0)
    a0 = slerp4(qn, bisect4(double4(qp, qn), qx), like(f_out, 1.0) / like(f_out, 3.0), zero)
    return slerp4(qn, a0, f_out, zero), slerp4(qn, double4(a0, qn), f_in, zero)


@rowloop(rows=1)
def _bezier_controls(q, f_out, f_in, a, b):
    """Controls of all K keys (flat (4K,) arrays), one pass. The end keys take the
    phantom keys q_{−1} = double(q_1, q_0) and q_K = double(q_{K−2}, q_{K−1}), for
    which :func:`controls4` gives a_0 = slerp(q_0, q_1, 1/3) and b_{K−1} =
    slerp(q_{K−1}, q_{K−2}, 1/3) (to rounding)."""
    k = f_out.shape[0]
    q0 = ld4flat_ir(q, 0)
    q1 = ld4flat_ir(q, 1)
    ends = controls4(double4(q1, q0), q0, q1, ld1_ir(f_out, 0), ld1_ir(f_in, 0))
    st4flat_ir(a, 0, ends[0])
    st4flat_ir(b, 0, ends[1])
    qm = ld4flat_ir(q, k - 2)
    ql = ld4flat_ir(q, k - 1)
    ends = controls4(qm, ql, double4(qm, ql), ld1_ir(f_out, k - 1), ld1_ir(f_in, k - 1))
    st4flat_ir(a, k - 1, ends[0])
    st4flat_ir(b, k - 1, ends[1])
    n = k - 2  # the interior keys 1 … K−2
    for blk in prange((n + ROWS - 1) // ROWS):
        lo = max(blk * ROWS, 0)  # provably >= 0: no negative-index wraparound, so LLVM vectorises
        for j in range(min(n - lo, ROWS)):
            i = lo + j + 1
            r = controls4(ld4flat_ir(q, i - 1), ld4flat_ir(q, i), ld4flat_ir(q, i + 1), ld1_ir(f_out, i), ld1_ir(f_in, i))
            st4flat_ir(a, i, r[0])
            st4flat_ir(b, i, r[1])


@rowloop(rows=4)
def _bezier(q0, a, b, q1, t, out):
    n = t.shape[0]
    for blk in prange((n + ROWS - 1) // ROWS):
        lo = max(blk * ROWS, 0)  # provably >= 0: no negative-index wraparound, so LLVM vectorises
        for k in range(min(n - lo, ROWS)):
            i = lo + k
            st4flat(out, i, bezier4(ld4flat(q0, i), ld4flat(a, i), ld4flat(b, i), ld4flat(q1, i), ld1(t, i)))


@rowloop(rows=4)
def _squad(q0, s0, s1, q1, t, out):
    n = t.shape[0]
    for blk in prange((n + ROWS - 1) // ROWS):
        lo = max(blk * ROWS, 0)  # provably >= 0: no negative-index wraparound, so LLVM vectorises
        for k in range(min(n - lo, ROWS)):
            i = lo + k
            st4flat(out, i, squad4(ld4flat(q0, i), ld4flat(s0, i), ld4flat(s1, i), ld4flat(q1, i), ld1(t, i)))


@kernel
def _unflip(q, out):
    # q, out: (K, M, 4); the sign scan runs along axis 0 for each of the M columns.
    for m in range(q.shape[1]):
        prev = (q[0, m, 0], q[0, m, 1], q[0, m, 2], q[0, m, 3])
        out[0, m, 0], out[0, m, 1], out[0, m, 2], out[0, m, 3] = prev
        for k in range(1, q.shape[0]):
            cur = (q[k, m, 0], q[k, m, 1], q[k, m, 2], q[k, m, 3])
            if E.qdot(cur, prev) < like(q, 0.0):
                cur = E.qneg(cur)
            out[k, m, 0], out[k, m, 1], out[k, m, 2], out[k, m, 3] = cur
            prev = cur


@kernel
def _sign_summary(q, rows, ends, negated, unit, dots):
    """What a blocked sign scan needs of one block of raw keys, seen as :func:`spline`
    sees them (normalised, then unflipped from the block's first row), without
    writing the block: ``ends`` = its first and last rows, ``negated[j]`` whether
    row ``rows[j]`` (ascending) was negated. Returns how many leading rows a sign
    carried into the block reaches: up to the first row whose dot product with the
    row before is 0 or nan (that row is kept as it is whatever came before).

    A negated row only negates its dot products with its neighbours (exactly), so
    the rows are normalised into `unit` and their dot products found into `dots`,
    ``len(dots)`` at a time (loops free of the sign chain, which LLVM vectorises;
    ``len(unit) == len(dots) + 1``), then the chain runs over their signs."""
    zero = like(ends, 0.0)
    n = q.shape[0]
    E.store4(unit, 0, E.qnormalize(E.load4(q, 0)))
    E.store4(ends, 0, E.load4(unit, 0))
    reach = n
    neg = False  # whether the row before is negated
    j = 0
    while j < rows.shape[0] and rows[j] == 0:
        negated[j] = False
        j += 1
    for base in range(1, n, dots.shape[0]):
        m = min(dots.shape[0], n - base)
        for k in range(m):
            E.store4(unit, k + 1, E.qnormalize(E.load4(q, base + k)))
        for k in range(m):
            dots[k] = E.qdot(E.load4(unit, k + 1), E.load4(unit, k))
        for k in range(m):
            d = -dots[k] if neg else dots[k]  # as _unflip: the dot product with the row before as it stands
            if reach == n and not (d < zero or d > zero):
                reach = base + k
            neg = d < zero
            while j < rows.shape[0] and rows[j] == base + k:
                negated[j] = neg
                j += 1
        E.store4(unit, 0, E.load4(unit, m))
    E.store4(ends, 1, E.qneg(E.load4(unit, 0)) if neg else E.load4(unit, 0))
    return reach


# ---- spline: per-segment tables, segment search, batched evaluation ----


@inline
def put(seg, n, c, q):
    """Table row n, columns c … c + 3: the quaternion q."""
    seg[n, c], seg[n, c + 1], seg[n, c + 2], seg[n, c + 3] = q


@inline
def put_arc(seg, n, c, p, q):
    """Table row n, columns c … c + 4: (θ, v) of the fixed arc from p to q (:func:`arc`)."""
    th, v, sgn = arc(p, q, like(p[0], 0.0))
    seg[n, c] = th
    put(seg, n, c + 1, v)


KIND = 1  # rebound in each method's copy of _segments (see _SEGMENTS)


def _segments(q, c_out, c_in, seg):
    """Row n of a spline's segment table, written once: q_n, c_out[n], c_in[n+1],
    q_{n+1}, then the fixed arcs its evaluation loop needs (see the table's layout
    below): ``KIND`` 1 (Bézier) q_n → c_out[n] → c_in[n+1] → q_{n+1}; 2 (squad)
    q_n → q_{n+1} and c_out[n] → c_in[n+1]; 0 (slerp) q_n → q_{n+1}; 3 (nlerp) none.
    ``KIND`` is a constant of each method's compiled copy, so each compiles only
    the arcs it writes."""
    for n in prange(seg.shape[0]):
        p = ld4(q, n)
        r = ld4(q, n + 1)
        a = ld4(c_out, n)
        b = ld4(c_in, n + 1)
        put(seg, n, 0, p)
        put(seg, n, 4, a)
        put(seg, n, 8, b)
        put(seg, n, 12, r)
        if KIND == 1:
            put_arc(seg, n, 16, p, a)
            put_arc(seg, n, 21, a, b)
            put_arc(seg, n, 26, b, r)
        if KIND == 2:
            put_arc(seg, n, 16, p, r)
            put_arc(seg, n, 21, a, b)
        if KIND == 0:
            put_arc(seg, n, 16, p, r)


@inline
def arc_slerp(p, q, c, t):
    """slerp(p, q, t) = p cos tθ + v sin tθ on a fixed arc, c = (θ, v) from :func:`put_arc`."""
    th, v0, v1, v2, v3 = c
    s, co = sincos(t * th)
    r = (co * p[0] + s * v0, co * p[1] + s * v1, co * p[2] + s * v2, co * p[3] + s * v3)
    if t == like(t, 1.0):  # exact end (t = 0 is exact already: sincos(0) = (0, 1))
        r = q
    return r


@inline
def next_run(times, new_t, j, hi, n):
    """(segment, end) of the run of samples j, j+1, ..., end−1 (< hi) in one segment.

    Segment n of a time t: times[n] ≤ t < times[n+1], or n = K−2 up to and
    including times[K−1]. Binary search, started by an exponential search
    from the previous segment `n`, so sorted samples cost O(1) each and any
    order O(log K); the run then extends while the samples stay in the segment.
    """
    k = times.shape[0]
    t = new_t[j]
    lo = n if times[n] <= t else 0  # invariant: times[lo] <= t
    step = 1
    hi_s = lo + 1
    while hi_s < k - 1 and times[hi_s] <= t:
        lo = hi_s
        step *= 2
        hi_s = lo + step
    if hi_s > k - 1:
        hi_s = k - 1
    while hi_s - lo > 1:  # invariant: times[lo] <= t, hi_s == k-1 or times[hi_s] > t
        mid = (lo + hi_s) >> 1
        if times[mid] <= t:
            lo = mid
        else:
            hi_s = mid
    t0 = times[lo]
    t1 = times[lo + 1]
    last = lo == k - 2
    e = j + 1
    while e < hi and new_t[e] >= t0 and (new_t[e] < t1 or last):
        e += 1
    return lo, e


@inline
def seg_arc(seg, n, c):
    return seg[n + c], seg[n + c + 1], seg[n + c + 2], seg[n + c + 3], seg[n + c + 4]


@inline
def seg_q(seg, n, c):
    return seg[n + c], seg[n + c + 1], seg[n + c + 2], seg[n + c + 3]


@inline
def seg_keys(seg, n):
    """The four quaternions of a table row: q_n, its two controls, q_{n+1}."""
    return seg_q(seg, n, 0), seg_q(seg, n, 4), seg_q(seg, n, 8), seg_q(seg, n, 12)


# Segment table columns: 0-3 q_n, 4-7 first control, 8-11 second control,
# 12-15 q_{n+1}, then (θ, v) of up to three fixed arcs (`put_arc`) at 16, 21, 26
# (written by `_segments`, one copy per method in `_SEGMENTS`).
#
# The evaluation loops go segment by segment: for each run of samples in one
# segment (the whole run when new times are sorted, single samples when not)
# the segment's values are read once into scalars and the inner loop over the
# run's samples -- loads of u, polynomial trig, flat stores -- runs as SIMD.


@rowloop(rows=1)
def _eval_slerp(times, new_t, seg, out):
    m = new_t.shape[0]
    x0 = like(seg, 0.0)  # a scalar of the output type (like() on an array inside the loop stops the vectoriser)
    for blk in prange((m + BLOCK - 1) // BLOCK):
        j = blk * BLOCK
        hi = min(m, j + BLOCK)
        sg = 0
        while j < hi:
            sg, e = next_run(times, new_t, j, hi, sg)
            t0 = times[sg]
            h = times[sg + 1] - t0
            n = NSEG * sg
            p = seg_q(seg, n, 0)
            q = seg_q(seg, n, 12)
            c = seg_arc(seg, n, 16)
            for i in range(j, e):
                st4flat(out, i, arc_slerp(p, q, c, like(x0, (ld1(new_t, i) - t0) / h)))
            j = e


@rowloop(rows=1)
def _eval_nlerp(times, new_t, seg, out):
    m = new_t.shape[0]
    x0 = like(seg, 0.0)  # a scalar of the output type (like() on an array inside the loop stops the vectoriser)
    for blk in prange((m + BLOCK - 1) // BLOCK):
        j = blk * BLOCK
        hi = min(m, j + BLOCK)
        sg = 0
        while j < hi:
            sg, e = next_run(times, new_t, j, hi, sg)
            t0 = times[sg]
            h = times[sg + 1] - t0
            n = NSEG * sg
            p = seg_q(seg, n, 0)
            q = seg_q(seg, n, 12)
            for i in range(j, e):
                t = like(x0, (ld1(new_t, i) - t0) / h)
                s = like(t, 1.0) - t
                r = (s * p[0] + t * q[0], s * p[1] + t * q[1], s * p[2] + t * q[2], s * p[3] + t * q[3])
                nr = np.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3])
                st4flat(out, i, (r[0] / nr, r[1] / nr, r[2] / nr, r[3] / nr))
            j = e


@inline
def bezier_seg(q0, a, b, q1, c0, c1, c2, t):
    """Segment value at u = t: the level-1 slerps on the three fixed control arcs, then two levels of slerp."""
    p01 = arc_slerp(q0, a, c0, t)
    p12 = arc_slerp(a, b, c1, t)
    p23 = arc_slerp(b, q1, c2, t)
    zero = like(t, 0.0)
    p012 = slerp4(p01, p12, t, zero)
    p123 = slerp4(p12, p23, t, zero)
    return slerp4(p012, p123, t, zero)


@inline
def tile_q(tile, c, lane):
    return (ld1(tile, c * TILE + lane), ld1(tile, (c + 1) * TILE + lane),
            ld1(tile, (c + 2) * TILE + lane), ld1(tile, (c + 3) * TILE + lane))


@inline
def tile_arc(tile, c, lane):
    return (ld1(tile, c * TILE + lane), ld1(tile, (c + 1) * TILE + lane), ld1(tile, (c + 2) * TILE + lane),
            ld1(tile, (c + 3) * TILE + lane), ld1(tile, (c + 4) * TILE + lane))


@kernel
def bezier_tile(tile, u, res, rows, count, out):
    """Evaluate the `count` samples waiting in a tile (SIMD over its lanes, into `res`
    column by column), then store them in their rows of `out`."""
    for lane in range(count):
        r = bezier_seg(tile_q(tile, 0, lane), tile_q(tile, 4, lane), tile_q(tile, 8, lane), tile_q(tile, 12, lane),
                       tile_arc(tile, 16, lane), tile_arc(tile, 21, lane), tile_arc(tile, 26, lane), ld1(u, lane))
        st1(res, lane, r[0])
        st1(res, TILE + lane, r[1])
        st1(res, 2 * TILE + lane, r[2])
        st1(res, 3 * TILE + lane, r[3])
    for lane in range(count):
        for c in range(4):
            out[4 * rows[lane] + c] = res[c * TILE + lane]


@rowloop(rows=1)
def _eval_bezier(times, new_t, seg, out):
    m = new_t.shape[0]
    x0 = like(seg, 0.0)  # a scalar of the output type (like() on an array inside the loop stops the vectoriser)
    for blk in prange((m + BLOCK - 1) // BLOCK):
        j = blk * BLOCK
        hi = min(m, j + BLOCK)
        sg = 0
        # samples wait in a tile: their segments' rows column by column, u, and the sample
        tile = np.empty(NSEG * TILE, seg.dtype)
        u = np.empty(TILE, seg.dtype)
        res = np.empty(4 * TILE, seg.dtype)
        rows = np.empty(TILE, np.int64)
        count = np.int64(0)  # not the literal 0: bezier_tile would compile for it too
        while j < hi:
            sg, e = next_run(times, new_t, j, hi, sg)
            t0 = times[sg]
            h = times[sg + 1] - t0
            n = NSEG * sg
            for i in range(j, e):
                for c in range(NSEG):
                    tile[c * TILE + count] = seg[n + c]
                u[count] = like(x0, (new_t[i] - t0) / h)
                rows[count] = i
                count += 1
                if count == TILE:
                    bezier_tile(tile, u, res, rows, count, out)
                    count = np.int64(0)
            j = e
        bezier_tile(tile, u, res, rows, count, out)


@rowloop(rows=1)
def _eval_squad(times, new_t, seg, out):
    m = new_t.shape[0]
    x0 = like(seg, 0.0)  # a scalar of the output type (like() on an array inside the loop stops the vectoriser)
    for blk in prange((m + BLOCK - 1) // BLOCK):
        j = blk * BLOCK
        hi = min(m, j + BLOCK)
        sg = 0
        while j < hi:
            sg, e = next_run(times, new_t, j, hi, sg)
            t0 = times[sg]
            h = times[sg + 1] - t0
            n = NSEG * sg
            q0, s0, s1, q1 = seg_keys(seg, n)
            c0 = seg_arc(seg, n, 16)
            c1 = seg_arc(seg, n, 21)
            for i in range(j, e):
                t = like(x0, (ld1(new_t, i) - t0) / h)
                pq = arc_slerp(q0, q1, c0, t)
                ps = arc_slerp(s0, s1, c1, t)
                st4flat(out, i, slerp4(pq, ps, like(t, 2.0) * t * (like(t, 1.0) - t), like(t, 0.0)))
            j = e


# ---- angular velocity ----


@kernel
def _interval_rates(q, h, body, w):
    """w[k] = rotation vector of the step k → k+1 divided by h[k] (sign-flip safe)."""
    for k in range(q.shape[0] - 1):
        a = E.load4(q, k)
        b = E.load4(q, k + 1)
        d = E.qmul(E.qconj(a), b) if body else E.qmul(b, E.qconj(a))
        if d[0] < like(h, 0.0):
            d = E.qneg(d)
        un = E.vnorm((d[1], d[2], d[3]))
        f = like(h, 2.0) * math.atan2(un, d[0]) / un / h[k] if un > like(h, 0.0) else like(h, 0.0)
        w[k, 0] = f * d[1]
        w[k, 1] = f * d[2]
        w[k, 2] = f * d[3]


# Sorted new times go through the table piece by piece: each piece of PIECE
# samples builds only the rows of the segments it spans (for keys as dense as
# the samples, a table of about 1 MB that stays in cache) and evaluates its
# samples from them; the pieces run in parallel.
PIECE = 4096
_segments_1 = _eval_1 = None  # bound in each method's copy (_PIECES)


@inline
def seg_index(times, t):
    """The segment of time t: the largest n ≤ K − 2 with times[n] ≤ t (0 before times[0])."""
    lo = 0
    hi = times.shape[0] - 1  # invariant: lo == 0 or times[lo] <= t; the answer is below hi
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if times[mid] <= t:
            lo = mid
        else:
            hi = mid
    return lo


def _spline_pieces(times, new_t, q, c_out, c_in, out):
    """:func:`spline`'s table and evaluation for sorted `new_t`, piece by piece.

    `out` flat (4m,); ``_segments_1`` and ``_eval_1`` are the serial table and
    evaluation loops of the method (one compiled copy per method, see
    ``_PIECES``). Samples are assigned to segments as in the whole table (a
    piece's last segment ends before the next piece's first sample, except the
    stream's last segment, which includes times[K−1]).
    """
    m = new_t.shape[0]
    for p in prange((m + PIECE - 1) // PIECE):
        j0 = p * PIECE
        j1 = min(m, j0 + PIECE)
        s0 = seg_index(times, new_t[j0])
        s1 = seg_index(times, new_t[j1 - 1]) + 1
        seg = np.empty((s1 - s0, NSEG), out.dtype)
        _segments_1(q[s0 : s1 + 1], c_out[s0 : s1 + 1], c_in[s0 : s1 + 1], seg)
        _eval_1(times[s0 : s1 + 1], new_t[j0:j1], seg.reshape(-1), out[4 * j0 : 4 * j1])


# --------------------------------------------------------------------------
# front end helpers


def _flat(kern, *extra):
    """Adapt a kernel on flat arrays to `elementwise`'s ``(n,) + core`` views.

    Every input and the output are passed as 1-D C-contiguous arrays
    (quaternions as (4n,)): views where the layout allows, else contiguous
    copies (broadcast or strided inputs). The kernels then index with
    constant strides, which LLVM vectorises. ``extra`` are trailing scalar
    arguments passed before the output.
    """

    def run(*args):
        *ins, out = args
        ins = [np.ascontiguousarray(a).reshape(-1) for a in ins]
        extra_t = [out.dtype.type(x) for x in extra]  # float32 kernels stay float32
        if out.flags.c_contiguous:
            kern(*ins, *extra_t, out.reshape(-1))
        else:
            tmp = np.empty(out.shape, out.dtype)
            kern(*ins, *extra_t, tmp.reshape(-1))
            out[...] = tmp

    return run


def _pqt(p, q, t):
    return [(p, "p", Q), (q, "q", Q), (t, "t", ())]


# --------------------------------------------------------------------------
# public functions


def lerp(p, q, t, out=None):
    """Linear blend (1 − t) p + t q, without normalising.

    Parameters
    ----------
    p, q : array_like, shape (..., 4)
        Quaternions (w, x, y, z).
    t : array_like, shape (...)
        Parameter; `p`, `q` and `t` broadcast together.
    out : ndarray, optional

    Returns
    -------
    ndarray, shape (..., 4)

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.lerp([1, 0, 0, 0], [0, 1, 0, 0], 0.25)
    array([0.75, 0.25, 0.  , 0.  ])
    """
    return elementwise(_flat(_lerp), _pqt(p, q, t), [Q], out)


def nlerp(p, q, t, shortest=True, out=None):
    """Normalised linear blend ((1 − t) p + t q)/|…|.

    With ``shortest=True`` q is first flipped into p's hemisphere (p·q ≥ 0).

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> qa.nlerp([1, 0, 0, 0], [-0.6, 0, 0, -0.8], 0.5)  # -q is nearer: blend with (0.6, 0, 0, 0.8)
    array([0.89442719, 0.        , 0.        , 0.4472136 ])
    """
    return elementwise(_flat(_nlerp, 1.0 if shortest else 0.0), _pqt(p, q, t), [Q], out)


def slerp(p, q, t, shortest=True, out=None):
    """Spherical linear interpolation (great-arc, constant speed) of unit quaternions.

    slerp(p, q, t) = [sin((1 − t)θ) p + sin(tθ) q] / sin θ with
    θ = 2·atan2(|p − q|, |p + q|), the angle between p and q on S³.

    Parameters
    ----------
    p, q : array_like, shape (..., 4)
        Unit quaternions (w, x, y, z); normalise first if they are not.
    t : array_like, shape (...)
        Parameter; `p`, `q` and `t` broadcast (N pairs with N values, one pair
        with M values → ``(M, 4)``, ...). t = 0 gives `p` and t = 1 gives `q`
        exactly; t outside [0, 1] extrapolates along the same great arc.
    shortest : bool, default True
        Flip `q` into `p`'s hemisphere first (q and −q are the same rotation;
        the flipped one gives the shorter rotation path). Then t = 1 gives −q.
    out : ndarray, optional
        Result array of the broadcast shape and result dtype; may be an input.

    Returns
    -------
    ndarray, shape (..., 4)

    Notes
    -----
    Stable for identical, nearly identical and (with ``shortest=True``)
    antipodal inputs; about one ulp from the exact result in float64. Exactly
    antipodal p = −q with ``shortest=False`` has no unique arc and follows
    p ⊗ (cos tπ, sin tπ, 0, 0).

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> p = [1, 0, 0, 0]
    >>> q = qa.from_rotvec([0, 0, np.pi / 2])
    >>> np.allclose(qa.slerp(p, q, 0.5), qa.from_rotvec([0, 0, np.pi / 4]))
    True
    >>> qa.slerp(p, q, [0.0, 0.5, 1.0]).shape
    (3, 4)
    """
    return elementwise(_flat(_slerp, 1.0 if shortest else 0.0), _pqt(p, q, t), [Q], out)


def double(p, q, out=None):
    """Shoemake's Double(p, q) = 2(p·q) q − p: p reflected through q.

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.double([1, 0, 0, 0], [0.6, 0.8, 0, 0])
    array([-0.28,  0.96,  0.  ,  0.  ])
    """
    return elementwise(_flat(_double), [(p, "p", Q), (q, "q", Q)], [Q], out)


def bisect(p, q, out=None):
    """Shoemake's Bisect(p, q) = (p + q)/|p + q|: the great-arc midpoint.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> np.round(qa.bisect([1, 0, 0, 0], [0, 1, 0, 0]), 6)
    array([0.707107, 0.707107, 0.      , 0.      ])
    """
    return elementwise(_flat(_bisect), [(p, "p", Q), (q, "q", Q)], [Q], out)


def _keys(keys, name="keys", k_min=2):
    a = check_core(as_float(keys, name), name, Q)
    if a.ndim != 2:
        raise shape_error(name, "(K, 4)", a.shape)
    if a.shape[0] < k_min:
        raise ValueError(f"Expected `{name}` to hold at least {k_min} keys, got {a.shape[0]}.")
    return a


def _tangent_scales(h):
    """Outgoing/incoming tangent factors 2hₙ/(hₙ₋₁+hₙ), 2hₙ₋₁/(hₙ₋₁+hₙ); 1 at the ends.

    Factors within 1e-12 of 1 (evenly spaced times up to rounding) are set to
    exactly 1, so even spacing reproduces :func:`bezier_controls` bit for bit.
    """
    k = h.shape[0] + 1
    f_out = np.ones(k)
    f_in = np.ones(k)
    if k > 2:
        s = h[:-1] + h[1:]
        f_out[1:-1] = 2 * h[1:] / s
        f_in[1:-1] = 2 * h[:-1] / s
        for f in (f_out, f_in):
            f[np.abs(f - 1) <= 1e-12] = 1.0
    return f_out, f_in


def bezier_controls(keys, times=None):
    """Control points (a, b) of Shoemake's spherical Bézier spline through `keys`.

    Segment n of the curve is ``bezier(keys[n], a[n], b[n+1], keys[n+1], u)``.
    Interior keys: â_n = bisect(double(q_{n−1}, q_n), q_{n+1}),
    a_n = slerp(q_n, â_n, 1/3), b_n = double(a_n, q_n). The ends use phantom
    keys q_{−1} = double(q_1, q_0), q_K = double(q_{K−2}, q_{K−1}), which
    gives a_0 = slerp(q_0, q_1, 1/3) and b_{K−1} = slerp(q_{K−1}, q_{K−2}, 1/3).
    Every slerp is the plain great-arc one; the keys are used as given (call
    :func:`unflip` first, and normalise).

    Parameters
    ----------
    keys : array_like, shape (K, 4), K ≥ 2
    times : array_like, shape (K,), optional
        Key times for uneven spacing. With h_n = t_{n+1} − t_n the outgoing
        arc q_n→a_n is scaled (along its great circle) by 2h_n/(h_{n−1}+h_n)
        and the incoming arc q_n→b_n by 2h_{n−1}/(h_{n−1}+h_n). The Bézier
        tangent at a segment end is three times its control arc per unit u, so
        the angular velocity leaving key n is 6·log(q_n* a_n)/h̄_n on both
        sides, with h̄_n = (h_{n−1}+h_n)/2: continuous in time across keys.
        Evenly spaced times give factors of exactly 1 (the formula above).

    Returns
    -------
    a, b : ndarray, shape (K, 4)

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> keys = qa.from_rotvec([[0, 0, 0], [0, 0, 0.3]])
    >>> a, b = qa.bezier_controls(keys)
    >>> np.allclose(a[0], qa.slerp(keys[0], keys[1], 1 / 3))
    True
    """
    q = _keys(keys)
    k = q.shape[0]
    if times is None:
        f_out = f_in = np.ones(k)
    else:
        t = _times(times, k)
        f_out, f_in = _tangent_scales(np.diff(t))
    a = np.empty(q.shape, q.dtype)
    b = np.empty(q.shape, q.dtype)
    _bezier_controls(np.ascontiguousarray(q).reshape(-1), f_out.astype(q.dtype), f_in.astype(q.dtype),
                     a.reshape(-1), b.reshape(-1))
    return a, b


def bezier(q0, a, b, q1, t, out=None):
    """Spherical cubic Bézier curve by de Casteljau's construction with slerp.

    Three levels, six great-arc slerps (no hemisphere flips):
    level 1 slerp(q0, a, t), slerp(a, b, t), slerp(b, q1, t); level 2 and 3
    slerp the results pairwise. All arguments broadcast like :func:`slerp`.
    t = 0 gives `q0` and t = 1 gives `q1` exactly.

    Parameters
    ----------
    q0, a, b, q1 : array_like, shape (..., 4)
        End keys and control points (see :func:`bezier_controls`).
    t : array_like, shape (...)
    out : ndarray, optional

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> keys = qa.from_rotvec([[0, 0, 0], [0, 0, 0.3]])
    >>> a, b = qa.bezier_controls(keys)
    >>> c = qa.bezier(keys[0], a[0], b[1], keys[1], 0.5)  # two keys: exactly slerp
    >>> np.allclose(c, qa.slerp(keys[0], keys[1], 0.5), rtol=0, atol=1e-15)
    True
    """
    ins = [(q0, "q0", Q), (a, "a", Q), (b, "b", Q), (q1, "q1", Q), (t, "t", ())]
    return elementwise(_flat(_bezier), ins, [Q], out)


def squad_controls(keys):
    """Shoemake's squad inner points s_n = q_n exp(−(log(q_n⁻¹q_{n+1}) + log(q_n⁻¹q_{n−1}))/4).

    The end keys use s = q. Keys are used as given (unit, unflipped).

    Returns
    -------
    ndarray, shape (K, 4)

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> keys = qa.from_rotvec([[0, 0, 0], [0, 0, 0.2], [0, 0, 0.4]])
    >>> np.allclose(qa.interpolation.squad_controls(keys), keys)  # one great circle
    True
    """
    q = _keys(keys)
    s = q.copy()
    if q.shape[0] > 2:
        _squad_inner(np.ascontiguousarray(q), s)
    return s


@rowloop
def _squad_inner(q, s):
    """Rows 1 … K−2 of :func:`squad_controls` (one kernel: no temporaries)."""
    quarter = like(q, -0.25)
    for n in prange(1, q.shape[0] - 1):
        qn = E.load4(q, n)
        inv = E.qconj(qn)
        a = E.qlog(E.qmul(inv, E.load4(q, n + 1)))
        b = E.qlog(E.qmul(inv, E.load4(q, n - 1)))
        E.store4(s, n, E.qmul(qn, E.qexp(((a[0] + b[0]) * quarter, (a[1] + b[1]) * quarter,
                                           (a[2] + b[2]) * quarter, (a[3] + b[3]) * quarter))))


def squad(q0, s0, s1, q1, t, out=None):
    """Shoemake's squad: slerp(slerp(q0, q1, t), slerp(s0, s1, t), 2t(1 − t)).

    Segment n of a key stream is ``squad(q[n], s[n], s[n+1], q[n+1], u)`` with
    `s` from :func:`squad_controls`. Plain great-arc slerps; broadcasting and
    `out` as :func:`slerp`. For comparison with the Bézier scheme.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> q0, q1 = qa.from_rotvec([[0, 0, 0], [0, 0, 0.4]])
    >>> np.allclose(qa.squad(q0, q0, q1, q1, 0.5), qa.slerp(q0, q1, 0.5))
    True
    """
    ins = [(q0, "q0", Q), (s0, "s0", Q), (s1, "s1", Q), (q1, "q1", Q), (t, "t", ())]
    return elementwise(_flat(_squad), ins, [Q], out)


def unflip(q, axis=0):
    """Sign continuity along a stream: q[i] is negated when its dot product with
    q[i−1] (already processed) is negative. Rotations are unchanged.

    `axis` counts the leading (non-quaternion) axes. Returns a new array.

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.unflip([[1, 0, 0, 0], [-1, 0, 0, 0], [-0.8, -0.6, 0, 0]]) + 0.0  # + 0.0: no -0
    array([[1. , 0. , 0. , 0. ],
           [1. , 0. , 0. , 0. ],
           [0.8, 0.6, 0. , 0. ]])
    """
    return scan(_unflip, q, axis, "unflip")


def _times(times, k=None, name="times"):
    t = np.asarray(times)
    _check_times(t, k, name)
    i = _first_not_increasing(t)
    if i is not None:
        raise _not_increasing(name, i, t[i], t[i + 1])
    return t


def _check_times(t, k, name):
    """The dtype and shape rules for key times (a numpy or a Dask array)."""
    if t.dtype.kind not in "biuf":
        raise TypeError(f"Expected `{name}` to have a real dtype, got {t.dtype}.")
    if t.ndim != 1 or (k is not None and t.shape[0] != k):
        raise ValueError(f"Expected `{name}` to have shape ({'K' if k is None else k},), got {tuple(t.shape)}.")


def _first_not_increasing(t):
    """The first i with ``not t[i] < t[i + 1]`` (nan included), or None."""
    bad = ~(t[1:] > t[:-1])
    return int(np.argmax(bad)) if bad.any() else None


def _not_increasing(name, i, before, after):
    return ValueError(
        f"Expected `{name}` to be strictly increasing, got {name}[{i + 1}] = {after.item()} "
        f"after {name}[{i}] = {before.item()}."
    )


@kernel
def _n_outside(lo, hi, x):
    """How many x are not within [lo, hi] (nan included)."""
    c = 0
    for i in range(x.shape[0]):
        c += not (x[i] >= lo and x[i] <= hi)
    return c


_SPLINE = {"bezier": _eval_bezier, "slerp": _eval_slerp, "nlerp": _eval_nlerp, "squad": _eval_squad}
_KINDS = {"bezier": 1, "squad": 2, "slerp": 0, "nlerp": 3}  # the arcs each method's table holds
_SEGMENTS = {m: rowloop(rows=3)(specialise(_segments, f"_{m}", KIND=kind)) for m, kind in _KINDS.items()}
_PIECES = {
    m: rowloop(rows=1)(specialise(_spline_pieces, f"_{m}", _eval_1=ir_inline(specialise(ev.py_func, "_piece")),
                                  _segments_1=ir_inline(specialise(_SEGMENTS[m].py_func, "_piece"))))
    for m, ev in _SPLINE.items()
}


def _seconds(t_raw, nt_raw, origin):
    """Key times and new times as float64 for the segment search: relative to
    `origin` (the first key time) when both are integers (exact for ns stamps
    since the epoch), else as they are. Element by element, so a block of key
    times converts to the same numbers as the whole array."""
    if t_raw.dtype.kind in "biu" and nt_raw.dtype.kind in "biu":
        t = (t_raw - origin).astype(np.float64)
        nt = (nt_raw.astype(np.int64) - np.int64(origin)).astype(np.float64)
    else:
        t = t_raw.astype(np.float64)
        nt = np.asarray(nt_raw, np.float64)
    return t, nt


def _plan_times(t_raw, nt_raw, index0=0, origin=None):
    """:func:`_seconds` of key times and new times (integers taken from `origin`,
    default the first key time), or the ValueError naming the first new time
    outside the keys' span (its flat index counted from `index0`). Only the first
    and last key times are looked at here."""
    if nt_raw.dtype.kind not in "biuf":
        raise TypeError(f"Expected `new_times` to have a real dtype, got {nt_raw.dtype}.")
    t, nt = _seconds(t_raw, nt_raw, t_raw[0] if origin is None else origin)
    flat_nt = np.ascontiguousarray(nt.reshape(-1))
    if _n_outside(t[0], t[-1], flat_nt):
        i = int(np.argmax(~((flat_nt >= t[0]) & (flat_nt <= t[-1]))))
        raise ValueError(
            f"Expected `new_times` within [{t_raw[0].item()}, {t_raw[-1].item()}] (the key times), "
            f"got {nt_raw.reshape(-1)[i].item()} at flat index {index0 + i}."
        )
    return t, nt


def spline(times, keys, new_times, method="bezier"):
    """Resample a timestamped key stream at `new_times`.

    The keys are normalised and unflipped first (real streams are slightly
    non-unit and contain sign flips). Each new time is placed in its segment
    [times[n], times[n+1]] by binary search and evaluated at
    u = (t − times[n])/(times[n+1] − times[n]) in one batched kernel.

    Parameters
    ----------
    times : array_like, shape (K,)
        Strictly increasing key times (floats, or integers such as
        nanosecond stamps: these are taken relative to ``times[0]`` exactly).
    keys : array_like, shape (K, 4), K ≥ 2
    new_times : array_like, any shape
        Within [times[0], times[−1]], in any order.
    method : {"bezier", "slerp", "nlerp", "squad"}
        ``"bezier"``: segment n is ``bezier(q_n, a_n, b_{n+1}, q_{n+1}, u)``
        with the controls of ``bezier_controls(keys, times)``: for evenly
        spaced times exactly the contract's formula; for uneven spacing the
        tangent arcs at key n are scaled by 2h_n/(h_{n−1}+h_n) (outgoing) and
        2h_{n−1}/(h_{n−1}+h_n) (incoming), h_n = t_{n+1} − t_n, so the angular
        velocity is continuous in time across keys. ``"slerp"``, ``"nlerp"``:
        piecewise great arc / normalised chord. ``"squad"``: Shoemake's squad
        with :func:`squad_controls` (no time scaling).

    Returns
    -------
    ndarray, shape ``new_times.shape + (4,)``, dtype of the keys.

    Raises
    ------
    ValueError
        `times` not strictly increasing, shapes that do not match, a new time
        outside the key range (the message names the first one), unknown method.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> keys = qa.from_rotvec([[0, 0, 0], [0, 0, 0.5], [0, 0, 1.0]])
    >>> r = qa.spline([0, 1, 2], keys, [0.0, 0.5, 2.0])
    >>> np.allclose(qa.as_rotvec(r)[:, 2], [0, 0.25, 1.0])
    True
    """
    if method not in _SPLINE:
        raise ValueError(f"Expected `method` to be one of {sorted(_SPLINE)}, got {method!r}.")
    q = _keys(keys)
    t, nt = _plan_times(_times(as_times(times, "times"), q.shape[0]), as_times(new_times, "new_times"))
    return _spline_unit(t, nt, _unit_keys([q]), method)


def _unit_keys(parts, flip0=False):
    """The keys as :func:`spline` interpolates them: the rows of `parts` (float arrays
    of shape (k, 4), one after the other) normalised into one fresh array, the first
    row negated if `flip0`, then unflipped, in one pass into one array: `parts` may
    be the pieces of a window of keys taken across blocks."""
    q = np.empty((sum(len(p) for p in parts), 4), parts[0].dtype)
    a = 0
    for p in parts:
        _unit_unflip(p, q, a, flip0)
        a += len(p)
    return q


@kernel
def _unit_unflip(p, out, a, flip0):
    """Rows a … a + len(p) − 1 of `out`: the rows of `p` normalised (:func:`quatarray.normalize`),
    each negated when its dot product with the row before in `out` is negative (as
    :func:`unflip`); the first row of `out` is negated instead when `flip0`."""
    zero = like(out, 0.0)
    for k in range(p.shape[0]):
        i = a + k
        r = E.qnormalize(E.load4(p, k))
        if i == 0:
            if flip0:
                r = E.qneg(r)
        elif E.qdot(r, E.load4(out, i - 1)) < zero:
            r = E.qneg(r)
        E.store4(out, i, r)


def _spline_unit(t, nt, q, method):
    """:func:`spline` on times `t`, new times `nt` (as :func:`_plan_times` gives them)
    and unit, unflipped keys `q`."""
    k = q.shape[0]
    flat_nt = np.ascontiguousarray(nt.reshape(-1))
    c_out = c_in = q  # slerp, nlerp: no controls (the table's columns 4-11 repeat the keys)
    if method == "bezier":
        c_out, c_in = bezier_controls(q, t)
    elif method == "squad":
        c_out = c_in = squad_controls(q)
    m = flat_nt.shape[0]
    out = np.empty((m, 4), q.dtype)
    if m > 1 and (flat_nt[1:] >= flat_nt[:-1]).all():
        _PIECES[method](t, flat_nt, q, c_out, c_in, out.reshape(-1))
    elif m:
        seg = np.empty((k - 1, NSEG), q.dtype)
        _SEGMENTS[method](q, c_out, c_in, seg)
        _SPLINE[method](t, flat_nt, seg.reshape(-1), out.reshape(-1))
    return out.reshape(nt.shape + Q)


def angular_velocity(q, times, frame="space"):
    """Angular velocity (rad per time unit) of a sampled rotation stream.

    For each step k the rotation vector of q[k+1] q[k]⁻¹ (``"space"``: axes
    of the fixed frame) or q[k]⁻¹ q[k+1] (``"body"``: axes of the moving
    frame), taken on the short side (sign-flip safe), divided by the step
    h_k, is the step's rate w_k. At sample i the result is the second-order
    (numpy ``gradient``) blend (h_i w_{i−1} + h_{i−1} w_i)/(h_{i−1} + h_i);
    the first and last samples take their one step's rate. Constant angular
    velocity is reproduced exactly, whatever the spacing, and
    ``space = rotate(q, body)``.

    Parameters
    ----------
    q : array_like, shape (N, 4), N ≥ 2
        Quaternions (need not be unit; signs may flip).
    times : array_like, shape (N,)
        Strictly increasing sample times.
    frame : {"space", "body"}

    Returns
    -------
    ndarray, shape (N, 3)

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> t = np.array([0.0, 0.1, 0.3])
    >>> q = qa.from_rotvec(np.outer(t, [0, 0, 2.0]))  # 2 rad/s about z
    >>> np.allclose(qa.angular_velocity(q, t), [0, 0, 2.0])
    True
    """
    if frame not in ("space", "body"):
        raise ValueError(f"Expected `frame` to be 'space' or 'body', got {frame!r}.")
    a = _keys(q, "q")
    n = a.shape[0]
    # Steps in the times' own type (exact for int64 ns stamps), then float.
    h = np.diff(_times(as_times(times, "times"), n)).astype(a.dtype)
    w = np.empty((n - 1, 3), a.dtype)
    _interval_rates(a, h, frame == "body", w)
    out = np.empty((n, 3), a.dtype)
    out[0] = w[0]
    out[-1] = w[-1]
    if n > 2:
        h0 = h[:-1, None]
        h1 = h[1:, None]
        out[1:-1] = (h1 * w[:-1] + h0 * w[1:]) / (h0 + h1)
    return out
