"""A chunk of a stream (optional times, optional positions, and the rows), the
:class:`Reader` base every stream reader extends, and what turns chunk iterators
into others: joined, re-cut, timed, paired."""

from dataclasses import dataclass, replace

import numpy as np

from .errors import DataError


@dataclass
class Chunk:
    """Consecutive rows of a stream.

    Attributes
    ----------
    data : ndarray, shape (n, 4) or (n, 3)
        Quaternions in (w, x, y, z) order, or vectors.
    t : ndarray, shape (n,), or None
        Times in seconds.
    pos : ndarray, shape (n, 3), or None
        Positions.
    row0 : int
        Index of the first row in the file's data rows (for error messages).
    ns : ndarray of int64, shape (n,), or None
        The times as the file's integer nanoseconds (EuRoC IMU rates only), exact.
    """

    data: np.ndarray
    t: np.ndarray = None
    pos: np.ndarray = None
    row0: int = 0
    ns: np.ndarray = None

    def __len__(self):
        return self.data.shape[0]

    def take(self, idx):
        return Chunk(
            self.data[idx],
            None if self.t is None else self.t[idx],
            None if self.pos is None else self.pos[idx],
            self.row0,
            None if self.ns is None else self.ns[idx],
        )

    def slice(self, a, b):
        return Chunk(
            self.data[a:b],
            None if self.t is None else self.t[a:b],
            None if self.pos is None else self.pos[a:b],
            self.row0 + a,
            None if self.ns is None else self.ns[a:b],
        )

    def replace(self, **kw):
        return replace(self, **kw)


class Reader:
    """What every stream reader is: an iterable of :class:`Chunk` objects and the
    attributes that describe its stream (see :mod:`quatarray.io.readers`)."""

    kind = "quat"
    layout = "wxyz"
    has_time = False
    has_pos = False
    rows = None
    skipped = 0
    format = ""
    columns = ()
    projected = 0  # rotation matrices that were not orthonormal (above rounding level)
    max_projection = 0.0  # the largest |R^T R - I| entry among them

    @property
    def notes(self):
        """One-line remarks for stderr: the layout assumed for a file without column
        names, an option that does not apply, a frame count that does not match."""
        return self.__dict__.setdefault("_notes", [])

    def say(self, err):
        """Write the notes not written yet to `err`."""
        said = self.__dict__.get("_said", 0)
        for note in self.notes[said:]:
            print(note, file=err)
        self._said = len(self.notes)

    @property
    def noun(self):
        return {"quat": "quaternion", "rate": "angular velocity"}.get(self.kind, "vector")

    def where(self, row):
        return f"{self.name}: row {row}"


def concat(chunks):
    """One chunk holding the rows of ``chunks`` (all with the same columns)."""
    first = chunks[0]
    if len(chunks) == 1:
        return first
    return Chunk(
        np.concatenate([c.data for c in chunks]),
        None if first.t is None else np.concatenate([c.t for c in chunks]),
        None if first.pos is None else np.concatenate([c.pos for c in chunks]),
        first.row0,
        None if first.ns is None else np.concatenate([c.ns for c in chunks]),
    )


def rechunk(chunks, size):
    """Re-cut a chunk iterator into pieces of exactly ``size`` rows (the last may be shorter)."""
    buf, have = [], 0
    for ch in chunks:
        if len(ch) == 0:
            continue
        buf.append(ch)
        have += len(ch)
        while have >= size:
            whole = concat(buf)
            yield whole.slice(0, size)
            rest = whole.slice(size, len(whole))
            buf, have = ([rest] if len(rest) else []), len(rest)
    if have:
        yield concat(buf)


def timed_chunks(reader, in_rate, in_times=None):
    """The reader's chunks, with times when the file has none: ``row / in_rate``, or row
    i's time from `in_times` (a :class:`quatarray.jobs.FileTimes` of ``--in-times``, as
    many times as the stream has rows). A dropped row keeps its time out, as the rows
    after it keep theirs."""
    if reader.has_time:
        yield from reader
        return
    rows = 0
    chunks = iter(reader)
    for ch in chunks:
        k = ch.row0 + np.arange(len(ch))
        if in_times is None:
            yield ch.replace(t=k / in_rate)
        elif len(ch) and k[-1] >= in_times.times.size:
            rows = ch.row0 + len(ch) + sum(len(c) for c in chunks)
            break
        else:
            yield ch.replace(t=in_times.times[k])
        rows = ch.row0 + len(ch)
    if in_times is not None and rows + reader.skipped != in_times.times.size:
        raise DataError(f"{in_times.name} has {in_times.times.size} times but {reader.name} has "
                        f"{rows + reader.skipped} rows; they must match")


def paired(ra, rb, chunk):
    """Chunks of two streams in step; a one-row stream is broadcast against the other."""
    ia, ib = iter(rechunk(ra, chunk)), iter(rechunk(rb, chunk))
    a0, a1 = next(ia, None), None
    b0, b1 = next(ib, None), None
    if a0 is not None and len(a0) == 1:
        a1 = next(ia, None)
    if b0 is not None and len(b0) == 1:
        b1 = next(ib, None)
    if a0 is None or b0 is None:
        return
    a_one = len(a0) == 1 and a1 is None
    b_one = len(b0) == 1 and b1 is None

    def rest(first, second, it):
        yield first
        if second is not None:
            yield second
        yield from it

    if a_one and not b_one:
        for b in rest(b0, b1, ib):
            yield a0, b, len(b)
        return
    if b_one and not a_one:
        for a in rest(a0, a1, ia):
            yield a, b0, len(a)
        return
    ga, gb = rest(a0, a1, ia), rest(b0, b1, ib)
    na = nb = 0
    while True:
        a, b = next(ga, None), next(gb, None)
        if a is None or b is None:
            if a is not None or b is not None:
                na += len(a) if a is not None else 0
                nb += len(b) if b is not None else 0
                na += sum(len(x) for x in ga)
                nb += sum(len(x) for x in gb)
                raise DataError(f"{ra.name} has {na} rows but {rb.name} has {nb}; they must match (or one has 1 row)")
            return
        if len(a) != len(b):
            na, nb = na + len(a), nb + len(b)
            na += sum(len(x) for x in ga)
            nb += sum(len(x) for x in gb)
            raise DataError(f"{ra.name} has {na} rows but {rb.name} has {nb}; they must match (or one has 1 row)")
        na += len(a)
        nb += len(b)
        yield a, b, len(a)


def pair_rows(a, b):
    """The rows of a pair of chunks from :func:`paired` (a one-row chunk broadcasts)."""
    return max(len(a), len(b)) if min(len(a), len(b)) else 0
