"""quatarray on Dask arrays: the top-level names, lazily, block by block.

For streams that no longer fit one machine's memory or time. Every function
here has the name and the arguments of its in-memory twin in :mod:`quatarray`
and takes Dask arrays chunked along the leading axes (the quaternion axis —
4, 3 or 3×3 — in one chunk; other chunkings are rechunked). Nothing is
computed until you call ``.compute()``, ``dask.compute`` or store the result.

Element-wise functions
    ``multiply``, ``conjugate``, ``inverse``, ``normalize``, ``norm``, ``dot``,
    ``exp``, ``log``, ``power``, ``canonical``, ``angle``, ``distance``,
    ``rotate``, every conversion (``as_matrix`` … ``from_su2``, ``as_euler``,
    ``from_euler``), ``lerp``, ``nlerp``, ``slerp``, ``double``, ``bisect``,
    ``bezier``: one task per block, calling the very same numba kernel as the
    in-memory function on that block, so the result is bitwise the in-memory
    one. Leading dimensions broadcast as in numpy (numpy arrays and Python
    scalars mix freely with Dask arrays); there is no ``out=``.
Scans and neighbours (exact whatever the chunking)
    ``cumprod`` (blocked scan: each chunk's running product, then each
    chunk's total carried across the borders), ``unflip`` (flip within
    chunks, then carry the sign across borders), ``integrate_angular_velocity``
    (each block from the identity, then the orientation carried block to
    block), ``angular_velocity`` and
    ``spline`` (each block sees the neighbouring keys across its borders;
    the key times and new times may be Dask arrays too, kept on the workers).
Files
    :func:`convert_file` and :func:`resample_file` stream ``.npy`` (and, with
    ``zarr`` installed, ``.zarr``) files through a scheduler: threads, a local
    cluster of worker processes, or a distributed scheduler's address. They
    back ``quatarray convert/resample --scheduler``.

Kernels run single-threaded inside a task (the scheduler supplies the
parallelism), and all task functions live in this importable module, so
graphs travel to worker processes by reference.

Examples
--------
>>> import dask.array as da, numpy as np, quatarray as qa, quatarray.dask as qd
>>> q = qa.random(1000, rng=1)
>>> lazy = qd.as_rotvec(da.from_array(q, chunks=(300, 4)))
>>> lazy.chunks
((300, 300, 300, 100), (3,))
>>> bool(np.array_equal(lazy.compute(), qa.as_rotvec(q)))
True
"""

import contextlib
import inspect
import math
import operator
import os
import sys
import threading
import uuid
import warnings

import numpy as np

try:
    import dask
    import dask.array as da
    from dask.base import tokenize
    from dask.core import flatten as _flatten_keys
    from dask.delayed import Delayed
    from dask.highlevelgraph import HighLevelGraph
    from dask.layers import ArrayValuesDep
except ImportError as exc:  # pragma: no cover - depends on the installation
    raise ImportError(
        "quatarray.dask needs Dask; install the optional extra: pip install 'quatarray[dask]'"
    ) from exc

import quatarray as qa

from . import _jit
from ._validate import as_float, check_core, is_weak, leading, origin, result_dtype

Q, V, M3 = (4,), (3,), (3, 3)

# --------------------------------------------------------------------------
# kernels run serially inside tasks

def _serial():
    """Run row kernels on one thread inside a task (this thread only: other
    threads' calls keep their parallel variant).

    The scheduler (threads or worker processes) is the parallel layer; numba
    threads inside every task would oversubscribe the cores.
    """
    return _jit.serial()


def _public(name):
    return getattr(qa, name)


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
        with _serial(), origin(start):
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
    _known_chunks(x, name)
    k = len(core)
    split = {ax: -1 for ax in range(x.ndim - k, x.ndim) if len(x.chunks[ax]) > 1}
    if split:
        x = x.rechunk(split)
    return x


def _known_chunks(x, name):
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
    wrapper.__module__ = __name__
    argtext = ", ".join(f"`{p}` {('(..., ' + ', '.join(map(str, c)) + ')') if c else '(...)'}" for p, c in arrays)
    wrapper.__doc__ = (
        f"Dask version of :func:`quatarray.{name}`: a lazy Dask array, block by block.\n\n"
        f"Same arguments as the in-memory function (no ``out=``); array arguments: {argtext}.\n"
        "Blocks are computed by the same kernel, so the result equals the in-memory one bitwise.\n"
    )
    return wrapper


