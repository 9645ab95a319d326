"""Per-element kernels: one quaternion (a 4-tuple ``(w, x, y, z)``) or one
vector (a 3-tuple) in, a tuple or scalar out.

These are the single definitions of the quaternion formulas; the batched
loops in the public modules call them row by row. They never allocate,
validate or raise, and they keep the float type of their arguments
(constants go through :func:`quatarray._jit.like`).
"""

import math

import numpy as np

from numba import types
from numba.extending import lower_builtin, overload, type_callable

from ._access import (  # noqa: F401  (row access: kernels spell it E.load4 & co.)
    load1, load3, load4, load33, loads, loads_at, prefetch, store1, store3, store4, store33, stores, stores_at,
    stream4, stream_end,
)
from ._jit import (
    CACHE, bit_distance, bits_type, element, exponent_scales, like, lower_bit_distance, prange, prefer_no_gather, select, specialise,
)
from ._trig import atan2


@element
def qmul(p, q):
    """Hamilton product p⊗q: (p_w q_w − p_v·q_v, (p_w q_v + q_w p_v) + p_v × q_v).

    The vector part is summed as two groups, the terms that cancel for q = p*
    (or q = −p*) meeting first: p_w q_v + q_w p_v is then exactly 0, and so is
    every component a·b − b·a of the cross product, so p*⊗p has an exactly
    zero vector part and :func:`quatarray.algebra.distance` of a rotation to
    itself is exactly 0 (as scipy's). Added in the order of the formula as
    written, two of the three components left a rounding error (up to 1e-16).
    Same operations as before, in shorter chains. No fused multiply-adds here
    (:func:`quatarray._jit.fmuladd`): they would break the cancellation.
    """
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (
        pw * qw - px * qx - py * qy - pz * qz,
        (pw * qx + px * qw) + (py * qz - pz * qy),
        (pw * qy + py * qw) + (pz * qx - px * qz),
        (pw * qz + pz * qw) + (px * qy - py * qx),
    )


@element
def qconj(q):
    return (q[0], -q[1], -q[2], -q[3])


@element
def qdot(p, q):
    return p[0] * q[0] + p[1] * q[1] + p[2] * q[2] + p[3] * q[3]


@element
def qscaled(q):
    """(a, c) with q = c·a exactly: a = q·2^(1-E), c = 2^(E-1), 2^E ≤ m < 2^(E+1)
    for m the largest |component| of q (c = 1 when m is 0 or inf).

    The components of a are below 4 in magnitude and the largest is in [2, 4),
    so their squares neither overflow nor underflow, whatever the scale of q:
    every function that squares components works on a (the same rotation).
    The scale is a power of two read from m's exponent bits
    (:func:`quatarray._jit.exponent_scales`): exact, so results are those of
    the unscaled formulas wherever those do not overflow, and cheap (no
    division, branch-free: the row loops stay vectorised). Zero and inf
    quaternions pass through unscaled, to give nan (or inf, or a zero norm) as
    before; nan ones, and those whose largest component is subnormal (below
    2.2e-308 in float64, 1.2e-38 in float32), give nan.
    """
    # max(max(|q0|, |q1|), max(|q2|, |q3|)) as numba's max computes it (b if b > a else
    # a), without its overload to compile in each process (0.02 s of a first call)
    a0, a1, a2, a3 = abs(q[0]), abs(q[1]), abs(q[2]), abs(q[3])
    m01 = select(a1 > a0, a1, a0)
    m23 = select(a3 > a2, a3, a2)
    m = select(m23 > m01, m23, m01)
    r, c = exponent_scales(m)
    zero = like(m, 0.0)
    keep = like(m, 1.0) if (m == zero) | (m == like(m, np.inf)) else like(m, np.nan)
    normal = (c > zero) & (r > zero)  # not for 0, subnormal, inf or nan m
    c = like(m, 0.5) * c if normal else keep
    r = r if normal else keep
    return (q[0] * r, q[1] * r, q[2] * r, q[3] * r), c


