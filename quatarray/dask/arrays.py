"""Dask twins of the element-wise functions (one factory), the blocked scans
(``cumprod``, ``unflip``, ``integrate_angular_velocity``), ``align_vectors``
(problems block by block) and ``mean`` (a reduction across blocks); see
:mod:`quatarray.dask`.

Task functions run the in-memory kernels on one block, serially
(``_jit.serial()``, for the task's thread only): the scheduler (threads or
worker processes) supplies the parallelism, and numba threads inside every
task would oversubscribe the cores.
"""

import importlib
import inspect
import math
import operator

import dask.array as da
import numpy as np
from dask.base import tokenize
from dask.core import flatten as _flatten_keys
from dask.highlevelgraph import HighLevelGraph
from dask.layers import ArrayValuesDep

from .. import _WHERE, _jit
from .._validate import as_float, check_core, is_weak, leading, origin, result_dtype

Q, V, M3 = (4,), (3,), (3, 3)

def _public(name):
    """The in-memory function `name`, from the module the package registers it in
    (``quatarray._MODULES``): tasks pickle the name, workers import the module."""
    return getattr(importlib.import_module(f"quatarray.{_WHERE[name]}"), name)


# --------------------------------------------------------------------------
# element-wise functions: one factory


class _Block:
    """The per-block call of a public function (picklable by value: a name and constants).

    With `located`, the first argument is the block's first index along the
    leading axes: a row an error message names is counted in the whole array.
    """

    def __init__(self, name, arrays, consts, nout, located=False):
        self.name, self.arrays, self.consts, self.nout = name, tuple(arrays), dict(consts), nout
        self.located = located

    def __call__(self, *blocks):
        start = ()
        if self.located:
            start, blocks = blocks[0], blocks[1:]
        kwargs = dict(self.consts)
        kwargs.update(zip(self.arrays, blocks))
        with _jit.serial(), origin(start):
            return _public(self.name)(**kwargs)

    def __dask_tokenize__(self):
        return (type(self).__name__, self.name, self.arrays, sorted(self.consts.items(), key=str), self.nout,
                self.located)

    def __repr__(self):
        return f"quatarray.{self.name}"


def _float_rule(dtypes):
    return result_dtype([np.empty(0, d) for d in dtypes])


def _su2_rule(dtypes):
    return np.dtype(np.complex64) if _float_rule(dtypes) == np.float32 else np.dtype(np.complex128)


def _from_su2_rule(dtypes):
    return np.dtype(np.float32) if all(d in (np.complex64, np.float32) for d in dtypes) else np.dtype(np.float64)


def _bool_rule(dtypes):
    return np.dtype(np.bool_)


def _check_dtype(x, name, rule):
    """The dtype a block of `x` is computed in (TypeError for complex/object, as in memory)."""
    if rule is _from_su2_rule and x.dtype.kind == "c":
        return x.dtype
    return as_float(np.empty(0, x.dtype), name).dtype


def as_dask(x, name="q", core=Q):
    """`x` as a Dask array whose last ``len(core)`` axes are one chunk.

    numpy arrays and lists become one-chunk Dask arrays (Dask unifies their
    chunks with the other arguments); Dask arrays chunked along a core axis
    are rechunked to hold that axis whole.

    Examples
    --------
    >>> import dask.array as da, quatarray.dask as qd
    >>> qd.as_dask(da.zeros((10, 4), chunks=(5, 2))).chunks
    ((5, 5), (4,))
    """
    if not isinstance(x, da.Array):
        a = np.asarray(x)
        x = da.from_array(a, chunks=a.shape or -1)
    check_core(x, name, core)
    known_chunks(x, name)
    k = len(core)
    split = {ax: -1 for ax in range(x.ndim - k, x.ndim) if len(x.chunks[ax]) > 1}
    if split:
        x = x.rechunk(split)
    return x


def known_chunks(x, name):
    """A ValueError for a Dask array whose chunk sizes are unknown (after boolean indexing)."""
    if any(math.isnan(c) for cs in x.chunks for c in cs):
        raise ValueError(f"Expected `{name}` with known chunk sizes, got unknown ones; "
                         f"call `{name}.compute_chunk_sizes()` first.")


