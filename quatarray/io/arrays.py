"""Stored arrays as streams: ``.npy`` files (memory-mapped, one chunk at a time) and
``.zarr`` stores (block by block, with the optional package zarr), of quaternions,
rotation matrices or vectors."""

import os

import numpy as np

from . import formats as F
from .clean import ROUNDING
from .errors import DataError, UsageError
from .streams import Chunk, Reader


def reorder(q, layout):
    """(n, 4) quaternion columns in file order → (w, x, y, z)."""
    if layout == "xyzw":
        return q[:, [3, 0, 1, 2]]
    return q


def array_layout(name, kind, layout, shape, dtype):
    """``(core, columns, layout)`` of a stored array of rotations or vectors (npy, zarr),
    or a :class:`DataError` saying what is wrong with its dtype or shape."""
    if dtype.kind not in "fiub" or dtype.fields is not None:
        raise DataError(f"{name}: expected an array of real numbers, got dtype {dtype}")
    if kind == "quat":
        if len(shape) == 2 and shape[1] == 4:
            return (4,), ["w", "x", "y", "z"] if layout == "wxyz" else ["x", "y", "z", "w"], layout
        if len(shape) == 3 and shape[1:] == (3, 3):
            return (3, 3), ["matrix 3x3"], "matrix"
        raise DataError(f"{name}: expected quaternions of shape (N, 4) (or rotation matrices (N, 3, 3)), got {shape}")
    if len(shape) == 2 and shape[1] == 3:
        return (3,), ["x", "y", "z"], layout
    raise DataError(f"{name}: expected vectors of shape (N, 3), got {shape}")


def kernel_dtype(dtype):
    """The float type the kernels take for an array of `dtype`: float32 for float16, native
    float32/float64 as they are, float64 for the rest (integers, long double)."""
    if dtype.kind == "f" and dtype.itemsize <= 4:
        return np.dtype(np.float32)
    if dtype.kind == "f" and dtype.itemsize == 8:
        return dtype.newbyteorder("=")
    return np.dtype(np.float64)


class NpyReader(Reader):
    """A ``.npy`` array read one memory-mapped chunk at a time.

    Each chunk maps only its own byte range and the map is released when the
    chunk is dropped, so resident memory stays bounded by a few chunks
    whatever the file size.
    """

    format = "npy"

    def __init__(self, path, name, kind, layout, chunk, on_invalid="error"):
        self.path, self.name, self.kind, self.chunk = path, name, kind, chunk
        self.bad_ok = on_invalid == "drop"  # a matrix that is no rotation becomes a nan row, dropped later
        self.layout = layout or "wxyz"
        try:
            with open(path, "rb") as f:
                version = np.lib.format.read_magic(f)
                read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
                shape, fortran, dtype = read(f)
                self.offset = f.tell()
        except (ValueError, OSError, EOFError) as exc:
            if os.path.getsize(path) == 0:
                raise F.empty(name) from None
            raise DataError(f"{name}: not a valid .npy file ({F.shown(exc, 100)})") from None
        self.dtype, self.shape, self.fortran = dtype, shape, fortran
        self.core, self.columns, self.layout = array_layout(name, kind, self.layout, shape, dtype)
        self.rows = shape[0]
        if self.rows == 0:
            raise F.empty(name)
        size = self.offset + int(np.prod(shape)) * dtype.itemsize
        if os.path.getsize(path) < size:
            raise DataError(f"{name}: truncated file ({os.path.getsize(path)} bytes, the header promises {size})")

    def _block(self, a, b):
        if self.fortran:
            whole = np.load(self.path, mmap_mode="r")
            return np.ascontiguousarray(whole[a:b])
        rowbytes = int(np.prod(self.core)) * self.dtype.itemsize
        return np.memmap(self.path, self.dtype, "r", offset=self.offset + a * rowbytes, shape=(b - a,) + self.core)

    def read(self, a, b, bad_ok=False):
        """Rows ``[a, b)`` as a chunk of (w, x, y, z) quaternions (or vectors),
        with only those rows' pages mapped. Matrices become quaternions; one
        that is not a rotation raises, or becomes a nan row with `bad_ok`."""
        block = self._block(a, b)
        if self.dtype.kind != "f" or not self.dtype.isnative or self.dtype.itemsize not in (4, 8):
            block = block.astype(kernel_dtype(self.dtype))
        if self.core == (3, 3):
            return Chunk(matrix_rows(block, self, a, bad_ok), row0=a)
        if self.kind == "quat":
            return Chunk(reorder(block, self.layout), row0=a)
        return Chunk(block, row0=a)

    def __iter__(self):
        for a in range(0, self.rows, self.chunk):
            yield self.read(a, min(a + self.chunk, self.rows), self.bad_ok)


class ZarrReader(NpyReader):
    """A zarr array (a ``.zarr`` store of shape (N, 4), (N, 3, 3) or (N, 3)) read
    one block of rows at a time; needs the optional package ``zarr``."""

    format = "zarr"

    def __init__(self, path, name, kind, layout, chunk, on_invalid="error"):
        zarr = import_zarr(name)
        try:
            arr = zarr.open_array(path, mode="r")
        except Exception as exc:  # zarr raises several kinds for a folder that is no array
            raise DataError(f"{name}: not a zarr array ({type(exc).__name__}: {F.shown(exc, 100)})") from None
        self.path, self.name, self.kind, self.chunk = path, name, kind, chunk
        self.bad_ok = on_invalid == "drop"
        self.dtype, self.shape, self.fortran = np.dtype(arr.dtype), tuple(arr.shape), False
        self.core, self.columns, self.layout = array_layout(name, kind, layout or "wxyz", self.shape, self.dtype)
        self.rows = self.shape[0]
        if self.rows == 0:
            raise F.empty(name)

    def _block(self, a, b):
        import zarr

        return zarr.open_array(self.path, mode="r")[a:b]


def import_zarr(name):
    """The ``zarr`` module, or a usage error naming the file that needs it."""
    try:
        import zarr
    except ImportError:
        raise UsageError(f"{name}: zarr stores need the package 'zarr': pip install 'quatarray[dask]'") from None
    return zarr


def matrix_rows(m, reader, row0, bad_ok=False):
    """Quaternions of (n, 3, 3) rotation matrices; rows that are not rotations become nan
    (and raise in error mode)."""
    from ..conversions import from_matrix

    m = np.asarray(m, dtype=np.float64) if m.dtype.kind != "f" else m
    det = np.linalg.det(m) if len(m) else np.zeros(0)
    ok = np.isfinite(det) & (det > 0)
    if ok.any():
        with np.errstate(over="ignore", invalid="ignore"):
            dev = np.abs(np.einsum("nji,njk->nik", m[ok], m[ok]) - np.eye(3)).max(axis=(1, 2))
        over = dev > max(ROUNDING[m.dtype.char], getattr(reader, "matrix_tolerance", 0.0))
        if over.any():
            reader.projected += int(np.count_nonzero(over))
            reader.max_projection = max(reader.max_projection, float(dev.max()))
    if ok.all():
        return from_matrix(m)
    i = int(np.argmin(ok))
    if not bad_ok and np.isfinite(m[i]).all():
        raise DataError(f"{reader.where(row0 + i)}: not a rotation matrix (determinant {det[i]:.6g})")
    q = np.full(m.shape[:1] + (4,), np.nan, dtype=m.dtype)
    if ok.any():
        q[ok] = from_matrix(m[ok])
    return q
