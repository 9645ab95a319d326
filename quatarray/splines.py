"""Resampling of timestamped key streams: the spline engine behind :func:`spline`.

A stream of K keys becomes a table of K − 1 segment rows (:func:`_segments`),
each new time is placed in its segment by a run search (:func:`next_run`), and
one evaluation loop per method evaluates the runs (``_eval_*``). Sorted new
times go through the table piece by piece (:func:`_spline_pieces`). The per-element
slerp math is :mod:`quatarray._slerp`, the controls come from
:mod:`quatarray.interpolation`.

Methods
-------
``_METHODS`` maps each method name to a :class:`Method`: ``kind`` (which fixed
arcs its table rows hold: a branch of :func:`_segments`), ``controls(q, t)``
(the table's columns 4-11 from unit keys and float64 times) and ``evaluate``
(its evaluation loop, ``(times, new_t, seg, out)`` on the flat table). A new
method plugs in with one row there, a ``KIND`` branch in :func:`_segments` if it
needs other arcs, and its loop; the whole-table and the piecewise kernels of
each method are derived from the row (``_SEGMENTS``, ``_PIECES``).

Internal API (for :mod:`quatarray.dask`; no leading underscore)
----------------------------------------------------------------
``check_method(method)``
    Raise the ValueError for an unknown method.
``seconds(t_raw, nt_raw, origin)``
    Key times and new times as float64 for the segment search.
``plan_times(t_raw, nt_raw, index0=0, origin=None)``
    :func:`seconds`, with the error naming the first new time outside the keys.
``unit_keys(parts, flip0=False)``
    The keys as the spline interpolates them (normalised, unflipped).
``resample_unit(t, nt, q, method)``
    :func:`spline` on planned times and unit keys (no checks).
``sign_summary(q, rows, ends, negated, unit, dots)``
    What a blocked sign scan needs of a block of raw keys.
``resample_streams(t, nt, keys, cols, method, out)``
    Many streams on one time plan (a clip's joints, keys (K, J, 4)): each as
    :func:`spline` gives it, bit for bit, in one pass, SIMD over the streams
    (the "lane layout" section; used by :meth:`quatarray.skeleton.Clip.resample`).

The key-time rules (``key_times``, ``check_times``, ``first_not_increasing``,
``not_increasing``) are in :mod:`quatarray._validate`.
"""

from typing import Callable, NamedTuple

import numpy as np

from . import _elements as E
from ._access import load1, load4, store1, store4
from ._jit import inline, ir_inline, kernel, like, prange, rowloop, specialise
from ._slerp import arc, arc_slerp, bezier_seg, bisect4, controls4, double4, nlerp4, slerp4
from ._validate import as_times, key_array, key_times
from .interpolation import _tangent_scales, controls_bezier, controls_squad

Q = (4,)
BLOCK = 2048  # samples per block of the segment search
# The Bézier samples are gathered, TILE at a time, into a column-major tile of
# their segments' rows and evaluated there as SIMD lanes (see _eval_bezier):
# one copy of the long de Casteljau chain serves runs of any length (a separate
# loop for long runs in one segment was no faster, and doubled its compile time).
TILE = 64
NSEG = 31  # floats per row of a spline's segment table: 4 quaternions, 3 arcs


@kernel
def sign_summary(q, rows, ends, negated, unit, dots):
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
        p = load4(q, n)
        r = load4(q, n + 1)
        a = load4(c_out, n)
        b = load4(c_in, n + 1)
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
                store4(out, i, arc_slerp(p, q, c, like(x0, (load1(new_t, i) - t0) / h)))
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
                t = like(x0, (load1(new_t, i) - t0) / h)
                store4(out, i, nlerp4(p, q, like(t, 1.0) - t, t))
            j = e


@inline
def tile_q(tile, c, lane):
    return (load1(tile, c * TILE + lane), load1(tile, (c + 1) * TILE + lane),
            load1(tile, (c + 2) * TILE + lane), load1(tile, (c + 3) * TILE + lane))


@inline
def tile_arc(tile, c, lane):
    return (load1(tile, c * TILE + lane), load1(tile, (c + 1) * TILE + lane), load1(tile, (c + 2) * TILE + lane),
            load1(tile, (c + 3) * TILE + lane), load1(tile, (c + 4) * TILE + lane))


