"""Stream writers: npy (appended chunk by chunk), csv, parquet, tum.

Every writer writes to a temporary file beside OUT (:func:`temporary_beside`)
and renames it over OUT in :meth:`Writer.close` (:func:`publish`); the
block-by-block targets of the Dask file jobs (:mod:`quatarray.io.targets`)
do the same; :meth:`Writer.abort` (or leaving a ``with`` block by
an exception) removes the temporary file, so a failed or interrupted run
never leaves a partial OUT.
"""

import contextlib
import os
import stat
import tempfile

import numpy as np

from .._compat import csv_write_options, header_line
from . import formats as F
from .errors import OutputError, UsageError
from .formats import is_zarr


def check_output(out, inputs=(), force=False):
    """Refuse OUT when it is one of the inputs, or exists without ``force``.

    Raises :class:`~quatarray.io.UsageError`.

    Examples
    --------
    >>> from quatarray import io
    >>> io.check_output("walk.npy", ["walk.npy"])
    Traceback (most recent call last):
    ...
    quatarray.io.errors.UsageError: walk.npy: the output is the input file; write to another file
    """
    out = os.fspath(out)
    for src in inputs:
        src = os.fspath(src)
        same = os.path.exists(out) and os.path.exists(src) and os.path.samefile(out, src)
        if same or os.path.abspath(out) == os.path.abspath(src):
            raise UsageError(f"{out}: the output is the input file; write to another file")
    if os.path.isdir(out) and not is_zarr(out):  # a zarr store is a folder
        raise UsageError(f"{out}: is a directory")
    if os.path.exists(out) and not os.path.isdir(out) and not stat.S_ISREG(os.stat(out).st_mode):
        raise UsageError(f"{out}: is not a regular file (a FIFO, socket or device); refusing to replace it")
    if os.path.exists(out) and not force:
        raise UsageError(f"{out}: exists; use --force to overwrite it")
    parent = os.path.dirname(os.path.abspath(out))
    if not os.path.isdir(parent):
        up = parent
        while not os.path.exists(up):  # the nearest existing ancestor tells which it is
            up = os.path.dirname(up)
        if not os.path.isdir(up):
            raise UsageError(f"{out}: {up} is not a folder")
        raise UsageError(f"{out}: the folder {parent} does not exist")


def output_mode(out):
    """The permissions OUT gets: those of the regular file it replaces (``--force``), else
    0666 less the umask, as any other tool's new file (``mkstemp`` makes 0600)."""
    try:
        st = os.stat(out)
    except OSError:
        st = None
    if st is not None and stat.S_ISREG(st.st_mode):
        return stat.S_IMODE(st.st_mode)
    mask = os.umask(0o022)  # reading the umask means setting it: put it back at once
    os.umask(mask)
    return 0o666 & ~mask


def temporary_beside(path, suffix=".tmp", folder=False):
    """A new, empty temporary file (or with `folder`, folder) beside `path`, hidden:
    ``.<name of path>.<random><suffix>``. Renamed over `path` when done (:func:`publish`),
    it never crosses file systems, so OUT appears whole or not at all."""
    where, base = os.path.split(os.path.abspath(path))
    if folder:
        return tempfile.mkdtemp(prefix=f".{base}.", suffix=suffix, dir=where)
    fd, tmp = tempfile.mkstemp(prefix=f".{base}.", suffix=suffix, dir=where)
    os.close(fd)
    return tmp


def publish(tmp, path):
    """Move the finished temporary file `tmp` over `path`, with the mode `path` gets
    (:func:`output_mode`; ``mkstemp`` made `tmp` 0600)."""
    os.chmod(tmp, output_mode(path))
    os.replace(tmp, path)


def pwrite_all(fd, data, at):
    """Write the bytes of the contiguous array `data` into file `fd` at offset `at`
    (a positioned write: no seek, no page faults as a memory map would take)."""
    view = memoryview(data).cast("B")
    while view:  # a write may take fewer bytes than asked (large writes, signals)
        done = os.pwrite(fd, view, at)
        view, at = view[done:], at + done


def _size(nbytes):
    for unit in ("bytes", "KiB", "MiB", "GiB", "TiB"):
        if nbytes < 1024 or unit == "TiB":
            return f"{nbytes:.4g} {unit}"
        nbytes /= 1024


