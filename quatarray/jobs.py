"""What a convert or resample job is, for the command line and the Dask file jobs alike.

:mod:`quatarray.app.cli` (one process, chunk by chunk) and
:mod:`quatarray.dask.files` (``--scheduler``, block by block on workers)
run the same jobs; what those are is written once, here:

- the ``--to`` targets of ``convert`` (:func:`target`), the note on rows at
  gimbal lock (:func:`gimbal_note`) and the rows per kernel call
  (:data:`ROWS_PER_PIECE`);
- the new times of ``resample`` (:class:`RateTimes` for ``--rate``,
  :class:`FileTimes` for ``--times`` and ``--in-times``; :func:`new_times`
  picks one) and the checks on an input's own times (:func:`check_key_times`);
- the in-process drivers of both jobs (:func:`convert_stream`,
  :func:`resample_stream`).

Errors are those of :mod:`quatarray.io.errors`: a :class:`~quatarray.io.UsageError`
(a request that cannot be carried out: a bad option value) or a
:class:`~quatarray.io.DataError` (bad data). They stay defined there, in the
lowest layer, because the readers and writers raise them too; the command line
maps them to its exit statuses.
"""

import numpy as np

from .io.errors import DataError, UsageError
from .io.formats import plain_number
from .io.readers import read_times
from .io.streams import concat, timed_chunks

METHODS = ("bezier", "slerp", "nlerp", "squad", "cubic")
# methods whose curve is one system over all keys: resample_stream holds every key
GLOBAL_METHODS = ("cubic",)
TARGETS = ("quat, xyzw, matrix, rotvec, axis-angle, euler:SEQ (e.g. euler:ZXY intrinsic, euler:zxy extrinsic), "
           "positions (world joint positions of a BVH clip: npy (F, J, 3), csv/parquet t joint x y z)")
QUAT_FIELDS = ["qw", "qx", "qy", "qz"]
# Rows per kernel call in convert (in process and in every Dask task) and per
# checked piece of a task's keys: small enough that a piece is checked,
# converted and copied out while it is in cache, and that the kernel takes its
# serial variant (see :func:`convert_stream`). Not the spline's ``PIECE``
# (new times per evaluation piece).
ROWS_PER_PIECE = 1 << 16

__all__ = [
    "METHODS", "TARGETS", "QUAT_FIELDS", "ROWS_PER_PIECE", "euler_seq", "target", "gimbal_note",
    "convert_stream", "RateTimes", "FileTimes", "new_times", "check_key_times", "resample_stream",
    "library_error", "no_rows",
]


def library_error(name, exc):
    """A library ValueError on file data → a one-line DataError naming the file."""
    return DataError(f"{name}: {str(exc).splitlines()[0]}")


def no_rows(name):
    return DataError(f"{name}: no valid rows left")


# --------------------------------------------------------------------------
# convert


def euler_seq(seq, option, example):
    """`seq` if it is an Euler sequence, else a UsageError naming `option`."""
    if not (len(seq) == 3 and (set(seq) <= set("xyz") or set(seq) <= set("XYZ"))
            and seq[0] != seq[1] and seq[1] != seq[2]):
        raise UsageError(
            f"{option}: SEQ is three axes from xyz (extrinsic) or XYZ (intrinsic), "
            f"no axis twice in a row, e.g. {example}"
        )
    return seq