def _leaves(tmp, name, outs, metas):
    """Split a blockwise array whose blocks are tuples into one array per output."""
    keys = list(_flatten_keys(tmp.__dask_keys__()))
    res = []
    for j, (core, meta) in enumerate(zip(outs, metas)):
        leaf = f"{name}-{j}"
        zeros = (0,) * len(core)
        dsk = {(leaf,) + k[1:] + zeros: (operator.getitem, k, j) for k in keys}
        graph = HighLevelGraph.from_collections(leaf, dsk, dependencies=[tmp])
        chunks = tmp.chunks + tuple((c,) for c in core)
        res.append(da.Array(graph, leaf, chunks=chunks, meta=meta))
    return tuple(res)


def _elementwise(name, arrays, outs, rule=_float_rule):
    """Build the Dask twin of the element-wise public function `name`.

    arrays: ((parameter, core shape), ...) — the array arguments;
    outs: core shapes of the results; rule: result dtype from input dtypes.
    """

    def wrapper(*args, **kwargs):
        sig = inspect.signature(_public(name))
        bound = sig.bind(*args, **kwargs)
        if bound.arguments.pop("out", None) is not None:
            raise TypeError(
                f"quatarray.dask.{name} takes no `out=`: Dask arrays are immutable "
                "(store the lazy result with dask.array.store or .to_zarr)."
            )
        bound.apply_defaults()
        given = dict(bound.arguments)
        given.pop("out", None)
        xs, names, cores, dtypes = [], [], [], []
        for pname, core in arrays:
            value = given[pname]
            if is_weak(value) and core == ():
                continue  # a Python scalar stays a constant: it never upcasts float32
            x = as_dask(value, pname, core)
            dtypes.append(_check_dtype(x, pname, rule))
            given.pop(pname)
            xs.append(x)
            names.append(pname)
            cores.append(core)
        if not xs:
            raise TypeError(f"quatarray.dask.{name} needs at least one array argument.")
        lead = leading(xs, cores, names)  # the in-memory broadcasting message
        dtype = rule(dtypes)
        nlead = len(lead)
        out_lead = tuple(f"l{i}" for i in range(nlead))
        pairs = []
        for x, pname, core in zip(xs, names, cores):
            k = len(core)
            ind = out_lead[nlead - (x.ndim - k) :] + tuple(f"{pname}.{j}" for j in range(k))
            pairs += [x, ind]
        call = _Block(name, names, given, len(outs), located=nlead > 0)
        token = tokenize(call, *xs)
        if nlead:  # each block is told where it starts, for errors that name a row
            chunkss, unified = da.core.unify_chunks(*pairs)
            pairs[::2] = unified
            lead_chunks = tuple(chunkss[i] for i in out_lead)
            starts = [np.cumsum((0,) + c)[:-1].tolist() for c in lead_chunks]
            where = {b: tuple(s[i] for s, i in zip(starts, b)) for b in np.ndindex(*map(len, lead_chunks))}
            pairs = [ArrayValuesDep(lead_chunks, where), out_lead] + pairs
        metas = [np.empty((0,) * (nlead + len(c)), dtype) for c in outs]
        if len(outs) == 1:
            ocore = tuple(f"out.{j}" for j in range(len(outs[0])))
            return da.blockwise(
                call, out_lead + ocore, *pairs, new_axes=dict(zip(ocore, outs[0])),
                concatenate=True, meta=metas[0], name=f"{name}-{token}", align_arrays=False,
            )
        tmp = da.blockwise(
            call, out_lead, *pairs, concatenate=True, meta=np.empty((0,) * nlead), name=f"{name}-tuple-{token}",
            align_arrays=False,
        )
        return _leaves(tmp, f"{name}-{token}", outs, metas)

    wrapper.__name__ = wrapper.__qualname__ = name
    wrapper.__module__ = __package__  # shown as quatarray.dask.<name>, its public home
    argtext = ", ".join(f"`{p}` {('(..., ' + ', '.join(map(str, c)) + ')') if c else '(...)'}" for p, c in arrays)
    wrapper.__doc__ = (
        f"Dask version of :func:`quatarray.{name}`: a lazy Dask array, block by block.\n\n"
        f"Same arguments as the in-memory function (no ``out=``); array arguments: {argtext}.\n"
        "Blocks are computed by the same kernel, so the result equals the in-memory one bitwise.\n"
    )
    return wrapper


