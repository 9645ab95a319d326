"""Dask twins that need the neighbouring rows across chunk borders: :func:`spline`
(windows of keys around each output block, the keys' signs carried across the
blocks first) and :func:`angular_velocity`; see :mod:`quatarray.dask`."""

import operator
import uuid

import dask
import dask.array as da
import numpy as np
from dask.base import tokenize
from dask.delayed import Delayed
from dask.highlevelgraph import HighLevelGraph

from .._validate import as_float, spline_order
from .. import _jit
from .arrays import Q, as_dask, carry_all, known_chunks, row_pieces, row_window, unflip_carry


# --------------------------------------------------------------------------
# neighbours across chunk borders: spline and angular_velocity


def _materialise(x, name):
    """`x` as a 1-D numpy array (a Dask array is computed: times are small next to keys)."""
    if isinstance(x, da.Array):
        x = x.compute()
    a = np.asarray(x)
    if a.dtype.kind not in "biuf":
        raise TypeError(f"Expected `{name}` to have a real dtype, got {a.dtype}.")
    if a.ndim != 1:
        raise ValueError(f"Expected `{name}` to have shape (N,), got {a.shape}.")
    return a


def _flip_summary(block, rows):
    """What the sign scan needs of one key block: its first row, its last row after
    the block is unflipped on its own, whether that negated each of `rows` (the
    windows' first rows in this block), how many leading rows take the sign carried
    into the block (see :func:`quatarray.dask.arrays._sign_breaks`) and whether that is all of them
    (``full``); keys normalised first, as
    :func:`quatarray.spline` does. One pass, nothing the size of the block written.
    Also the block's first and last ``EDGE_ROWS`` rows as they are: the rows
    neighbouring windows take from it travel with the summary."""
    from ..splines import sign_summary

    if not len(block):
        return None
    block = np.ascontiguousarray(block)
    ends = np.empty((2, 4), block.dtype)
    negated = np.zeros(len(rows), np.bool_)
    tile = min(len(block), 1024)
    unit, dots = np.empty((tile + 1, 4), block.dtype), np.empty(tile, block.dtype)
    reach = sign_summary(block, np.asarray(rows, np.int64), ends, negated, unit, dots)
    full = np.array([[reach == len(block)]])
    edges = block[:EDGE_ROWS].copy(), block[-EDGE_ROWS:].copy()
    return ends[:1], ends[1:], full, reach, dict(zip(rows, negated.tolist())), edges


# Up to this many key blocks, each spline window finds the sign carried into its first
# block from the summaries before it (a graph of two layers); beyond, one task carries
# the signs across all blocks first (the windows' inputs then stay few).
_FEW_BLOCKS = 16
# The rows at each end of a key block that travel with its sign summary (which the
# windows after it fetch for the sign carried, or the carries task beyond
# _FEW_BLOCKS): neighbouring windows take theirs from there (a window reaches one
# key before its first sample's segment and two after its last: with output blocks
# split where key blocks start, a few rows). Other rows taken from part of a block
# (output blocks that do not start near where key blocks do) are cut by a task of
# their own.
EDGE_ROWS = 8


def _carries(summaries):
    """The sign carried into every key block (None for the first and for empty blocks),
    from their summaries."""
    return carry_all(unflip_carry, [None if f is None else f[:3] for f in summaries])


def _carry_into(summaries):
    """The sign carried into the last of `summaries`' blocks."""
    return _carries(summaries)[-1]


def _window_flip(carry, summary, row):
    """Whether the global unflip negates `row` of a key block, from the sign carried
    into the block and the block's summary."""
    _, _, _, reach, negated, _ = summary
    carried = carry is not None and bool(np.ravel(carry)[0]) and row < reach
    return carried != negated[row]


def _edge_rows(summary, end, lo, hi):
    """Rows ``lo:hi`` of a key block's first (`end` 0) or last (1) edge rows."""
    return summary[5][end][lo:hi]


