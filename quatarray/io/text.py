"""Tabular streams: text (csv with named columns, headerless csv, TUM, EuRoC, KITTI),
parsed by pyarrow's streaming CSV reader block by block, and parquet files.

The format and the columns' roles are told from the extension, the header
names and the first rows (:class:`TextReader`); only when pyarrow reports a
malformed file is the file scanned line by line in Python, to name the first
bad line.
"""

import os
import re
import weakref

import numpy as np

from . import formats as F
from .arrays import matrix_rows
from .clean import TEXT_ROUNDING
from .errors import DataError
from .formats import is_number
from .streams import Chunk, Reader


def _half_ulp(s):
    """Half a unit in the last place written of the number `s`: its rounding (0 for an
    integer, taken as exact; 5e-7 for ``1.000000e-01``: exponents below 0 do not count,
    as the components rounded are at most 1 in size)."""
    mant, _, exp = F.unquoted(s).lower().partition("e")
    if "." not in mant and not exp:
        return 0.0
    return 0.5 * 10.0 ** (max(int(exp or 0), 0) - len(mant.partition(".")[2]))


def _split(line, delim):
    return line.split() if delim == " " else [f.strip() for f in line.split(delim)]


def _find_roles(names, kind, name, lineno):
    """Map header names to (time, pos, quat/vec) columns, or raise for a missing column."""
    low = {n.strip().lower(): n for n in names}
    t = next((low[k] for k in F.TIME_NAMES if k in low), None)
    if kind == "quat":
        pos = next(([low[k] for k in c] for c in F.POS_NAMES if all(k in low for k in c)), None)
        cands = F.QUAT_NAMES if pos is None else F.QUAT_NAMES[:1]
        q = next(([low[k] for k in c] for c in cands if all(k in low for k in c)), None)
        if q is None:
            missing = [k for k in F.QUAT_NAMES[0] if k not in low]
            raise DataError(
                f"{name}:{lineno}: missing column {', '.join(missing)} "
                f"(need qw, qx, qy, qz; the header has {F.shown(', '.join(n.strip() for n in names))})"
            )
        return t, pos, q
    cands = F.RATE_NAMES if kind == "rate" else F.VEC_NAMES
    v = next(([low[k] for k in c] for c in cands if all(k in low for k in c)), None)
    if v is None:
        missing = [k for k in cands[0] if k not in low]
        raise DataError(f"{name}:{lineno}: missing column {', '.join(missing)} (need {', '.join(cands[0])})")
    return t, None, v


