"""Checking rows as they stream past: drop or reject bad rows, normalise.

A row is bad when its time or position is not finite, its quaternion has a
non-finite component or is zero, or (where order matters) its time is not
after the previous row's. Slightly non-unit quaternions are the normal case
in real recordings: they are normalised and the largest deviation ``| |q| - 1 |``
is kept for the report.

The checks are plain numpy (:func:`norms`, :func:`dots`), not compiled
kernels: reading and checking a stream then loads no numba (about 0.4 s of
a command's start-up), and these few operations per row run at memory
speed either way.
"""

import numpy as np

from .errors import DataError


class Cleaner:
    """Validate chunks of one stream.

    Parameters
    ----------
    reader : a stream reader (see :mod:`quatarray.io.readers`)
        Used for its name and to turn a row index into ``file:line``.
    on_invalid : {"error", "drop"}
    ordered : bool
        Times must be strictly increasing (``resample``).
    normalize : bool
        Normalise quaternions (vectors are never normalised).

    Examples
    --------
    >>> import os, sys, tempfile, numpy as np
    >>> from quatarray import io
    >>> path = os.path.join(tempfile.mkdtemp(), "q.npy")
    >>> np.save(path, np.array([[2.0, 0, 0, 0], [0, 0, 0, 0], [0, 1, 0, 0]]))
    >>> reader = io.open_stream(path, name="q.npy")
    >>> clean = io.Cleaner(reader, on_invalid="drop")
    >>> [clean(chunk).data for chunk in reader]
    [array([[1., 0., 0., 0.],
           [0., 1., 0., 0.]])]
    >>> clean.report(sys.stdout)
    q.npy: dropped 1 invalid row
    q.npy: normalised 1 non-unit quaternion (largest | |q| - 1 | = 1)
    """

    def __init__(self, reader, on_invalid="error", ordered=False, normalize=True):
        self.reader = reader
        self.drop = on_invalid == "drop"
        self.ordered = ordered
        self.normalize = normalize and reader.kind == "quat"
        self.dropped = 0
        self.normalised = 0
        self.max_dev = 0.0
        self.last_t = None

    def _fail(self, row, what):
        raise DataError(f"{self.reader.where(row)}: {what}")

    def __call__(self, ch):
        """Return the chunk with bad rows dropped (or raise) and quaternions normalised."""
        ch, good = self.check(ch)
        if not good.all():
            keep = np.flatnonzero(good)
            self.dropped += good.size - keep.size
            ch = ch.take(keep)
        return ch

    def check(self, ch):
        """``(chunk with quaternions normalised, mask of good rows)``; raises on a bad
        row unless dropping. Rows are not removed (paired verbs drop row pairs)."""
        n = len(ch)
        if n == 0:
            return ch, np.ones(0, bool)
        data = ch.data
        if self.reader.kind == "quat":
            norm = norms(data)
            good = np.isfinite(norm) & (norm > 0)
        else:
            norm = None
            good = np.isfinite(data).all(axis=1)
        if ch.t is not None:
            good &= np.isfinite(ch.t)
        if ch.pos is not None:
            good &= np.isfinite(ch.pos).all(axis=1)
        if not self.drop and not good.all():
            i = int(np.argmin(good))
            self._fail(ch.row0 + i, self._why(ch, i, norm))
        if self.ordered and ch.t is not None:
            good = self._order(ch, good)
        if self.normalize:
            dev = np.abs(norm[good] - 1.0)
            count = int(np.count_nonzero(dev > _TOL[data.dtype.char])) if dev.size else 0
            if count:
                self.normalised += count
                self.max_dev = max(self.max_dev, float(dev.max()))
                with np.errstate(invalid="ignore", divide="ignore"):
                    ch = ch.replace(data=np.asarray(data) / norm[:, None])
        return ch, good

    def _order(self, ch, good):
        t = ch.t
        if not self.drop:
            prev = np.empty_like(t)
            prev[0] = self.last_t if self.last_t is not None else -np.inf
            prev[1:] = t[:-1]
            bad = ~(t > prev)
            if bad.any():
                i = int(np.argmax(bad))
                what = "repeated" if t[i] == prev[i] else "decreasing"
                self._fail(ch.row0 + i, f"{what} time {float(t[i])!r} (previous {float(prev[i])!r}); times must increase")
            self.last_t = float(t[-1])
            return good
        # drop: a row is kept when its time is after the last kept time; the
        # running maximum of kept times makes this one vectorised pass.
        tt = np.where(good, t, -np.inf)
        start = self.last_t if self.last_t is not None else -np.inf
        runmax = np.maximum.accumulate(np.concatenate(([start], tt)))
        keep = good & (t > runmax[:-1])
        if keep.any():
            self.last_t = float(t[keep][-1])
        return keep

    def _why(self, ch, i, norm):
        if ch.t is not None and not np.isfinite(ch.t[i]):
            return f"time is not a finite number ({float(ch.t[i])!r})"
        if ch.pos is not None and not np.isfinite(ch.pos[i]).all():
            return f"position is not finite ({_fmt(ch.pos[i])})"
        row = ch.data[i]
        if not np.isfinite(row).all():
            return f"{self.reader.noun} is not finite ({_fmt(row)})"
        return f"zero {self.reader.noun} ({_fmt(row)})"

    def report(self, err):
        """Write the drop count and the normalisation note to ``err``."""
        name = self.reader.name
        dropped = self.dropped + getattr(self.reader, "skipped", 0)
        if dropped:
            print(f"{name}: dropped {dropped} invalid row{'s' if dropped != 1 else ''}", file=err)
        if self.normalised:
            print(
                f"{name}: normalised {self.normalised} non-unit quaternion"
                f"{'s' if self.normalised != 1 else ''} (largest | |q| - 1 | = {self.max_dev:.3g})",
                file=err,
            )


# deviations below rounding level are not worth a report (but are still normalised by
# the conversions themselves where it matters)
_TOL = {"f": 1e-6, "d": 1e-12}


def norms(q):
    """|q| of each row of an ``(n, 4)`` array, in q's float type: the sum of squares in
    the order of :func:`quatarray.norm`, so the same bits, without loading a kernel."""
    q = np.asarray(q)
    if q.dtype not in (np.float32, np.float64):
        q = q.astype(np.float64)
    q0, q1, q2, q3 = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)


def dots(p, q):
    """The 4-D inner product of the rows of two ``(n, 4)`` arrays (as :func:`quatarray.dot`)."""
    return p[:, 0] * q[:, 0] + p[:, 1] * q[:, 1] + p[:, 2] * q[:, 2] + p[:, 3] * q[:, 3]


def _fmt(row):
    return ", ".join(repr(float(v)) for v in np.ravel(row))
