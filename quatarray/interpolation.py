"""Interpolation of unit quaternions (Shoemake), pointwise: lerp, nlerp, slerp,
Double and Bisect, spherical Bézier curves and their controls, squad, unflip,
and the angular velocity of a sampled stream. Resampling of timestamped key
streams is :mod:`quatarray.splines`; the per-element math is
:mod:`quatarray._slerp`.

Quaternions are ``(..., 4)`` arrays in (w, x, y, z) order, Hamilton algebra.
Leading dimensions broadcast like numpy; float32 stays float32, float64 stays
float64, mixed gives float64. Every slerp is the great-arc one of
:func:`quatarray._slerp.arc` (θ from atan2 of the chords, never an arccos).

Internal API (no checks; for :mod:`quatarray.splines`, on unit keys of shape (K, 4)):

- ``controls_bezier(q, t=None)``: the (a, b) of :func:`bezier_controls` for
  times `t` (float64, strictly increasing) or even spacing.
- ``controls_squad(q)``: :func:`squad_controls`.
"""

import math
import threading

import numba
import numpy as np

from . import _elements as E
from ._access import streams
from ._jit import fmuladd, like, prange, prefer_wide_vectors, rowloop, specialise
from ._slerp import (
    arc,
    arc_fast,
    bezier4,
    bisect4,
    controls4,
    double4,
    flip_rule,
    lerp4,
    nlerp4,
    squad4,
    squad_inner4,
    tie_band,
    unflip_sign,
)
from ._trig import sincos
from ._validate import as_times, elementwise, key_array, key_times, scan

Q = (4,)
# rows per block of a row loop: prange runs over blocks and the plain inner
# loop is what LLVM vectorises (a prange loop body itself is not vectorised)
ROWS = 1024

# --------------------------------------------------------------------------
# batched loops. Quaternion outputs are flat (4n,) views (see `_flat`).


SLERP_BLOCK = 256  # rows of _slerp's planes (8 planes: 16 KB in float64, in L1 cache)
SLERP_CHUNKS = 4  # chunks of rows (each with its own planes) per numba thread, at most
STREAM = False  # _slerp's rows written past the caches (E.stream4): True in _slerp_stream
# _slerp's prefetch hints, in elements: a 4 KiB page and a 64-byte line of float64 (for
# float32 they fall twice a page and twice a line: harmless, and a step read from the
# array's item size, not a constant for LLVM, cost 2 % of a call)
PAGE, LINE = 512, 8