class TextReader(Reader):
    """csv / tum / euroc / kitti through pyarrow's streaming CSV reader."""

    def __init__(self, path, name, fmt, kind, layout, chunk, on_invalid):
        self.path, self.name, self.kind, self.chunk = path, name, kind, chunk
        self.drop = on_invalid == "drop"
        self.skipped = 0
        self.ns_time = False
        self.matrix = False
        self._sniff(fmt, layout)
        self.tolerance, self.matrix_tolerance = self._rounding()

    # -- header ------------------------------------------------------------

    def _sniff(self, fmt, layout):
        name = self.name
        head = []
        with open(self.path, "rb") as f:
            for raw in f:
                line = raw.decode("utf-8", "backslashreplace").rstrip("\r\n")
                line = line if head else line.removeprefix("\ufeff")  # a byte-order mark
                head.append(line)
                if len(head) >= 1000 or (line.strip() and not line.lstrip().startswith("#")):
                    break
        if not any(h.strip() for h in head):
            raise F.empty(name)
        first = head[0].lstrip()
        if fmt == "euroc" or (fmt == "text" and first.startswith("#timestamp") and "_RS_" in first):
            return self._euroc(head, layout)
        # skip comments and blank lines at the top
        i = 0
        while i < len(head) and (not head[i].strip() or head[i].lstrip().startswith("#")):
            i += 1
        if i >= len(head):
            raise F.empty(name)
        line = head[i]
        self.skip = i  # lines before the first data (or header) line
        # any run of spaces and tabs separates the columns of whitespace-separated text
        self.squeeze = "," not in line
        self.delim = delim = " " if self.squeeze else ","
        fields = _split(line, delim)
        numeric = all(is_number(x) for x in fields)
        # a `# timestamp tx ty tz qx qy qz qw` comment just above the numbers names them
        named = self._comment_header(head[i - 1], len(fields)) if numeric and i and fmt in ("text", "csv") else None
        if fmt == "text":
            if named is not None:
                fmt = "tum" if [n.lower() for n in named] == F.TUM_NAMES else "csv"
            elif numeric and self.squeeze and len(fields) == 8 and self.kind == "quat" and layout is None:
                fmt = "tum"  # the TUM format's own layout, as evo and the TUM tools read it: nothing to say
            elif numeric and self.squeeze and len(fields) == 12 and self.kind == "quat":
                fmt = "kitti"
            else:
                fmt = "csv"
        self.format = fmt
        self.header_line = False  # whether pyarrow skips a header line
        if fmt in ("tum", "kitti"):
            if self.kind != "quat":
                raise DataError(f"{name}: a {fmt} file holds poses, not vectors")
            want = 8 if fmt == "tum" else 12
            if len(fields) != want:
                raise DataError(f"{name}:{i + 1}: expected {want} numbers, got {len(fields)} ({fmt} format)")
            self.names = list(F.TUM_NAMES if fmt == "tum" else F.KITTI_NAMES)
            self.columns = list(self.names)
            if fmt == "tum":
                self.t, self.pos, self.q = "timestamp", ["tx", "ty", "tz"], ["qw", "qx", "qy", "qz"]
                self.layout = "xyzw"
            else:
                self.t, self.pos, self.q = None, ["t0", "t1", "t2"], None
                self.matrix = True
                self.layout = "matrix 3x4 [R | t]"
            self.header = False
            self._ignored(layout, f"{fmt} files are read as {'qx qy qz qw' if fmt == 'tum' else '3x4 pose matrices'}")
            return
        # csv
        if numeric and named is None:
            self.header = False
            n = len(fields)
            self.layout = layout or "wxyz"
            qn = ["q0", "q1", "q2", "q3"]
            order = qn if self.layout == "wxyz" else [qn[3], qn[0], qn[1], qn[2]]
            if self.kind == "quat":
                shapes = {4: (None, None), 5: ("t", None), 7: (None, ["x", "y", "z"]), 8: ("t", ["x", "y", "z"])}
                if n not in shapes:
                    raise DataError(
                        f"{name}:{i + 1}: expected 4 (quaternion), 5 (t, quaternion), 7 (x y z, quaternion) "
                        f"or 8 (t x y z, quaternion) numbers without a header, got {n}"
                    )
                self.t, self.pos = shapes[n]
                self.names = ([self.t] if self.t else []) + (self.pos or []) + qn
                self.q = order
                if layout is None:
                    cols = " ".join(([self.t] if self.t else []) + (self.pos or []) + ["qw", "qx", "qy", "qz"])
                    how = "--layout xyzw" + (" or --format tum" if n == 8 else "")
                    self._assumed(f"{cols} (scalar first)", how)
            else:
                if n not in (3, 4):
                    raise DataError(f"{name}:{i + 1}: expected 3 (x y z) or 4 (t x y z) numbers, got {n}")
                self.t = "t" if n == 4 else None
                self.pos = None
                self.names = ([self.t] if self.t else []) + ["x", "y", "z"]
                self.q = ["x", "y", "z"]
            self.columns = list(self.names)
            return
        self.header = True
        if named is not None:
            self.names = named
        else:
            self.names = [F.unquoted(f) for f in fields]
            self.skip = i + 1
            self.header_line = True
            lineno = i + 1
            seen = set()
            for n in self.names:
                if n in seen:
                    raise DataError(f"{name}:{lineno}: repeated column name {F.shown(n)!r} in the header")
                seen.add(n)
        self.t, self.pos, self.q = _find_roles(self.names, self.kind, name, i + (0 if named else 1))
        self.layout = "named columns"
        self.columns = [c for c in [self.t] + (self.pos or []) + self.q if c]
        self._ignored(layout, "the file names its columns")

    def _rounding(self, sample=200):
        """``(| |q| - 1 |, |R^T R - I|)`` the rounding of this text's printed digits explains
        (at least ``TEXT_ROUNDING``), from the digits of its first rows (the median row's)."""
        cols = [c for c in self.names if c[0] == "r"] if self.matrix else self.q if self.kind == "quat" else []
        idx = [self.names.index(c) for c in cols]
        bounds = []
        for k, (_, line) in enumerate(self._data_lines()):
            if k >= sample:
                break
            fields = _split(line, self.delim)
            if len(fields) == len(self.names) and all(is_number(fields[j]) for j in idx):
                bounds.append(sum(_half_ulp(fields[j]) for j in idx))
        best = float(np.median(bounds)) if bounds else 0.0
        return (max(best, TEXT_ROUNDING), max(2 * best, TEXT_ROUNDING)) if idx else (0.0, 0.0)

    def _comment_header(self, line, n):
        """The column names a comment line gives (``# t qw qx qy qz``), or None when it is
        no header for rows of `n` fields."""
        text = line.lstrip()[1:]
        names = [F.unquoted(x) for x in _split(text, self.delim)]
        if len(names) != n or len(set(names)) != n or any(not x or is_number(x) for x in names):
            return None
        try:
            _find_roles(names, self.kind, self.name, 0)
        except DataError:
            return None
        return names

    def _assumed(self, what, how):
        """Note the column layout taken for a file that does not name its columns."""
        self.notes.append(f"{self.name}: no column names: read as {what}; choose with {how}")

    def _ignored(self, layout, why):
        """Note a ``--layout`` that does not apply to this file."""
        if layout is not None:
            self.notes.append(f"{self.name}: --layout {layout} ignored: {why}")

    def _euroc(self, head, layout):
        name = self.name
        if self.kind == "vector":
            raise DataError(f"{name}: a euroc file holds poses, not vectors")
        line = head[0].lstrip().lstrip("#")
        names = [F.unquoted(F.unquoted(n).split(" [")[0]) for n in line.split(",")]
        rate = self.kind == "rate"  # an IMU file: the gyroscope's w_RS_S_x ... columns
        cols = [F.EUROC_TIME] + (F.EUROC_RATE if rate else F.EUROC_POS + F.EUROC_QUAT)
        missing = [c for c in cols if c not in names]
        if missing:
            what = "EuRoC IMU" if rate else "EuRoC ground truth"
            raise DataError(f"{name}:1: missing column {', '.join(missing)} ({what})")
        self.format, self.delim, self.header, self.skip = "euroc", ",", True, 1
        self.squeeze, self.header_line = False, True
        self.names = names
        self.t, self.pos, self.q = F.EUROC_TIME, list(F.EUROC_POS), list(F.EUROC_QUAT)
        if rate:
            self.pos, self.q = None, list(F.EUROC_RATE)
        self.ns_time = True
        self.layout = "wxyz"
        self.columns = [self.t] + (self.pos or []) + self.q
        if not rate:
            self._ignored(layout, "euroc files are read as q_RS_w q_RS_x q_RS_y q_RS_z")

    @property
    def has_time(self):
        return self.t is not None

    @property
    def has_pos(self):
        return self.pos is not None

    def where(self, row):
        return f"{self.name}:{self._line_of_row(row)}"

    def _data_lines(self):
        """(line number, text) of each data line, as pyarrow counts rows."""
        with open(self.path, "rb") as f:
            for lineno, raw in enumerate(f, 1):
                if lineno <= self.skip:
                    continue
                line = raw.decode("utf-8", "backslashreplace").rstrip("\r\n")
                if lineno == 1:
                    line = line.removeprefix("\ufeff")
                if not (line.strip() if self.squeeze else line) or line.lstrip().startswith("#"):
                    continue  # pyarrow skips comments and empty lines too
                yield lineno, line

    def _line_of_row(self, row):
        for k, (lineno, _) in enumerate(self._data_lines()):
            if k == row:
                return lineno
        return "?"

    # -- reading -----------------------------------------------------------

    def _needed(self):
        cols = [c for c in [self.t] + (self.pos or []) if c]
        cols += self.names if self.matrix else self.q
        return list(dict.fromkeys(cols))

    def _options(self, strings):
        import pyarrow as pa
        import pyarrow.csv as pcsv

        needed = self._needed()
        types = {c: (pa.string() if strings else pa.float64()) for c in needed}
        if self.ns_time and not strings:
            types[self.t] = pa.int64()
        width = max(16, 12 * len(self.names))
        ro = pcsv.ReadOptions(
            skip_rows=int(self.header_line) if self.squeeze else self.skip,  # _Squeezed drops comments
            column_names=self.names, block_size=int(min(max(self.chunk * width, 1 << 16), 1 << 26)),
        )

        def skip(row):
            # `#` comment lines may stand anywhere in TUM-style text files
            if (row.text or "").lstrip().startswith("#"):
                return "skip"
            if self.drop:
                self.skipped += 1
                return "skip"
            return "error"

        po = pcsv.ParseOptions(delimiter=self.delim, invalid_row_handler=skip)
        co = pcsv.ConvertOptions(column_types=types, include_columns=needed, strings_can_be_null=True)
        return ro, po, co

    def __iter__(self):
        import pyarrow as pa
        import pyarrow.csv as pcsv

        ro, po, co = self._options(strings=self.drop)
        handler = weakref.ref(po.invalid_row_handler)
        row0 = 0
        reader = failed = None
        try:
            src = _Squeezed(self.path) if self.squeeze else self.path
            reader = pcsv.open_csv(src, read_options=ro, parse_options=po, convert_options=co)
            for batch in reader:
                if batch.num_rows == 0:
                    continue
                ch = self._chunk(batch, row0)
                row0 += batch.num_rows
                yield ch
        except pa.ArrowInvalid as exc:
            failed = str(exc).splitlines()[0]
        finally:
            if reader is not None:
                reader.close()
            reader = po = None
            _released(handler)
        if failed is not None:
            if self.drop:
                raise DataError(f"{self.name}: {F.shown(failed, 100)}")
            self._scan_for_error(failed)
        if row0 == 0 and not self.skipped:
            raise F.empty(self.name)

    def _col(self, batch, c):
        import pyarrow as pa

        col = batch.column(batch.schema.names.index(c))
        if col.type != pa.string():
            if self.ns_time and c == self.t:
                return _ns_to_s(to_numpy(col))
            return to_numpy(col).astype(np.float64, copy=False)
        if self.ns_time and c == self.t:
            vals = [_int_or_none(s) for s in col.to_pylist()]
            return np.array([np.nan if v is None else _ns_to_s(v) for v in vals], dtype=np.float64)
        import pyarrow.compute as pc  # only here: importing it costs ~30 ms

        try:
            return pc.cast(col, pa.float64()).to_numpy(zero_copy_only=False)
        except pa.ArrowInvalid:
            return np.array([_float_or_nan(s) for s in col.to_pylist()], dtype=np.float64)

    def _chunk(self, batch, row0):
        get = lambda c: self._col(batch, c)  # noqa: E731
        t = get(self.t) if self.t else None
        if self.ns_time and self.kind == "rate":  # integrate takes its steps in exact ns
            return Chunk(np.column_stack([get(c) for c in self.q]), t, None, row0, ns=self._ns(batch))
        if self.matrix:
            m = np.column_stack([get(c) for c in self.names]).reshape(-1, 3, 4)
            pos = np.ascontiguousarray(m[:, :, 3])
            q = matrix_rows(np.ascontiguousarray(m[:, :, :3]), self, row0, bad_ok=self.drop)
            return Chunk(q, t, pos, row0)
        pos = np.column_stack([get(c) for c in self.pos]) if self.pos else None
        data = np.column_stack([get(c) for c in self.q])
        return Chunk(data, t, pos, row0)

    def _ns(self, batch):
        """The integer nanoseconds of the time column (a null or bad field: 0, its row is
        dropped or named by its nan seconds)."""
        col = batch.column(batch.schema.names.index(self.t))
        vals = col.to_numpy(zero_copy_only=False)
        if vals.dtype.kind not in "iu":
            vals = np.array([_int_or_none(s) or 0 for s in col.to_pylist()], dtype=np.int64)
        return vals.astype(np.int64, copy=False)

    def _scan_for_error(self, exc):
        """pyarrow refused the file (its message `exc`): find and name the first bad line."""
        idx = {c: k for k, c in enumerate(self.names)}
        needed = self._needed()
        n = len(self.names)
        what = "numbers" if not self.header else "fields"
        for lineno, line in self._data_lines():
            fields = _split(line, self.delim)
            if len(fields) != n:
                raise DataError(f"{self.name}:{lineno}: expected {n} {what}, got {len(fields)}")
            for c in needed:
                s = fields[idx[c]].strip()
                if s == "":
                    raise DataError(f"{self.name}:{lineno}: empty field in column {c}")
                ok = _int_or_none(s) is not None if (self.ns_time and c == self.t) else is_number(s)
                if not ok:
                    kind = "an integer" if self.ns_time and c == self.t else "a number"
                    raise DataError(f"{self.name}:{lineno}: not {kind}: '{F.shown(s)}' in column {c}")
        raise DataError(f"{self.name}: {F.shown(exc, 100)}")


