"""Outputs written block by block, in any order, by many tasks: ``.npy`` files and zarr stores.

What the Dask file jobs (:mod:`quatarray.dask.files`) write into. As the
stream writers (:mod:`quatarray.io.writers`), a target is a temporary file
or store beside OUT (:func:`~quatarray.io.writers.temporary_beside`), moved
over OUT when its ``with`` block ends well and removed when it fails; unlike
them, its shape is known from the start, and tasks (threads or worker
processes, which get the target pickled) write their rows at their place.
"""

import contextlib
import os

import numpy as np

from .formats import is_zarr
from .writers import publish, pwrite_all, temporary_beside


class NpyTarget:
    """A temporary ``.npy`` beside `dst` with its header written; renamed over `dst` on success.

    Tasks write their rows with :meth:`write` (a positioned write: no page
    faults on the fresh file, unlike a memory map), in any order and in
    pieces of any size (`piecewise`).
    """

    piecewise = True

    def __init__(self, dst, shape, dtype, chunk):
        self.dst = os.fspath(dst)
        self.tmp = temporary_beside(self.dst)
        with self._or_remove():
            mm = np.lib.format.open_memmap(self.tmp, mode="w+", dtype=dtype, shape=tuple(shape))
            self.offset, self.dtype, self.rowbytes = mm.offset, np.dtype(dtype), mm[:1].nbytes
            del mm

    @contextlib.contextmanager
    def _or_remove(self):
        """Remove the temporary output if what is inside fails."""
        try:
            yield
        except BaseException:
            self._remove(self.tmp)
            raise

    @staticmethod
    def _remove(path):
        import shutil

        if os.path.isdir(path) and not os.path.islink(path):
            shutil.rmtree(path, ignore_errors=True)
        elif os.path.lexists(path):
            os.remove(path)

    def write(self, row0, data):
        """Write `data` as rows ``row0, row0 + 1, …``; returns how many."""
        if len(data) == 0:
            return 0
        data = np.ascontiguousarray(data, dtype=self.dtype)
        fd = os.open(self.tmp, os.O_WRONLY)
        try:
            pwrite_all(fd, data, self.offset + row0 * self.rowbytes)
        finally:
            os.close(fd)
        return len(data)

    def _publish(self):
        publish(self.tmp, self.dst)

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        if kind is not None:
            self._remove(self.tmp)
            return
        with self._or_remove():
            self._publish()


class ZarrTarget(NpyTarget):
    """A temporary zarr store beside `dst`, chunked by `chunk` rows; moved over `dst` on success.

    Every task writes whole zarr chunks (its rows start at a multiple of
    `chunk`), so no two tasks touch the same chunk.
    """

    piecewise = False  # a piece smaller than a zarr chunk rewrites the whole chunk

    def __init__(self, dst, shape, dtype, chunk):
        from .arrays import import_zarr

        zarr = import_zarr(dst)
        self.dst = os.fspath(dst).rstrip("/" + os.sep)
        self.tmp = temporary_beside(self.dst, folder=True)
        shape = tuple(int(n) for n in shape)
        with self._or_remove():
            zarr.create_array(store=self.tmp, shape=shape, dtype=dtype, overwrite=True,
                              chunks=(max(1, min(int(chunk), shape[0])),) + shape[1:])
        self.dtype = np.dtype(dtype)

    def write(self, row0, data):
        import zarr

        if len(data):
            zarr.open_array(self.tmp, mode="r+")[row0 : row0 + len(data)] = np.asarray(data, self.dtype)
        return len(data)

    def _publish(self):
        old = None
        if os.path.lexists(self.dst):  # --force: the old store moved aside first, removed after
            old = self.tmp + ".old"
            os.replace(self.dst, old)
        os.replace(self.tmp, self.dst)
        if old:
            self._remove(old)


def open_target(dst, shape, dtype, chunk):
    """The target for `dst`: a :class:`ZarrTarget` for a ``.zarr`` store, else an :class:`NpyTarget`."""
    return (ZarrTarget if is_zarr(dst) else NpyTarget)(dst, shape, dtype, chunk)