@rowloop(rows=2)
def _slerp(p, q, t, shortest, planes, rare_bits, out):
    """:func:`quatarray._slerp.slerp4` row by row but for the rare pairs (nearly
    antipodal, identical ends, ties, nan: see :func:`quatarray._slerp.arc_fast`),
    which it leaves as they are in `out`, sets their bits in `rare_bits` (bit i % 64
    of word i // 64, all zero on entry) and counts: :func:`_slerp_rare` does them
    (compiled only when a call meets one). Returns how many there were.

    The rows come in ``planes.shape[0] // (8 SLERP_BLOCK)`` chunks (the prange), each
    with its own planes, in blocks of SLERP_BLOCK rows, in three passes: the arcs (the
    angle tθ, the tangent v and the sign of q, from :func:`quatarray._slerp.arc_fast`)
    into planes; the sine and cosine of the angles, in place; then the rows
    p cos tθ + v sin tθ (±q where t = 1), read from the planes and the inputs, so
    `out` may be `p` or `q`. :data:`STREAM` (the variant ``_slerp_stream``, for a
    caller's output that :func:`quatarray._access.streams`: see :func:`_run_slerp`)
    writes them with non-temporal stores (no cache line of `out` read only to be
    overwritten).

    In one pass, each row is a chain of dependent operations (chords, square
    roots, atan, sincos) longer than the CPU can overlap with the next rows: the
    loop waited on it (48 Mq/s on one Zen 3 core). Each pass's chain is shorter,
    and the first two run as SIMD code (the third, light, LLVM leaves scalar):
    61 Mq/s, and 70 with the fused multiply-adds of :func:`quatarray._jit.fmuladd`
    in the trigonometry, the chords and the rows. A first call compiles less than
    with the planes allocated here (that was 15 % of its compile) and the rare
    pairs' exact arc (:func:`quatarray._slerp.arc`) inlined (another 15 %)."""
    n = t.shape[0]
    B = SLERP_BLOCK
    chunks = planes.shape[0] // (8 * B)
    per = ((n + chunks - 1) // chunks + B - 1) // B * B  # rows per chunk: whole blocks (whole words of rare_bits)
    total = 0
    for ch in prange(chunks):
        prefer_wide_vectors()
        # (the planes' accessors are builtins, without numba's wraparound of negative
        # indices; conditionals, not min and max, which are numba overloads to compile)
        pb = ch * (8 * B)
        lo = ch * per
        hi = lo + per if lo + per < n else n
        for b0 in range(lo, hi, B):
            m = hi - b0 if hi - b0 < B else B
            # the next block's first lines of each 4 KiB into L2 (E.prefetch): 1.08-1.1x
            # from memory, where the rows come in while the arcs are computed
            nx = b0 + B
            if nx + B <= hi:
                for j in range(4 * nx, 4 * (nx + B), PAGE):
                    for c in range(0, 4 * LINE, LINE):
                        E.prefetch(p, j + c)
                        E.prefetch(q, j + c)
                E.prefetch(t, nx)
            # planes (B apart): tθ then sin tθ, v (four), ±1, rare, cos tθ
            for k in range(m):
                th, v, sgn, r = arc_fast(E.load4(p, b0 + k), E.load4(q, b0 + k), shortest)
                E.stores_at(planes, pb + k, B, (E.load1(t, b0 + k) * th, v[0], v[1], v[2], v[3], like(th, 1.0) - sgn, r))
            for k in range(m):
                E.stores_at(planes, pb + k, 7 * B, sincos(E.load1(planes, pb + k)))
            for k in range(m):
                i = b0 + k
                pi = E.load4(p, i)
                qi = E.load4(q, i)  # loaded whatever t (a load under a branch stops LLVM's vectoriser)
                s, v0, v1, v2, v3, sq, rare, c = E.loads_at(planes, pb + k, B, 8)
                r = (fmuladd(s, v0, c * pi[0]), fmuladd(s, v1, c * pi[1]), fmuladd(s, v2, c * pi[2]),
                     fmuladd(s, v3, c * pi[3]))
                # exact end (t = 0 is exact: sincos(0) = (0, 1)); a branch, which LLVM leaves
                # scalar: the SIMD select of slerp_row ran 1.17x faster in cache but 0.8x at
                # 2·10⁶ rows (from memory)
                if E.load1(t, i) == like(s, 1.0):
                    r = (sq * qi[0], sq * qi[1], sq * qi[2], sq * qi[3])
                if rare == like(s, 0.0):
                    if STREAM:
                        E.stream4(out, i, r)
                    else:
                        E.store4(out, i, r)
                else:  # a rare row keeps its input (out may be p or q), for _slerp_rare
                    rare_bits[i >> 6] |= np.uint64(1) << np.uint64(i & 63)
                    total += 1
        if STREAM:
            E.stream_end()
    return total


_slerp_stream = rowloop(rows=2)(specialise(_slerp.py_func, "_stream", STREAM=True))


@rowloop(parallel=False)
def _slerp_rare(p, q, t, shortest, rare_bits, out):
    """The rows of `rare_bits` that :func:`_slerp` left: the same rows on the exact arc of
    :func:`quatarray._slerp.arc` (bit for bit what :func:`quatarray._slerp.slerp4` gives)."""
    for w in range(rare_bits.shape[0]):
        word = rare_bits[w]
        if word:
            for j in range(64):
                if (word >> np.uint64(j)) & np.uint64(1):
                    i = 64 * w + j
                    pi = E.load4(p, i)
                    qi = E.load4(q, i)
                    ti = E.load1(t, i)
                    th, v, sgn = arc(pi, qi, shortest)
                    s, c = sincos(ti * th)
                    r = (fmuladd(s, v[0], c * pi[0]), fmuladd(s, v[1], c * pi[1]),
                         fmuladd(s, v[2], c * pi[2]), fmuladd(s, v[3], c * pi[3]))
                    if ti == like(s, 1.0):
                        sq = like(th, 1.0) - sgn
                        r = (sq * qi[0], sq * qi[1], sq * qi[2], sq * qi[3])
                    E.store4(out, i, r)


_SCRATCH = threading.local()  # each thread's planes and rare bits for calls of one block (see _run_slerp)


def _run_slerp(p, q, t, shortest, given, out):
    """:func:`_slerp` on flat rows, then :func:`_slerp_rare` if it left rows.

    `given` (non-zero): `out` is the caller's ``out=``, whose pages are touched already:
    a large one is written past the caches (:func:`_slerp_stream`, 1.06-1.23x at
    10⁶-4·10⁶ rows). A new output is not: the system zeroes its pages as the loop
    first touches them, which leaves the zeros in the cache, where ordinary stores
    find them (streamed stores ran 0.92x there).

    A call of one block (at most SLERP_BLOCK rows: one chunk, the serial loop) takes
    its planes and rare bits from its thread's scratch, which it holds (takes out)
    while it runs, so that no two calls ever share them, and gives back with the bits
    zero: allocating them was a sixth of a small call's time. Larger calls allocate."""
    n = t.shape[0]
    if n <= SLERP_BLOCK:
        scratch = _SCRATCH.__dict__
        key = out.dtype.char
        bufs = scratch.pop(key, None)
        if bufs is None:
            bufs = (np.empty(8 * SLERP_BLOCK, out.dtype), np.zeros(SLERP_BLOCK // 64, np.uint64))
        if _slerp.serial(p, q, t, shortest, bufs[0], bufs[1], out):
            _slerp_rare(p, q, t, shortest, bufs[1], out)
            bufs[1][:] = 0
        scratch[key] = bufs
        return
    blocks = max(1, (n + SLERP_BLOCK - 1) // SLERP_BLOCK)
    chunks = blocks if blocks <= SLERP_CHUNKS else min(blocks, SLERP_CHUNKS * numba.get_num_threads())
    planes = np.empty(chunks * 8 * SLERP_BLOCK, out.dtype)
    rare_bits = np.zeros((n + 63) // 64, np.uint64)
    if (_slerp_stream if given and streams(out) else _slerp)(p, q, t, shortest, planes, rare_bits, out):
        _slerp_rare(p, q, t, shortest, rare_bits, out)


@rowloop(rows=2)
def _nlerp(p, q, t, shortest, out):
    n = t.shape[0]
    for blk in prange((n + ROWS - 1) // ROWS):
        lo = max(blk * ROWS, 0)  # provably >= 0: no negative-index wraparound, so LLVM vectorises
        for k in range(min(n - lo, ROWS)):
            i = lo + k
            ti = E.load1(t, i)
            pi = E.load4(p, i)
            qi = E.load4(q, i)
            d = pi[0] * qi[0] + pi[1] * qi[1] + pi[2] * qi[2] + pi[3] * qi[3]
            s = like(ti, 1.0) - ti
            tol = tie_band(ti) * like(ti, 0.5) * (E.qdot(pi, pi) + E.qdot(qi, qi))
            flip = flip_rule(pi, qi, d, tol, tol)[0] & (shortest > like(ti, 0.0))  # the tie rule of _slerp
            # −t when q is flipped into p's hemisphere; 0 or 2 from the boolean (no select)
            ts = ti - like(ti, 2.0) * flip * ti
            E.store4(out, i, nlerp4(pi, qi, s, ts))


@rowloop(rows=2)
def _lerp(p, q, t, out):
    n = t.shape[0]
    for blk in prange((n + ROWS - 1) // ROWS):
        lo = max(blk * ROWS, 0)  # provably >= 0: no negative-index wraparound, so LLVM vectorises
        for k in range(min(n - lo, ROWS)):
            i = lo + k
            ti = E.load1(t, i)
            pi = E.load4(p, i)
            qi = E.load4(q, i)
            s = like(ti, 1.0) - ti
            E.store4(out, i, lerp4(pi, qi, s, ti))


@rowloop
def _unflip_signs(p, q, out):
    """:func:`quatarray._slerp.unflip_sign` of rows (for the Dask sign scans)."""
    for i in prange(p.shape[0]):
        out[i] = unflip_sign(E.load4(p, i), E.load4(q, i))


def unflip_signs(p, q):
    """What :func:`unflip` does to each row of `q` after the row of `p`, shape (...):
    −1 negate, 1 keep, 0 keep whatever the signs (`q` or `p` a zero or nan row)."""
    return elementwise(_unflip_signs, [(p, "p", Q), (q, "q", Q)], [()])


@rowloop
def _double(p, q, out):
    n = p.shape[0] // 4
    for blk in prange((n + ROWS - 1) // ROWS):
        lo = max(blk * ROWS, 0)  # provably >= 0: no negative-index wraparound, so LLVM vectorises
        for k in range(min(n - lo, ROWS)):
            i = lo + k
            E.store4(out, i, double4(E.load4(p, i), E.load4(q, i)))


@rowloop
def _bisect(p, q, out):
    n = p.shape[0] // 4
    for blk in prange((n + ROWS - 1) // ROWS):
        lo = max(blk * ROWS, 0)  # provably >= 0: no negative-index wraparound, so LLVM vectorises
        for k in range(min(n - lo, ROWS)):
            i = lo + k
            E.store4(out, i, bisect4(E.load4(p, i), E.load4(q, i)))


@rowloop(rows=1)
def _bezier_controls(q, f_out, f_in, a, b):
    """Controls of all K keys (flat arrays), one pass over them: `q` holds K + 2 keys,
    the phantom q_{−1} = double(q_1, q_0), the keys, then q_K = double(q_{K−2}, q_{K−1})
    (see :func:`_with_phantoms`), for which :func:`controls4` gives a_0 = slerp(q_0, q_1, 1/3)
    and b_{K−1} = slerp(q_{K−1}, q_{K−2}, 1/3) (to rounding)."""
    n = f_out.shape[0]
    for blk in prange((n + ROWS - 1) // ROWS):
        prefer_wide_vectors()
        lo = blk * ROWS  # (the row accessors are builtins: no wraparound; no min, a numba overload)
        for j in range(n - lo if n - lo < ROWS else ROWS):
            i = lo + j
            r = controls4(E.load4(q, i), E.load4(q, i + 1), E.load4(q, i + 2), E.load1(f_out, i), E.load1(f_in, i))
            E.store4(a, i, r[0])
            E.store4(b, i, r[1])


def _double_row(p, q):
    """:func:`quatarray._slerp.double4` of two rows, in numpy (the same operations in the
    same order, so the same bits)."""
    d2 = 2.0 * (p[0] * q[0] + p[1] * q[1] + p[2] * q[2] + p[3] * q[3])
    return d2 * q - p


def _with_phantoms(q):
    """The K ≥ 2 keys `q` between the phantom keys of :func:`_bezier_controls`, flat."""
    k = q.shape[0]
    x = np.empty((k + 2, 4), q.dtype)
    x[1:-1] = q
    x[0] = _double_row(q[1], q[0])
    x[-1] = _double_row(q[k - 2], q[k - 1])
    return x.reshape(-1)


@rowloop(rows=4)
def _bezier(q0, a, b, q1, t, out):
    n = t.shape[0]
    for blk in prange((n + ROWS - 1) // ROWS):
        lo = max(blk * ROWS, 0)  # provably >= 0: no negative-index wraparound, so LLVM vectorises
        for k in range(min(n - lo, ROWS)):
            i = lo + k
            E.store4(out, i, bezier4(E.load4(q0, i), E.load4(a, i), E.load4(b, i), E.load4(q1, i), E.load1(t, i)))


@rowloop(rows=4)
def _squad(q0, s0, s1, q1, t, out):
    n = t.shape[0]
    for blk in prange((n + ROWS - 1) // ROWS):
        lo = max(blk * ROWS, 0)  # provably >= 0: no negative-index wraparound, so LLVM vectorises
        for k in range(min(n - lo, ROWS)):
            i = lo + k
            E.store4(out, i, squad4(E.load4(q0, i), E.load4(s0, i), E.load4(s1, i), E.load4(q1, i), E.load1(t, i)))


@rowloop(parallel=False)
def _unflip(q, out):
    # q, out: (K, M, 4); the sign scan runs along axis 0 for each of the M columns.
    for m in range(q.shape[1]):
        prev = (q[0, m, 0], q[0, m, 1], q[0, m, 2], q[0, m, 3])
        out[0, m, 0], out[0, m, 1], out[0, m, 2], out[0, m, 3] = prev
        for k in range(1, q.shape[0]):
            cur = (q[k, m, 0], q[k, m, 1], q[k, m, 2], q[k, m, 3])
            if unflip_sign(prev, cur) < like(q, 0.0):
                cur = E.qneg(cur)
            out[k, m, 0], out[k, m, 1], out[k, m, 2], out[k, m, 3] = cur
            prev = cur


@rowloop(parallel=False)
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

    With ``shortest=True`` q is first flipped into p's hemisphere (p·q ≥ 0; a
    pair a half turn apart, p·q = 0, by the tie rule of :func:`slerp`).

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

    A pair a half turn apart (p·q = 0, within 64 ulp: both arcs are equally
    short) takes the arc scipy's ``Slerp`` takes for an exact tie: q is flipped
    when the first non-negligible x, y, z of the relative rotation p* ⊗ q is
    negative. The rule depends on p* ⊗ q only, so
    ``slerp(r ⊗ p, r ⊗ q, t)`` is ``r ⊗ slerp(p, q, t)`` for any rotation r,
    whatever sign rounding gives (r ⊗ p)·(r ⊗ q).

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
    # a caller's C-contiguous `out` is the loop's output itself (others go through a new temporary)
    given = out is not None and bool(getattr(getattr(out, "flags", None), "c_contiguous", False))
    return elementwise(_flat(_run_slerp, 1.0 if shortest else 0.0, given), _pqt(p, q, t), [Q], out)


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


def tangent_scales(h):
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
    q = key_array(keys)
    return controls_bezier(q, None if times is None else key_times(times, q.shape[0]))


def controls_bezier(q, t=None):
    """:func:`bezier_controls` of valid keys `q` (K, 4) and valid times `t` or None (no checks)."""
    k = q.shape[0]
    if t is None:
        f_out = f_in = np.ones(k)
    else:
        f_out, f_in = tangent_scales(np.diff(t))
    a = np.empty(q.shape, q.dtype)
    b = np.empty(q.shape, q.dtype)
    _bezier_controls(_with_phantoms(q), f_out.astype(q.dtype), f_in.astype(q.dtype), a.reshape(-1), b.reshape(-1))
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
    return controls_squad(key_array(keys))


def controls_squad(q):
    """:func:`squad_controls` of valid keys `q` (K, 4) (no checks)."""
    s = q.copy()
    if q.shape[0] > 2:
        _squad_inner(np.ascontiguousarray(q), s)
    return s


@rowloop
def _squad_inner(q, s):
    """Rows 1 … K−2 of :func:`squad_controls` (one kernel: no temporaries), in blocks of
    ROWS rows whose plain inner loop runs as SIMD code (the logs and the exp of unit
    quaternions by the branch-free trigonometry: 4x the libm-based loop)."""
    n = q.shape[0] - 2
    for blk in prange((n + ROWS - 1) // ROWS):
        lo = max(blk * ROWS, 0)  # provably >= 0: no negative-index wraparound, so LLVM vectorises
        for k in range(min(n - lo, ROWS)):
            i = lo + k + 1
            E.store4(s, i, squad_inner4(E.load4(q, i - 1), E.load4(q, i), E.load4(q, i + 1)))


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

    A tie (q[i] a half turn from q[i−1]: dot product 0, to 64 ulp) is resolved by
    the relative rotation D = q[i−1]* ⊗ q[i], as scipy resolves it: q[i] is
    negated when the first non-negligible of D's x, y, z is negative (see
    :mod:`quatarray._slerp`). The rule depends on D only, so
    ``unflip(R ⊗ q)`` is ``R ⊗ unflip(q)`` for any rotation R (to rounding).
    A zero or nan row is kept as it is, and so is the row after it.

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
    a = key_array(q, "q")
    n = a.shape[0]
    # Steps in the times' own type (exact for int64 ns stamps), then float.
    h = np.diff(key_times(as_times(times, "times"), n)).astype(a.dtype)
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