ELEMENTWISE = {
    "multiply": ((("p", Q), ("q", Q)), (Q,)),
    "conjugate": ((("q", Q),), (Q,)),
    "inverse": ((("q", Q),), (Q,)),
    "normalize": ((("q", Q),), (Q,)),
    "norm": ((("q", Q),), ((),)),
    "dot": ((("p", Q), ("q", Q)), ((),)),
    "exp": ((("q", Q),), (Q,)),
    "log": ((("q", Q),), (Q,)),
    "power": ((("q", Q), ("t", ())), (Q,)),
    "canonical": ((("q", Q),), (Q,)),
    "angle": ((("q", Q),), ((),)),
    "distance": ((("p", Q), ("q", Q)), ((),)),
    "rotate": ((("q", Q), ("v", V)), (V,)),
    "as_matrix": ((("q", Q),), (M3,)),
    "from_matrix": ((("m", M3),), (Q,)),
    "as_rotvec": ((("q", Q),), (V,)),
    "from_rotvec": ((("r", V),), (Q,)),
    "as_axis_angle": ((("q", Q),), (V, ())),
    "from_axis_angle": ((("axis", V), ("angle", ())), (Q,)),
    "as_xyzw": ((("q", Q),), (Q,)),
    "from_xyzw": ((("a", Q),), (Q,)),
    "as_left_matrix": ((("q", Q),), ((4, 4),)),
    "as_right_matrix": ((("q", Q),), ((4, 4),)),
    "as_su2": ((("q", Q),), ((2, 2),), _su2_rule),
    "from_su2": ((("m", (2, 2)),), (Q,), _from_su2_rule),
    "as_euler": ((("q", Q),), (V,)),
    "from_euler": ((("angles", V),), (Q,)),
    "lerp": ((("p", Q), ("q", Q), ("t", ())), (Q,)),
    "nlerp": ((("p", Q), ("q", Q), ("t", ())), (Q,)),
    "slerp": ((("p", Q), ("q", Q), ("t", ())), (Q,)),
    "double": ((("p", Q), ("q", Q)), (Q,)),
    "bisect": ((("p", Q), ("q", Q)), (Q,)),
    "bezier": ((("q0", Q), ("a", Q), ("b", Q), ("q1", Q), ("t", ())), (Q,)),
    "as_mrp": ((("q", Q),), (V,)),
    "from_mrp": ((("p", V),), (Q,)),
    "as_gibbs": ((("q", Q),), (V,)),
    "from_gibbs": ((("g", V),), (Q,)),
    "rotation_between": ((("u", V), ("v", V)), (Q,)),
    "approx_equal": ((("p", Q), ("q", Q)), ((),), _bool_rule),
}

for _name, _spec in ELEMENTWISE.items():
    globals()[_name] = _elementwise(_name, *_spec)
del _name, _spec

# from_euler: the core of `angles` is (len(seq),), one twin per length
_FROM_EULER = {k: _elementwise("from_euler", (("angles", (k,)),), (Q,)) for k in (1, 2)}
_FROM_EULER[3] = globals()["from_euler"]


def from_euler(seq, angles, degrees=False):
    """Dask version of :func:`quatarray.from_euler`: a lazy Dask array, block by block.

    `angles` has shape ``(..., len(seq))`` (a 1-, 2- or 3-axis sequence; one angle
    about one axis may be a scalar); a bad `seq` raises at once, as in memory.
    Blocks are computed by the same kernel, so the result equals the in-memory one bitwise.
    """
    from ..euler import _parse_from_seq

    k = _parse_from_seq(seq)[2]
    if not hasattr(angles, "ndim"):
        angles = np.asarray(angles)
    if k == 1 and angles.ndim == 0:
        angles = angles[None]
    return _FROM_EULER[k](seq, angles, degrees=degrees)


from_euler.__module__ = __package__

# --------------------------------------------------------------------------
# blocked scans along a leading axis: cumprod and unflip


def _lead_axis(x, axis, fname):
    lead = x.ndim - 1
    if lead == 0:
        raise ValueError(f"Expected `q` to have shape (N, ..., 4) for {fname}, got {tuple(x.shape)}.")
    if not -lead <= axis < lead:
        raise ValueError(f"Expected `axis` in [{-lead}, {lead - 1}] for `q` of shape {tuple(x.shape)}, got {axis}.")
    return axis % lead