class _Squeezed:
    """A whitespace-separated text file as pyarrow's reader should see it: every run of
    spaces and tabs one space, none at the ends of a line, comment and blank lines
    and a byte-order mark gone (as numpy's ``loadtxt`` reads such files).

    A file-like object with ``read``; whole lines are transformed, block by block.
    """

    _ENDS = re.compile(rb"^[ \t]+|[ \t]+(?=\r?$)", re.M)  # spaces at the ends of a line
    _RUNS = re.compile(rb"[ \t]{2,}|\t")

    def __init__(self, path, block=1 << 20):
        self.f = open(path, "rb")
        self.block = block
        self.rest = b""  # an incomplete last line, waiting for its end
        self.out = b""  # transformed text not handed out yet
        self.first = True
        self.closed = False

    def _squeeze(self, text):
        if self.first:
            text, self.first = text.removeprefix(b"\xef\xbb\xbf"), False
        if self._clean(text):
            return text
        if text[:1] in b" \t" or b"\n " in text or b"\n\t" in text or b" \n" in text or b"\t\n" in text \
                or b" \r" in text or b"\t\r" in text:
            text = self._ENDS.sub(b"", text)
        if b"#" in text or b"\n\n" in text or b"\n\r\n" in text or text[:1] in b"\r\n":
            kept = [ln for ln in text.split(b"\n")[:-1] if ln.strip() and not ln.startswith(b"#")]
            text = b"\n".join(kept) + b"\n" if kept else b""
        if b"  " in text or b"\t" in text:
            text = self._RUNS.sub(b" ", text)
        return text

    @staticmethod
    def _clean(text):
        """Whether `text` (whole lines) needs no change: the common case, told in one pass of numpy
        over its bytes (the substring tests below take about ten times as long)."""
        if text[:1] in b" \t\r\n" or b"\t" in text or b"#" in text or b"\r" in text:  # single bytes: fast
            return False
        b = np.frombuffer(text, np.uint8)
        sp, nl = b == 32, b == 10
        after = sp[:-1] | nl[:-1]  # a space or a line end before: "  ", "\n ", " \n", "\n\n"
        return not ((sp[1:] & after).any() or (nl[1:] & after).any())

    def read(self, n=-1):
        while len(self.out) < max(n, 1) and self.f is not None:
            data = self.f.read(max(n, self.block))
            text = self.rest + data
            if not data:  # end of file: the last line, ended
                self.rest = b""
                self.f.close()
                self.f = None
                if text:
                    self.out += self._squeeze(text + b"\n")
                break
            cut = text.rfind(b"\n") + 1
            self.rest = text[cut:]
            if cut:
                self.out += self._squeeze(text[:cut])
        if n is None or n < 0:
            n = len(self.out)
        out, self.out = self.out[:n], self.out[n:]
        return out

    def close(self):
        if self.f is not None:
            self.f.close()
            self.f = None
        self.closed = True