_ELEMENTWISE = {
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

for _name, _spec in _ELEMENTWISE.items():
    globals()[_name] = _elementwise(_name, *_spec)
del _name, _spec

# --------------------------------------------------------------------------
# blocked scans along a leading axis: cumprod and unflip


def _lead_axis(x, axis, fname):
    lead = x.ndim - 1
    if lead == 0:
        raise ValueError(f"Expected `q` to have shape (N, ..., 4) for {fname}, got {tuple(x.shape)}.")
    if not -lead <= axis < lead:
        raise ValueError(f"Expected `axis` in [{-lead}, {lead - 1}] for `q` of shape {tuple(x.shape)}, got {axis}.")
    return axis % lead


def _rows(a, which, axis):
    """Row 0 or −1 of `a` along `axis`, keeping the axis."""
    return np.take(a, [which], axis=axis)


# cumprod: local running products, each chunk's total carried forward


def _cumprod_local(block, axis):
    with _serial():
        return qa.cumprod(block, axis=axis)


def _cumprod_summary(local, axis):
    return _rows(local, -1, axis) if local.shape[axis] else None


def _cumprod_carry(carry, prev, cur):
    # carry: product of every chunk before `prev`; returns the product through `prev`.
    if carry is None:
        return prev
    with _serial():
        return qa.multiply(carry, prev)


def _cumprod_apply(local, carry, axis):
    if carry is None:
        return local
    with _serial():
        return qa.multiply(carry, local)


# unflip: local flips, then one sign per chunk carried forward. The carry stops
# where the chain breaks: a row whose dot product with the row before is 0 or nan
# (a zero or non-finite row, or an exact quarter turn) is kept as it is whatever
# the sign before it, so from there on the block's own flips are the global ones.


def _sign_breaks(local, axis):
    """How many leading rows of a locally unflipped block (per line along `axis`,
    shaped like a row with a last axis of 1) take the sign carried into the block:
    up to the first row whose dot product with the row before is 0 or nan."""
    n = local.shape[axis]
    a = np.moveaxis(local, axis, 0)
    if n < 2:
        return np.expand_dims(np.full(a.shape[1:-1], n), (axis, -1))
    with _serial():
        d = qa.dot(a[1:], a[:-1])  # as unflip's kernel (its sign aside: 0 and nan stay)
    broken = ~((d < 0) | (d > 0))
    reach = np.where(broken.any(axis=0), broken.argmax(axis=0) + 1, n)
    return np.expand_dims(reach, (axis, -1))


def _unflip_local(block, axis):
    with _serial():
        local = qa.unflip(block, axis=axis)
    return local, _sign_breaks(local, axis)


def _unflip_summary(local, axis):
    local, reach = local
    n = local.shape[axis]
    return (_rows(local, 0, axis), _rows(local, -1, axis), reach == n) if n else None


def _unflip_carry(carry, prev, cur):
    # carry: True where chunk `prev` was negated; returns the same for chunk `cur`.
    # prev[2]: whether prev's carry reaches its last row (no break in the chain)
    last = prev[1] if carry is None else np.where(carry & prev[2], -prev[1], prev[1])
    with _serial():
        d = qa.dot(cur[0], last)
    return (np.asarray(d) < 0)[..., None]


def _unflip_apply(local, carry, axis):
    local, reach = local
    if carry is None:
        return local
    shape = [1] * local.ndim
    shape[axis] = local.shape[axis]
    row = np.arange(local.shape[axis]).reshape(shape)
    return np.where(carry & (row < reach), -local, local)


def _carry_all(carry_fn, summaries):
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
                _carry_all, carry_fn, [(sname,) + idx[:axis] + (j,) + idx[axis + 1 :] for j in range(nb)]
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
    return _scan(x, ax, "unflip", _unflip_local, _unflip_summary, _unflip_carry, _unflip_apply)


# --------------------------------------------------------------------------
# files: convert_file and resample_file (quatarray convert/resample --scheduler)


@contextlib.contextmanager
def scheduler_options(scheduler=None):
    """Keyword arguments for ``dask.compute`` that run on `scheduler`.

    ``None``: Dask's threads in this process. ``"local"``: a
    ``distributed.LocalCluster`` of 2 single-threaded worker processes on
    127.0.0.1, started here and closed on exit. Any other string: the address
    of a running distributed scheduler (``tcp://host:8786``); a
    ``distributed.Client`` is used as it is.
    """
    if scheduler is None:
        yield {"scheduler": "threads"}
        return
    if not isinstance(scheduler, str):
        yield {"scheduler": scheduler}
        return
    try:
        from distributed import Client
    except ImportError:  # pragma: no cover - depends on the installation
        raise _usage("--scheduler needs the package 'distributed': pip install 'quatarray[dask]'") from None
    cluster = None
    if scheduler == "local":
        cluster = local_cluster()
        address = cluster
    else:
        address = scheduler
    try:
        try:
            client = Client(address, timeout="20s", set_as_default=False)
        except OSError as exc:
            raise _usage(f"--scheduler {scheduler}: cannot reach the scheduler ({exc})") from None
        try:
            yield {"scheduler": client}
        finally:
            client.close()
    finally:
        if cluster is not None:
            cluster.close()


# How the local cluster departs from Dask's defaults, and why:
# - Tasks that read their own input (convert's blocks) have no dependencies,
#   and by default the scheduler hands such "root" tasks to a worker about one
#   at a time (queuing, ``worker-saturation: 1.1``): every task then waits for
#   a round trip to the scheduler, about 3 ms here. Our tasks are few and even:
#   send them all at once.
# - Worker processes are started with ``MALLOC_TRIM_THRESHOLD_=65536``, which
#   also switches off glibc's adaptive mmap threshold: every array of a few MB
#   is then a fresh mmap, page-faulted and zeroed in each task (convert's
#   tasks ran 1.8x slower than the same blocks in one process). We leave the
#   variable out so big buffers are reused.
def _cluster_config():
    environ = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
    environ.pop("MALLOC_TRIM_THRESHOLD_", None)
    return {"distributed.scheduler.worker-saturation": "inf", "distributed.nanny.pre-spawn-environ": environ}


def local_cluster(n_workers=2, **kwargs):
    """A ``distributed.LocalCluster`` of single-threaded worker processes on 127.0.0.1.

    What ``--scheduler local`` starts (with ``n_workers=2``). Two settings
    differ from Dask's defaults — no queuing of root tasks, and workers keep
    glibc's adaptive reuse of big buffers — see the README to set them on a
    real cluster. Close it when done (it is a context manager).

    Examples
    --------
    >>> import dask.array as da, numpy as np, distributed, quatarray as qa, quatarray.dask as qd
    >>> with qd.local_cluster(1) as cluster, distributed.Client(cluster) as client:
    ...     q = qa.random(10, rng=0) * 2
    ...     lazy = qd.normalize(da.from_array(q, chunks=(5, 4)))
    ...     bool(np.array_equal(client.compute(lazy, sync=True), qa.normalize(q)))
    True
    """
    from distributed import LocalCluster

    import logging

    # the workers' own log lines (a failed task's traceback) stay out of the command line's
    # stderr: the error reaches the caller as an exception
    options = dict(n_workers=n_workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                   dashboard_address=None, silence_logs=logging.CRITICAL)
    options.update(kwargs)
    with dask.config.set(_cluster_config()), warnings.catch_warnings():
        # its HTTP endpoint takes another port when 8787 is taken (another cluster): not news
        warnings.filterwarnings("ignore", message="Port .* is already in use", category=UserWarning)
        return LocalCluster(**options)


def _compute_all(tasks, opts, independent=True):
    """``dask.compute(*tasks)`` on the scheduler of `opts`, as a list. Every task
    finishes (or fails) before an error is raised — none may still be writing into an
    output that is being removed. For `independent` tasks, the error raised is that of
    the earliest in `tasks` (the first bad row of the file, as in memory); otherwise the
    tasks share one graph, computed once."""
    sched = opts["scheduler"]
    if not isinstance(sched, str):  # a distributed Client (not necessarily the default one)
        futures = sched.compute(list(tasks))
        results = lambda: sched.gather(futures)  # noqa: E731
    else:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(os.cpu_count() or 1) as pool:  # leaving it waits for every thread
            if independent:
                futures = [pool.submit(dask.compute, t, scheduler="sync") for t in tasks]
                results = lambda: [f.result()[0] for f in futures]  # noqa: E731
            else:
                try:
                    return list(dask.compute(*tasks, scheduler=sched, pool=pool))
                finally:
                    pool.shutdown(wait=True, cancel_futures=True)
    for f in futures:
        error = f.exception()  # waits for it
        if error is not None:
            raise error
    return results()


def _usage(msg):
    from .io.errors import UsageError

    return UsageError(msg)


# --------------------------------------------------------------------------
# files: where the blocks come from and go to


def _open_source(src, layout, chunk):
    """An ``.npy`` file or ``.zarr`` store of quaternions or matrices, read by the workers."""
    from .io.formats import is_zarr
    from .io.readers import open_stream

    if not (is_zarr(src) or os.fspath(src).endswith(".npy")):
        raise _usage(f"{src}: with --scheduler the input is an .npy file or a .zarr store")
    # workers open it by its absolute path (theirs may run in another folder)
    return open_stream(os.path.abspath(src), "npy", kind="quat", layout=layout, chunk=chunk, name=os.fspath(src))


class _NpyTarget:
    """A temporary ``.npy`` beside `dst` with its header written; renamed over `dst` on success.

    Tasks write their rows with :meth:`write` (a positioned write: no page
    faults on the fresh file, unlike a memory map), in any order and in
    pieces of any size (`piecewise`).
    """

    piecewise = True

    def __init__(self, dst, shape, dtype, chunk):
        import tempfile

        self.dst = os.fspath(dst)
        folder, base = os.path.split(os.path.abspath(self.dst))
        fd, self.tmp = tempfile.mkstemp(prefix=f".{base}.", suffix=".tmp", dir=folder)
        os.close(fd)
        with self._or_remove():
            mm = np.lib.format.open_memmap(self.tmp, mode="w+", dtype=dtype, shape=tuple(shape))
            self.offset, self.dtype, self.rowbytes = mm.offset, np.dtype(dtype), mm[:1].nbytes
            del mm

    @contextlib.contextmanager
    def _or_remove(self):
        """Remove the temporary output if what is inside fails."""
        try:
            yield
        except BaseException:
            self._remove(self.tmp)
            raise

    @staticmethod
    def _remove(path):
        import shutil

        if os.path.isdir(path) and not os.path.islink(path):
            shutil.rmtree(path, ignore_errors=True)
        elif os.path.lexists(path):
            os.remove(path)

    def write(self, row0, data):
        if len(data) == 0:
            return 0
        data = np.ascontiguousarray(data, dtype=self.dtype)
        fd = os.open(self.tmp, os.O_WRONLY)
        try:
            view, at = memoryview(data).cast("B"), self.offset + row0 * self.rowbytes
            while len(view):
                done = os.pwrite(fd, view, at)
                view, at = view[done:], at + done
        finally:
            os.close(fd)
        return len(data)

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        if kind is not None:
            self._remove(self.tmp)
            return
        with self._or_remove():
            old = None
            if os.path.isdir(self.tmp) and os.path.lexists(self.dst):  # --force, for a store: moved aside first
                old = self.tmp + ".old"
                os.replace(self.dst, old)
            if not os.path.isdir(self.tmp):  # mkstemp made it 0600
                from .io.writers import output_mode

                os.chmod(self.tmp, output_mode(self.dst))
            os.replace(self.tmp, self.dst)
        if old:
            self._remove(old)


class _ZarrTarget(_NpyTarget):
    """A temporary zarr store beside `dst`, chunked by `chunk` rows; moved over `dst` on success.

    Every task writes whole zarr chunks (its rows start at a multiple of
    `chunk`), so no two tasks touch the same chunk.
    """

    piecewise = False  # a piece smaller than a zarr chunk rewrites the whole chunk

    def __init__(self, dst, shape, dtype, chunk):
        import tempfile

        from .io.readers import import_zarr

        zarr = import_zarr(dst)
        self.dst = os.fspath(dst).rstrip("/" + os.sep)
        folder, base = os.path.split(os.path.abspath(self.dst))
        self.tmp = tempfile.mkdtemp(prefix=f".{base}.", suffix=".tmp", dir=folder)
        shape = tuple(int(n) for n in shape)
        with self._or_remove():
            zarr.create_array(store=self.tmp, shape=shape, dtype=dtype, overwrite=True,
                              chunks=(max(1, min(int(chunk), shape[0])),) + shape[1:])
        self.dtype = np.dtype(dtype)

    def write(self, row0, data):
        import zarr

        if len(data):
            zarr.open_array(self.tmp, mode="r+")[row0 : row0 + len(data)] = np.asarray(data, self.dtype)
        return len(data)


def _open_target(dst, shape, dtype, chunk):
    from .io.formats import is_zarr

    return (_ZarrTarget if is_zarr(dst) else _NpyTarget)(dst, shape, dtype, chunk)


def _check_files(src, dst, force):
    from .io.formats import is_zarr
    from .io.writers import check_output

    if not (is_zarr(dst) or os.fspath(dst).endswith(".npy")):
        raise _usage(f"{dst}: with --scheduler the output is an .npy file or a .zarr store, written block by block")
    check_output(dst, [src], force)


def _blocks(rows, chunk):
    chunk = int(chunk)
    if chunk < 1:
        raise _usage(f"--chunk must be at least 1, got {chunk}")
    return [(a, min(a + chunk, rows)) for a in range(0, rows, chunk)]


_scratch = threading.local()


def _scratch_rows(n, core, dtype):
    """A reused ``(n,) + core`` array of this thread (fresh pages in every task cost more
    than the conversion)."""
    key = (tuple(core), np.dtype(dtype))
    buf = getattr(_scratch, "buf", None)
    if buf is None or buf[0] != key or buf[1].shape[0] < n:
        buf = _scratch.buf = (key, np.empty((n,) + tuple(core), dtype))
    return buf[1][:n]


# --------------------------------------------------------------------------
# files: which input rows each task reads (--on-invalid drop), and the report


def _bad_rows_task(reader, a, b):
    """Input rows in ``[a, b)`` that ``--on-invalid drop`` drops."""
    from .io.clean import Cleaner

    with _serial():
        _, good = Cleaner(reader, "drop").check(reader.read(a, b, bad_ok=True))
    return a + np.flatnonzero(~good)


def _plan_rows(reader, chunk, drop, opts):
    """``[(in_a, in_b, out_a), ...]``: the input rows each task reads and the first
    output row it writes, and the (sorted) input rows dropped.

    Without `drop`, input and output rows are the same blocks of `chunk`
    rows. With `drop`, a first pass finds the bad rows; then task j reads the
    input rows that hold output rows ``[j·chunk, (j+1)·chunk)``, so every
    task still writes whole output blocks (whole zarr chunks).
    """
    from .io.errors import DataError

    blocks = _blocks(reader.rows, chunk)
    if not drop:
        return [(a, b, a) for a, b in blocks], np.empty(0, np.int64)
    found = _compute_all([dask.delayed(_bad_rows_task, pure=False)(reader, a, b) for a, b in blocks], opts)
    bad = np.concatenate(found) if found else np.empty(0, np.int64)
    kept = reader.rows - bad.size
    if kept == 0:
        raise DataError(f"{reader.name}: no valid rows (all {reader.rows} dropped)")
    # output row k is input row k + (the bad rows before it): bad row i has bad[i] - i good rows before it
    outs = np.arange(0, kept, int(chunk))
    ins = outs + np.searchsorted(bad - np.arange(bad.size), outs, side="right")
    ends = np.append(ins[1:], reader.rows)
    return [(int(a), int(b), int(o)) for a, b, o in zip(ins, ends, outs)], bad


def _plan_sizes(plan, kept):
    """The good rows each planned task gives (its output block's size: at most `chunk`)."""
    return [int(n) for n in np.diff([o for _, _, o in plan] + [kept])]


def _report(reader, figures, dropped, err):
    """The command line's notes: rows dropped, quaternions normalised."""
    from .io.clean import Cleaner

    clean = Cleaner(reader, "drop")
    clean.dropped = dropped
    clean.normalised = sum(f[0] for f in figures)
    clean.max_dev = max((f[1] for f in figures), default=0.0)
    clean.report(err)


def _read_clean(reader, a, b, drop, clean):
    """Rows ``[a, b)`` checked and normalised (bad rows dropped, or a DataError naming the row)."""
    return clean(reader.read(a, b, bad_ok=drop))


# --------------------------------------------------------------------------
# convert_file


def _convert_task(reader, a, b, row0, rows, to, degrees, target, drop):
    """Read, check, normalise, convert and write input rows ``[a, b)`` (`rows` of them
    good) from output row `row0` on.

    The rows go through in pieces of the command line's size, so each piece
    is checked and converted while it is in cache, into a reused buffer; an
    npy target takes each piece from there while it is still in cache (with
    both workers converting, the block-sized buffer's extra trip through
    memory slowed both), a zarr target the whole block in one call. Returns
    the report figures.
    """
    from .cli import _PIECE, _target
    from .io.clean import Cleaner

    _, core, fn = _target(to, degrees)
    piecewise = target.piecewise
    out = _scratch_rows(min(rows, _PIECE) if piecewise else rows, core, target.dtype)
    clean = Cleaner(reader, "drop" if drop else "error")
    n = 0
    with _serial():
        for p in range(a, b, _PIECE):
            ch = _read_clean(reader, p, min(p + _PIECE, b), drop, clean)
            piece = out[: len(ch)] if piecewise else out[n : n + len(ch)]
            fn(ch.data.astype(target.dtype, copy=False), out=piece)
            if piecewise:
                target.write(row0 + n, piece)
            n += len(ch)
    if not piecewise:
        target.write(row0, out[:n])
    return clean.normalised, clean.max_dev, getattr(fn, "locked", 0)


def convert_file(src, dst, to, *, degrees=False, layout="wxyz", chunk=1_000_000, scheduler=None,
                 on_invalid="error", force=False, err=None):
    """``quatarray convert SRC DST --to TO --scheduler …``: a stream converted block by block.

    Every block of `chunk` rows is read by one task (from a memory map, or
    from the zarr store), checked (a non-finite or zero quaternion, or a
    matrix that is not a rotation, is an error naming its row, or is dropped),
    normalised, converted and written into its place in DST; DST appears
    (moved from a temporary file or store beside it) only when every block
    succeeded.

    Parameters
    ----------
    src : str or path-like
        An ``.npy`` file or ``.zarr`` store holding ``(N, 4)`` quaternions in
        `layout` order or ``(N, 3, 3)`` rotation matrices.
    dst : str or path-like
        An ``.npy`` file or a ``.zarr`` store (chunked by `chunk` rows).
    to : {"quat", "xyzw", "matrix", "rotvec", "axis-angle", "euler:SEQ"}
    degrees : bool
    layout : {"wxyz", "xyzw"}
    chunk : int
        Rows per block (per task).
    scheduler : None, "local", str or distributed.Client
        See :func:`scheduler_options`. Workers must see SRC and DST at the
        same paths (a shared file system on a real cluster).
    on_invalid : {"error", "drop"}
        ``"drop"`` first finds the bad rows (one more pass over SRC), so
        that every task still writes whole blocks of DST.
    force : bool
        Overwrite an existing DST.
    err : file, optional
        Where the notes (rows dropped, normalised, gimbal lock) go (default stderr).

    Returns
    -------
    int
        0 (the command line's exit status).
    """
    from .cli import _target, gimbal_note

    err = sys.stderr if err is None else err
    _check_files(src, dst, force)
    _, core, _ = _target(to, degrees)  # a bad --to fails here, before any work
    reader = _open_source(src, layout or "wxyz", chunk)
    dtype = as_float(np.empty(0, reader.dtype), "IN").dtype
    drop = on_invalid == "drop"
    with scheduler_options(scheduler) as opts:
        plan, bad = _plan_rows(reader, chunk, drop, opts)
        kept = reader.rows - bad.size
        with _open_target(dst, (kept,) + tuple(core), dtype, chunk) as target:
            tasks = [dask.delayed(_convert_task, pure=False)(reader, a, b, o, n, to, degrees, target, drop)
                     for (a, b, o), n in zip(plan, _plan_sizes(plan, kept))]
            figures = _compute_all(tasks, opts)
    _report(reader, figures, bad.size, err)
    gimbal_note(reader.name, sum(f[2] for f in figures), err)
    return 0


# --------------------------------------------------------------------------
# neighbours across chunk borders: spline and angular_velocity


def _concat_rows(parts):
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


def _pieces(x, a, b, dsk, cut=None):
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


def _window(x, a, b, dsk):
    """A task expression for rows [a, b) of `x` as one array (see :func:`_pieces`)."""
    return (_concat_rows, _pieces(x, a, b, dsk))


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
    into the block (see :func:`_sign_breaks`) and whether that is all of them
    (``full``); keys normalised first, as
    :func:`quatarray.spline` does. One pass, nothing the size of the block written.
    Also the block's first and last ``_EDGE_ROWS`` rows as they are: the rows
    neighbouring windows take from it travel with the summary."""
    from .interpolation import _sign_summary

    if not len(block):
        return None
    block = np.ascontiguousarray(block)
    ends = np.empty((2, 4), block.dtype)
    negated = np.zeros(len(rows), np.bool_)
    tile = min(len(block), 1024)
    unit, dots = np.empty((tile + 1, 4), block.dtype), np.empty(tile, block.dtype)
    reach = _sign_summary(block, np.asarray(rows, np.int64), ends, negated, unit, dots)
    full = np.array([[reach == len(block)]])
    edges = block[:_EDGE_ROWS].copy(), block[-_EDGE_ROWS:].copy()
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
_EDGE_ROWS = 8


def _carries(summaries):
    """The sign carried into every key block (None for the first and for empty blocks),
    from their summaries."""
    return _carry_all(_unflip_carry, [None if f is None else f[:3] for f in summaries])


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


def _spline_task(times, pieces, flip0, new_times, method, origin):
    """The in-memory spline on a window of keys given in pieces (its rows in the
    blocks it spans), its first row taking the global sign; integer times are taken
    from `origin`, the whole stream's first key time, as in memory."""
    from .interpolation import _plan_times, _spline_unit, _times, _unit_keys

    with _serial():
        q = _unit_keys(pieces, flip0)
        t, nt = _plan_times(_times(times, len(q)), np.asarray(new_times), origin=origin)
        return _spline_unit(t, nt, q, method)


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
    from .interpolation import _plan_times

    try:
        _plan_times(t_ends, block, start)
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
    _known_chunks(new_times, "new_times")
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
    from .interpolation import _plan_times, _seconds

    ends = t_raw[[0, -1]]
    if isinstance(new_times, da.Array):
        nt_d, parts, sizes, starts = _lazy_parts(new_times, chunks)
        spans, deps, nt_dtype = _span_pass(nt_d, starts, ends), [nt_d], nt_d.dtype
    else:
        nt_raw = _materialise(new_times, "new_times")
        _, nt = _plan_times(ends, nt_raw)
        starts = np.cumsum((0,) + tuple(key_chunks))[1:-1]
        cuts = _seconds(t_raw[starts[starts < t_raw.shape[0]]], nt_raw[:0], ends[0])[0]
        sizes = _output_chunks(nt, cuts, len(key_chunks), chunks)
        parts = _split(nt_raw, sizes)
        spans, deps, nt_dtype = [_span(p) for p in parts], [], nt_raw.dtype
    t = _seconds(t_raw, np.empty(0, nt_dtype), ends[0])[0]
    values, at = _span_ends(spans, nt_dtype)
    found = np.searchsorted(t, _seconds(ends, values, ends[0])[1], side="right")
    segs = [None if m is None else found[m : m + 2] for m in at]
    return parts, sizes, segs, deps, lambda w0, w1, dsk: t_raw[w0:w1], ends[0]


def _key_time_block(block, start, origin, spans, nt_dtype):
    """What planning needs of one block of lazy key times (None when it is empty):
    its first and last times; its first pair that does not increase, as (index in
    the whole array, time, next time), or None; and, for each end of an output
    block's span (see :func:`_span_ends`) within the block's times, how many of
    its times are ≤ that end (in seconds from `origin`, the first key time, when
    both are integers: see ``interpolation._seconds``)."""
    from .interpolation import _first_not_increasing, _seconds

    if not block.size:
        return None
    i = _first_not_increasing(block)
    worst = None if i is None else (start + i, block[i], block[i + 1])
    values, _ = _span_ends(spans, nt_dtype)
    t, v = _seconds(block, values, origin)
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
    from .interpolation import _check_times, _not_increasing, _plan_times, _seconds

    _check_times(tt, k, "times")
    _known_chunks(tt, "times")
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
    origin = (operator.getitem, _window(tt, 0, 1, dsk), 0) if ints else None
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
            raise _not_increasing("times", int(tstarts[i]) - 1, last, info[0])
        if info[2] is not None:
            raise _not_increasing("times", *info[2])
        last = info[1]
    full = [i for i, info in enumerate(infos) if info is not None]
    ends = np.array([infos[full[0]][0], last], tt.dtype)
    if not lazy_nt:
        _plan_times(ends, nt_raw)  # a new time outside the keys' span: the in-memory message
    elif not all(s is None or _inside(ends, np.array(s, nt_dtype)) for s in spans):
        _span_pass(nt_d, starts, ends)  # raises the in-memory message, naming the time
    firsts = _seconds(np.array([infos[i][0] for i in full], tt.dtype), np.empty(0, nt_dtype), ends[0])[0]
    values, at = _span_ends(spans, nt_dtype)
    values = _seconds(ends, values, ends[0])[1]

    def found(m):  # searchsorted(times, values[m], "right") from the blocks' counts
        c = int(np.searchsorted(firsts, values[m], side="right")) - 1
        if c < 0:
            return 0
        i = full[c]
        return int(tstarts[i]) + infos[i][3].get(m, tt.chunks[0][i])

    segs = [None if m is None else np.array([found(m), found(m + 1)]) for m in at]
    return parts, sizes, segs, deps, lambda w0, w1, dsk: _window(tt, w0, w1, dsk), ends[0]


def _inside(t_ends, nt_raw):
    """Whether new times are within the key times' span (nan is not)."""
    from .interpolation import _plan_times

    try:
        _plan_times(t_ends, nt_raw)
    except ValueError:
        return False
    return True


def spline(times, keys, new_times, method="bezier", chunks=None):
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
    chunks : int, optional
        Rows per output block. Default: the chunks of `new_times` when it is
        a Dask array; else, for sorted new times, one output block per key
        block (split where the key blocks start, or evenly when the key
        times are a Dask array).

    Returns
    -------
    dask.array.Array, shape (M, 4)

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
    from .interpolation import _SPLINE, _times

    if method not in _SPLINE:
        raise ValueError(f"Expected `method` to be one of {sorted(_SPLINE)}, got {method!r}.")
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
        plan = _plan_given_times(_times(times, k), new_times, chunks, x.chunks[0])
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
        tail = max(0, x.chunks[0][i] - _EDGE_ROWS)  # where the last edge rows start
        if hi <= _EDGE_ROWS:
            return (_edge_rows, (sname, i), 0, lo, hi)
        if lo >= tail:
            return (_edge_rows, (sname, i), 1, lo - tail, hi - tail)
        return None

    if nb > _FEW_BLOCKS:
        dsk[cname] = (_carries, [(sname, i) for i in range(nb)])
    for j, (part, seg) in enumerate(zip(parts, segs)):
        if seg is None:
            dsk[(name, j, 0)] = (np.empty, (0, 4), dtype)
            continue
        # the segments of the block's earliest and latest new times bound all of its segments
        seg = np.clip(seg - 1, 0, k - 2)
        w0, w1 = max(0, int(seg[0]) - 1), min(k, int(seg[1]) + 3)
        c = int(np.searchsorted(starts, w0, side="right")) - 1
        rows[c].add(int(w0 - starts[c]))
        carry = (operator.getitem, cname, c) if nb > _FEW_BLOCKS else (_carry_into, [(sname, i) for i in range(c + 1)])
        flip = (_window_flip, carry, (sname, c), int(w0 - starts[c]))
        dsk[(name, j, 0)] = (_spline_task, times_window(w0, w1, dsk), _pieces(x, w0, w1, dsk, edge), flip, part, method, origin)
    for i in range(nb):
        dsk[(sname, i)] = (_flip_summary, (x.name, i, 0), sorted(rows[i]))
    graph = HighLevelGraph.from_collections(name, dsk, dependencies=[x] + deps)
    return da.Array(graph, name, chunks=(tuple(sizes), (4,)), meta=np.empty((0, 0), dtype))


def _angular_velocity_task(q, times, frame, lo, hi):
    with _serial():
        return qa.angular_velocity(q, times, frame=frame)[lo:hi]


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
            _angular_velocity_task, _window(x, w0, w1, dsk), _window(tt, w0, w1, dsk), frame, a - w0, b - w0
        )
        a = b
    graph = HighLevelGraph.from_collections(name, dsk, dependencies=[x, tt])
    return da.Array(graph, name, chunks=(x.chunks[0], (3,)), meta=np.empty((0, 0), dtype))


