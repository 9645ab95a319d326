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
    chunks, then carry the sign across borders), ``angular_velocity`` and
    ``spline`` (each block sees the neighbouring keys across its borders).
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

import numpy as np

try:
    import dask
    import dask.array as da
    from dask.base import tokenize
    from dask.core import flatten as _flatten_keys
    from dask.highlevelgraph import HighLevelGraph
except ImportError as exc:  # pragma: no cover - depends on the installation
    raise ImportError(
        "quatarray.dask needs Dask; install the optional extra: pip install 'quatarray[dask]'"
    ) from exc

import quatarray as qa

from . import _jit
from ._validate import as_float, check_core, is_weak, leading, result_dtype

Q, V, M3 = (4,), (3,), (3, 3)

# --------------------------------------------------------------------------
# kernels run serially inside tasks

_serial_lock = threading.Lock()
_serial_depth = 0
_serial_saved = None


@contextlib.contextmanager
def _serial():
    """Run row kernels on one thread while any task runs in this process.

    The scheduler (threads or worker processes) is the parallel layer; numba
    threads inside every task would oversubscribe the cores.
    """
    global _serial_depth, _serial_saved
    with _serial_lock:
        if _serial_depth == 0:
            _serial_saved = _jit.PARALLEL_MIN_ROWS
            _jit.PARALLEL_MIN_ROWS = sys.maxsize
        _serial_depth += 1
    try:
        yield
    finally:
        with _serial_lock:
            _serial_depth -= 1
            if _serial_depth == 0:
                _jit.PARALLEL_MIN_ROWS = _serial_saved


def _public(name):
    return getattr(qa, name)


# --------------------------------------------------------------------------
# element-wise functions: one factory


class _Block:
    """The per-block call of a public function (picklable by value: a name and constants)."""

    def __init__(self, name, arrays, consts, nout):
        self.name, self.arrays, self.consts, self.nout = name, tuple(arrays), dict(consts), nout

    def __call__(self, *blocks):
        kwargs = dict(self.consts)
        kwargs.update(zip(self.arrays, blocks))
        with _serial():
            return _public(self.name)(**kwargs)

    def __dask_tokenize__(self):
        return (type(self).__name__, self.name, self.arrays, sorted(self.consts.items(), key=str), self.nout)

    def __repr__(self):
        return f"quatarray.{self.name}"


def _float_rule(dtypes):
    return result_dtype([np.empty(0, d) for d in dtypes])


def _su2_rule(dtypes):
    return np.dtype(np.complex64) if _float_rule(dtypes) == np.float32 else np.dtype(np.complex128)


def _from_su2_rule(dtypes):
    return np.dtype(np.float32) if all(d in (np.complex64, np.float32) for d in dtypes) else np.dtype(np.float64)


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
    k = len(core)
    split = {ax: -1 for ax in range(x.ndim - k, x.ndim) if len(x.chunks[ax]) > 1}
    if split:
        x = x.rechunk(split)
    return x


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
        call = _Block(name, names, given, len(outs))
        token = tokenize(call, *xs)
        metas = [np.empty((0,) * (nlead + len(c)), dtype) for c in outs]
        if len(outs) == 1:
            ocore = tuple(f"out.{j}" for j in range(len(outs[0])))
            return da.blockwise(
                call, out_lead + ocore, *pairs, new_axes=dict(zip(ocore, outs[0])),
                concatenate=True, meta=metas[0], name=f"{name}-{token}",
            )
        tmp = da.blockwise(
            call, out_lead, *pairs, concatenate=True, meta=np.empty((0,) * nlead), name=f"{name}-tuple-{token}"
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
    return _rows(local, -1, axis)


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


# unflip: local flips, then one sign per chunk carried forward


def _unflip_local(block, axis):
    with _serial():
        return qa.unflip(block, axis=axis)


def _unflip_summary(local, axis):
    return (_rows(local, 0, axis), _rows(local, -1, axis))


def _unflip_carry(carry, prev, cur):
    # carry: True where chunk `prev` was negated; returns the same for chunk `cur`.
    last = prev[1] if carry is None else np.where(carry, -prev[1], prev[1])
    with _serial():
        d = qa.dot(cur[0], last)
    return (np.asarray(d) < 0)[..., None]


def _unflip_apply(local, carry, axis):
    if carry is None:
        return local
    return np.where(carry, -local, local)


def _carry_all(carry_fn, summaries):
    """Every chunk's carry along one scan (None for the first chunk), in one task."""
    carries, carry = [None], None
    for prev, cur in zip(summaries[:-1], summaries[1:]):
        carry = carry_fn(carry, prev, cur)
        carries.append(carry)
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
    and chunks whose sign is −1 are negated. Equal to the in-memory result
    bitwise, whatever the chunking.

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
        from distributed import Client, LocalCluster
    except ImportError:  # pragma: no cover - depends on the installation
        raise _usage("--scheduler needs the package 'distributed': pip install 'quatarray[dask]'") from None
    cluster = None
    if scheduler == "local":
        cluster = LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
        )
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


def _usage(msg):
    from .io.errors import UsageError

    return UsageError(msg)


def _read_chunk(reader, a, b):
    """Rows [a, b) of an ``.npy`` stream reader as a Chunk (only those pages mapped)."""
    from .io.readers import _from_matrix, _reorder
    from .io.streams import Chunk

    block = reader._block(a, b)
    if reader.dtype.kind != "f" or not reader.dtype.isnative:
        block = block.astype(np.float64 if reader.dtype.kind != "f" else reader.dtype.newbyteorder("="))
    if reader.core == (3, 3):
        data = _from_matrix(block, reader, a)
    else:
        data = np.array(_reorder(block, reader.layout))
    return Chunk(data, row0=a)