@element(how="call")
def qnorm(q):
    """|q| for any scale of q (no overflow or underflow in the squares)."""
    a, c = qscaled(q)
    return c * np.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2] + a[3] * a[3])


# Squared norms for which the formulas on q itself (unscaled) are exact to
# rounding: no square or product of components overflows or underflows to a
# loss (|q| between about 5e-76 and 2e75 in float64, 1e-9 and 1e9 in float32).
# Batched loops compute the plain formulas and `far_scale` of |q|²; the rare
# rows outside (and zero, inf, nan ones) are redone on ``qscaled(q)`` in a
# second pass, so the common case costs what it did before scaling existed
# (the loops: :class:`FarRows`).
NEAR_64 = (2.0**-500, 2.0**500)
NEAR_32 = (2.0**-60, 2.0**60)


def far_scale(n2):
    """``int32`` 1 when the squared norm `n2` is outside the range where the
    unscaled formulas are exact (or is 0, inf, nan), else 0. (An int32, so a
    ``max`` reduction of it keeps float32 loops vectorised.)"""
    lo, hi = NEAR_32 if isinstance(n2, np.float32) else NEAR_64
    return np.int32(0) if (n2 >= lo) & (n2 <= hi) else np.int32(1)


def far_excess(n2):
    """An unsigned integer (of the width of `n2`) above the limit of :func:`far_any`
    exactly when :func:`far_scale` of `n2` is 1: ``bit_distance(n2, lo)``, lo the
    bottom of the range (below it, and for a negative nan, it wraps to values above
    the limit). Its ``max`` over a loop's rows says whether a row was far, at two
    integer SIMD instructions per vector of rows: less than ``far_scale``'s
    compares, conversion and stored flag (the flag blocks of :class:`FarRows`).
    The loop starts its ``max`` at :func:`far_start`."""
    return bit_distance(n2, _limits(32 if isinstance(n2, np.float32) else 64)[0])


def far_start(a):
    """:func:`far_excess` of 1 in the float type of the array `a`: where a loop's
    ``max`` of far_excess values starts (a near value of the right type)."""
    return _limits(8 * a.dtype.itemsize)[1]


def far_any(m):
    """Whether `m`, a ``max`` of :func:`far_excess` values, is one of a far row."""
    return bool(m > _limits(32 if isinstance(m, np.uint32) else 64)[2])


def _limits(bits):
    """(lo, start, limit) of far_excess, far_start and far_any for floats of `bits` bits."""
    t = np.float32 if bits == 32 else np.float64
    lo, hi = (t(x) for x in (NEAR_32 if bits == 32 else NEAR_64))
    return lo, bit_distance(t(1.0), lo), bit_distance(hi, lo)


# far_excess, far_start and far_any are builtins (typed and lowered in place, as
# ``_jit.like``): as overloads each was a numba compile per type in every process.
@type_callable(far_excess)
def _type_far_excess(context):
    return lambda n2: bits_type(n2) if isinstance(n2, types.Float) else None


@lower_builtin(far_excess, types.Float)
def _lower_far_excess(context, builder, sig, args):
    t = sig.args[0]
    return lower_bit_distance(builder, args[0], context.get_constant(t, _limits(t.bitwidth)[0]), t.bitwidth)


@type_callable(far_start)
def _type_far_start(context):
    def typer(a):
        if isinstance(a, types.Array) and isinstance(a.dtype, types.Float):
            return bits_type(a.dtype)

    return typer


@lower_builtin(far_start, types.Array)
def _lower_far_start(context, builder, sig, args):
    return context.get_constant(sig.return_type, int(_limits(sig.args[0].dtype.bitwidth)[1]))


@type_callable(far_any)
def _type_far_any(context):
    return lambda m: types.boolean if isinstance(m, types.Integer) and not m.signed else None


@lower_builtin(far_any, types.Integer)
def _lower_far_any(context, builder, sig, args):
    limit = context.get_constant(sig.args[0], int(_limits(sig.args[0].bitwidth)[2]))
    return builder.icmp_unsigned(">", args[0], limit)


