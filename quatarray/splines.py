"""Resampling of timestamped key streams: the spline engine behind :func:`spline`.

A stream of K keys becomes a table of K − 1 segment rows (:func:`_segments`),
each new time is placed in its segment by a run search (:func:`next_run`), and
one evaluation loop (:func:`_eval`) evaluates the runs with the method's RUN.
Sorted new times go through the table piece by piece (:func:`_spline_pieces`).
The per-element slerp math is :mod:`quatarray._slerp`, the controls come from
:mod:`quatarray.interpolation`.

Methods
-------
``_METHODS`` maps each method name to a :class:`Method`: ``kind`` (which fixed
arcs its table rows hold: a branch of :func:`_segments`), ``controls(q, t)``
(the table's columns 4-11 from unit keys and float64 times), ``run`` (the
inner loop over one run's samples, inlined into :func:`_eval`) and, for a
method that batches samples, ``start``, ``flush`` and ``cap`` (a block's
state, its evaluation, its size: the Bézier tile). A new method plugs in with
one row there, a ``KIND`` branch in :func:`_segments` if it needs other arcs
(or more columns: ``NSEG``), and its ``run``; the method's compiled loops are
derived from the row (``_EVALS``, ``_SEGMENTS``, ``_PIECES``), and so are its
rate loops (``order`` 1 and 2: :func:`_run_rates` on the whole table, or
for the Bézier curve its tiles, :func:`bezier_rate_tile`; ``_RATES``) when its
``KIND`` is one of theirs. A method whose curve is not a
table of independent segments gives ``resample(t, nt, q, order)`` instead and
does everything itself: ``"cubic"``, scipy's RotationSpline, whose rates come
from one system over all keys (:mod:`quatarray._cubic`, :func:`_run_cubic`).

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
``resample_unit(t, nt, q, method, order=0)``
    :func:`spline` on planned times and unit keys (no checks).
``cubic_curve(t, q)``
    ``method="cubic"`` on planned key times and unit keys, solved once: a
    function of planned new times (for the command line's pieces).
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

from . import _cubic
from . import _elements as E
from ._jit import element, like, prange, prefer_wide_vectors, rowloop, scratch, specialise
from ._rates import acc_coeffs, arc_rotvec, jac, jac_coeffs, jac_dot, qexp_half, slerp_acc, slerp_acc_fixed, slerp_rates
from ._slerp import arc, arc_fast, arc_slerp, nlerp4, slerp4, unflip_sign
from ._trig import sincos
from ._validate import as_times, key_array, key_times, spline_order
from .interpolation import controls_bezier, controls_squad

Q = (4,)
BLOCK = 2048  # samples per block of the segment search
# The Bézier samples are gathered, TILE at a time, into a column-major tile of
# their segments' rows and evaluated there as SIMD lanes (see run_bezier):
# one copy of the long de Casteljau chain serves runs of any length (a separate
# loop for long runs in one segment was no faster, and doubled its compile time).
TILE = 64
NSEG = 31  # floats per row of a spline's segment table: 4 quaternions, 3 arcs
# A tile is one float array (start_bezier): its samples' table rows as TILE columns
# (NSEG planes of TILE), then their u (a plane at U), then their results (four planes
# from RES; the rates' fourth: each sample's 1/h or 1/h²). Every access is at a constant
# distance from one base, so LLVM proves the loops free of overlaps: the lane loop has no
# scalar copy for overlapping arrays beside its SIMD one (the long chain compiled once).
U = NSEG * TILE
RES = U + TILE
# then the de Casteljau levels of the values (bezier_tile): the three points of level 1
# (twelve planes from MID) and the two of level 2 (eight more)
MID = RES + 4 * TILE
TILE_FLOATS = MID + 20 * TILE
# The lanes are evaluated in groups of LANES (a constant trip count: SIMD with no scalar
# remainder loop); the lanes of the last group past the samples compute on what the
# tile holds there, zeros or an earlier tile's rows (no denormals: the tile starts as
# zeros), and their results are not used.
LANES = 16


@rowloop(parallel=False)
def sign_summary(q, rows, ends, negated, unit, dots):
    """What a blocked sign scan needs of one block of raw keys, seen as :func:`spline`
    sees them (normalised, then unflipped from the block's first row), without
    writing the block: ``ends`` = its first and last rows, ``negated[j]`` whether
    row ``rows[j]`` (ascending) was negated. Returns how many leading rows a sign
    carried into the block reaches: up to the first row whose unflip sign
    (:func:`quatarray._slerp.unflip_sign`) is 0: a nan row or the row after it (that
    row is kept as it is whatever came before).

    A negated row only negates its unflip signs with its neighbours (exactly), so
    the rows are normalised into `unit` and their signs found into `dots`,
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
            dots[k] = unflip_sign(E.load4(unit, k), E.load4(unit, k + 1))
        for k in range(m):
            d = -dots[k] if neg else dots[k]  # as _unflip: the sign after the row before as it stands
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


@element
def put_arc(seg, n, c, p, q):
    """Table row n, columns c … c + 4: (θ, v) of the fixed arc from p to q (:func:`arc`)."""
    th, v, sgn, rare = arc_fast(p, q, like(p[0], 0.0))
    if rare:  # nearly antipodal, identical or nan ends (the table's loop is scalar: a branch costs nothing)
        th, v, sgn = arc(p, q, like(p[0], 0.0))
    E.stores(seg, NSEG * n + c, (th, v[0], v[1], v[2], v[3]))


KIND = 1  # rebound in each method's copy of _segments (see _SEGMENTS)


def _segments(q, c_out, c_in, seg):
    """Row n of a spline's segment table, written once: q_n, c_out[n], c_in[n+1],
    q_{n+1}, then the fixed arcs its evaluation loop needs (see the table's layout
    below): ``KIND`` 1 (Bézier) q_n → c_out[n] → c_in[n+1] → q_{n+1}; 2 (squad)
    q_n → q_{n+1} and c_out[n] → c_in[n+1]; 0 (slerp) q_n → q_{n+1}; 3 (nlerp) none.
    ``KIND`` is a constant of each method's compiled copy, so each compiles only
    the arcs it writes."""
    for n in prange(seg.shape[0]):
        p = E.load4(q, n)
        r = E.load4(q, n + 1)
        a = E.load4(c_out, n)
        b = E.load4(c_in, n + 1)
        E.stores(seg, NSEG * n, p)
        E.stores(seg, NSEG * n + 4, a)
        E.stores(seg, NSEG * n + 8, b)
        E.stores(seg, NSEG * n + 12, r)
        # the fixed arcs, in a loop: one inlined copy of put_arc (arc_fast and arc), not three
        for k in range(3 if KIND == 1 else 2 if KIND == 2 else 1 if KIND == 0 else 0):
            c0 = NSEG * n + 4 * k  # from quaternion k of the row to quaternion k + 1 (Bézier) or 3 − k
            c1 = NSEG * n + (4 * k + 4 if KIND == 1 else 12 - 4 * k)
            put_arc(seg, n, 16 + 5 * k, E.loads(seg, c0, 4), E.loads(seg, c1, 4))


@element
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


@element
def seg_keys(seg, n):
    """The four quaternions of a table row (starting at flat element n): q_n, its two
    controls, q_{n+1}. A fixed arc of the row is ``E.loads(seg, n + c, 5)``, (θ, v) at column c."""
    return E.loads(seg, n, 4), E.loads(seg, n + 4, 4), E.loads(seg, n + 8, 4), E.loads(seg, n + 12, 4)


# Segment table columns: 0-3 q_n, 4-7 first control, 8-11 second control,
# 12-15 q_{n+1}, then (θ, v) of up to three fixed arcs (`put_arc`) at 16, 21, 26
# (written by `_segments`, one copy per method in `_SEGMENTS`).
#
# The evaluation loop (`_eval`, one copy per method and order) goes segment by
# segment: for each run of samples in one segment (the whole run when new times
# are sorted, single samples when not) the method's RUN reads the segment's
# values once into scalars and its inner loop over the run's samples -- loads
# of u, polynomial trig, flat stores -- runs as SIMD.

START = RUN = FLUSH = None  # rebound in each copy of _eval (the tables of _eval_of)
CAP = -1  # samples a tile of FLUSH holds (-1: no tiles); rebound with START, RUN, FLUSH


def _eval(times, new_t, data, out):
    """Samples `new_t` into the flat `out`, block by block of BLOCK samples (the
    prange) and, in a block, run by run (:func:`next_run`):
    ``RUN(times, new_t, data, out, sg, j, e, state, count)`` evaluates samples
    j, j + 1, … (up to e − 1), all in segment sg (`data`: the flat table, or what
    the method reads instead), and returns where it stopped and `count`. A
    method that batches its samples (the Bézier tile) has ``START(data)`` make a
    block's `state`, where `count` samples wait, stops a run when CAP are
    waiting, and has ``FLUSH(out, state, count, j)`` evaluate them (samples
    j − count … j − 1: a block's samples wait in their order): called at one
    place only (when CAP wait, and at the block's end), so the long chain of a
    Bézier tile is inlined once (numba's IR inlining: no kernel of its own to compile)."""
    m = new_t.shape[0]
    for blk in prange((m + BLOCK - 1) // BLOCK):
        j = blk * BLOCK
        hi = j + BLOCK if j + BLOCK < m else m  # (not min: a numba overload to compile)
        sg = 0
        state = START(data)
        count = np.int64(0)  # not the literal 0
        while True:
            if j < hi:
                sg, e = next_run(times, new_t, j, hi, sg)
                while j < e and count != CAP:
                    j, count = RUN(times, new_t, data, out, sg, j, e, state, count)
            if count == CAP or j >= hi:
                FLUSH(out, state, count, j)
                count = np.int64(0)
                if j >= hi:
                    break


@rowloop(inline=True)
def no_state(data):
    return 0


@rowloop(inline=True)
def no_flush(out, state, count, j):
    return None


def _eval_of(name, run, start=no_state, flush=no_flush, cap=-1):
    """The evaluation loop (a RowLoop over the new times) whose runs `run` evaluates."""
    return rowloop(rows=1)(specialise(_eval, name, START=start, RUN=run, FLUSH=flush, CAP=cap))


@element
def _segment(times, seg, sg):
    """(t0, h, n, x0): the start and length of segment sg, where its table row starts,
    and a zero of the output type (like() on an array inside the loop stops the vectoriser)."""
    t0 = times[sg]
    return t0, times[sg + 1] - t0, NSEG * sg, like(seg, 0.0)


@rowloop(inline=True)
def run_slerp(times, new_t, seg, out, sg, j, e, state, count):
    t0, h, n, x0 = _segment(times, seg, sg)
    p = E.loads(seg, n, 4)
    q = E.loads(seg, n + 12, 4)
    c = E.loads(seg, n + 16, 5)
    for i in range(j, e):
        E.store4(out, i, arc_slerp(p, q, c, like(x0, (E.load1(new_t, i) - t0) / h)))
    return e, count


@rowloop(inline=True)
def run_nlerp(times, new_t, seg, out, sg, j, e, state, count):
    t0, h, n, x0 = _segment(times, seg, sg)
    p = E.loads(seg, n, 4)
    q = E.loads(seg, n + 12, 4)
    for i in range(j, e):
        t = like(x0, (E.load1(new_t, i) - t0) / h)
        E.store4(out, i, nlerp4(p, q, like(t, 1.0) - t, t))
    return e, count


@rowloop(inline=True)
def run_squad(times, new_t, seg, out, sg, j, e, state, count):
    t0, h, n, x0 = _segment(times, seg, sg)
    q0, s0, s1, q1 = seg_keys(seg, n)
    c0 = E.loads(seg, n + 16, 5)
    c1 = E.loads(seg, n + 21, 5)
    for i in range(j, e):
        t = like(x0, (E.load1(new_t, i) - t0) / h)
        pq = arc_slerp(q0, q1, c0, t)
        ps = arc_slerp(s0, s1, c1, t)
        E.store4(out, i, slerp4(pq, ps, like(t, 2.0) * t * (like(t, 1.0) - t), like(t, 0.0)))
    return e, count


@rowloop(inline=True)
def bezier_tile(out, tile, count, j):
    """Evaluate the `count` samples waiting in a tile (see :func:`start_bezier`: SIMD over
    its lanes, into its result planes), then store them in their rows j − count … j − 1 of
    `out`. The FLUSH of the Bézier method, inlined at _eval's one place (one copy of the
    long de Casteljau chain), with 512-bit vectors where the CPU has them. Level by
    level, each a loop over the lanes of its own, through planes of the tile: a lane's
    chain in one loop was longer than the CPU could overlap with the next lanes'
    (10⁴ keys → 10⁶ samples 1.3x faster so, bit for bit the same)."""
    prefer_wide_vectors()
    groups = (count + LANES - 1) // LANES
    for g in range(groups):  # level 1: the slerps on the segment's three fixed arcs
        for k in range(LANES):
            lane = g * LANES + k
            col = E.loads_at(tile, lane, TILE, NSEG)  # the lane's table row
            u = E.load1(tile, U + lane)
            E.stores_at(tile, MID + lane, TILE, arc_slerp(col[0:4], col[4:8], col[16:21], u)
                        + arc_slerp(col[4:8], col[8:12], col[21:26], u) + arc_slerp(col[8:12], col[12:16], col[26:31], u))
    for g in range(groups):  # level 2: two slerps of moving ends
        for k in range(LANES):
            lane = g * LANES + k
            p = E.loads_at(tile, MID + lane, TILE, 12)
            u = E.load1(tile, U + lane)
            zero = like(u, 0.0)
            E.stores_at(tile, MID + 12 * TILE + lane, TILE, slerp4(p[0:4], p[4:8], u, zero) + slerp4(p[4:8], p[8:12], u, zero))
    for g in range(groups):  # level 3: the curve
        for k in range(LANES):
            lane = g * LANES + k
            p = E.loads_at(tile, MID + 12 * TILE + lane, TILE, 8)
            u = E.load1(tile, U + lane)
            E.stores_at(tile, RES + lane, TILE, slerp4(p[0:4], p[4:8], u, like(u, 0.0)))
    for lane in range(count):
        E.stores(out, 4 * (j - count + lane), E.loads_at(tile, RES + lane, TILE, 4))


@rowloop(inline=True)
def start_bezier(seg):
    """A block's tile, zeros: its samples' table rows column by column, their u, the results
    (see ``U``, ``RES``); allocated by :func:`quatarray._jit.scratch` (numba's ``np.zeros``
    was 0.07 s of the Bézier first calls' compile)."""
    return scratch(TILE_FLOATS, seg)


@rowloop(inline=True)
def fill_tile(seg, n, tile, count, m):
    """Table row n (flat) into lanes count … count + m − 1 of the tile: the samples of a
    run share their segment's row, read once, and a loop over them, free of loads,
    stores each plane's value into consecutive lanes (SIMD stores). The row read again
    for each sample, in a loop whose trip count LLVM could not tell, left one scalar store
    a float a sample: a fifth of the Bézier spline's time (10⁴ keys → 10⁶ samples 19.4-20.2
    → 16.4-16.6 ms)."""
    row = E.loads(seg, n, NSEG)
    for i in range(m):
        E.stores_at(tile, count + i, TILE, row)


@rowloop(inline=True)
def run_bezier(times, new_t, seg, out, sg, j, e, tile, count):
    """Samples j, j + 1, … wait in the tile until the run ends or the tile is full."""
    t0, h, n, x0 = _segment(times, seg, sg)
    m = e - j if e - j < TILE - count else TILE - count
    fill_tile(seg, n, tile, count, m)
    for i in range(m):
        E.store1(tile, U + count + i, like(x0, (E.load1(new_t, j + i) - t0) / h))
    return j + m, count + m


def run_bezier_rates(times, new_t, seg, out, sg, j, e, tile, count):
    """:func:`run_bezier` for the rates: each waiting sample's 1/h or 1/h² (``ORDER``
    1, 2) too, in the fourth plane of the tile's results. The row goes in sample by
    sample, as a column: :func:`fill_tile`'s SIMD loop, free in the values' first call,
    cost the rates' 0.1 s more of compiling (first calls stay within their figures)."""
    t0, h, n, x0 = _segment(times, seg, sg)
    inv_h = like(x0, 1.0 / h)
    scale = inv_h if ORDER == 1 else inv_h * inv_h
    i = j
    while i < e and count < TILE:
        E.stores_at(tile, count, TILE, E.loads(seg, n, NSEG))  # the sample's table row, as a column
        tile[U + count] = like(x0, (new_t[i] - t0) / h)
        tile[RES + 3 * TILE + count] = scale
        count += 1
        i += 1
    return i, count


def bezier_rate_tile(out, tile, count, j):
    """The FLUSH of the Bézier rates (``ORDER`` 1 angular velocity, 2 acceleration; `out`
    flat (3m,)): the derivative rules of :mod:`quatarray._rates` (as :func:`_run_rates`
    for the other methods) on the samples waiting in a tile (see :func:`bezier_tile`):
    the rates of the three fixed control arcs, then of the two levels of slerps of
    moving ends, SIMD over its lanes, with 512-bit vectors where the CPU has them
    (:func:`quatarray._jit.prefer_wide_vectors`). A run-by-run loop ran as SIMD only
    over the samples of one segment (a run of four was one 256-bit vector, of three or
    five scalar code)."""
    prefer_wide_vectors()
    for g in range((count + LANES - 1) // LANES):
        for k in range(LANES):
            lane = g * LANES + k
            col = E.loads_at(tile, lane, TILE, NSEG)  # the lane's table row
            q0, a, b, q1 = col[0:4], col[4:8], col[8:12], col[12:16]
            c0, c1, c2 = col[16:21], col[21:26], col[26:31]
            ul = E.load1(tile, U + lane)
            x0 = like(ul, 0.0)
            one = like(ul, 1.0)
            w0 = arc_rotvec(q0, c0[0], (c0[1], c0[2], c0[3], c0[4]))
            w1 = arc_rotvec(a, c1[0], (c1[1], c1[2], c1[3], c1[4]))
            w2 = arc_rotvec(b, c2[0], (c2[1], c2[2], c2[3], c2[4]))
            p01 = arc_slerp(q0, a, c0, ul)
            p12 = arc_slerp(a, b, c1, ul)
            p23 = arc_slerp(b, q1, c2, ul)
            if ORDER == 1:
                s012, w012, _x = slerp_rates(p01, w0, p12, w1, ul, one)
                s123, w123, _x = slerp_rates(p12, w1, p23, w2, ul, one)
                v = slerp_rates(s012, w012, s123, w123, ul, one)[1]
            else:
                s012, w012, g012 = slerp_acc_fixed(p01, w0, p12, w1, ul, one, x0)
                s123, w123, g123 = slerp_acc_fixed(p12, w1, p23, w2, ul, one, x0)
                v = slerp_acc(s012, w012, g012, s123, w123, g123, ul, one, x0)[2]
            scale = E.load1(tile, RES + 3 * TILE + lane)
            E.stores_at(tile, RES + lane, TILE, (v[0] * scale, v[1] * scale, v[2] * scale))
    for lane in range(count):
        E.stores(out, 3 * (j - count + lane), E.loads_at(tile, RES + lane, TILE, 3))


# Sorted new times of more than PIECES_MIN_KEYS keys go through the table piece by
# piece: each piece of PIECE_SAMPLES samples builds only the rows of the segments it
# spans (for keys as dense as the samples, a table of about 1 MB that stays in
# cache) and evaluates its samples from them; the pieces run in parallel. Fewer
# keys make a whole table that stays in cache anyway (4096 rows of 248 bytes), and
# take the whole-table kernels, which unsorted new times use too: a first call
# compiles less (0.3 s for Bézier) and sorted and unsorted calls share it.
PIECE_SAMPLES = 4096
PIECES_MIN_KEYS = 4097
SEGMENT_LOOP = EVAL_LOOP = None  # bound in each method's copy (_PIECES, _RATE_PIECES)
WIDTH = 4  # floats per sample of `out`: 4 (the curve), 3 (its rates); rebound with EVAL_LOOP
ZEROED = False  # whether a piece's table starts as zeros (rates of a method with fewer than three arcs)


@element
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

    `out` flat (WIDTH·m,); ``SEGMENT_LOOP`` and ``EVAL_LOOP`` are the serial table and
    evaluation loops of the method (one compiled copy per method, see
    ``_PIECES``; for the rates, ``_RATE_PIECES``, the rate loop of an order).
    Samples are assigned to segments as in the whole table (a piece's last
    segment ends before the next piece's first sample, except the stream's last
    segment, which includes times[K−1]).
    """
    m = new_t.shape[0]
    for p in prange((m + PIECE_SAMPLES - 1) // PIECE_SAMPLES):
        j0 = p * PIECE_SAMPLES
        j1 = min(m, j0 + PIECE_SAMPLES)
        s0 = seg_index(times, new_t[j0])
        s1 = seg_index(times, new_t[j1 - 1]) + 1
        if ZEROED:  # the rate loops read every arc column (a method's unused ones as zeros)
            seg = np.zeros((s1 - s0, NSEG), out.dtype)
        else:
            seg = np.empty((s1 - s0, NSEG), out.dtype)
        SEGMENT_LOOP(q[s0 : s1 + 1], c_out[s0 : s1 + 1], c_in[s0 : s1 + 1], seg)
        EVAL_LOOP(times[s0 : s1 + 1], new_t[j0:j1], seg.reshape(-1), out[WIDTH * j0 : WIDTH * j1])


# ---- the rates of the curves (order 1, 2) and the cubic spline


@element
def _arc_rate(seg, n, c, p):
    """The constant body rate per unit u of the fixed arc at column c of a table row."""
    a = E.loads(seg, n + c, 5)
    return arc_rotvec(p, a[0], (a[1], a[2], a[3], a[4]))


ORDER = 1  # 1 angular velocity, 2 angular acceleration: rebound in each copy of _run_rates, _run_cubic


def _run_rates(times, new_t, seg, out, sg, j, e, state, count):
    """Angular velocity (``ORDER`` 1) or acceleration (2) of the curve of the method
    whose table ``KIND`` is (see :func:`_segments`; slerp, squad, nlerp: the Bézier
    curve's rates are :func:`bezier_rate_tile`) on one run of samples (`out` flat
    (3m,)): the derivative rules of :mod:`quatarray._rates` on the table's fixed arcs
    (their constant rates) and the slerps of moving ends above them."""
    t0, h, n, x0 = _segment(times, seg, sg)
    zero3 = (x0, x0, x0)
    one = like(x0, 1.0)
    q0, a, b, q1 = seg_keys(seg, n)
    inv_h = like(x0, 1.0 / h)
    scale = inv_h if ORDER == 1 else inv_h * inv_h
    # the rates of the table's fixed arcs (those a method does not have are not used)
    w0 = _arc_rate(seg, n, 16, q0)
    w1 = _arc_rate(seg, n, 21, a)
    for i in range(j, e):
        u = like(x0, (E.load1(new_t, i) - t0) / h)
        if KIND == 0:
            v = w0 if ORDER == 1 else zero3
        if KIND == 3:
            c = (q0[0] + u * (q1[0] - q0[0]), q0[1] + u * (q1[1] - q0[1]), q0[2] + u * (q1[2] - q0[2]),
                 q0[3] + u * (q1[3] - q0[3]))
            dq = (q1[0] - q0[0], q1[1] - q0[1], q1[2] - q0[2], q1[3] - q0[3])
            cc = E.qdot(c, c)
            d = E.qmul(E.qconj(c), dq)
            f = like(x0, 2.0) / cc
            v = (f * d[1], f * d[2], f * d[3])
            if ORDER == 2:
                v = E.vscale(v, -like(x0, 2.0) * E.qdot(c, dq) / cc)
        if KIND == 2:
            pq = arc_slerp(q0, q1, E.loads(seg, n + 16, 5), u)
            ps = arc_slerp(a, b, E.loads(seg, n + 21, 5), u)
            w = like(x0, 2.0) * u * (one - u)
            dw = like(x0, 2.0) - like(x0, 4.0) * u
            if ORDER == 1:
                v = slerp_rates(pq, w0, ps, w1, w, dw)[1]
            else:
                v = slerp_acc_fixed(pq, w0, ps, w1, w, dw, like(x0, -4.0))[2]
        E.store1(out, 3 * i, v[0] * scale)
        E.store1(out, 3 * i + 1, v[1] * scale)
        E.store1(out, 3 * i + 2, v[2] * scale)
    return e, count



def _run_cubic(times, new_t, data, out, sg, j, e, state, count):
    """``method="cubic"``: samples of the curve (``ORDER`` 0: quaternions, flat (4m,)),
    its angular velocity (1) or acceleration (2) (flat (3m,)) on one run of samples,
    from `data` = (the keys, flat (4K,); the segments' coefficients, flat (9(K − 1),), see
    :mod:`quatarray._cubic`): the segment's key and coefficients are read once."""
    keys, coef = data
    t0 = times[sg]
    x0 = like(coef, 0.0)
    qn = E.load4(keys, sg)
    b = _cubic.NCOEF * sg
    c0 = (coef[b], coef[b + 1], coef[b + 2])
    c1 = (coef[b + 3], coef[b + 4], coef[b + 5])
    c2 = (coef[b + 6], coef[b + 7], coef[b + 8])
    for i in range(j, e):
        tau = like(x0, E.load1(new_t, i) - t0)
        rv = (((c0[0] * tau + c1[0]) * tau + c2[0]) * tau, ((c0[1] * tau + c1[1]) * tau + c2[1]) * tau,
              ((c0[2] * tau + c1[2]) * tau + c2[2]) * tau)
        n2 = rv[0] * rv[0] + rv[1] * rv[1] + rv[2] * rv[2]
        hs, hc = sincos(like(x0, 0.5) * np.sqrt(n2))
        if ORDER == 0:
            E.store4(out, i, E.qmul(qn, qexp_half(rv, n2, hs, hc)))
        else:
            three = like(x0, 3.0)
            two = like(x0, 2.0)
            rd = ((three * c0[0] * tau + two * c1[0]) * tau + c2[0],
                  (three * c0[1] * tau + two * c1[1]) * tau + c2[1],
                  (three * c0[2] * tau + two * c1[2]) * tau + c2[2])
            k1, k2 = jac_coeffs(n2, hs, hc)
            if ORDER == 1:
                v = jac(rv, k1, k2, rd)
            else:
                six = like(x0, 6.0)
                rdd = (six * c0[0] * tau + two * c1[0], six * c0[1] * tau + two * c1[1],
                       six * c0[2] * tau + two * c1[2])
                j1, j2 = acc_coeffs(n2, hs, hc)
                a = jac(rv, k1, k2, rdd)
                nl = jac_dot(rv, rd, j1, j2, k2)
                v = (a[0] + nl[0], a[1] + nl[1], a[2] + nl[2])
            E.store1(out, 3 * i, v[0])
            E.store1(out, 3 * i + 1, v[1])
            E.store1(out, 3 * i + 2, v[2])
    return e, count



def _resample_cubic(t, nt, q, order):
    """:func:`resample_unit` for ``method="cubic"``: :func:`cubic_curve` at `nt`."""
    return cubic_curve(t, q)(nt, order)


def cubic_curve(t, q):
    """``method="cubic"`` over planned key times `t` and unit, unflipped keys `q`,
    solved once: the coefficients of scipy's RotationSpline
    (:func:`quatarray._cubic.coefficients`, float64), and a function ``at(nt,
    order=0)`` of planned new times (any shape) that runs one evaluation loop in the
    keys' float type. For new times that come in pieces (the command line's
    ``resample --method cubic``): the system over all keys is solved once."""
    coef, _ = _cubic.coefficients(t, q)
    flat_q = np.ascontiguousarray(q).reshape(-1)
    flat_c = coef.astype(q.dtype, copy=False).reshape(-1)

    def at(nt, order=0):
        flat_nt = np.ascontiguousarray(nt.reshape(-1))
        width = 3 if order else 4
        out = np.empty(flat_nt.shape[0] * width, q.dtype)
        if out.shape[0]:
            _EVAL_CUBIC[order](t, flat_nt, (flat_q, flat_c), out)
        return out.reshape(nt.shape + (width,))

    return at


def _outside(lo, hi, x):
    """True when some x is not within [lo, hi] (nan included: numpy's min and max
    propagate it). Two vectorised reductions: no kernel to compile."""
    return x.size > 0 and not (x.min() >= lo and x.max() <= hi)


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
    if _outside(t[0], t[-1], flat_nt):
        i = int(np.argmax(~((flat_nt >= t[0]) & (flat_nt <= t[-1]))))
        raise ValueError(
            f"Expected `new_times` within [{t_raw[0].item()}, {t_raw[-1].item()}] (the key times), "
            f"got {nt_raw.reshape(-1)[i].item()} at flat index {index0 + i}."
        )
    return t, nt


def spline(times, keys, new_times, method="bezier", order=0):
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
    method : {"bezier", "slerp", "nlerp", "squad", "cubic"}
        ``"bezier"``: segment n is ``bezier(q_n, a_n, b_{n+1}, q_{n+1}, u)``
        with the controls of ``bezier_controls(keys, times)``: for evenly
        spaced times exactly the contract's formula; for uneven spacing the
        tangent arcs at key n are scaled by 2h_n/(h_{n−1}+h_n) (outgoing) and
        2h_{n−1}/(h_{n−1}+h_n) (incoming), h_n = t_{n+1} − t_n, so the angular
        velocity is continuous in time across keys. ``"slerp"``, ``"nlerp"``:
        piecewise great arc / normalised chord. ``"squad"``: Shoemake's squad
        with :func:`squad_controls` (no time scaling). ``"cubic"``: scipy's
        :class:`~scipy.spatial.transform.RotationSpline` (C² in time: the
        angular rate and acceleration are continuous; its global rate system
        and iteration, see :mod:`quatarray._cubic`), equal to it within 1e-10
        in values, rates and accelerations.
    order : {0, 1, 2}
        0: the rotations. 1: the curve's angular velocity, 2: its angular
        acceleration, both ``(..., 3)`` in the body frame (the moving frame's
        axes) in radians per time unit of `times` (per second for seconds, per
        nanosecond for ns stamps), as scipy's ``RotationSpline(t, r)(new_t,
        order)``. They are the analytic derivatives of the method's own curve,
        not finite differences: slerp's rate is constant on each segment
        (Log(q_n* q_{n+1})/h_n; acceleration 0, the rate jumps at keys);
        for Bézier the de Casteljau chain is differentiated slerp by slerp:
        a slerp of moving ends s = a ⊗ Exp(w Log(a* ⊗ b)) has body rate
        Ω_s = R(E)ᵀ Ω_a + J(y) y', E = Exp(y), y = w r, r = Log(a* ⊗ b),
        y' = w' r + w J(r)⁻¹ (Ω_b − R(a* ⊗ b)ᵀ Ω_a), J the right Jacobian,
        starting from the constant rates of the three fixed control arcs
        (and likewise for squad's outer slerp with w = 2u(1 − u), and the
        accelerations one derivative further; see :mod:`quatarray._rates`).
        The time-scaled Bézier controls make its rate continuous across keys.

    Returns
    -------
    ndarray, shape ``new_times.shape + (4,)`` (``order`` 0) or
    ``new_times.shape + (3,)``, dtype of the keys.

    Raises
    ------
    ValueError
        `times` not strictly increasing, shapes that do not match, a new time
        outside the key range (the message names the first one), unknown
        method, `order` not 0, 1 or 2.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> keys = qa.from_rotvec([[0, 0, 0], [0, 0, 0.5], [0, 0, 1.0]])
    >>> r = qa.spline([0, 1, 2], keys, [0.0, 0.5, 2.0])
    >>> np.allclose(qa.as_rotvec(r)[:, 2], [0, 0.25, 1.0])
    True
    >>> np.round(qa.spline([0, 1, 2], keys, [0.5, 1.5], order=1), 12) + 0.0  # 0.5 rad per unit about z
    array([[0. , 0. , 0.5],
           [0. , 0. , 0.5]])
    >>> from scipy.spatial.transform import Rotation, RotationSpline
    >>> t = [0, 1, 2.5, 3]
    >>> q = qa.from_rotvec([[0, 0, 0], [0.2, 0, 0.5], [0.4, 0.3, 1.0], [0.5, 0.2, 1.6]])
    >>> ref = RotationSpline(t, Rotation.from_quat(q, scalar_first=True))
    >>> np.allclose(qa.spline(t, q, [0.3, 2.2], method="cubic", order=2), ref([0.3, 2.2], 2), rtol=0, atol=1e-10)
    True
    """
    order = spline_order(order)
    check_method(method)
    q = key_array(keys)
    t, nt = plan_times(key_times(as_times(times, "times"), q.shape[0]), as_times(new_times, "new_times"))
    return resample_unit(t, nt, unit_keys([q]), method, order)


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


UNIT_BLOCK = 256  # rows of _unit_unflip's block: its normalised rows stay in L1


@rowloop(parallel=False)
def _unit_unflip(p, out, a, flip0):
    """Rows a … a + len(p) − 1 of `out`: the rows of `p` normalised (:func:`quatarray.normalize`),
    each negated when :func:`unflip` would negate it after the row before in `out`
    (:func:`quatarray._slerp.unflip_sign`: a negative dot product, or the tie rule);
    the first row of `out` is negated instead when `flip0`.

    Block by block: a loop free of the sign chain normalises the rows (LLVM
    vectorises it); then the sign chain runs over their dot products with the unit
    row before, not the row as it stands (a negated row only negates its dot
    products, exactly), so that a row waits for the one before by a boolean
    operation only: 0.67 against 0.93 ms for 125 000 keys, where the row-by-row
    loop made every row wait for the one before. The bits are those of that loop
    (a block's first row is negated with a sign flip, the others, which have no
    nan when negated, times −1), but for the sign bit of a nan row, which
    normalising leaves as its vectorised or scalar code makes it (as
    :func:`quatarray.normalize` does)."""
    zero = like(out, 0.0)
    one = like(out, 1.0)
    neg = False  # whether the row before, as it stands in `out`, is its unit row negated
    # the sign of unflip_sign (−1 negate, 1 keep, 0: a zero or nan row) in place of the
    # dot product's (the tie rule of quatarray._slerp)
    for base in range(0, p.shape[0], UNIT_BLOCK):
        m = UNIT_BLOCK if UNIT_BLOCK < p.shape[0] - base else p.shape[0] - base  # (not min: an overload)
        i0 = a + base
        for k in range(m):
            E.store4(out, i0 + k, E.qnormalize(E.load4(p, base + k)))
        r = E.load4(out, i0)  # the block's first unit row: the row before of the next
        if i0 == 0:
            neg = flip0
        else:  # the row before is final: compare with it as it stands
            neg = unflip_sign(E.load4(out, i0 - 1), r) < zero
        if neg:
            E.store4(out, i0, E.qneg(r))
        for k in range(1, m):
            u = E.load4(out, i0 + k)
            # the sign after the row before as it stands is ±d: negative when
            # d < 0 and that row kept, or d > 0 and that row negated; 0 never
            d = unflip_sign(r, u)
            neg = (neg & ((d < zero) | (d > zero))) != (d < zero)
            f = -one if neg else one
            E.store4(out, i0 + k, (f * u[0], f * u[1], f * u[2], f * u[3]))
            r = u


def resample_unit(t, nt, q, method, order=0):
    """:func:`spline` on times `t`, new times `nt` (as :func:`plan_times` gives them)
    and unit, unflipped keys `q`."""
    if _METHODS[method].resample is not None:
        return _METHODS[method].resample(t, nt, q, order)
    k = q.shape[0]
    flat_nt = np.ascontiguousarray(nt.reshape(-1))
    c_out, c_in = _METHODS[method].controls(q, t)
    m = flat_nt.shape[0]
    if order:  # the whole table (zeros: the rate loops read every arc column), then the rate loop
        out = np.empty((m, 3), q.dtype)
        if k >= PIECES_MIN_KEYS and m > 1 and (flat_nt[1:] >= flat_nt[:-1]).all():
            _RATE_PIECES[method, order](t, flat_nt, q, c_out, c_in, out.reshape(-1))
        elif m:
            seg = np.zeros((k - 1, NSEG), q.dtype)
            _SEGMENTS[method](q, c_out, c_in, seg)
            _RATES[method, order](t, flat_nt, seg.reshape(-1), out.reshape(-1))
        return out.reshape(nt.shape + (3,))
    out = np.empty((m, 4), q.dtype)
    if k >= PIECES_MIN_KEYS and m > 1 and (flat_nt[1:] >= flat_nt[:-1]).all():
        _PIECES[method](t, flat_nt, q, c_out, c_in, out.reshape(-1))
    elif m:
        seg = np.empty((k - 1, NSEG), q.dtype)
        _SEGMENTS[method](q, c_out, c_in, seg)
        _EVALS[method](t, flat_nt, seg.reshape(-1), out.reshape(-1))
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
    run: object  # RUN of _eval: the samples of one run from their segment's table row
    start: object = no_state  # START of _eval: a block's state (samples waiting)
    flush: object = no_flush  # FLUSH of _eval: evaluate the samples waiting
    cap: int = -1  # CAP of _eval: how many samples may wait (-1: none wait)
    # a method without a segment table (cubic: one global system over all keys) does
    # all of resample_unit itself: resample(t, nt, q, order) -> the result
    resample: Callable = None


def _no_controls(q, t):
    return q, q  # slerp, nlerp: none (the table's columns 4-11 repeat the keys)


def _squad_controls(q, t):
    s = controls_squad(q)
    return s, s


_METHODS = {
    "bezier": Method(1, controls_bezier, run_bezier, start_bezier, bezier_tile, TILE),
    "slerp": Method(0, _no_controls, run_slerp),
    "nlerp": Method(3, _no_controls, run_nlerp),
    "squad": Method(2, _squad_controls, run_squad),
    "cubic": Method(-1, None, None, resample=_resample_cubic),
}
TABLED = {name: m for name, m in _METHODS.items() if m.resample is None}
# each table method's compiled loops: the evaluation loop, the table, and both in pieces
# (the piece kernel calls the serial whole-table loops, which a first call on fewer
# keys has typed and compiled already: inlining them ran numba's front end again)
_EVALS = {name: _eval_of(f"_{name}", m.run, m.start, m.flush, m.cap) for name, m in TABLED.items()}
_SEGMENTS = {name: rowloop(rows=3)(specialise(_segments, f"_{name}", KIND=m.kind)) for name, m in TABLED.items()}
_PIECES = {
    name: rowloop(rows=1)(specialise(_spline_pieces, f"_{name}", EVAL_LOOP=_EVALS[name].serial,
                                     SEGMENT_LOOP=_SEGMENTS[name].serial))
    for name, m in TABLED.items()
}
# order 1 and 2 of the table methods: one rate loop per (method, order), on the whole table;
# the Bézier rates in tiles, as its values (their chain is the longest)
_RATES = {(name, order): _eval_of(f"_rates_{name}_{order}",
                                  rowloop(specialise(_run_rates, f"_{name}_{order}", KIND=m.kind, ORDER=order), inline=True))
          for name, m in TABLED.items() if name != "bezier" for order in (1, 2)}
for _order in (1, 2):
    _RATES["bezier", _order] = _eval_of(
        f"_rates_bezier_{_order}", rowloop(specialise(run_bezier_rates, f"_{_order}", ORDER=_order), inline=True),
        start_bezier, rowloop(specialise(bezier_rate_tile, f"_{_order}", ORDER=_order), inline=True), TILE)
# the rates of sorted new times over many keys, piece by piece as _PIECES (the rate loop
# on each piece's table: a table that stays in cache, built in parallel)
_RATE_PIECES = {
    (name, order): rowloop(rows=1)(specialise(_spline_pieces, f"_rates_{name}_{order}",
                                              EVAL_LOOP=_RATES[name, order].serial,
                                              SEGMENT_LOOP=_SEGMENTS[name].serial, WIDTH=3, ZEROED=m.kind != 1))
    for name, m in TABLED.items() for order in (1, 2)
}
_EVAL_CUBIC = {order: _eval_of(f"_cubic_{order}", element(specialise(_run_cubic, f"_{order}", ORDER=order)))
               for order in (0, 1, 2)}
