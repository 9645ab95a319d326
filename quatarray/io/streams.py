"""A chunk of a stream: optional times, optional positions, and the rows."""

from dataclasses import dataclass, replace

import numpy as np


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