def _integrate_task(omega, times, frame, hold, index0):
    # the block's rows and the first row of the next block: local orientations from
    # the identity, through the step that crosses into the next block
    with _serial():
        return qa.integrate_angular_velocity(omega, times, frame=frame, hold=hold, _index0=index0)


def _integrate_carries(q0, body, *locals_):
    """The orientation where each block starts: q0, then each block's local end
    (its row past the block) applied in turn."""
    carries = [q0]
    with _serial():
        for local in locals_[:-1]:
            end, c = local[-1], carries[-1]
            carries.append(qa.multiply(c, end) if body else qa.multiply(end, c))
    return carries


def _integrate_apply(local, carries, j, size, body):
    c = carries[j]
    with _serial():
        return qa.multiply(c, local[:size]) if body else qa.multiply(local[:size], c)


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
    from .kinematics import _check_options

    _check_options(frame, hold)
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
            dsk[(lname, j)] = (_integrate_task, _window(x, a, w1, dsk), _window(tt, a, w1, dsk), frame, hold, a)
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
# resample_file


def _read_keys_task(reader, a, b, drop):
    """Input rows ``[a, b)`` of a key stream, checked and normalised as the command line
    does, piece by piece (a long run of dropped rows never sits in memory), and the
    normalisation figures; or the DataError naming the block's first bad row, returned
    (see :func:`_first_error`)."""
    from .cli import _PIECE
    from .io.clean import Cleaner
    from .io.errors import DataError

    clean = Cleaner(reader, "drop" if drop else "error")
    try:
        with _serial():
            parts = [_read_clean(reader, p, min(p + _PIECE, b), drop, clean).data for p in range(a, b, _PIECE)]
    except DataError as exc:
        return exc
    data = np.concatenate(parts) if len(parts) > 1 else np.array(parts[0])  # not a view of the map
    return data, clean.normalised, clean.max_dev