def _end_rows(a, which, axis):
    """Row 0 or −1 of `a` along `axis`, keeping the axis."""
    return np.take(a, [which], axis=axis)


# cumprod: local running products, each chunk's total carried forward


def _cumprod_local(block, axis):
    from ..algebra import cumprod

    with _jit.serial():
        return cumprod(block, axis=axis)


def _cumprod_summary(local, axis):
    return _end_rows(local, -1, axis) if local.shape[axis] else None


def _cumprod_carry(carry, prev, cur):
    # carry: product of every chunk before `prev`; returns the product through `prev`.
    if carry is None:
        return prev
    from ..algebra import multiply

    with _jit.serial():
        return multiply(carry, prev)


def _cumprod_apply(local, carry, axis):
    if carry is None:
        return local
    from ..algebra import multiply

    with _jit.serial():
        return multiply(carry, local)


# unflip: local flips, then one sign per chunk carried forward. The carry stops
# where the chain breaks: a row whose unflip sign after the row before is 0 (a
# zero or non-finite row, or the row after one; see quatarray._slerp.unflip_sign)
# is kept as it is whatever the sign before it, so from there on the block's own
# flips are the global ones.


def _sign_breaks(local, axis):
    """How many leading rows of a locally unflipped block (per line along `axis`,
    shaped like a row with a last axis of 1) take the sign carried into the block:
    up to the first row whose unflip sign after the row before is 0."""
    n = local.shape[axis]
    a = np.moveaxis(local, axis, 0)
    if n < 2:
        return np.expand_dims(np.full(a.shape[1:-1], n), (axis, -1))
    from ..interpolation import unflip_signs

    with _jit.serial():
        d = unflip_signs(a[:-1], a[1:])  # as unflip's kernel (its sign aside: 0 stays)
    broken = ~((d < 0) | (d > 0))
    reach = np.where(broken.any(axis=0), broken.argmax(axis=0) + 1, n)
    return np.expand_dims(reach, (axis, -1))


def _unflip_local(block, axis):
    from ..interpolation import unflip

    with _jit.serial():
        local = unflip(block, axis=axis)
    return local, _sign_breaks(local, axis)


def _unflip_summary(local, axis):
    local, reach = local
    n = local.shape[axis]
    return (_end_rows(local, 0, axis), _end_rows(local, -1, axis), reach == n) if n else None


def unflip_carry(carry, prev, cur):
    # carry: True where chunk `prev` was negated; returns the same for chunk `cur`.
    # prev[2]: whether prev's carry reaches its last row (no break in the chain)
    last = prev[1] if carry is None else np.where(carry & prev[2], -prev[1], prev[1])
    from ..interpolation import unflip_signs

    with _jit.serial():
        d = unflip_signs(last, cur[0])
    return (np.asarray(d) < 0)[..., None]


def _unflip_apply(local, carry, axis):
    local, reach = local
    if carry is None:
        return local
    shape = [1] * local.ndim
    shape[axis] = local.shape[axis]
    row = np.arange(local.shape[axis]).reshape(shape)
    return np.where(carry & (row < reach), -local, local)


def carry_all(carry_fn, summaries):
    """Every chunk's carry along one scan (None for the first chunk), in one task.

    An empty chunk (summary None) is passed over: the next chunk's carry comes from
    the last chunk that had rows."""
    carries, carry, prev = [], None, None
    for cur in summaries:
        if cur is None:
            carries.append(None)
            continue
        if prev is not None:
            carry = carry_fn(carry, prev, cur)
        carries.append(carry)
        prev = cur
    return carries