def target(to, degrees):
    """(fields, npy core shape, function) for ``--to``; the function maps (n, 4) unit
    quaternions to the target and takes an optional ``out=`` array of its result shape.

    Examples
    --------
    >>> import numpy as np
    >>> fields, core, fn = target("rotvec", degrees=True)
    >>> fields, core
    (['rx', 'ry', 'rz'], (3,))
    >>> fn(np.array([[0.0, 0, 0, 1]])).round(9)
    array([[  0.,   0., 180.]])
    """
    angles = to in ("rotvec", "axis-angle") or to.startswith("euler:")
    if degrees and not angles:
        raise UsageError(f"--degrees applies to rotvec, axis-angle and euler outputs, not {to}")
    if to == "quat":
        def quat(q, out=None):
            if out is None:
                return q
            np.copyto(out, q)
            return out

        return QUAT_FIELDS, (4,), quat
    if to == "xyzw":  # a permutation of columns: no kernel to load for it
        return ["qx", "qy", "qz", "qw"], (4,), lambda q, out=None: np.take(q, [1, 2, 3, 0], axis=1, out=out)
    if to == "matrix":
        from .conversions import as_matrix

        return [f"r{i}{j}" for i in range(3) for j in range(3)], (3, 3), as_matrix
    if to == "rotvec":
        from .conversions import as_rotvec

        return ["rx", "ry", "rz"], (3,), lambda q, out=None: as_rotvec(q, degrees=degrees, out=out)
    if to == "axis-angle":
        from .conversions import as_axis_angle

        def axis_angle(q, out=None):
            axis, ang = as_axis_angle(q, degrees=degrees)
            if out is None:
                return np.column_stack([axis, ang])
            out[:, :3], out[:, 3] = axis, ang
            return out

        return ["ax", "ay", "az", "angle"], (4,), axis_angle
    if to.startswith("euler:"):
        seq = euler_seq(to[6:], f"--to {to}", "euler:ZXY")

        from .euler import euler_locked

        def euler(q, out=None):
            e, locked = euler_locked(q, seq, degrees)
            euler.locked += locked  # rows at gimbal lock, for the note (no warnings: threads)
            if out is None:
                return e
            out[...] = e
            return out

        euler.locked = 0
        return [f"e{k + 1}_{a}" for k, a in enumerate(seq)], (3,), euler
    raise UsageError(f"--to {to}: expected one of {TARGETS}")


def gimbal_note(name, locked, err):
    """The note for rows converted to Euler angles at gimbal lock (scipy's rule applied)."""
    if locked:
        print(f"{name}: gimbal lock in {locked} row{'s' if locked != 1 else ''}: the third angle "
              "was set to 0 there (as scipy does)", file=err)


def convert_stream(reader, clean, fn, w, bar):
    """Convert `reader`'s chunks, checked by `clean`, with `fn` (of :func:`target`) into
    the writer `w`; `bar` counts the rows read."""
    for ch in reader:
        n = len(ch)
        ch = clean(ch)
        # An .npy OUT lends reused, already-faulted arrays for the kernel's output
        # and copies them into the file in a background thread. Pieces of
        # ROWS_PER_PIECE rows keep those arrays small and the kernel on its
        # serial variant, leaving a core to the writer's thread.
        for a in range(0, len(ch), ROWS_PER_PIECE):
            part = ch.slice(a, a + ROWS_PER_PIECE)
            w.write(fn(part.data, out=w.buffer(len(part), part.data.dtype)), part.t, part.pos)
        bar.update(n)
    if w.rows == 0:
        raise no_rows(reader.name)


# --------------------------------------------------------------------------
# resample: where the new times come from


class RateTimes:
    """New times t0 + k / rate, handed out interval by interval, in pieces."""

    def __init__(self, rate):
        if not (rate > 0 and np.isfinite(rate)):
            raise UsageError(f"--rate must be a positive number, got {rate}")
        self.rate = float(rate)
        self.t0 = None
        self.k = 0

    def end(self, b, closed):
        """The count of new times up to `b` (the next index not handed out)."""
        t0, r = self.t0, self.rate
        kb = max(self.k, int(np.ceil((b - t0) * r)) - 1)
        inside = (lambda k: t0 + k / r <= b) if closed else (lambda k: t0 + k / r < b)
        while inside(kb):
            kb += 1
        while kb > self.k and not inside(kb - 1):
            kb -= 1
        return kb

    def _check_resolution(self, b):
        """Refuse a step finer than float64 times near `b` can tell apart (they would repeat)."""
        ulp = float(np.spacing(max(abs(self.t0), abs(b))))
        if 1 / self.rate < 2 * ulp:
            raise UsageError(
                f"--rate {self.rate:g}: finer than the time resolution: times near {b:.6g} s are "
                f"{ulp:.3g} s apart in float64, so new times would repeat; use at most {1 / (2 * ulp):.3g} Hz"
            )

    def count(self, b, closed):
        """How many new times up to `b` are still to come."""
        self._check_resolution(b)
        return self.end(b, closed) - self.k

    def pieces(self, b, closed, size):
        """The new times up to `b`, at most `size` at a time."""
        kb = self.end(b, closed)
        while self.k < kb:
            ks = np.arange(self.k, min(self.k + size, kb), dtype=np.float64)
            self.k += ks.size
            yield self.t0 + ks / self.rate

    def finish(self, last):
        pass


