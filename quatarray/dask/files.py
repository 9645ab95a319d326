"""The Dask file jobs: ``quatarray convert/resample --scheduler`` (:func:`convert_file`,
:func:`resample_file`), their drop planning, and the cluster they run on
(:func:`scheduler_options`, :func:`local_cluster`); see :mod:`quatarray.dask`.

What a job is (targets, new times, checks) comes from :mod:`quatarray.jobs`,
as for the command line in one process; the blocks are read by
:mod:`quatarray.io` readers and written into :mod:`quatarray.io.targets`.
"""

import contextlib
import os
import sys
import threading
import warnings

import dask
import dask.array as da
import numpy as np
from dask.base import tokenize
from dask.core import flatten as _flatten_keys
from dask.delayed import Delayed
from dask.highlevelgraph import HighLevelGraph

from .._validate import as_float
from ..io.clean import Cleaner
from ..io.errors import DataError, UsageError
from ..io.formats import is_zarr
from ..io.readers import open_stream
from ..io.streams import concat, timed_chunks
from ..io.targets import open_target
from ..io.writers import check_output
from .. import _jit, jobs
from ..jobs import ROWS_PER_PIECE, check_key_times, gimbal_note, new_times
from .windows import spline

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
        raise UsageError("--scheduler needs the package 'distributed': pip install 'quatarray[dask]'") from None
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
            raise UsageError(f"--scheduler {scheduler}: cannot reach the scheduler ({exc})") from None
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
#   a round trip to the scheduler (about 3 ms on a local cluster). Our tasks
#   are few and even: send them all at once.
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


# --------------------------------------------------------------------------
# files: where the blocks come from and go to


def _open_source(src, layout, chunk):
    """An ``.npy`` file or ``.zarr`` store of quaternions or matrices, read by the workers."""
    if not (is_zarr(src) or os.fspath(src).endswith(".npy")):
        raise UsageError(f"{src}: with --scheduler the input is an .npy file or a .zarr store")
    # workers open it by its absolute path (theirs may run in another folder)
    return open_stream(os.path.abspath(src), "npy", kind="quat", layout=layout, chunk=chunk, name=os.fspath(src))


def _check_files(src, dst, force):
    if not (is_zarr(dst) or os.fspath(dst).endswith(".npy")):
        raise UsageError(f"{dst}: with --scheduler the output is an .npy file or a .zarr store, written block by block")
    check_output(dst, [src], force)


def _blocks(rows, chunk):
    chunk = int(chunk)
    if chunk < 1:
        raise UsageError(f"--chunk must be at least 1, got {chunk}")
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
    with _jit.serial():
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


def plan_sizes(plan, kept):
    """The good rows each planned task gives (its output block's size: at most `chunk`)."""
    return [int(n) for n in np.diff([o for _, _, o in plan] + [kept])]