def _scan(x, axis, kind, local_fn, summary_fn, carry_fn, apply_fn):
    """A blocked prefix scan along leading `axis` of `x` (core axis whole).

    Per block: ``local_fn`` (the in-memory scan of the block) and
    ``summary_fn`` (what the next block needs, e.g. the last row). Per line of
    blocks along `axis`: one task runs ``carry_fn`` down the summaries (a
    cheap sequential pass over one small item per block). Per block again:
    ``apply_fn(local, carry)`` gives the global result. The graph depth stays
    four whatever the number of chunks.
    """
    token = tokenize(kind, x, axis)
    lname, sname, cname, oname = (f"{kind}-{p}-{token}" for p in ("local", "summary", "carry", "out"))
    nb = x.numblocks[axis]
    dsk = {}
    for idx in np.ndindex(*x.numblocks):
        i = idx[axis]
        dsk[(lname,) + idx] = (local_fn, (x.name,) + idx, axis)
        line = idx[:axis] + (0,) + idx[axis + 1 :]
        if nb == 1:
            dsk[(oname,) + idx] = (apply_fn, (lname,) + idx, None, axis)
            continue
        dsk[(sname,) + idx] = (summary_fn, (lname,) + idx, axis)
        if i == 0:
            dsk[(cname,) + line] = (
                carry_all, carry_fn, [(sname,) + idx[:axis] + (j,) + idx[axis + 1 :] for j in range(nb)]
            )
        dsk[(oname,) + idx] = (apply_fn, (lname,) + idx, (operator.getitem, (cname,) + line, i), axis)
    graph = HighLevelGraph.from_collections(oname, dsk, dependencies=[x])
    return da.Array(graph, oname, chunks=x.chunks, meta=x._meta)


def _scan_input(q, axis, fname):
    x = as_dask(q, "q", Q)
    dtype = as_float(np.empty(0, x.dtype), "q").dtype
    if x.dtype != dtype:
        x = x.astype(dtype)
    return x, _lead_axis(x, axis, fname)


def cumprod(q, axis=0):
    """Dask version of :func:`quatarray.cumprod`: out[i] = out[i−1]⊗q[i] along a leading axis.

    A blocked scan: every chunk's running product is computed in parallel,
    each chunk's total is carried across the borders (a short chain of
    quaternion products), and the carried product multiplies the chunk. The
    result equals the in-memory one up to rounding (the products are grouped
    differently), whatever the chunking.

    Examples
    --------
    >>> import dask.array as da, numpy as np, quatarray as qa, quatarray.dask as qd
    >>> q = qa.random(100, rng=2)
    >>> np.allclose(qd.cumprod(da.from_array(q, chunks=(7, 4))).compute(), qa.cumprod(q), atol=1e-13)
    True
    """
    x, ax = _scan_input(q, axis, "cumprod")
    return _scan(x, ax, "cumprod", _cumprod_local, _cumprod_summary, _cumprod_carry, _cumprod_apply)


def unflip(q, axis=0):
    """Dask version of :func:`quatarray.unflip`: sign continuity along a leading axis.

    A prefix scan: each chunk is unflipped on its own (in parallel), then one
    sign per chunk is carried across the borders (the dot product of a
    chunk's first row with the previous chunk's last row, already signed),
    and chunks whose sign is −1 are negated up to the first row whose dot
    product with the row before is 0 or nan (a zero or non-finite row, an
    exact quarter turn: the in-memory scan keeps that row, and so the rest,
    whatever came before). Equal to the in-memory result bitwise, whatever
    the chunking.

    Examples
    --------
    >>> import dask.array as da, numpy as np, quatarray as qa, quatarray.dask as qd
    >>> q = qa.random(50, rng=3)
    >>> np.array_equal(qd.unflip(da.from_array(q, chunks=(4, 4))).compute(), qa.unflip(q))
    True
    """
    x, ax = _scan_input(q, axis, "unflip")
    return _scan(x, ax, "unflip", _unflip_local, _unflip_summary, unflip_carry, _unflip_apply)


# --------------------------------------------------------------------------
# rows across block borders (integrate_angular_velocity here, spline and
# angular_velocity in quatarray.dask.windows)


def _concat_rows(parts):
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


def row_pieces(x, a, b, dsk, cut=None):
    """Task expressions for rows [a, b) of `x` (chunked along axis 0 only), one per
    block they fall in (whole blocks are the blocks' keys).

    Rows taken from part of a block are cut by a small task of their own, added
    to `dsk`: it runs where the block is kept, so only those rows travel to the
    worker that needs them, not the whole block. Or `cut` gives the expression
    for them: ``cut(i, (lo, hi))``, rows ``lo:hi`` of block `i` (None: a task of
    their own after all).
    """
    starts = np.cumsum((0,) + x.chunks[0])
    first = int(np.searchsorted(starts, a, side="right")) - 1
    parts = []
    for i in range(first, len(x.chunks[0])):
        lo, hi = starts[i], starts[i + 1]
        if lo >= b:
            break
        key = (x.name, i) + (0,) * (x.ndim - 1)
        if a <= lo and hi <= b:
            parts.append(key)
            continue
        rows = int(max(a, lo) - lo), int(min(b, hi) - lo)
        expr = None if cut is None else cut(i, rows)
        if expr is not None:
            parts.append(expr)
            continue
        task = (f"rows-{x.name}", i) + rows
        dsk[task] = (operator.getitem, key, slice(*rows))
        parts.append(task)
    return parts