def to_numpy(col):
    """A numeric arrow array as numpy: without nulls, a read-only view of its data
    buffer (pyarrow's own ``to_numpy`` imports pandas where it is installed, about
    0.5 s of a command's start-up); otherwise pyarrow's conversion."""
    dtype = _NUMPY.get(str(col.type))
    if dtype is None or col.null_count:
        return col.to_numpy(zero_copy_only=False)
    return np.frombuffer(col.buffers()[1], dtype, count=len(col), offset=col.offset * dtype.itemsize)


_NUMPY = {"double": np.dtype(np.float64), "float": np.dtype(np.float32), "int64": np.dtype(np.int64)}


def _released(ref, timeout=2.0):
    """Wait until pyarrow's I/O threads have dropped the Python row handler `ref` points to.

    After a failed read, pyarrow's read-ahead thread may hold the last
    reference to the reader and free it (taking the GIL to release our
    handler) a moment later; if the interpreter is exiting by then, that
    thread is killed inside C++ and the process aborts ("terminate called
    without an active exception"). Waiting here (a few ms at most) makes the
    release happen while Python is alive.
    """
    import time

    end = time.monotonic() + timeout
    while ref() is not None and time.monotonic() < end:
        time.sleep(0.001)


def _ns_to_s(ns):
    """Integer nanoseconds → float seconds, rounded once (full float64 precision)."""
    if isinstance(ns, (int, np.integer)):
        return (ns // 1_000_000_000) + (ns % 1_000_000_000) * 1e-9
    ns = np.asarray(ns)
    if ns.dtype.kind == "f":  # nulls came through as float
        return ns * 1e-9
    return (ns // 1_000_000_000).astype(np.float64) + (ns % 1_000_000_000) * 1e-9


def _int_or_none(s):
    try:
        return int(s)
    except (TypeError, ValueError):
        return None


def _float_or_nan(s):
    try:
        return float(s)
    except (TypeError, ValueError):
        return np.nan


# --------------------------------------------------------------------------
# parquet


class ParquetReader(Reader):
    """Parquet with columns named as for csv, read in record batches."""

    format = "parquet"

    def __init__(self, path, name, kind, chunk):
        import pyarrow.parquet as pq

        self.path, self.name, self.kind, self.chunk = path, name, kind, chunk
        try:
            self.file = pq.ParquetFile(path)
        except Exception as exc:  # pyarrow raises several types for a bad file
            if os.path.getsize(path) == 0:
                raise F.empty(name) from None
            raise DataError(f"{name}: not a readable parquet file ({F.shown(str(exc).splitlines()[0], 100)})") from None
        names = self.file.schema_arrow.names
        self.t, self.pos, self.q = _find_roles(names, kind, name, "header")
        self.columns = [c for c in [self.t] + (self.pos or []) + self.q if c]
        self.layout = "named columns"
        self.rows = self.file.metadata.num_rows
        if self.rows == 0:
            raise F.empty(name)

    has_time = property(lambda self: self.t is not None)
    has_pos = property(lambda self: self.pos is not None)

    def __iter__(self):
        row0 = 0
        for batch in self.file.iter_batches(batch_size=self.chunk, columns=self.columns):
            get = lambda c: to_numpy(batch.column(batch.schema.names.index(c)))  # noqa: E731
            try:
                t = get(self.t).astype(np.float64) if self.t else None
                pos = np.column_stack([get(c) for c in self.pos]).astype(np.float64) if self.pos else None
                data = np.column_stack([get(c) for c in self.q]).astype(np.float64)
            except (TypeError, ValueError) as exc:
                raise DataError(f"{self.name}: a column is not numeric ({F.shown(exc, 100)})") from None
            yield Chunk(data, t, pos, row0)
            row0 += batch.num_rows