class FileTimes:
    """Times from a file: ``--times`` (new times, non-decreasing, inside the key times)
    or ``--in-times`` (the key times of a stream without a time column, increasing)."""

    def __init__(self, path, fmt="auto", order="non-decreasing", times=None):
        self.name = path
        # `times`: what load() gave, read once for all the inputs of a run
        self.times, self.where = self.load(path, fmt, order) if times is None else times
        self.p = 0
        self.t0 = None

    @staticmethod
    def load(path, fmt="auto", order="non-decreasing"):
        """``(times, where)`` of a times file: float64 times, checked finite and in
        `order`, and ``where(i)`` naming time i's line for messages."""
        times, where = read_times(path, fmt if fmt in ("npy", "csv") else "auto", order=order, locate=True)
        times = np.asarray(times, dtype=np.float64)
        if times.size == 0:
            raise DataError(f"{path}: no times")
        return times, where

    def _end(self, b, closed):
        if self.p == 0 and self.times[0] < self.t0:
            raise DataError(f"{self.where(0)}: time {plain_number(self.times[0])} is before the first key time "
                            f"{plain_number(self.t0)}")
        return max(self.p, int(np.searchsorted(self.times, b, side="right" if closed else "left")))

    def count(self, b, closed):
        return self._end(b, closed) - self.p

    def upto(self, b, closed):
        """All the new times up to `b` (a view of the file's times)."""
        j = self._end(b, closed)
        out, self.p = self.times[self.p:j], j
        return out

    def pieces(self, b, closed, size):
        out = self.upto(b, closed)
        for a in range(0, out.size, size):
            yield out[a:a + size]

    def finish(self, last):
        if self.p < self.times.size:
            raise DataError(f"{self.where(self.p)}: time {plain_number(self.times[self.p])} is after the last "
                            f"key time {plain_number(last)}")


def new_times(rate=None, times=None, loaded=None):
    """The new times of a resample job: ``--rate`` (:class:`RateTimes`) or the file
    ``--times`` (:class:`FileTimes`; `loaded`: what :meth:`FileTimes.load` gave for it)."""
    if (rate is None) == (times is None):
        raise UsageError("resample needs exactly one of --rate and --times")
    return RateTimes(rate) if rate is not None else FileTimes(times, times=loaded)


def check_key_times(name, has_time, in_rate=None, in_times=None, err=None, in_times_option=True):
    """Check how an input's key times are known: its time column, else ``--in-rate``
    (row i at i / HZ s) or ``--in-times``.

    A stream without times and without either option is a usage error (naming
    ``--in-times`` too where the job offers it: `in_times_option`); with `err`,
    an option given for a stream that has its own times is said to be ignored.
    """
    keyed = in_rate is not None or in_times is not None
    if not has_time and not keyed:
        alternative = " or its times with --in-times FILE" if in_times_option else ""
        raise UsageError(f"{name}: has no time column; give its sampling rate with --in-rate HZ{alternative}")
    if in_rate is not None and not (in_rate > 0 and np.isfinite(in_rate)):
        raise UsageError(f"--in-rate must be positive, got {in_rate}")
    if has_time and keyed and err is not None:
        opt = "--in-rate" if in_rate is not None else "--in-times"
        print(f"{name}: has a time column; {opt} ignored", file=err)


# --------------------------------------------------------------------------
# resample: the in-process driver