def row_window(x, a, b, dsk):
    """A task expression for rows [a, b) of `x` as one array (see :func:`row_pieces`)."""
    return (_concat_rows, row_pieces(x, a, b, dsk))


# --------------------------------------------------------------------------
# integrate_angular_velocity: each block from the identity, the orientation carried


def _integrate_task(omega, times, frame, hold, index0):
    # the block's rows and the first row of the next block: local orientations from
    # the identity, through the step that crosses into the next block
    from ..kinematics import integrate_angular_velocity

    with _jit.serial():
        return integrate_angular_velocity(omega, times, frame=frame, hold=hold, _index0=index0)


def _integrate_carries(q0, body, *locals_):
    """The orientation where each block starts: q0, then each block's local end
    (its row past the block) applied in turn."""
    from ..algebra import multiply

    carries = [q0]
    with _jit.serial():
        for local in locals_[:-1]:
            end, c = local[-1], carries[-1]
            carries.append(multiply(c, end) if body else multiply(end, c))
    return carries


def _integrate_apply(local, carries, j, size, body):
    from ..algebra import multiply

    c = carries[j]
    with _jit.serial():
        return multiply(c, local[:size]) if body else multiply(local[:size], c)


def integrate_angular_velocity(omega, times, q0=None, frame="space", hold="mean"):
    """Dask version of :func:`quatarray.integrate_angular_velocity`: ``(N, 4)``, a blocked scan.

    Each block is integrated from the identity on its rows plus the first row
    of the next block (the step across the border: ``hold="mean"`` needs the
    next rate), in parallel; one task carries the orientation from block to
    block (q0, then each block's end applied in turn); each block is then
    multiplied by the orientation where it starts. The steps are taken in the
    times' own type, so int64 nanoseconds stay exact. Equal to the in-memory
    result to rounding (about 1e-13: the products are grouped differently),
    whatever the chunking. `times` may be a Dask array (rechunked like
    `omega`) or a numpy array.

    Examples
    --------
    >>> import dask.array as da, numpy as np, quatarray as qa, quatarray.dask as qd
    >>> t = np.linspace(0, 1, 50)
    >>> w = np.tile([0, 0, 2.0], (50, 1))  # 2 rad/s about z
    >>> q = qd.integrate_angular_velocity(da.from_array(w, chunks=(8, 3)), t).compute()
    >>> np.allclose(q, qa.from_rotvec(np.outer(t, [0, 0, 2.0])))
    True
    """
    from ..kinematics import check_options

    check_options(frame, hold)
    x = as_dask(omega, "omega", V)
    if x.ndim != 2:
        raise ValueError(f"Expected `omega` to have shape (N, 3), got {tuple(x.shape)}.")
    dtype = as_float(np.empty(0, x.dtype), "omega").dtype
    if x.dtype != dtype:
        x = x.astype(dtype)
    if q0 is None:
        start = np.array([1.0, 0.0, 0.0, 0.0], dtype)
    else:
        start = check_core(as_float(q0, "q0"), "q0", Q)
        if start.ndim != 1:
            raise ValueError(f"Expected `q0` to have shape (4,), got {start.shape}.")
        dtype = result_dtype([np.empty(0, dtype), start])
    tt = times if isinstance(times, da.Array) else da.from_array(np.asarray(times))
    if tt.ndim != 1 or tt.shape[0] != x.shape[0]:
        raise ValueError(f"Expected `times` to have shape ({x.shape[0]},) like `omega`, got {tuple(tt.shape)}.")
    if tt.dtype.kind not in "iuf":
        raise TypeError(f"Expected `times` to have a real (float or integer) dtype, got {tt.dtype}.")
    tt = tt.rechunk((x.chunks[0],))
    n = x.shape[0]
    body = frame == "body"
    token = tokenize("integrate_angular_velocity", x, tt, start, frame, hold)
    lname, cname, name = (f"integrate-{p}-{token}" for p in ("local", "carry", "out"))
    dsk, locals_, a = {}, [], 0
    for j, size in enumerate(x.chunks[0]):
        b = a + size
        w1 = min(n, b + 1)
        if w1 > a:
            dsk[(lname, j)] = (_integrate_task, row_window(x, a, w1, dsk), row_window(tt, a, w1, dsk), frame, hold, a)
        else:  # an empty last block
            dsk[(lname, j)] = np.zeros((0, 4), dtype)
        locals_.append((lname, j))
        a = b
    dsk[cname] = (_integrate_carries, start, body) + tuple(locals_)
    for j, size in enumerate(x.chunks[0]):
        dsk[(name, j, 0)] = (_integrate_apply, (lname, j), cname, j, size, body)
    graph = HighLevelGraph.from_collections(name, dsk, dependencies=[x, tt])
    return da.Array(graph, name, chunks=(x.chunks[0], (4,)), meta=np.empty((0, 0), dtype))


