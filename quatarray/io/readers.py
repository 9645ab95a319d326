"""Stream readers: npy (memory-mapped chunks), csv, tum, euroc, kitti, parquet, bvh.

Every reader is an iterable of :class:`~quatarray.io.streams.Chunk` objects
and describes its stream with a few attributes:

``name``      the path as the user wrote it (used in messages)
``format``    the format read
``kind``      ``"quat"`` (a rotation stream, rows are (w, x, y, z)), ``"vector"`` or
              ``"rate"`` (angular velocity: columns ``wx wy wz``, or an EuRoC IMU file)
``columns``   the source columns used, in the file's own names
``layout``    how the quaternion columns were laid out in the file
``has_time``, ``has_pos``
``rows``      the row count when known before reading (npy, parquet, bvh), else None
``skipped``   rows the parser dropped (``on_invalid="drop"`` only)

``.zarr`` stores (with the optional package zarr) are read like npy files,
block by block.

``where(row)`` turns a data-row index into ``file:line`` (text) or
``file: row N`` (binary) for error messages.

The readers live by subject: stored arrays (npy, zarr) in
:mod:`quatarray.io.arrays`, text and parquet in :mod:`quatarray.io.text`
(parsed by pyarrow's streaming CSV reader, block by block; only when pyarrow
reports a malformed file is the file scanned line by line in Python, to name
the first bad line), one BVH joint in :mod:`quatarray.io.bvh`; all extend
:class:`quatarray.io.streams.Reader`. This module opens the right one, and
reads the times files of ``resample --times`` and ``--in-times``.
"""

import os

import numpy as np

from . import formats as F
from .arrays import NpyReader, ZarrReader, import_zarr
from .bvh import BvhReader
from .clean import time_order
from .errors import DataError, UsageError
from .formats import is_zarr
from .text import ParquetReader, TextReader

__all__ = ["DEFAULT_CHUNK", "open_stream", "read_times", "import_zarr"]

DEFAULT_CHUNK = 1 << 18


def open_stream(path, fmt="auto", kind="quat", layout=None, joint=None, chunk=DEFAULT_CHUNK,
                on_invalid="error", name=None):
    r"""Open a stream file for chunked reading.

    Parameters
    ----------
    path : str or path-like
    fmt : {"auto", "npy", "csv", "tum", "euroc", "parquet", "bvh", "kitti"}
        ``"auto"`` decides by extension and by the header.
    kind : {"quat", "vector", "rate"}
        A rotation stream, a stream of 3-vectors (``rotate``'s VECTORS) or of
        angular velocities (``integrate``'s input).
    layout : {"wxyz", "xyzw"}, optional
        Order of quaternion columns in inputs without named columns
        (npy, headerless csv); default wxyz.
    joint : str, optional
        BVH joint (default: the root).
    chunk : int
        Rows per chunk.
    on_invalid : {"error", "drop"}
        What the parser does with a malformed row (the row checks themselves
        live in :class:`~quatarray.io.clean.Cleaner`).

    Returns
    -------
    reader
        An iterable of chunks with the attributes listed in the module docstring.

    Examples
    --------
    >>> import os, tempfile, numpy as np
    >>> from quatarray import io
    >>> path = os.path.join(tempfile.mkdtemp(), "walk.csv")
    >>> _ = open(path, "w").write("t,qx,qy,qz,qw\n0,0,0,0,1\n0.5,0,0,1,0\n")
    >>> reader = io.open_stream(path)
    >>> reader.format, reader.has_time, reader.columns
    ('csv', True, ['t', 'qw', 'qx', 'qy', 'qz'])
    >>> chunk = next(iter(reader))
    >>> chunk.t, chunk.data  # quaternions as (w, x, y, z)
    (array([0. , 0.5]), array([[1., 0., 0., 0.],
           [0., 0., 0., 1.]]))
    """
    path = os.fspath(path)
    name = name or path
    if not os.path.exists(path):
        raise UsageError(f"{name}: no such file")
    if os.path.isdir(path) and not is_zarr(path):
        raise UsageError(f"{name}: is a directory")
    if fmt not in F.FORMATS:
        raise UsageError(f"unknown format {fmt!r}")
    if fmt == "auto":
        fmt = F.by_extension(path) or "text"
    if joint is not None and fmt != "bvh":
        raise UsageError(f"{name}: --joint applies to bvh files only")
    if layout not in (None, "wxyz", "xyzw"):
        raise UsageError(f"unknown layout {layout!r}")
    chunk = int(chunk)
    if chunk < 1:
        raise UsageError(f"--chunk must be at least 1, got {chunk}")
    if is_zarr(path):
        return ZarrReader(path, name, kind, layout, chunk, on_invalid)
    if fmt == "npy":
        return NpyReader(path, name, kind, layout, chunk, on_invalid)
    if fmt == "parquet":
        return ParquetReader(path, name, kind, chunk)
    if fmt == "bvh":
        if kind != "quat":
            raise DataError(f"{name}: a bvh file holds rotations, not vectors")
        return BvhReader(path, name, joint, chunk, on_invalid)
    return TextReader(path, name, fmt, kind, layout, chunk, on_invalid)


# --------------------------------------------------------------------------
# times for `resample --times`