def resample_stream(reader, clean, newt, w, method, chunk, in_rate=None, in_times=None, bar=None, poses="linear"):
    """Resample `reader`'s key chunks (checked by `clean`, ordered) at the new times
    `newt` (:func:`new_times`) into the writer `w`, at most `chunk` new times at a time.

    The key times are the reader's own, else those of `in_rate` or `in_times` (a
    :class:`FileTimes`; see :func:`check_key_times`). `bar` counts the rows read.
    Memory stays bounded by `chunk` whatever the stream's length, except for the
    methods of :data:`GLOBAL_METHODS` (``"cubic"``), whose curve between two keys
    depends on every key: their keys are all held (:func:`_resample_global`).
    Positions, where the reader has them, are interpolated linearly between the two
    keys around each new time (``poses="linear"``, the rotations by `method`), or
    rotation and position together by screw linear interpolation between those keys
    (``poses="screw"``, :func:`quatarray.sclerp`; `method` is not used).
    """
    from .interpolation import unflip
    from .splines import spline

    if method in GLOBAL_METHODS and poses != "screw":  # the screw rule does not use `method`
        return _resample_global(reader, clean, newt, w, method, chunk, in_rate, in_times, bar)

    def emit(keys, lo, hi, closed):
        # The new times of keys[lo:hi] come and are written at most `chunk` at a time, each
        # piece from the keys around it (two of halo each side, as for the intervals below):
        # memory stays bounded whatever the rate.
        w.reserve(newt.count(keys.t[hi], closed))
        for nt in newt.pieces(keys.t[hi], closed, chunk):
            a = max(int(np.searchsorted(keys.t, nt[0], side="right")) - 3, 0)
            b = min(int(np.searchsorted(keys.t, nt[-1], side="left")) + 3, len(keys))
            near = keys.slice(a, b)
            if poses == "screw" and near.pos is not None:
                from .rigid import pose_spline

                try:
                    q, pos = pose_spline(near.t, near.data, near.pos, nt, poses="screw")
                except ValueError as exc:
                    raise library_error(reader.name, exc) from None
                w.write(q, nt, pos)
                continue
            try:
                q = spline(near.t, near.data, nt, method=method)
            except ValueError as exc:
                raise library_error(reader.name, exc) from None
            pos = None
            if near.pos is not None:
                pos = np.column_stack([np.interp(nt, near.t, near.pos[:, k]) for k in range(3)])
            w.write(q, nt, pos)

    buf, lo, last_q = None, 0, None
    step = max(min(chunk, 1 << 16), 8)
    for ch in timed_chunks(reader, in_rate, in_times):
        n = len(ch)
        ch = clean(ch)
        if bar is not None:
            bar.update(n)
        if not len(ch):
            continue
        q = ch.data
        # sign continuity across chunks: unflip continuing from the last key
        q = unflip(q if last_q is None else np.concatenate([last_q[None], q]))
        q = q if last_q is None else q[1:]
        last_q = q[-1]
        ch = ch.replace(data=q)
        if buf is None:
            newt.t0 = float(ch.t[0])
        buf = ch if buf is None else concat([buf, ch])
        # Intervals of `step` keys [lo, lo + step) are interpolated from their keys
        # plus two of halo on each side (the Bézier and squad controls of a key use
        # its neighbours), so each spline call sees at most step + 5 keys.
        while len(buf) - 3 - lo >= step:
            a = max(lo - 2, 0)
            emit(buf.slice(a, lo + step + 3), lo - a, lo + step - a, closed=False)
            lo += step
        if lo > 2:
            buf = buf.slice(lo - 2, len(buf))
            lo = 2
    if buf is None:
        raise no_rows(reader.name)
    if len(buf) < 2:
        raise DataError(f"{reader.name}: resampling needs at least 2 valid rows, got {len(buf)}")
    emit(buf.slice(max(lo - 2, 0), len(buf)), min(lo, 2), len(buf) - 1 - max(lo - 2, 0), closed=True)
    newt.finish(float(buf.t[-1]))


def _resample_global(reader, clean, newt, w, method, chunk, in_rate=None, in_times=None, bar=None):
    """:func:`resample_stream` for a method whose curve is one system over all keys
    (``"cubic"``, scipy's RotationSpline: each key's rate depends on every other
    key): every key is read and held (its time, quaternion and position: 40 to 64
    bytes a key), the system is solved once, and the new times are evaluated and
    written at most `chunk` at a time, as :func:`quatarray.spline` on the whole
    stream gives them."""
    from .splines import cubic_curve, unit_keys

    parts = []
    for ch in timed_chunks(reader, in_rate, in_times):
        n = len(ch)
        ch = clean(ch)
        if bar is not None:
            bar.update(n)
        if len(ch):
            parts.append(ch)
    if not parts:
        raise no_rows(reader.name)
    keys = concat(parts)
    if len(keys) < 2:
        raise DataError(f"{reader.name}: resampling needs at least 2 valid rows, got {len(keys)}")
    t = np.ascontiguousarray(keys.t, dtype=np.float64)
    t0, t1 = float(t[0]), float(t[-1])
    try:
        at = cubic_curve(t, unit_keys([keys.data]))
    except ValueError as exc:  # pragma: no cover - the Cleaner has checked the rows and times
        raise library_error(reader.name, exc) from None
    newt.t0 = t0
    w.reserve(newt.count(t1, True))
    for nt in newt.pieces(t1, True, chunk):
        nt = np.asarray(nt, dtype=np.float64)
        if nt.size and not (nt.min() >= t0 and nt.max() <= t1):  # pragma: no cover - the pieces stay inside
            raise DataError(f"{reader.name}: a new time outside the key times [{t0!r}, {t1!r}]")
        pos = None
        if keys.pos is not None:
            pos = np.column_stack([np.interp(nt, t, keys.pos[:, k]) for k in range(3)])
        w.write(at(nt), nt, pos)
    newt.finish(t1)