def _redo(i, args):
    # the scaled pass of redo(): each copy rebinds _STORE and _FORMULA
    a = load4(args[0], i)
    if far_scale(qdot(a, a)):
        _STORE(args[-1], i, _FORMULA(a))


def redo(store, formula, name):
    """The ``scaled`` function of a :class:`FarRows` kernel whose first argument
    is the quaternions q, whose last is the output, and whose far rows are
    those of |q|²: ``store(out, i, formula(q_i))`` on those rows (`formula`
    being the any-scale one, e.g. :func:`qinverse`)."""
    return element(specialise(_redo, "_" + name, home=formula, _STORE=store, _FORMULA=formula))


@overload(far_scale, jit_options={"cache": CACHE})
def _far_scale(n2):
    if isinstance(n2, types.Float):
        ftype = np.float32 if n2.bitwidth == 32 else np.float64
        lo, hi = (ftype(x) for x in (NEAR_32 if n2.bitwidth == 32 else NEAR_64))
        return lambda n2: np.int32(0) if (n2 >= lo) & (n2 <= hi) else np.int32(1)


@element
def pick4(c, a, b):
    """a if c else b for 4-tuples, as one select per component (both already
    computed), which keeps row loops vectorisable where a tuple-valued ``if``
    would not be."""
    return select(c, a[:4], b[:4])


@element
def pick3(c, a, b):
    """:func:`pick4` for 3-tuples."""
    return select(c, a[:3], b[:3])


@element
def qscale(q, s):
    return (q[0] * s, q[1] * s, q[2] * s, q[3] * s)


@element
def qneg(q):
    return (-q[0], -q[1], -q[2], -q[3])


@element
def canonical_flip(q):
    """True when scipy's canonical form (w > 0, ties to the first non-zero of
    x, y, z being positive) needs the sign of q flipped. (Bitwise operators,
    not ``and``/``or``: no branches, so row loops stay vectorisable.)"""
    w, x, y, z = q
    zero = like(w, 0.0)
    return (w < zero) | ((w == zero) & ((x < zero) | ((x == zero) & ((y < zero) | ((y == zero) & (z < zero))))))


@element(how="call")
def qnormalize(q):
    """q / |q| for any non-zero scale of q; zero, inf and nan give nan."""
    a = qscaled(q)[0]
    n = np.sqrt(qdot(a, a))
    return (a[0] / n, a[1] / n, a[2] / n, a[3] / n)


@element(how="call")
def qinverse(q):
    """q* / |q|² for any non-zero scale of q (inf where 1/|q| overflows); zero gives nan."""
    a, c = qscaled(q)
    k = like(c, 1.0) / qdot(a, a) / c  # 1/|q|² = 1/(c²|a|²), a's factor 1/c left in k
    return (a[0] * k, -a[1] * k, -a[2] * k, -a[3] * k)


@element
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@element
def vdot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@element
def vnorm(v):
    return np.sqrt(vdot(v, v))