def _first_error(results):
    """Raise the error of the earliest block that has one (the file's first bad row, as
    in memory, whichever block was read first); else the blocks' normalisation figures."""
    for r in results:
        if isinstance(r, Exception):
            raise r
    return [(normalised, dev) for _, normalised, dev in results]


def _key_block(result, checked):
    return result[0]


def _lazy_keys(reader, plan, kept, drop):
    """A key stream (npy or zarr) as a Dask array read and checked by the workers, one
    block per planned task (see :func:`_plan_rows`), and a Delayed list of the blocks'
    normalisation figures (compute both together: the blocks are read once). No block
    is handed on before every block was read and checked."""
    from dask.delayed import Delayed

    dtype = as_float(np.empty(0, reader.dtype), "IN").dtype
    mtime = os.path.getmtime(reader.path)
    token = tokenize(reader.path, mtime, reader.layout, plan, drop)
    raw, name, report = f"read-keys-raw-{token}", f"read-keys-{token}", f"read-keys-report-{token}"
    dsk = {(raw, i): (_read_keys_task, reader, a, b, drop) for i, (a, b, _) in enumerate(plan)}
    dsk[report] = (_first_error, [(raw, i) for i in range(len(plan))])
    dsk.update({(name, i, 0): (_key_block, (raw, i), report) for i in range(len(plan))})
    graph = HighLevelGraph.from_collections(name, dsk, dependencies=[])
    keys = da.Array(graph, name, (tuple(_plan_sizes(plan, kept)), (4,)), meta=np.empty((0, 0), dtype))
    return keys, Delayed(report, graph, layer=name)