def _write_rows(path, offset, dtype, core, row0, data):
    """Write `data` as rows ``row0 …`` of the ``.npy`` file `path` (header already written)."""
    rowbytes = math.prod(core) * np.dtype(dtype).itemsize
    if len(data) == 0:
        return 0
    mm = np.memmap(path, dtype, "r+", offset=offset + row0 * rowbytes, shape=(len(data),) + tuple(core))
    mm[...] = data
    mm.flush()
    del mm
    return len(data)


def _convert_task(reader, a, b, to, degrees, tmp, offset, dtype):
    """Read, check, normalise, convert and write one block; returns the report figures."""
    import warnings

    from .cli import _target
    from .io.clean import Cleaner

    with _serial():
        ch = _read_chunk(reader, a, b)
        clean = Cleaner(reader, "error")
        ch, _ = clean.check(ch)  # a bad row raises DataError naming its global row
        _, core, fn = _target(to, degrees)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            out = np.asarray(fn(ch.data), dtype=dtype)
        lock = any("gimbal" in str(c.message).lower() for c in caught)
    _write_rows(tmp, offset, dtype, core, a, out)
    return clean.normalised, clean.max_dev, lock


class _NpyTarget:
    """A temporary ``.npy`` beside `dst` with its header written; renamed over `dst` on success."""

    def __init__(self, dst, shape, dtype):
        import tempfile

        self.dst = os.fspath(dst)
        folder, base = os.path.split(os.path.abspath(self.dst))
        fd, self.tmp = tempfile.mkstemp(prefix=f".{base}.", suffix=".tmp", dir=folder)
        os.close(fd)
        mm = np.lib.format.open_memmap(self.tmp, mode="w+", dtype=dtype, shape=tuple(shape))
        self.offset = mm.offset
        del mm

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        if kind is None:
            os.replace(self.tmp, self.dst)
        elif os.path.exists(self.tmp):
            os.remove(self.tmp)


def _check_files(src, dst, force, what="IN"):
    from .io.writers import check_output

    if os.fspath(dst).endswith(".zarr") or os.fspath(src).endswith(".zarr"):
        raise _usage("--scheduler: .zarr files are not supported yet; use .npy")
    if not os.fspath(dst).endswith(".npy"):
        raise _usage(f"{dst}: with --scheduler the output is written block by block to an .npy file")
    check_output(dst, [src], force)


def _blocks(rows, chunk):
    chunk = int(chunk)
    if chunk < 1:
        raise _usage(f"--chunk must be at least 1, got {chunk}")
    return [(a, min(a + chunk, rows)) for a in range(0, rows, chunk)]


def convert_file(src, dst, to, *, degrees=False, layout="wxyz", chunk=1_000_000, scheduler=None,
                 force=False, err=None):
    """``quatarray convert SRC DST --to TO --scheduler …``: an ``.npy`` stream converted block by block.

    Every block of `chunk` rows is read from a memory map, checked (a
    non-finite or zero quaternion, or a matrix that is not a rotation, is an
    error naming its row), normalised, converted and written into its place
    in DST by one task; DST appears (renamed from a temporary file beside
    it) only when every block succeeded.

    Parameters
    ----------
    src, dst : str or path-like
        ``.npy`` files: SRC holds ``(N, 4)`` quaternions in `layout` order or
        ``(N, 3, 3)`` rotation matrices.
    to : {"quat", "xyzw", "matrix", "rotvec", "axis-angle", "euler:SEQ"}
    degrees : bool
    layout : {"wxyz", "xyzw"}
    chunk : int
        Rows per block (per task).
    scheduler : None, "local", str or distributed.Client
        See :func:`scheduler_options`. Workers must see SRC and DST at the
        same paths (a shared file system on a real cluster).
    force : bool
        Overwrite an existing DST.
    err : file, optional
        Where the normalisation and gimbal-lock notes go (default stderr).

    Returns
    -------
    int
        0 (the command line's exit status).
    """
    from .cli import _target
    from .io.readers import open_stream

    err = sys.stderr if err is None else err
    _check_files(src, dst, force)
    _, core, _ = _target(to, degrees)  # a bad --to fails here, before any work
    reader = open_stream(src, "npy", kind="quat", layout=layout or "wxyz", chunk=chunk)
    dtype = as_float(np.empty(0, reader.dtype), "IN").dtype
    blocks = _blocks(reader.rows, chunk)
    with _NpyTarget(dst, (reader.rows,) + tuple(core), dtype) as target:
        tasks = [
            dask.delayed(_convert_task, pure=False)(reader, a, b, to, degrees, target.tmp, target.offset, dtype)
            for a, b in blocks
        ]
        with scheduler_options(scheduler) as opts:
            figures = dask.compute(*tasks, **opts)
    normalised = sum(f[0] for f in figures)
    if normalised:
        dev = max(f[1] for f in figures)
        print(f"{reader.name}: normalised {normalised} non-unit quaternion{'s' if normalised != 1 else ''} "
              f"(largest | |q| - 1 | = {dev:.3g})", file=err)
    lock = sum(f[2] for f in figures)
    if lock:
        print(f"{reader.name}: gimbal lock in {lock} chunk(s): the third angle was set to 0 there "
              "(as scipy does)", file=err)
    return 0