@element
def vadd(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@element
def vsub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@element
def vscale(a, k):
    return (a[0] * k, a[1] * k, a[2] * k)


@element(how="call")
def qrotate(q, v):
    """Vector part of q (0, v) q⁻¹, for any non-zero q (|q| need not be 1).

    With u the vector part and t = u × v: v + (2/|q|²)(w t + u × t), on q
    scaled by its largest component (:func:`qscaled`), so any scale works.
    """
    a = qscaled(q)[0]
    return qrotate_raw(a, v, qdot(a, a))


@element
def qrotate_raw(q, v, n2):
    """:func:`qrotate` on q as it is, given n2 = |q|² (no scaling: see :func:`far_scale`)."""
    w = q[0]
    u = (q[1], q[2], q[3])
    k = like(w, 2.0) / n2
    t = cross(u, v)
    s = cross(u, t)
    return (
        v[0] + k * (w * t[0] + s[0]),
        v[1] + k * (w * t[1] + s[1]),
        v[2] + k * (w * t[2] + s[2]),
    )


@element(how="call")
def qmatrix(q):
    """Row-major 3×3 rotation matrix of q/|q| (9-tuple), for any non-zero scale
    of q (:func:`qscaled`); zero q gives nan."""
    a = qscaled(q)[0]
    return qmatrix_raw(a, qdot(a, a))


@element
def qmatrix_raw(q, n2):
    """:func:`qmatrix` on q as it is, given n2 = |q|² (no scaling: see :func:`far_scale`)."""
    w, x, y, z = q
    s = like(w, 2.0) / n2
    one = like(w, 1.0)
    xx, yy, zz = s * x * x, s * y * y, s * z * z
    xy, xz, yz = s * x * y, s * x * z, s * y * z
    wx, wy, wz = s * w * x, s * w * y, s * w * z
    return (
        one - yy - zz, xy - wz, xz + wy,
        xy + wz, one - xx - zz, yz - wx,
        xz - wy, yz + wx, one - xx - yy,
    )  # fmt: skip


@element
def half_angle(q):
    """atan2(|u|, |w|): half the rotation angle in [0, π/2] of a quaternion whose
    components may be squared (scale it with :func:`qscaled` first); nan for the
    zero quaternion. Branch-free (``_trig.atan2`` and selects), so the loops using
    it vectorise."""
    un = vnorm((q[1], q[2], q[3]))
    aw = abs(q[0])
    h = atan2(un, aw)
    return like(aw, np.nan) if un + aw == like(aw, 0.0) else h


@element
def half_angle_raw(q):
    """:func:`half_angle` without the zero-quaternion select (0 for it): for the
    first pass of the batched loops, where a zero q is a :func:`far_scale` row
    that the second pass redoes."""
    return atan2(vnorm((q[1], q[2], q[3])), abs(q[0]))


@element(how="call")
def sinc(x):
    """sin(x)/x, exact to rounding also for tiny x."""
    if abs(x) < like(x, 1e-4):
        x2 = x * x
        return like(x, 1.0) - x2 / like(x, 6.0) + x2 * x2 / like(x, 120.0)
    return np.sin(x) / x


@element(how="call")
def qexp(q):
    """exp(w + u) = e^w (cos|u|, sin|u| u/|u|)."""
    th = vnorm((q[1], q[2], q[3]))
    e = np.exp(q[0])
    s = e * sinc(th)
    return (e * np.cos(th), s * q[1], s * q[2], s * q[3])


@element(how="call")
def qlog(q):
    """Principal logarithm: (log|q|, θ u/|u|) with θ = atan2(|u|, w) in [0, π].

    A negative real q has no unique axis; x is used, (log|w|, π, 0, 0). Any
    scale of q: log|q| = log c + log|q/c| (:func:`qscaled`) where c·|q/c|
    would leave the normal float range.
    """
    q, c = qscaled(q)
    n = np.sqrt(qdot(q, q))
    cn = c * n
    if (cn > like(cn, 1e-37)) & (cn < like(cn, 1e37)):
        lw = np.log(cn)
    else:
        lw = np.log(c) + np.log(n)
    return log_vector(q, lw)


@element(how="call")
def qlog_raw(q):
    """:func:`qlog` on q as it is (no scaling: see :func:`far_scale`)."""
    return log_vector(q, np.log(np.sqrt(qdot(q, q))))


@element
def log_vector(q, lw):
    """(lw, θ u/|u|), θ = atan2(|u|, w): the logarithm of q given lw = log|q|."""
    un = vnorm((q[1], q[2], q[3]))
    zero = like(un, 0.0)
    if un == zero:
        if q[0] < zero:
            return (lw, like(un, math.pi), zero, zero)
        return (lw, zero, zero, zero)
    f = np.arctan2(un, q[0]) / un
    return (lw, f * q[1], f * q[2], f * q[3])