# --------------------------------------------------------------------------
# align_vectors: problems chunked along the leading axes, each problem's pairs whole


def _pair_input(x, name):
    """`x` as a Dask array of shape (..., n, 3) (a single vector (3,) is one pair, as in memory)."""
    x = as_dask(x, name, V)
    if x.ndim == 1:
        x = x[None]
    if x.ndim < 2:
        raise ValueError(f"Expected `{name}` to have shape (..., n, 3), got {tuple(x.shape)}.")
    return x


def _align_rule(dtypes):
    return _float_rule(dtypes[:2])  # as in memory: the weights take the vectors' type


def align_vectors(a, b, weights=None, return_sensitivity=False):
    """Dask version of :func:`quatarray.align_vectors`: a batch of problems, block by block.

    `a` and `b` have shape ``(..., n, 3)`` and `weights` ``(..., n)``: the problems
    are chunked along the leading axes and each block is solved by the in-memory
    kernel, so the results (``q``, ``rssd`` and, with ``return_sensitivity=True``,
    the sensitivity matrices) equal the in-memory ones bitwise. A problem's n pairs
    are one chunk (an array chunked along them is rechunked): for one problem of
    very many pairs, use the in-memory function. Leading dimensions broadcast, as
    in memory. Errors about a problem's values (negative weights, several infinite
    weights, zero primary vectors) are raised at compute, naming the problem's index
    in the whole batch; the warning for problems whose optimum is not unique is
    given by the block's task (on a worker, in its log).

    Examples
    --------
    >>> import dask.array as da, numpy as np, quatarray as qa, quatarray.dask as qd
    >>> b = np.random.default_rng(0).standard_normal((100, 5, 3))  # 100 problems of 5 pairs
    >>> a = qa.rotate(qa.random((100, 1), rng=1), b)
    >>> q, rssd = qd.align_vectors(da.from_array(a, chunks=(30, 5, 3)), b)
    >>> q.chunks[0], bool(np.array_equal(q.compute(), qa.align_vectors(a, b)[0]))
    ((30, 30, 30, 10), True)
    """
    av, bv = _pair_input(a, "a"), _pair_input(b, "b")
    n = av.shape[-2]
    if bv.shape[-2] != n:
        raise ValueError(
            f"Expected `a` and `b` to hold the same number of vectors, got shapes {tuple(av.shape)} and "
            f"{tuple(bv.shape)}."
        )
    arrays = [("a", (n, 3)), ("b", (n, 3))]
    if weights is not None:
        if not isinstance(weights, da.Array):
            weights = np.asarray(weights)
        if weights.ndim == 0:
            weights = weights[None]
        if weights.shape[-1] != n:
            raise ValueError(f"Expected `weights` to have shape (..., {n}), got {tuple(weights.shape)}.")
        arrays.append(("weights", (n,)))
    outs = (Q, ()) + ((M3,) if return_sensitivity else ())
    twin = _elementwise("align_vectors", tuple(arrays), outs, _align_rule)
    return twin(av, bv, weights=weights, return_sensitivity=return_sensitivity)


align_vectors.__module__ = __package__


# --------------------------------------------------------------------------
# mean: each block's sums Σ w q qᵀ/|q|², summed across blocks, then one solve


def _mean_block(start, qb, *wb, red):
    from ..algebra import mean_check_weights, mean_sums

    w = wb[0] if wb else np.ones(qb.shape[:-1])
    with _jit.serial(), origin(start):
        if wb:
            mean_check_weights(w)
        acc = mean_sums(qb, w, red)
    return np.expand_dims(acc, red)  # the reduced axes kept, of length 1 (summed next)