def _report(reader, figures, dropped, err):
    """The command line's notes: rows dropped, quaternions normalised."""
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
    _, core, fn = jobs.target(to, degrees)
    piecewise = target.piecewise
    out = _scratch_rows(min(rows, ROWS_PER_PIECE) if piecewise else rows, core, target.dtype)
    clean = Cleaner(reader, "drop" if drop else "error")
    n = 0
    with _jit.serial():
        for p in range(a, b, ROWS_PER_PIECE):
            ch = _read_clean(reader, p, min(p + ROWS_PER_PIECE, b), drop, clean)
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
    str
        DST, written.
    """
    err = sys.stderr if err is None else err
    _check_files(src, dst, force)
    _, core, _ = jobs.target(to, degrees)  # a bad --to fails here, before any work
    reader = _open_source(src, layout or "wxyz", chunk)
    dtype = as_float(np.empty(0, reader.dtype), "IN").dtype
    drop = on_invalid == "drop"
    with scheduler_options(scheduler) as opts:
        plan, bad = _plan_rows(reader, chunk, drop, opts)
        kept = reader.rows - bad.size
        with open_target(dst, (kept,) + tuple(core), dtype, chunk) as target:
            tasks = [dask.delayed(_convert_task, pure=False)(reader, a, b, o, n, to, degrees, target, drop)
                     for (a, b, o), n in zip(plan, plan_sizes(plan, kept))]
            figures = _compute_all(tasks, opts)
    _report(reader, figures, bad.size, err)
    gimbal_note(reader.name, sum(f[2] for f in figures), err)
    return str(dst)


# --------------------------------------------------------------------------
# resample_file


def read_keys_task(reader, a, b, drop):
    """Input rows ``[a, b)`` of a key stream, checked and normalised as the command line
    does, piece by piece (a long run of dropped rows never sits in memory), and the
    normalisation figures; or the DataError naming the block's first bad row, returned
    (see :func:`_first_error`)."""
    clean = Cleaner(reader, "drop" if drop else "error")
    try:
        with _jit.serial():
            parts = [_read_clean(reader, p, min(p + ROWS_PER_PIECE, b), drop, clean).data for p in range(a, b, ROWS_PER_PIECE)]
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
    dtype = as_float(np.empty(0, reader.dtype), "IN").dtype
    mtime = os.path.getmtime(reader.path)
    token = tokenize(reader.path, mtime, reader.layout, plan, drop)
    raw, name, report = f"read-keys-raw-{token}", f"read-keys-{token}", f"read-keys-report-{token}"
    dsk = {(raw, i): (read_keys_task, reader, a, b, drop) for i, (a, b, _) in enumerate(plan)}
    dsk[report] = (_first_error, [(raw, i) for i in range(len(plan))])
    dsk.update({(name, i, 0): (_key_block, (raw, i), report) for i in range(len(plan))})
    graph = HighLevelGraph.from_collections(name, dsk, dependencies=[])
    keys = da.Array(graph, name, (tuple(plan_sizes(plan, kept)), (4,)), meta=np.empty((0, 0), dtype))
    return keys, Delayed(report, graph, layer=name)


def _kept_times(a, b, bad, in_rate):
    """The times (row / in_rate) of input rows [a, b) but the `bad` ones."""
    return np.delete(np.arange(a, b, dtype=np.float64), bad - a) / in_rate


def lazy_key_times(plan, bad, rows, in_rate):
    """The key times of a stream read by :func:`_lazy_keys` (row k at k / in_rate,
    dropped rows left out) as a Dask array made by the workers, blocked like the keys,
    and its first and last times (as the array would hold them)."""
    name = f"key-times-{tokenize(plan, bad, rows, in_rate)}"
    dsk = {}
    for i, (a, b, _) in enumerate(plan):
        dsk[(name, i)] = (_kept_times, a, b, bad[(bad >= a) & (bad < b)], in_rate)
    sizes = tuple(plan_sizes(plan, rows - bad.size))
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
    is interpolated with :func:`~quatarray.dask.windows.spline` by one task and written into its
    rows of DST (an ``.npy`` file or a ``.zarr`` store chunked by `chunk`
    rows), which appears when all succeeded.

    In error mode, the error names the file's first bad row, as in memory.

    An ``.npy`` or ``.zarr`` SRC has no times: give its sampling rate as
    `in_rate` (key k at k / in_rate seconds; dropped rows keep their times
    out); its blocks are read by the workers. Other formats (csv, tum,
    euroc, parquet, bvh) are read on the client.

    Returns
    -------
    str
        DST, written.
    """
    _check_files(src, dst, force)
    err = sys.stderr if err is None else err
    if times is not None:
        check_output(dst, [times], True)  # DST must not be the times file
    newt = new_times(rate, times)
    reader = open_stream(src, "auto", kind="quat", layout=layout, chunk=chunk, on_invalid=on_invalid)
    check_key_times(reader.name, reader.has_time, in_rate, in_times_option=False)
    drop = on_invalid == "drop"
    with scheduler_options(scheduler) as opts:
        figures, dropped = [], 0
        if reader.format in ("npy", "zarr"):
            plan, bad = _plan_rows(reader, chunk, drop, opts)
            keys, report = _lazy_keys(reader, plan, reader.rows - bad.size, drop)
            figures = [report]
            t, ends = lazy_key_times(plan, bad, reader.rows, in_rate)
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
        with open_target(dst, lazy.shape, lazy.dtype, chunk) as target:
            done = _compute_all([_store(lazy, target).sum()] + figures, opts, independent=False)
    if figures:
        _report(reader, done[1], dropped, err)
    return str(dst)


__all__ = ["scheduler_options", "local_cluster", "convert_file", "resample_file"]