def _spline_task(times, pieces, flip0, new_times, method, origin, order=0):
    """The in-memory spline on a window of keys given in pieces (its rows in the
    blocks it spans), its first row taking the global sign; integer times are taken
    from `origin`, the whole stream's first key time, as in memory."""
    from .._validate import key_times
    from ..splines import plan_times, resample_unit, unit_keys

    with _jit.serial():
        q = unit_keys(pieces, flip0)
        t, nt = plan_times(key_times(times, len(q)), np.asarray(new_times), origin=origin)
        return resample_unit(t, nt, q, method, order)


def _output_chunks(nt, cuts, n_key_blocks, chunks):
    """Row boundaries of the output blocks for new times `nt` (seconds) held here.

    `chunks` rows each if given; else, for sorted new times, one block per key
    block, split at `cuts` (the key times, in seconds, where key blocks 1, 2, …
    start; None when the key times are lazy: the new times are then split
    evenly into as many blocks as there are key blocks).
    """
    m = nt.shape[0]
    if chunks is not None:
        sizes = [min(int(chunks), m - a) for a in range(0, m, int(chunks))]
    elif cuts is not None and m and np.all(np.diff(nt) >= 0):
        edges = np.unique(np.concatenate(([0], np.searchsorted(nt, cuts, side="left"), [m])))
        sizes = list(np.diff(edges))
    else:
        per = max(1, -(-m // max(1, n_key_blocks)))
        sizes = [min(per, m - a) for a in range(0, m, per)]
    return [int(s) for s in sizes if s > 0] or [0]


def _split(a, sizes):
    edges = np.cumsum([0] + sizes)
    return [a[i:j] for i, j in zip(edges[:-1], edges[1:])]


def _span(part):
    """The earliest and latest of some new times (None when there are none)."""
    return (part.min(), part.max()) if part.size else None


def _span_task(block, t_ends, start):
    """:func:`_span` of a block of new times, or the in-memory ValueError for its first
    time outside the keys' span `t_ends` (returned, so that the first block's error is
    the one raised; `start` is the block's first index)."""
    from ..splines import plan_times

    try:
        plan_times(t_ends, block, start)
    except ValueError as exc:
        return exc
    return _span(block)


def _span_pass(nt_d, starts, t_ends):
    """Each block of a Dask array of new times' span, in one pass, or the in-memory
    ValueError for its first time outside the keys' span `t_ends`."""
    spans = dask.compute(*[
        dask.delayed(_span_task, pure=True)(b, t_ends, int(a)) for b, a in zip(nt_d.to_delayed().ravel(), starts)
    ])
    for f in spans:
        if isinstance(f, ValueError):
            raise f
    return spans


def _span_ends(spans, dtype):
    """The output blocks' earliest and latest new times in one array, and where each
    block's two are in it (None for an empty block, or one holding an error)."""
    values, at = [], []
    for s in spans:
        if s is None or isinstance(s, Exception):
            at.append(None)
            continue
        at.append(len(values))
        values += [s[0], s[1]]
    return np.array(values, dtype), at


def _lazy_parts(new_times, chunks):
    """A Dask array of new times as output blocks: one per block of it (rechunked to
    `chunks` rows if given), each interpolated where it lives. Returns the array, the
    blocks' keys, their sizes and their first indices."""
    known_chunks(new_times, "new_times")
    nt_d = new_times if chunks is None else new_times.rechunk(int(chunks))
    if nt_d.ndim != 1:
        raise ValueError(f"Expected `new_times` to have shape (N,), got {tuple(nt_d.shape)}.")
    if nt_d.dtype.kind not in "biuf":
        raise TypeError(f"Expected `new_times` to have a real dtype, got {nt_d.dtype}.")
    starts = np.cumsum((0,) + nt_d.chunks[0])[:-1]
    return nt_d, [(nt_d.name, j) for j in range(nt_d.numblocks[0])], list(nt_d.chunks[0]), starts


def _plan_given_times(t_raw, new_times, chunks, key_chunks):
    """The spline's plan (see :func:`_plan_lazy_times`) for key times held here: their
    windows travel in the graph. New times held here need no pass over anything; a
    Dask array of them takes one small pass for each block's span (which raises the
    in-memory message for a time outside the keys' span)."""
    from ..splines import plan_times, seconds

    ends = t_raw[[0, -1]]
    if isinstance(new_times, da.Array):
        nt_d, parts, sizes, starts = _lazy_parts(new_times, chunks)
        spans, deps, nt_dtype = _span_pass(nt_d, starts, ends), [nt_d], nt_d.dtype
    else:
        nt_raw = _materialise(new_times, "new_times")
        _, nt = plan_times(ends, nt_raw)
        starts = np.cumsum((0,) + tuple(key_chunks))[1:-1]
        cuts = seconds(t_raw[starts[starts < t_raw.shape[0]]], nt_raw[:0], ends[0])[0]
        sizes = _output_chunks(nt, cuts, len(key_chunks), chunks)
        parts = _split(nt_raw, sizes)
        spans, deps, nt_dtype = [_span(p) for p in parts], [], nt_raw.dtype
    t = seconds(t_raw, np.empty(0, nt_dtype), ends[0])[0]
    values, at = _span_ends(spans, nt_dtype)
    found = np.searchsorted(t, seconds(ends, values, ends[0])[1], side="right")
    segs = [None if m is None else found[m : m + 2] for m in at]
    return parts, sizes, segs, deps, lambda w0, w1, dsk: t_raw[w0:w1], ends[0]


def _key_time_block(block, start, origin, spans, nt_dtype):
    """What planning needs of one block of lazy key times (None when it is empty):
    its first and last times; its first pair that does not increase, as (index in
    the whole array, time, next time), or None; and, for each end of an output
    block's span (see :func:`_span_ends`) within the block's times, how many of
    its times are ≤ that end (in seconds from `origin`, the first key time, when
    both are integers: see ``splines.seconds``)."""
    from .._validate import first_not_increasing
    from ..splines import seconds

    if not block.size:
        return None
    i = first_not_increasing(block)
    worst = None if i is None else (start + i, block[i], block[i + 1])
    values, _ = _span_ends(spans, nt_dtype)
    t, v = seconds(block, values, origin)
    inside = np.flatnonzero((v >= t[0]) & (v <= t[-1]))
    counts = dict(zip(inside.tolist(), np.searchsorted(t, v[inside], side="right").tolist()))
    return block[0], block[-1], worst, counts


def _plan_lazy_times(tt, k, new_times, chunks, key_chunks):
    """The spline's plan for key times in a Dask array, whose blocks stay on the workers.

    One pass of small tasks: each block of new times' span (for a Dask array of
    them), then per block of key times its order checked and where the spans'
    ends fall in it. Each window of key times then comes from the workers
    holding it, not through the graph.

    Returns (parts, sizes, segs, deps, times_window, origin): per output block
    its new times (an array or a task key), its size, and ``searchsorted(times,
    span, "right")`` of its span (None when empty); the Dask arrays the graph
    reads; a function giving the task expression of key times ``[w0, w1)``; and
    the first key time (integer times are counted from it).
    """
    from .._validate import check_times, not_increasing
    from ..splines import plan_times, seconds

    check_times(tt, k, "times")
    known_chunks(tt, "times")
    name = f"spline-plan-{uuid.uuid4().hex}"
    dsk = {}
    lazy_nt = isinstance(new_times, da.Array)
    if lazy_nt:
        nt_d, parts, sizes, starts = _lazy_parts(new_times, chunks)
        spans = [(name, "span", j) for j in range(len(parts))]
        dsk.update({key: (_span, part) for key, part in zip(spans, parts)})
        deps, nt_dtype = [tt, nt_d], nt_d.dtype
    else:
        nt_raw = _materialise(new_times, "new_times")
        sizes = _output_chunks(nt_raw, None, len(key_chunks), chunks)
        parts = _split(nt_raw, sizes)
        spans, deps, nt_dtype = [_span(p) for p in parts], [tt], nt_raw.dtype
    # integer times are taken from the first key time: the blocks need it
    ints = tt.dtype.kind in "biu" and nt_dtype.kind in "biu"
    origin = (operator.getitem, row_window(tt, 0, 1, dsk), 0) if ints else None
    tstarts = np.cumsum((0,) + tt.chunks[0])
    blocks = [(name, "block", i) for i in range(tt.numblocks[0])]
    for i, key in enumerate(blocks):
        dsk[key] = (_key_time_block, (tt.name, i), int(tstarts[i]), origin, spans, nt_dtype)
    graph = HighLevelGraph.from_collections(name, dsk, dependencies=deps)
    out = dask.compute(*[Delayed(key, graph, layer=name) for key in blocks + (spans if lazy_nt else [])])
    infos, spans = out[: len(blocks)], (out[len(blocks) :] if lazy_nt else spans)
    last = None
    for i, info in enumerate(infos):  # the first pair out of order, as in memory
        if info is None:
            continue
        if last is not None and not info[0] > last:
            raise not_increasing("times", int(tstarts[i]) - 1, last, info[0])
        if info[2] is not None:
            raise not_increasing("times", *info[2])
        last = info[1]
    full = [i for i, info in enumerate(infos) if info is not None]
    ends = np.array([infos[full[0]][0], last], tt.dtype)
    if not lazy_nt:
        plan_times(ends, nt_raw)  # a new time outside the keys' span: the in-memory message
    elif not all(s is None or _inside(ends, np.array(s, nt_dtype)) for s in spans):
        _span_pass(nt_d, starts, ends)  # raises the in-memory message, naming the time
    firsts = seconds(np.array([infos[i][0] for i in full], tt.dtype), np.empty(0, nt_dtype), ends[0])[0]
    values, at = _span_ends(spans, nt_dtype)
    values = seconds(ends, values, ends[0])[1]

    def found(m):  # searchsorted(times, values[m], "right") from the blocks' counts
        c = int(np.searchsorted(firsts, values[m], side="right")) - 1
        if c < 0:
            return 0
        i = full[c]
        return int(tstarts[i]) + infos[i][3].get(m, tt.chunks[0][i])

    segs = [None if m is None else np.array([found(m), found(m + 1)]) for m in at]
    return parts, sizes, segs, deps, lambda w0, w1, dsk: row_window(tt, w0, w1, dsk), ends[0]


def _inside(t_ends, nt_raw):
    """Whether new times are within the key times' span (nan is not)."""
    from ..splines import plan_times

    try:
        plan_times(t_ends, nt_raw)
    except ValueError:
        return False
    return True


def spline(times, keys, new_times, method="bezier", chunks=None, order=0):
    """Dask version of :func:`quatarray.spline`: resample a key stream, lazily in the keys.

    Each output block runs the in-memory :func:`quatarray.spline` on the new
    times it holds and the keys its segments need — one key before and two
    after, taken across chunk borders. The keys' sign continuity (the
    in-memory spline unflips the whole stream) is a prefix scan: one small
    task per key block finds the block's own sign flips (and keeps the rows
    at its two ends, which neighbouring windows take from it); each
    window carries the signs across the borders before it to find the global
    sign of its first key (with more than 16 key blocks, one task carries
    them for all). So the result equals the in-memory one (to rounding)
    whatever the chunking, in ``2·blocks`` tasks (one more beyond 16 blocks;
    plus a small task per window that starts away from a key block's ends, or
    per window of key times given as a Dask array, to cut its rows where they
    are kept).

    Times given as numpy arrays are read when this function is called, and
    their slices travel in the graph. Times given as Dask arrays
    (``da.linspace``, ``t0 + da.arange(n) / rate``, a persisted or stored
    array) stay on the workers, where their blocks are generated or read: a
    first pass of small tasks finds what the graph needs of them (each block
    of new times' span; each block of key times checked and searched for
    those spans). A stream too long for one machine therefore never passes
    through this process: give its key times as a Dask array too. Either way,
    key times out of order and new times outside the keys' span raise here,
    with the in-memory message.

    Parameters
    ----------
    times : array_like or Dask array, shape (K,)
        Strictly increasing key times; a Dask array may be chunked unlike
        the keys.
    keys : Dask array or array_like, shape (K, 4)
    new_times : array_like or Dask array, shape (M,)
    method : {"bezier", "slerp", "nlerp", "squad"}
        Not ``"cubic"``: its C² spline is global (one tridiagonal system over
        all keys), which key windows cannot give exactly; it raises
        ``ValueError`` (call :func:`quatarray.spline` on the keys in memory).
    chunks : int, optional
        Rows per output block. Default: the chunks of `new_times` when it is
        a Dask array; else, for sorted new times, one output block per key
        block (split where the key blocks start, or evenly when the key
        times are a Dask array).

    order : {0, 1, 2}
        As :func:`quatarray.spline`: the values, the angular velocity or the
        angular acceleration (from the same key windows).

    Returns
    -------
    dask.array.Array, shape (M, 4), or (M, 3) for ``order`` 1 and 2

    Examples
    --------
    >>> import dask.array as da, numpy as np, quatarray as qa, quatarray.dask as qd
    >>> t = np.arange(40.0)
    >>> keys = qa.from_rotvec(np.c_[np.sin(t / 5), np.cos(t / 7), t / 9])
    >>> nt = np.linspace(0, 39, 500)
    >>> lazy = qd.spline(t, da.from_array(keys, chunks=(7, 4)), nt)
    >>> np.allclose(lazy.compute(), qa.spline(t, keys, nt), rtol=0, atol=1e-13)
    True
    """
    from .._validate import key_times
    from ..splines import check_method

    if method == "cubic":
        raise ValueError("Expected `method` to be one of ['bezier', 'nlerp', 'slerp', 'squad'] in quatarray.dask, "
                         "got 'cubic': its C² spline is global (one tridiagonal system over all keys), which Dask's "
                         "key windows cannot give exactly; call quatarray.spline on the keys in memory.")
    order = spline_order(order)
    width = 3 if order else 4
    check_method(method)
    x = as_dask(keys, "keys", Q)
    if x.ndim != 2:
        raise ValueError(f"Expected `keys` to have shape (K, 4), got {tuple(x.shape)}.")
    k = x.shape[0]
    if k < 2:
        raise ValueError(f"Expected `keys` to hold at least 2 keys, got {k}.")
    dtype = as_float(np.empty(0, x.dtype), "keys").dtype
    x = x.astype(dtype)
    if chunks is not None and (isinstance(chunks, bool) or not isinstance(chunks, (int, np.integer)) or chunks < 1):
        raise ValueError(f"Expected `chunks` to be a positive integer (rows per output block), got {chunks!r}.")
    if isinstance(times, da.Array):
        plan = _plan_lazy_times(times, k, new_times, chunks, x.chunks[0])
    else:
        plan = _plan_given_times(key_times(times, k), new_times, chunks, x.chunks[0])
    parts, sizes, segs, deps, times_window, origin = plan
    # a fresh name rather than a hash of (maybe 10⁸) new times: hashing them cost more than
    # building the graph, and two calls then never share results
    token = uuid.uuid4().hex
    name, sname, cname = (f"spline{p}-{token}" for p in ("", "-summary", "-carries"))
    dsk = {}
    nb = x.numblocks[0]
    starts = np.cumsum((0,) + x.chunks[0])[:-1]
    rows = [set() for _ in range(nb)]  # the windows' first rows, block by block

    def edge(i, lohi):  # rows at either end of block i come with its summary
        lo, hi = lohi
        tail = max(0, x.chunks[0][i] - EDGE_ROWS)  # where the last edge rows start
        if hi <= EDGE_ROWS:
            return (_edge_rows, (sname, i), 0, lo, hi)
        if lo >= tail:
            return (_edge_rows, (sname, i), 1, lo - tail, hi - tail)
        return None

    if nb > _FEW_BLOCKS:
        dsk[cname] = (_carries, [(sname, i) for i in range(nb)])
    for j, (part, seg) in enumerate(zip(parts, segs)):
        if seg is None:
            dsk[(name, j, 0)] = (np.empty, (0, width), dtype)
            continue
        # the segments of the block's earliest and latest new times bound all of its segments
        seg = np.clip(seg - 1, 0, k - 2)
        w0, w1 = max(0, int(seg[0]) - 1), min(k, int(seg[1]) + 3)
        c = int(np.searchsorted(starts, w0, side="right")) - 1
        rows[c].add(int(w0 - starts[c]))
        carry = (operator.getitem, cname, c) if nb > _FEW_BLOCKS else (_carry_into, [(sname, i) for i in range(c + 1)])
        flip = (_window_flip, carry, (sname, c), int(w0 - starts[c]))
        dsk[(name, j, 0)] = (_spline_task, times_window(w0, w1, dsk), row_pieces(x, w0, w1, dsk, edge), flip, part, method,
                             origin, order)
    for i in range(nb):
        dsk[(sname, i)] = (_flip_summary, (x.name, i, 0), sorted(rows[i]))
    graph = HighLevelGraph.from_collections(name, dsk, dependencies=[x] + deps)
    return da.Array(graph, name, chunks=(tuple(sizes), (width,)), meta=np.empty((0, 0), dtype))


def _angular_velocity_task(q, times, frame, lo, hi):
    from ..interpolation import angular_velocity

    with _jit.serial():
        return angular_velocity(q, times, frame=frame)[lo:hi]


_AV_DEPTH = 2  # rows of neighbours each side that angular_velocity's differences can reach


def angular_velocity(q, times, frame="space"):
    """Dask version of :func:`quatarray.angular_velocity`: ``(N, 3)`` rad/s, block by block.

    Each block is computed by the in-memory function on its rows plus
    neighbouring rows across the chunk borders (taken from the adjacent
    blocks, however small), and trimmed: the same numbers as in memory,
    whatever the chunking. `times` may be a Dask array (it is rechunked like
    `q`) or a numpy array.

    Examples
    --------
    >>> import dask.array as da, numpy as np, quatarray as qa, quatarray.dask as qd
    >>> t = np.linspace(0, 1, 50)
    >>> q = qa.from_rotvec(np.c_[0 * t, 0 * t, 2 * t])  # 2 rad/s about z
    >>> w = qd.angular_velocity(da.from_array(q, chunks=(8, 4)), t).compute()
    >>> np.allclose(w, [0, 0, 2])
    True
    """
    x = as_dask(q, "q", Q)
    if x.ndim != 2:
        raise ValueError(f"Expected `q` to have shape (N, 4), got {tuple(x.shape)}.")
    if frame not in ("space", "body"):
        raise ValueError(f"Expected `frame` to be 'space' or 'body', got {frame!r}.")
    tt = times if isinstance(times, da.Array) else da.from_array(as_float(times, "times", np.float64))
    if tt.ndim != 1 or tt.shape[0] != x.shape[0]:
        raise ValueError(f"Expected `times` to have shape ({x.shape[0]},) like `q`, got {tuple(tt.shape)}.")
    tt = tt.rechunk((x.chunks[0],))
    dtype = as_float(np.empty(0, x.dtype), "q").dtype
    n = x.shape[0]
    token = tokenize("angular_velocity", x, tt, frame)
    name = f"angular_velocity-{token}"
    dsk = {}
    a = 0
    for j, size in enumerate(x.chunks[0]):
        b = a + size
        w0, w1 = max(0, a - _AV_DEPTH), min(n, b + _AV_DEPTH)
        dsk[(name, j, 0)] = (
            _angular_velocity_task, row_window(x, w0, w1, dsk), row_window(tt, w0, w1, dsk), frame, a - w0, b - w0
        )
        a = b
    graph = HighLevelGraph.from_collections(name, dsk, dependencies=[x, tt])
    return da.Array(graph, name, chunks=(x.chunks[0], (3,)), meta=np.empty((0, 0), dtype))


__all__ = ["spline", "angular_velocity"]