@kernel
def bezier_tile(tile, u, res, rows, count, out):
    """Evaluate the `count` samples waiting in a tile (SIMD over its lanes, into `res`
    column by column), then store them in their rows of `out`."""
    for lane in range(count):
        r = bezier_seg(tile_q(tile, 0, lane), tile_q(tile, 4, lane), tile_q(tile, 8, lane), tile_q(tile, 12, lane),
                       tile_arc(tile, 16, lane), tile_arc(tile, 21, lane), tile_arc(tile, 26, lane), load1(u, lane))
        store1(res, lane, r[0])
        store1(res, TILE + lane, r[1])
        store1(res, 2 * TILE + lane, r[2])
        store1(res, 3 * TILE + lane, r[3])
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
                t = like(x0, (load1(new_t, i) - t0) / h)
                pq = arc_slerp(q0, q1, c0, t)
                ps = arc_slerp(s0, s1, c1, t)
                store4(out, i, slerp4(pq, ps, like(t, 2.0) * t * (like(t, 1.0) - t), like(t, 0.0)))
            j = e


# Sorted new times go through the table piece by piece: each piece of
# PIECE_SAMPLES samples builds only the rows of the segments it spans (for keys as dense as
# the samples, a table of about 1 MB that stays in cache) and evaluates its
# samples from them; the pieces run in parallel.
PIECE_SAMPLES = 4096
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
    for p in prange((m + PIECE_SAMPLES - 1) // PIECE_SAMPLES):
        j0 = p * PIECE_SAMPLES
        j1 = min(m, j0 + PIECE_SAMPLES)
        s0 = seg_index(times, new_t[j0])
        s1 = seg_index(times, new_t[j1 - 1]) + 1
        seg = np.empty((s1 - s0, NSEG), out.dtype)
        _segments_1(q[s0 : s1 + 1], c_out[s0 : s1 + 1], c_in[s0 : s1 + 1], seg)
        _eval_1(times[s0 : s1 + 1], new_t[j0:j1], seg.reshape(-1), out[4 * j0 : 4 * j1])


@kernel
def _n_outside(lo, hi, x):
    """How many x are not within [lo, hi] (nan included)."""
    c = 0
    for i in range(x.shape[0]):
        c += not (x[i] >= lo and x[i] <= hi)
    return c


def seconds(t_raw, nt_raw, origin):
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


def plan_times(t_raw, nt_raw, index0=0, origin=None):
    """:func:`seconds` of key times and new times (integers taken from `origin`,
    default the first key time), or the ValueError naming the first new time
    outside the keys' span (its flat index counted from `index0`). Only the first
    and last key times are looked at here."""
    if nt_raw.dtype.kind not in "biuf":
        raise TypeError(f"Expected `new_times` to have a real dtype, got {nt_raw.dtype}.")
    t, nt = seconds(t_raw, nt_raw, t_raw[0] if origin is None else origin)
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
    check_method(method)
    q = key_array(keys)
    t, nt = plan_times(key_times(as_times(times, "times"), q.shape[0]), as_times(new_times, "new_times"))
    return resample_unit(t, nt, unit_keys([q]), method)


def unit_keys(parts, flip0=False):
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


def resample_unit(t, nt, q, method):
    """:func:`spline` on times `t`, new times `nt` (as :func:`plan_times` gives them)
    and unit, unflipped keys `q`."""
    k = q.shape[0]
    flat_nt = np.ascontiguousarray(nt.reshape(-1))
    c_out, c_in = _METHODS[method].controls(q, t)
    m = flat_nt.shape[0]
    out = np.empty((m, 4), q.dtype)
    if m > 1 and (flat_nt[1:] >= flat_nt[:-1]).all():
        _PIECES[method](t, flat_nt, q, c_out, c_in, out.reshape(-1))
    elif m:
        seg = np.empty((k - 1, NSEG), q.dtype)
        _SEGMENTS[method](q, c_out, c_in, seg)
        _METHODS[method].evaluate(t, flat_nt, seg.reshape(-1), out.reshape(-1))
    return out.reshape(nt.shape + Q)


def check_method(method):
    """Raise the ValueError for a method :func:`spline` does not know."""
    if method not in _METHODS:
        raise ValueError(f"Expected `method` to be one of {sorted(_METHODS)}, got {method!r}.")


# ---- the method table


class Method(NamedTuple):
    """One spline method: see the module docstring."""

    kind: int  # the fixed arcs its table rows hold (``KIND`` of _segments)
    controls: Callable  # (unit keys (K, 4), float64 times (K,)) -> (c_out, c_in), each (K, 4)
    evaluate: object  # the evaluation loop (times, new_t, seg, out), a RowLoop


def _no_controls(q, t):
    return q, q  # slerp, nlerp: none (the table's columns 4-11 repeat the keys)


def _squad_controls(q, t):
    s = controls_squad(q)
    return s, s


_METHODS = {
    "bezier": Method(1, controls_bezier, _eval_bezier),
    "slerp": Method(0, _no_controls, _eval_slerp),
    "nlerp": Method(3, _no_controls, _eval_nlerp),
    "squad": Method(2, _squad_controls, _eval_squad),
}
_SEGMENTS = {name: rowloop(rows=3)(specialise(_segments, f"_{name}", KIND=m.kind)) for name, m in _METHODS.items()}
_PIECES = {
    name: rowloop(rows=1)(specialise(_spline_pieces, f"_{name}", _eval_1=ir_inline(specialise(m.evaluate.py_func, "_piece")),
                                     _segments_1=ir_inline(specialise(_SEGMENTS[name].py_func, "_piece"))))
    for name, m in _METHODS.items()
}


# ---- many streams on one time plan (lane layout)
#
# The keys of J streams at the same K times (a clip's joints) are held in lane
# layout: groups of LANES streams, each group a (K, 4, LANES) block of a flat
# array (element ((g K + n) 4 + c) LANES + l is component c of key n of stream
# g LANES + l; spare lanes hold the identity). Every loop over a group's lanes
# reads and writes contiguous memory at constant strides (which LLVM vectorises:
# a run-time stride made it give up), so one segment search serves all streams
# and the math of a sample runs as SIMD over the streams: _lane_spline finds each
# run of samples in one segment (next_run), copies the segment's keys of a lane
# group into a small table, finds its fixed arcs once (_lane_arcs) and evaluates
# the run's samples (_lane_eval), in kernels that touch only the small tables.
# Each lane computes exactly what spline computes for its stream alone (the
# same element functions on the same numbers): equal bit for bit.

LANES = 32  # streams per group: the constant stride of the lane loops (as TILE for the Bézier tiles)
G4 = 4 * LANES  # floats per key of a group


def lane_groups(j):
    """Lane groups for j streams."""
    return max(1, -(-j // LANES))


@inline
def load_lane(a, b, l):
    """The quaternion of lane l at offset b (a key's start) of a lane-layout array."""
    return load1(a, b + l), load1(a, b + LANES + l), load1(a, b + 2 * LANES + l), load1(a, b + 3 * LANES + l)


@inline
def store_lane(a, b, l, q):
    store1(a, b + l, q[0])
    store1(a, b + LANES + l, q[1])
    store1(a, b + 2 * LANES + l, q[2])
    store1(a, b + 3 * LANES + l, q[3])


@kernel
def _gather_unit(p, cols, out):
    """Lane layout `out` of the streams ``p[:, cols[s]]`` (p of shape (K, J, 4)), each
    normalised and unflipped along K as :func:`quatarray.spline` does (the
    ``_unit_unflip`` rule); spare lanes hold the identity."""
    nk = p.shape[0]
    ng = out.shape[0] // (nk * G4)
    zero = like(out, 0.0)
    one = like(out, 1.0)
    for g in range(ng):
        for k in range(nk):
            b = (g * nk + k) * G4
            for l in range(LANES):
                s = g * LANES + l
                if s < cols.shape[0]:
                    j = cols[s]
                    r = E.qnormalize((p[k, j, 0], p[k, j, 1], p[k, j, 2], p[k, j, 3]))
                    if k > 0 and E.qdot(r, load_lane(out, b - G4, l)) < zero:
                        r = E.qneg(r)
                else:
                    r = (one, zero, zero, zero)
                store_lane(out, b, l, r)


@inline
def lane_neighbours(q, c, cp, cx, first, last, l):
    """(q_{n−1}, q_n, q_{n+1}) of lane l for the controls of key n, with the phantom end
    keys of ``_bezier_controls``: q_{−1} = double(q_1, q_0), q_K = double(q_{K−2}, q_{K−1})."""
    qn = load_lane(q, c, l)
    qp = load_lane(q, cp, l)
    qx = load_lane(q, cx, l)
    if first:
        qp = double4(qp, qn)
    if last:
        qx = double4(qx, qn)
    return qp, qn, qx


@rowloop(rows=0)
def _lane_bezier_controls(q, f_out, f_in, a, b):
    """:func:`quatarray.bezier_controls` of every lane (the ``_bezier_controls`` rule).

    A key whose tangent factors are both exactly 1 (evenly spaced times) skips the
    two scaling slerps of :func:`controls4`: a slerp at t = 1 returns its end
    exactly, so a_n = a₀ and b_n = double(a₀, q_n) bit for bit."""
    nk = f_out.shape[0]
    ng = q.shape[0] // (nk * G4)
    one = like(q, 1.0)
    third = one / like(q, 3.0)
    zero = like(q, 0.0)
    for i in prange(ng * nk):
        g = i // nk
        n = i - g * nk
        c = (g * nk + n) * G4
        first = n == 0
        last = n == nk - 1
        cp = c + G4 if first else c - G4  # key n − 1, or q_1 for the phantom q_{−1}
        cx = c - G4 if last else c + G4  # key n + 1, or q_{K−2} for the phantom q_K
        fo = f_out[n]
        fi = f_in[n]
        if fo == one and fi == one:
            for l in range(LANES):
                qp, qn, qx = lane_neighbours(q, c, cp, cx, first, last, l)
                a0 = slerp4(qn, bisect4(double4(qp, qn), qx), third, zero)
                store_lane(a, c, l, a0)
                store_lane(b, c, l, double4(a0, qn))
        else:
            for l in range(LANES):
                qp, qn, qx = lane_neighbours(q, c, cp, cx, first, last, l)
                r = controls4(qp, qn, qx, fo, fi)
                store_lane(a, c, l, r[0])
                store_lane(b, c, l, r[1])


@rowloop(rows=0)
def _lane_squad_controls(q, nk, s):
    """:func:`quatarray.interpolation.squad_controls` of every lane (`s` a copy of `q`)."""
    ng = q.shape[0] // (nk * G4)
    quarter = like(q, -0.25)
    for i in prange(ng * (nk - 2)):
        g = i // (nk - 2)
        n = i - g * (nk - 2) + 1
        c = (g * nk + n) * G4
        for l in range(LANES):
            qn = load_lane(q, c, l)
            inv = E.qconj(qn)
            x = E.qlog(E.qmul(inv, load_lane(q, c + G4, l)))
            y = E.qlog(E.qmul(inv, load_lane(q, c - G4, l)))
            store_lane(s, c, l, E.qmul(qn, E.qexp(((x[0] + y[0]) * quarter, (x[1] + y[1]) * quarter,
                                             (x[2] + y[2]) * quarter, (x[3] + y[3]) * quarter))))


@inline
def put_lane_arc(arcs, c, l, p, q):
    """(θ, v) of the fixed arc p → q (as the table's ``put_arc``) at rows c … c + 4 of lane l."""
    th, v, sgn = arc(p, q, like(p[0], 0.0))
    store1(arcs, c * LANES + l, th)
    store1(arcs, (c + 1) * LANES + l, v[0])
    store1(arcs, (c + 2) * LANES + l, v[1])
    store1(arcs, (c + 3) * LANES + l, v[2])
    store1(arcs, (c + 4) * LANES + l, v[3])


@inline
def lane_arc(arcs, c, l):
    return (load1(arcs, c * LANES + l), load1(arcs, (c + 1) * LANES + l), load1(arcs, (c + 2) * LANES + l),
            load1(arcs, (c + 3) * LANES + l), load1(arcs, (c + 4) * LANES + l))


@inline
def lane_keys(keys, l):
    """Lane l of a segment's small table: q_n, c_out[n], c_in[n+1], q_{n+1}."""
    return load_lane(keys, 0, l), load_lane(keys, G4, l), load_lane(keys, 2 * G4, l), load_lane(keys, 3 * G4, l)


def _lane_arcs(keys, count, arcs):
    """The fixed arcs of one segment for lanes 0 … count − 1: `keys` (16 LANES,) holds
    q_n, c_out[n], c_in[n+1], q_{n+1} of a group; `arcs` (15 LANES,) gets up to three (θ, v)."""
    for l in range(count):
        p, a, b, r = lane_keys(keys, l)
        if KIND == 1:
            put_lane_arc(arcs, 0, l, p, a)
            put_lane_arc(arcs, 5, l, a, b)
            put_lane_arc(arcs, 10, l, b, r)
        elif KIND == 2:
            put_lane_arc(arcs, 0, l, p, r)
            put_lane_arc(arcs, 5, l, a, b)
        elif KIND == 0:
            put_lane_arc(arcs, 0, l, p, r)


def _lane_eval(keys, arcs, t, count, res):
    """One sample at segment parameter t for lanes 0 … count − 1 (SIMD over lanes) into `res` (4 LANES,)."""
    for l in range(count):
        p, a, b, r = lane_keys(keys, l)
        if KIND == 1:
            v = bezier_seg(p, a, b, r, lane_arc(arcs, 0, l), lane_arc(arcs, 5, l), lane_arc(arcs, 10, l), t)
        elif KIND == 2:
            pq = arc_slerp(p, r, lane_arc(arcs, 0, l), t)
            ps = arc_slerp(a, b, lane_arc(arcs, 5, l), t)
            v = slerp4(pq, ps, like(t, 2.0) * t * (like(t, 1.0) - t), like(t, 0.0))
        elif KIND == 0:
            v = arc_slerp(p, r, lane_arc(arcs, 0, l), t)
        else:
            v = nlerp4(p, r, like(t, 1.0) - t, t)
        store_lane(res, 0, l, v)


lane_arcs = lane_eval = None  # bound in each method's copy of _lane_spline


def _lane_spline(times, new_t, q, c_out, c_in, cols, nj, out):
    """Every stream of the lane-layout keys `q` (with controls `c_out`, `c_in`) at
    `new_t`: stream s into column ``cols[s]`` of `out`, flat (M·nj·4,) for (M, nj, 4).

    Blocks of ``BLOCK`` samples run in parallel; in each, for the run of samples
    in one segment (the engine's ``next_run``) and each lane group, the segment's
    keys are copied into a small table, its fixed arcs found once, and each sample
    evaluated for all lanes (SIMD over lanes, in kernels that touch only the small
    tables)."""
    nk = times.shape[0]
    ng = q.shape[0] // (nk * G4)
    ns = cols.shape[0]
    m = new_t.shape[0]
    x0 = like(q, 0.0)
    for blk in prange((m + BLOCK - 1) // BLOCK):
        j = blk * BLOCK
        hi = min(m, j + BLOCK)
        keys = np.empty(4 * G4, q.dtype)
        arcs = np.empty(15 * LANES, q.dtype)
        res = np.empty(G4, q.dtype)
        sg = 0
        while j < hi:
            sg, e = next_run(times, new_t, j, hi, sg)
            t0 = times[sg]
            h = times[sg + 1] - t0
            for g in range(ng):
                b0 = (g * nk + sg) * G4
                b1 = b0 + G4
                count = min(LANES, ns - g * LANES)
                vec = min(LANES, (count + 7) // 8 * 8)  # whole SIMD steps (spare lanes hold the identity)
                for c in range(G4):
                    keys[c] = q[b0 + c]
                    keys[G4 + c] = c_out[b0 + c]
                    keys[2 * G4 + c] = c_in[b1 + c]
                    keys[3 * G4 + c] = q[b1 + c]
                lane_arcs(keys, vec, arcs)
                for i in range(j, e):
                    lane_eval(keys, arcs, like(x0, (new_t[i] - t0) / h), vec, res)
                    for l in range(count):
                        o = 4 * (i * nj + cols[g * LANES + l])
                        out[o] = res[l]
                        out[o + 1] = res[LANES + l]
                        out[o + 2] = res[2 * LANES + l]
                        out[o + 3] = res[3 * LANES + l]
            j = e


# multi-threaded by the size of `out` (4 per joint-sample): a sample costs one evaluation per stream
_LANE_SPLINE = {
    name: rowloop(rows=7)(specialise(_lane_spline, f"_{name}",
                                     lane_arcs=kernel(specialise(_lane_arcs, f"_{name}", KIND=m.kind)),
                                     lane_eval=kernel(specialise(_lane_eval, f"_{name}", KIND=m.kind))))
    for name, m in _METHODS.items()
}


def resample_streams(t, nt, keys, cols, method, out):
    """Many streams on one time plan: ``resample_unit`` of each stream ``keys[:, cols[s]]``
    (raw keys (K, J, 4), normalised and unflipped here per stream), at times `t` and
    new times `nt` (1-D, any order) as :func:`plan_times` gives them, into
    ``out[:, cols]`` (C-contiguous (M, J', 4) of the keys' dtype): bit for bit what
    :func:`spline` gives each stream alone, in one pass (see "Many streams" above)."""
    nk = t.shape[0]
    cols = np.asarray(cols, np.int64)
    dt = out.dtype
    q = np.empty(lane_groups(len(cols)) * nk * G4, dt)
    _gather_unit(keys, cols, q)
    c_out = c_in = q
    if method == "bezier":
        f_out, f_in = _tangent_scales(np.diff(t))
        c_out = np.empty_like(q)
        c_in = np.empty_like(q)
        _lane_bezier_controls(q, f_out.astype(dt), f_in.astype(dt), c_out, c_in)
    elif method == "squad":
        c_out = c_in = q.copy()
        if nk > 2:
            _lane_squad_controls(q, nk, c_out)
    if nt.shape[0]:
        _LANE_SPLINE[method](t, nt, q, c_out, c_in, cols, out.shape[1], out.reshape(-1))
    return out