def open_writer(path, fields, core=None, time=False, pos=False, fmt=None):
    """A writer for OUT, by its extension unless ``fmt`` is given.

    Parameters
    ----------
    path : str
    fields : list of str
        Column names of the verb's array, flattened (csv, parquet).
    core : tuple, optional
        Trailing shape of the array in an ``.npy`` output (default ``(len(fields),)``).
    time, pos : bool
        Whether chunks carry a time column and x, y, z columns (csv, parquet, tum).

    Examples
    --------
    >>> import os, tempfile, numpy as np
    >>> from quatarray import io
    >>> out = os.path.join(tempfile.mkdtemp(), "o.csv")
    >>> with io.open_writer(out, ["qw", "qx", "qy", "qz"], time=True) as w:
    ...     w.write(np.array([[1.0, 0, 0, 0]]), t=np.array([0.5]))
    >>> print(open(out).read(), end="")
    t,qw,qx,qy,qz
    0.5,1,0,0,0
    """
    fmt = fmt or F.output_format(path)
    core = tuple(core) if core is not None else (len(fields),)
    if fmt == "npy":
        return NpyWriter(path, core)
    cols = (["t"] if time else []) + (["x", "y", "z"] if pos else []) + list(fields)
    if fmt == "csv":
        return CsvWriter(path, cols)
    if fmt == "parquet":
        return ParquetWriter(path, cols)
    if fmt == "tum":
        if list(fields) != ["qw", "qx", "qy", "qz"]:
            raise UsageError(f"{path}: a TUM output holds quaternions only (it has no columns {' '.join(fields)})")
        missing = [what for what, have in (("times", time), ("positions", pos)) if not have]
        if missing:
            raise UsageError(f"{path}: a TUM output (timestamp tx ty tz qx qy qz qw) needs times and "
                             f"positions; this stream has no {' and no '.join(missing)}")
        return TumWriter(path, cols)
    raise UsageError(f"{path}: cannot write format {fmt!r}")


class Writer:
    """Where an output goes while it is written: a temporary file beside OUT.

    The file is renamed over OUT by :meth:`close`, with the mode OUT gets
    (:func:`output_mode`); :meth:`abort`, or a ``with`` block left by an
    exception, removes it. An :class:`OSError` on the way (an unwritable
    folder, a full disk, a file-size limit) becomes an
    :class:`~quatarray.io.OutputError` naming OUT, and the temporary file
    goes. The base class itself suits code that writes the temporary file
    by its path (``tmp``), as a plot's ``savefig`` does.

    Parameters
    ----------
    path : str
        OUT.
    suffix : str, optional
        Of the temporary file (default ``".tmp"``).
    """

    min_row_bytes = 0  # a lower bound on the bytes a row takes in the file (see reserve)

    def buffer(self, n, dtype):
        """Where a kernel may put the next ``n`` rows (``out=``), or None to allocate."""
        with self._naming_out():
            return self._buffer(n, dtype)

    def _buffer(self, n, dtype):
        return None

    def __init__(self, path, suffix=".tmp"):
        self.path = os.fspath(path)
        self.rows = 0
        self.closed = True  # until the temporary file exists
        with self._naming_out():
            self.tmp = temporary_beside(self.path, suffix)
            self.closed = False
            self._open()

    @contextlib.contextmanager
    def _naming_out(self):
        """An OSError inside → the temporary file removed, and an OutputError naming OUT."""
        try:
            yield
        except OSError as exc:
            self.abort()
            raise OutputError(f"{self.path}: cannot write the output: {exc.strerror or exc}") from None
        except BaseException:
            self.abort()
            raise

    def _open(self):
        pass

    def write(self, data, t=None, pos=None):
        """Append rows (with their times and positions, where the output has those columns)."""
        with self._naming_out():
            self._write(data, t, pos)

    def _write(self, data, t, pos):
        raise NotImplementedError

    def reserve(self, rows):
        """Refuse, before any is computed, ``rows`` more rows that cannot fit on OUT's disk.

        Raises :class:`~quatarray.io.OutputError` when even at
        ``min_row_bytes`` a row they need more than the free space.
        """
        need = rows * self.min_row_bytes
        if not need:
            return
        st = os.statvfs(os.path.dirname(os.path.abspath(self.tmp)))
        free = st.f_bavail * st.f_frsize
        if need > free:
            self.abort()
            raise OutputError(f"{self.path}: {rows:.4g} more rows need at least {_size(need)}, "
                              f"more than the {_size(free)} free on its disk")

    def _finish(self):
        pass

    def close(self):
        """Finish the file and move it to OUT."""
        if self.closed:
            return
        with self._naming_out():
            self._finish()
            publish(self.tmp, self.path)
        self.closed = True

    def abort(self):
        """Drop the temporary file (errors on the way are ignored: the run is abandoned)."""
        if self.closed:
            return
        self.closed = True
        try:
            self._release()
        except OSError:
            pass
        finally:
            if os.path.exists(self.tmp):
                os.unlink(self.tmp)

    def _release(self):
        pass

    def __enter__(self):
        return self

    def __exit__(self, typ, exc, tb):
        if typ is None:
            self.close()
        else:
            self.abort()
        return False