def _mean_finish(acc, dtype):
    from ..algebra import mean_solve

    return mean_solve(np.array(acc, np.float64), dtype)  # a copy: the block may be shared


def mean(q, weights=None, axis=None):
    """Dask version of :func:`quatarray.mean`: the rotation mean over leading axes, across chunks.

    Each block adds up its own 4×4 sums Σ wᵢ qᵢqᵢᵀ/|qᵢ|² (in float64, the
    in-memory kernel) over the axes being averaged; Dask sums the blocks' sums
    (a tree reduction), and one task per result takes the eigenvector, as in
    memory. The answer is the in-memory one up to the order of the float64
    sums, whatever the chunking: within 1e-13 rad even where the mean is
    ill-conditioned (uniformly random rotations, whose sums are nearly
    isotropic); with the averaged axes in one chunk, bitwise. `weights` may be a Dask array or a numpy array. A bad row
    (a zero, inf or nan quaternion, a negative, inf or nan weight) is reported
    at compute, named by its index in the whole array.

    Examples
    --------
    >>> import dask.array as da, numpy as np, quatarray as qa, quatarray.dask as qd
    >>> q = qa.random(1000, rng=4)
    >>> m = qd.mean(da.from_array(q, chunks=(300, 4)))
    >>> bool(qa.distance(m.compute(), qa.mean(q)) < 1e-14)
    True
    >>> qd.mean(da.from_array(q.reshape(10, 100, 4), chunks=(5, 30, 4)), axis=1).shape
    (10, 4)
    """
    from ..algebra import mean_axes

    x = as_dask(q, "q", Q)
    dtype = as_float(np.empty(0, x.dtype), "q").dtype
    if x.dtype != dtype:
        x = x.astype(dtype)
    if x.ndim == 1 and (axis is not None or np.ndim(weights) > 0):
        x = x[None]  # one quaternion has one leading axis of length 1, as in memory
    red = mean_axes(x.shape, axis)
    if x.ndim == 1:  # a single quaternion, reduced over no axis: the same as over a leading axis of 1
        x, red = x[None], (0,)
    lead = x.shape[:-1]
    nlead = len(lead)
    idx = tuple(f"l{i}" for i in range(nlead))
    args = [x, idx + ("c",)]
    if weights is not None:
        w = weights if isinstance(weights, da.Array) else as_float(weights, "weights", np.float64)
        as_float(np.empty(0, w.dtype), "weights")  # TypeError for complex, object, strings
        try:
            shape = np.broadcast_shapes(tuple(w.shape), lead)
        except ValueError:
            shape = None
        if shape != lead:
            raise ValueError(f"Expected `weights` to broadcast to {lead}, got {tuple(w.shape)}.")
        if not isinstance(w, da.Array):
            w = da.from_array(w, chunks=w.shape or -1)
        known_chunks(w, "weights")
        w = da.broadcast_to(w.astype(np.float64), lead).rechunk(x.chunks[:-1])
        args += [w, idx]
    lead_chunks = x.chunks[:-1]
    starts = [np.cumsum((0,) + c)[:-1].tolist() for c in lead_chunks]
    where = {b: tuple(s[i] for s, i in zip(starts, b)) for b in np.ndindex(*map(len, lead_chunks))}
    token = tokenize("mean", x, *args[2::2], red)
    sums = da.blockwise(
        _mean_block, idx + ("c", "d"), ArrayValuesDep(lead_chunks, where), idx, *args,
        new_axes={"d": 4}, adjust_chunks={idx[k]: 1 for k in red}, concatenate=True,
        meta=np.empty((0,) * (nlead + 2)), name=f"mean-sums-{token}", align_arrays=False, red=red,
    )
    total = sums.sum(axis=red)
    keep = total.ndim - 2
    return total.map_blocks(
        _mean_finish, dtype, drop_axis=keep + 1, chunks=total.chunks[:keep] + ((4,),),
        meta=np.empty((0,) * (keep + 1), dtype), name=f"mean-{token}",
    )


mean.__module__ = __package__


__all__ = ["as_dask", "cumprod", "unflip", "integrate_angular_velocity", "align_vectors", "mean", *ELEMENTWISE]
