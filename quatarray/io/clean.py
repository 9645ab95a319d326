"""Checking rows as they stream past: drop or reject bad rows, normalise.

A row is bad when its time or position is not finite, its quaternion has a
non-finite component or is zero, or (where order matters) its time is not
after the previous row's. Slightly non-unit quaternions are the normal case
in real recordings: they are normalised and the largest deviation ``| |q| - 1 |``
is kept for the report. Deviations the input's own rounding explains are not
reported: for text, those its printed digits allow (the reader's
``tolerance``, at least 1e-6); for binary input, the dtype's rounding level.
A quaternion whose norm over- or underflows (1e308 · q) is the rotation q:
its norm is taken after dividing by its largest component.

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
            unit_by = norm  # what the rows are divided by: |q| (of the rescaled rows, below)
            if not good.all():
                data, norm, good = _rescaled(data, norm, good)
                ch = ch.replace(data=data)
                unit_by = norms(data)
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
            with np.errstate(over="ignore", invalid="ignore"):
                dev = np.abs(norm[good] - 1.0)
            rounding = ROUNDING[data.dtype.char]
            if dev.size and (dev > rounding).any():
                count = int(np.count_nonzero(dev > max(rounding, getattr(self.reader, "tolerance", 0.0))))
                if count:
                    self.normalised += count
                    self.max_dev = max(self.max_dev, float(dev.max()))
                with np.errstate(invalid="ignore", divide="ignore"):
                    ch = ch.replace(data=np.asarray(data) / unit_by[:, None])
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
                self._fail(ch.row0 + i, time_order(t[i], prev[i]))
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
        if hasattr(self.reader, "say"):
            self.reader.say(err)
        dropped = self.dropped + getattr(self.reader, "skipped", 0)
        if dropped:
            print(f"{name}: dropped {dropped} invalid row{'s' if dropped != 1 else ''}", file=err)
        if self.normalised:
            print(fixed_note(name, "normalised", self.normalised, "non-unit quaternion", "| |q| - 1 |",
                             self.max_dev), file=err)
        projected = getattr(self.reader, "projected", 0)
        if projected:
            print(fixed_note(name, "projected", projected, "non-orthonormal rotation matrix", "|R^T R - I|",
                             self.reader.max_projection, plural="non-orthonormal rotation matrices"), file=err)


def clean_pair(ca, cb, a, b):
    """Check both chunks of a pair (:func:`quatarray.io.streams.paired`) with their
    Cleaners; in drop mode a row pair goes when either row is bad."""
    a, ga = ca.check(a)
    b, gb = cb.check(b)
    if len(a) == 1 and len(b) > 1:
        ga = np.repeat(ga, len(b))
    if len(b) == 1 and len(a) > 1:
        gb = np.repeat(gb, len(a))
    good = ga & gb
    if good.all():
        return a, b
    keep = np.flatnonzero(good)
    ca.dropped += good.size - keep.size
    a = a if len(a) == 1 else a.take(keep)
    b = b if len(b) == 1 else b.take(keep)
    return a, b


def time_order(t, prev, strict=True):
    """What is wrong with time `t` after `prev`: ``repeated time 2.0 (previous 2.0);
    times must increase`` (``must not decrease`` when not `strict`)."""
    what = "repeated" if t == prev else "decreasing"
    return f"{what} time {float(t)!r} (previous {float(prev)!r}); times must {'increase' if strict else 'not decrease'}"


def fixed_note(name, verb, count, noun, measure, largest, plural=None):
    """The one-line report of rows fixed on the way, e.g. ``walk.csv: normalised 3
    non-unit quaternions (largest | |q| - 1 | = 0.002)``."""
    noun = noun if count == 1 else plural or noun + "s"
    size = f"{largest:.3g}" if np.isfinite(largest) else f"> {np.finfo(np.float64).max:.3g}"
    return f"{name}: {verb} {count} {noun} (largest {measure} = {size})"


def _rescaled(data, norm, good):
    """``(data, norm, good)`` with the finite, non-zero rows whose norm over- or
    underflowed divided by their largest component (the same rotation), their norms
    taken from that."""
    fin = np.isfinite(data).all(axis=1)
    scale = np.abs(np.where(fin[:, None], data, 0)).max(axis=1)
    fix = ~good & fin & (scale > 0)
    if not fix.any():
        return data, norm, good
    data, norm = np.array(data), np.array(norm)  # copies: a chunk may be a read-only map
    data[fix] /= scale[fix, None]
    with np.errstate(over="ignore"):
        norm[fix] = norms(data[fix]) * scale[fix]
    return data, norm, good | fix


# deviations below rounding level are not worth a report (nor a normalisation); text
# input is not reported below its printed digits' rounding, and never below TEXT_ROUNDING
# (float32 sources printed with many digits)
ROUNDING = {"f": 1e-6, "d": 1e-12}
TEXT_ROUNDING = 1e-6


def norms(q):
    """|q| of each row of an ``(n, 4)`` array, in q's float type: the plain sum of
    squares, without loading a kernel (over- or underflowing rows: :func:`_rescaled`)."""
    q = np.asarray(q)
    if q.dtype not in (np.float32, np.float64):
        q = q.astype(np.float64)
    q0, q1, q2, q3 = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    with np.errstate(over="ignore", under="ignore"):  # inf or 0: such rows are rescaled
        return np.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)


def dots(p, q):
    """The 4-D inner product of the rows of two ``(n, 4)`` arrays (as :func:`quatarray.dot`)."""
    return p[:, 0] * q[:, 0] + p[:, 1] * q[:, 1] + p[:, 2] * q[:, 2] + p[:, 3] * q[:, 3]


def _fmt(row):
    return ", ".join(repr(float(v)) for v in np.ravel(row))