def _kept_times(a, b, bad, in_rate):
    """The times (row / in_rate) of input rows [a, b) but the `bad` ones."""
    return np.delete(np.arange(a, b, dtype=np.float64), bad - a) / in_rate


def _lazy_key_times(plan, bad, rows, in_rate):
    """The key times of a stream read by :func:`_lazy_keys` (row k at k / in_rate,
    dropped rows left out) as a Dask array made by the workers, blocked like the keys,
    and its first and last times (as the array would hold them)."""
    name = f"key-times-{tokenize(plan, bad, rows, in_rate)}"
    dsk = {}
    for i, (a, b, _) in enumerate(plan):
        dsk[(name, i)] = (_kept_times, a, b, bad[(bad >= a) & (bad < b)], in_rate)
    sizes = tuple(_plan_sizes(plan, rows - bad.size))
    t = da.Array(HighLevelGraph.from_collections(name, dsk, dependencies=[]), name, (sizes,), np.float64)
    def leading(flags):  # how many of the first flags are true
        return flags.size if flags.all() else int(np.argmin(flags))

    n = np.arange(bad.size)
    first, last = leading(bad == n), rows - 1 - leading(bad[::-1] == rows - 1 - n)  # the first and last kept rows
    return t, np.array([first, last], np.float64) / in_rate