def read_times(path, fmt="auto", name=None, order=None, locate=False):
    r"""A 1-D float64 array of times from a file.

    ``.npy``: a 1-D float (or integer) array (or (N, 1)). Text: one number a
    line, or any stream file with a time column (csv/tum/euroc/parquet/bvh),
    whose times are used.

    Parameters
    ----------
    path : str or path-like
    fmt : {"auto", "npy", "csv", ...}
        As for :func:`open_stream` (default: by extension and contents).
    name : str, optional
        The file's name in messages (default `path`).
    order : {None, "non-decreasing", "increasing"}
        Check that the times are finite and in this order: the first that is
        not raises a :class:`DataError` naming its line (its row in an npy file).
    locate : bool, optional
        Also return ``where(i)``, the place of time ``i`` for a message
        (``"times.txt:12"``, 1-based lines; ``"t.npy: row 11"`` in an array).

    Examples
    --------
    >>> import os, tempfile
    >>> from quatarray import io
    >>> path = os.path.join(tempfile.mkdtemp(), "times.txt")
    >>> _ = open(path, "w").write("# s\n0.0\n0.25\n0.5\n")
    >>> io.read_times(path)
    array([0.  , 0.25, 0.5 ])
    >>> io.read_times(path, locate=True)[1](1) == f"{path}:3"
    True
    """
    path = os.fspath(path)
    name = name or path
    times, where = _times_and_where(path, fmt, name)
    if order is not None:
        fin = np.isfinite(times)
        if not fin.all():
            i = int(np.argmin(fin))
            raise DataError(f"{where(i)}: time is not a finite number ({float(times[i])!r})")
        d = np.diff(times)
        bad = (d <= 0) if order == "increasing" else (d < 0)
        if bad.any():
            i = int(np.argmax(bad)) + 1
            raise DataError(f"{where(i)}: {time_order(times[i], times[i - 1], order == 'increasing')}")
    return (times, where) if locate else times


def _names_time(text):
    """Whether a header line names a time column (``t``, ``time``, ``timestamp [s]`` …)."""
    return F.unquoted(text).split("[")[0].split("(")[0].strip().lower() in F.TIME_NAMES


def _one_a_line(path, name):
    """A text file of one time a line: the times and ``where(i)``. ``#`` comments and blank
    lines are skipped, and a first line that is not a number when a number follows it (a
    header such as ``t``); any other line that is not a number is named."""
    out, lines = [], []
    header = None  # (line number, text) of a first line that is not a number
    with open(path, "r", encoding="utf-8-sig", errors="backslashreplace") as f:
        for lineno, line in enumerate(f, 1):
            s = line.strip()
            if not s or s.startswith("#"):
                continue
            try:
                out.append(float(s))
            except ValueError:
                if out or header is not None:  # after the header or a time: bad data
                    # two lines before the first time: the second is the bad one when the first names
                    # the time column, else the first (a header is one line of names, not of data)
                    bad = (lineno, s) if out or _names_time(header[1]) else header
                    raise DataError(f"{name}:{bad[0]}: not a number: '{F.shown(bad[1])}' (a times file "
                                    f"holds one time a line, after at most one header line)") from None
                header = (lineno, s)
                continue
            lines.append(lineno)
    if not out:
        if header is not None:
            raise DataError(f"{name}:{header[0]}: not a number: '{F.shown(header[1])}' (a times file holds "
                            f"one time a line; this one has none)")
        raise F.empty(name)
    return np.array(out), lambda i: f"{name}:{lines[i]}"


def _times_and_where(path, fmt, name):
    """The times of a file and ``where(i)``, the ``file:line`` (or row) of time i."""
    if not os.path.exists(path):
        raise UsageError(f"{name}: no such file")
    if (fmt == "auto" and F.by_extension(path) == "npy") or fmt == "npy":
        bad = f"{name}: not a valid .npy float array"
        try:
            with open(path, "rb") as f:
                np.lib.format.read_magic(f)
        except (ValueError, OSError, EOFError):
            raise DataError(f"{bad} (no .npy header)") from None
        try:
            a = np.load(path, mmap_mode="r", allow_pickle=False)
        except (ValueError, OSError, EOFError) as exc:
            why = "it holds Python objects" if "pickle" in str(exc) or "object" in str(exc) else F.shown(exc, 100)
            raise DataError(f"{bad} ({why})") from None
        if a.dtype.kind not in "fiu" or a.dtype.fields is not None:
            raise DataError(f"{bad} (dtype {a.dtype})")
        if a.ndim == 2 and a.shape[1] == 1:
            a = a[:, 0]
        if a.ndim != 1:
            raise DataError(f"{name}: expected a 1-D array of times, got shape {a.shape}")
        return a, lambda i: f"{name}: row {i}"
    if F.by_extension(path) is None and fmt in ("auto", "csv"):
        with open(path, "rb") as f:
            first = next((ln for ln in f if ln.strip() and not ln.lstrip().startswith(b"#")), b"")
        fields = first.replace(b",", b" ").split()
        if len(fields) == 1:
            return _one_a_line(path, name)
    reader = open_stream(path, fmt, name=name)
    if not reader.has_time:
        raise DataError(f"{name}: has no time column")
    return np.concatenate([ch.t for ch in reader]), reader.where