class NpyWriter(Writer):
    """``.npy`` written incrementally: a header with room for any row count, then the
    chunks appended; the header is rewritten with the final count at the end.

    :meth:`buffer` lends one of two reused in-memory arrays (``out=`` for the
    kernels); :meth:`write` hands it to a background thread that copies it
    into the file with ``pwrite`` while the caller computes the next chunk
    into the other array. Their pages are faulted in once; a fresh array per
    chunk, or a memory map of the file, would page-fault (and have the system
    zero) every output page again, which costs about as much as the kernel
    itself, and copying into the file would not overlap the computing.
    Resident memory stays bounded by two chunks of output.
    """

    def __init__(self, path, core):
        self.core = core
        self.min_row_bytes = int(np.prod(core)) * 4  # float32 at the least
        self.dtype = None
        self.f = None
        self._scratch = [None, None]  # the two arrays buffer() lends, reused chunk after chunk
        self._lent = None  # index of the array lent and not yet written
        self._next = 0  # the array to lend next (the other one may be in flight)
        self._pool = None  # the background writer (one thread), started on the first write
        self._flight = None  # its pending write
        super().__init__(path)

    def _open(self):
        self.f = open(self.tmp, "w+b", buffering=0)  # unbuffered: data goes by os.pwrite

    def _header(self, rows):
        shape = (rows,) + self.core
        d = {"descr": np.lib.format.dtype_to_descr(self.dtype), "fortran_order": False, "shape": shape}
        text = repr(d).encode("latin1")
        size = 10 + len(text) + 1
        total = -(-(10 + 100 + 1) // 64) * 64  # fixed: room for a 20-digit row count
        if size > total:  # pragma: no cover - cores are tiny
            total = -(-size // 64) * 64
        pad = total - size
        return b"\x93NUMPY\x01\x00" + np.uint16(total - 10).tobytes() + text + b" " * pad + b"\n"

    def _start(self, dtype):
        if self.dtype is None:
            self.dtype = np.dtype(dtype)
            self.head = len(self._header(0))
            self.rowbytes = int(np.prod(self.core)) * self.dtype.itemsize
            self.f.write(self._header(0))

    def _end(self):
        return self.head + self.rows * self.rowbytes

    def _buffer(self, n, dtype):
        """An ``(n,) + core`` array for the next ``n`` rows; pass it (or a leading
        slice of it) to :meth:`write` once filled. Its storage comes back two
        calls later, so write each one before asking for the next."""
        self._start(dtype)
        self._lent = None
        if n == 0 or np.dtype(dtype) != self.dtype:
            return None
        k = self._next
        if self._scratch[k] is None or self._scratch[k].shape[0] < n:
            self._scratch[k] = np.empty((n,) + self.core, self.dtype)
        self._lent = k
        return self._scratch[k][:n]

    def _pwrite(self, data, at):
        pwrite_all(self.f.fileno(), data, at)

    def _wait(self):
        """Wait for the write in flight; its error (a full disk, …) is raised here."""
        flight, self._flight = self._flight, None
        if flight is not None:
            flight.result()

    def _write(self, data, t, pos):
        lent, self._lent = self._lent, None
        scratch = self._scratch[lent] if lent is not None else None
        own = (
            scratch is not None and isinstance(data, np.ndarray) and data.dtype == self.dtype
            and data.flags.c_contiguous and data.shape[1:] == self.core and data.shape[0] <= scratch.shape[0]
            and data.__array_interface__["data"][0] == scratch.__array_interface__["data"][0]
        )
        if not own:  # the caller's own array, which it may reuse: written now
            data = np.ascontiguousarray(data)
            self._start(data.dtype)
            if data.dtype != self.dtype:
                data = data.astype(self.dtype)
            self._wait()
            self._pwrite(data, self._end())
            self.rows += data.shape[0]
            return
        self._wait()  # the other array's write: done before this one is queued
        if self._pool is None:
            from concurrent.futures import ThreadPoolExecutor

            self._pool = ThreadPoolExecutor(1, thread_name_prefix="quatarray-npy-writer")
        self._flight = self._pool.submit(self._pwrite, data, self._end())
        self.rows += data.shape[0]
        self._next = 1 - lent

    def _stop(self):
        try:
            self._wait()
        finally:
            if self._pool is not None:
                self._pool.shutdown()
            self._pool = None
            self._scratch = [None, None]

    def _finish(self):
        self._stop()
        self._start(np.float64)
        self.f.truncate(self._end())
        self.f.seek(0)
        self.f.write(self._header(self.rows))
        self.f.close()

    def _release(self):
        try:
            self._stop()
        except OSError:
            pass  # the run is being abandoned anyway; the temporary file goes
        finally:
            if self.f is not None:
                self.f.close()


def _table(cols, data, t, pos):
    import pyarrow as pa

    n = data.shape[0]
    flat = np.asarray(data).reshape(n, -1)
    arrays = []
    if t is not None:
        arrays.append(np.ascontiguousarray(t))
    if pos is not None:
        arrays += [np.ascontiguousarray(pos[:, k]) for k in range(3)]
    arrays += [np.ascontiguousarray(flat[:, k]) for k in range(flat.shape[1])]
    if len(arrays) != len(cols):  # pragma: no cover - a verb bug, not a user error
        raise RuntimeError(f"writer expected columns {cols}, got {len(arrays)} arrays")
    return pa.table([_arrow(a) for a in arrays], names=cols)


def _arrow(a):
    """A contiguous numpy column as an arrow array sharing its memory (``pa.array``
    imports pandas where it is installed, about 0.5 s of a command's start-up)."""
    import pyarrow as pa

    kind = _ARROW.get(a.dtype.str)
    if kind is None:
        return pa.array(a)
    return pa.Array.from_buffers(getattr(pa, kind)(), len(a), [None, pa.py_buffer(a)])


_ARROW = {"<f8": "float64", "<f4": "float32", "<i8": "int64"}


class CsvWriter(Writer):
    """csv with a header of the exact column names; numbers at full precision
    (shortest repr that reads back to the same float)."""

    delimiter = ","
    include_header = True
    preamble = b""

    def __init__(self, path, cols):
        self.cols = cols
        self.min_row_bytes = 2 * len(cols)  # a digit and a delimiter a column at the least
        self.w = self.sink = None
        super().__init__(path)

    def _open(self):
        self.sink = open(self.tmp, "wb")
        self.sink.write(self.preamble)

    def _write(self, data, t, pos):
        import pyarrow.csv as pcsv

        table = _table(self.cols, data, t, pos)
        if self.w is None:
            opts, by_hand = csv_write_options(
                include_header=self.include_header, delimiter=self.delimiter, quoting_style="none",
                batch_size=1 << 14,
            )
            if by_hand:  # pyarrow < 22 quotes its header
                self.sink.write(header_line(self.cols, self.delimiter))
            self.w = pcsv.CSVWriter(self.sink, table.schema, write_options=opts)
        self.w.write_table(table)
        self.rows += table.num_rows

    def _finish(self):
        if self.w is None and self.include_header:
            self.sink.write((self.delimiter.join(self.cols) + "\n").encode())
        if self.w is not None:
            self.w.close()
        self.sink.close()

    def _release(self):
        try:
            if self.w is not None:
                self.w.close()
        finally:
            if self.sink is not None:
                self.sink.close()


class TumWriter(CsvWriter):
    """TUM trajectory: ``timestamp tx ty tz qx qy qz qw`` (scalar last)."""

    delimiter = " "
    include_header = False
    preamble = b"# timestamp tx ty tz qx qy qz qw\n"

    def _write(self, data, t, pos):
        super()._write(np.asarray(data)[:, [1, 2, 3, 0]], t, pos)


class ParquetWriter(Writer):
    def __init__(self, path, cols):
        self.cols = cols
        self.w = None
        super().__init__(path)

    def _write(self, data, t, pos):
        import pyarrow.parquet as pq

        table = _table(self.cols, data, t, pos)
        if self.w is None:
            self.w = pq.ParquetWriter(self.tmp, table.schema)
        self.w.write_table(table)
        self.rows += table.num_rows

    def _finish(self):
        if self.w is None:
            import pyarrow as pa
            import pyarrow.parquet as pq

            pq.write_table(pa.table({c: pa.array([], pa.float64()) for c in self.cols}), self.tmp)
        else:
            self.w.close()

    def _release(self):
        if self.w is not None:
            self.w.close()