def _write_block(target, row0, data):
    return np.array([target.write(row0, data)])


def _store(x, target):
    """A lazy array of row counts whose tasks write every block of `x` into its rows of `target`."""
    starts = np.cumsum((0,) + x.chunks[0])
    keys = list(_flatten_keys(x.__dask_keys__()))
    name = "store-" + tokenize(x, target.tmp)
    dsk = {(name, i): (_write_block, target, int(starts[i]), k) for i, k in enumerate(keys)}
    graph = HighLevelGraph.from_collections(name, dsk, dependencies=[x])
    return da.Array(graph, name, chunks=((1,) * len(keys),), meta=np.empty(0, np.int64))


def resample_file(src, dst, *, rate=None, times=None, method="bezier", chunk=1_000_000, scheduler=None,
                  in_rate=None, layout=None, on_invalid="error", force=False, err=None):
    """``quatarray resample SRC DST (--rate HZ | --times FILE) --scheduler …`` on Dask workers.

    The keys are checked (a bad row is an error naming it, or is dropped),
    normalised and unflipped across the whole stream; the new times are
    those of the command line (``t0 + k/rate`` up to the last key time, or a
    file of times inside the keys' span); every output block of `chunk` rows
    is interpolated with :func:`spline` by one task and written into its
    rows of DST (an ``.npy`` file or a ``.zarr`` store chunked by `chunk`
    rows), which appears when all succeeded.

    In error mode, the error names the file's first bad row, as in memory.

    An ``.npy`` or ``.zarr`` SRC has no times: give its sampling rate as
    `in_rate` (key k at k / in_rate seconds; dropped rows keep their times
    out); its blocks are read by the workers. Other formats (csv, tum,
    euroc, parquet, bvh) are read on the client.

    Returns
    -------
    int
        0 (the command line's exit status).
    """
    from .cli import _FileTimes, _RateTimes, timed_chunks
    from .io.clean import Cleaner
    from .io.errors import DataError
    from .io.readers import open_stream
    from .io.streams import concat

    err = sys.stderr if err is None else err
    if (rate is None) == (times is None):
        raise _usage("resample needs exactly one of --rate and --times")
    _check_files(src, dst, force)
    if times is not None:
        from .io.writers import check_output

        check_output(dst, [times], True)  # DST must not be the times file
    newt = _RateTimes(rate) if rate is not None else _FileTimes(times, "auto")
    reader = open_stream(src, "auto", kind="quat", layout=layout, chunk=chunk, on_invalid=on_invalid)
    if not reader.has_time and in_rate is None:
        raise _usage(f"{reader.name}: has no time column; give its sampling rate with --in-rate HZ")
    if in_rate is not None and not (in_rate > 0 and np.isfinite(in_rate)):
        raise _usage(f"--in-rate must be positive, got {in_rate}")
    drop = on_invalid == "drop"
    with scheduler_options(scheduler) as opts:
        figures, dropped = [], 0
        if reader.format in ("npy", "zarr"):
            plan, bad = _plan_rows(reader, chunk, drop, opts)
            keys, report = _lazy_keys(reader, plan, reader.rows - bad.size, drop)
            figures = [report]
            t, ends = _lazy_key_times(plan, bad, reader.rows, in_rate)
            dropped = bad.size
        else:
            clean = Cleaner(reader, on_invalid, ordered=True)
            whole = [c for c in map(clean, timed_chunks(reader, in_rate)) if len(c)]
            if not whole:
                raise DataError(f"{reader.name}: no valid rows")
            whole = concat(whole)
            keys, t = da.from_array(whole.data, chunks=(int(chunk), 4)), whole.t
            ends = t[[0, -1]]
            clean.report(err)
        if t.shape[0] < 2:
            raise DataError(f"{reader.name}: resampling needs at least 2 valid rows, got {t.shape[0]}")
        newt.t0, last = float(ends[0]), float(ends[1])
        if rate is not None:  # t0 + k / rate, made by the workers block by block (as pieces() would)
            n = newt.count(last, True)
            nt = newt.t0 + da.arange(0, n, chunks=int(chunk), dtype=np.float64) / newt.rate
        else:
            nt = newt.upto(last, True)
            newt.finish(last)
        if nt.size == 0:
            raise DataError(f"{reader.name}: no new times inside the keys' span")
        try:
            with dask.config.set(scheduler=opts["scheduler"]):  # spline's pass over lazy new times
                lazy = spline(t, keys, nt, method=method, chunks=chunk)
        except ValueError as exc:
            raise DataError(f"{reader.name}: {exc}") from None
        with _open_target(dst, lazy.shape, lazy.dtype, chunk) as target:
            done = _compute_all([_store(lazy, target).sum()] + figures, opts, independent=False)
    if figures:
        _report(reader, done[1], dropped, err)
    return 0
