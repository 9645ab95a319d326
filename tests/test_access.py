"""quatarray._access: the row loads and stores, builtins of the kernels that use them."""

import os

import numba
import numpy as np
import pytest
from numba.core.errors import TypingError

from compile_events import compiles
from quatarray import _access
from quatarray._access import (load1, load3, load4, load33, loads, loads_at, store1, store3, store33, store4,
                               prefetch, stores, stores_at, stream4, stream_end, streams)

JIT = os.environ.get("NUMBA_DISABLE_JIT", "0") in ("", "0")


@numba.njit
def _copy_rows(q, v, s, m, q_out, v_out, s_out, m_out):
    for i in range(s.shape[0]):
        store4(q_out, i, load4(q, i))
        store3(v_out, i, load3(v, i))
        store1(s_out, i, load1(s, i) * 2)  # an integer product: cast to the output's float type
        store33(m_out, i, load33(m, i))


@numba.njit
def _stream_rows(q, out):
    for i in range(q.shape[0]):
        stream4(out, i, load4(q, i))
    stream_end()


@numba.njit
def _table_rows(seg, out):
    for n in range(seg.shape[0]):
        row = loads(seg, 7 * n, 7)
        stores(out, 7 * n, (row[6], row[5], row[4], row[3], row[2], row[1], row[0]))


@numba.njit
def _plane_columns(planes, out, step):
    """Column k of 5 planes `step` apart, reversed, into the same column of `out`."""
    for k in range(step):
        col = loads_at(planes, k, step, 5)
        stores_at(out, k, step, (col[4], col[3], col[2], col[1], col[0] * 2))


def _layouts(a):
    """`a` as C-contiguous, Fortran-ordered, strided, reversed and broadcast arrays
    (each with the same rows), and read-only."""
    strided = np.repeat(a, 2, axis=0)[::2]
    ro = a.copy()
    ro.flags.writeable = False
    return {"C": a, "F": np.asfortranarray(a), "strided": strided, "reversed": a[::-1].copy()[::-1],
            "broadcast": np.broadcast_to(a[:1], a.shape), "read-only": ro}


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("layout", ["C", "F", "strided", "reversed", "broadcast", "read-only"])
def test_rows_load_and_store_in_every_layout(dtype, layout):
    rng = np.random.default_rng(3)
    n = 37
    q, v, m = (rng.normal(size=shape).astype(dtype) for shape in ((n, 4), (n, 3), (n, 3, 3)))
    s = rng.integers(-5, 5, n)  # an integer scalar column: loaded as int, stored as float
    q, v, m = (_layouts(a)[layout] for a in (q, v, m))
    outs = [np.full((n, 4), np.nan, dtype), np.full((n, 3), np.nan, dtype), np.full(n, np.nan, dtype),
            np.full((n, 3, 3), np.nan, dtype)]
    for out_layout in ("C", "F", "strided"):
        o = [_layouts(a)[out_layout] for a in outs]
        _copy_rows(q, v, s, m, *o)
        np.testing.assert_array_equal(o[0], q)
        np.testing.assert_array_equal(o[1], v)
        np.testing.assert_array_equal(o[2], 2 * s)
        np.testing.assert_array_equal(o[3], m)
    # flat (4n,) quaternion buffers, as the interpolation loops pass them
    flat = np.empty(4 * n, dtype)
    _copy_rows(np.ascontiguousarray(q).reshape(-1), v, s, m, flat, *outs[1:])
    np.testing.assert_array_equal(flat.reshape(n, 4), q)


def test_table_rows_load_and_store():
    seg = np.arange(5 * 7, dtype=np.float64).reshape(5, 7)
    out = np.empty_like(seg)
    _table_rows(seg, out)
    np.testing.assert_array_equal(out, seg[:, ::-1])


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_plane_columns_load_and_store(dtype):
    """loads_at / stores_at: one lane's column of planes laid side by side (a tile)."""
    planes = np.arange(5 * 6, dtype=dtype)
    out = np.full(5 * 6, np.nan, dtype)
    _plane_columns(planes, out, 6)
    want = planes.reshape(5, 6)[::-1].copy()
    want[4] *= 2
    np.testing.assert_array_equal(out.reshape(5, 6), want)


@pytest.mark.skipif(not JIT, reason="typing and compiling need the JIT")
def test_a_store_into_a_read_only_array_does_not_type():
    ro = np.zeros((3, 4))
    ro.flags.writeable = False
    with pytest.raises(TypingError):
        _copy_rows(np.zeros((3, 4)), np.zeros((3, 3)), np.zeros(3), np.zeros((3, 3, 3)), ro,
                   np.zeros((3, 3)), np.zeros(3), np.zeros((3, 3, 3)))
    with pytest.raises(TypingError):
        _table_rows(np.zeros((2, 7)), ro)


@pytest.mark.skipif(not JIT, reason="typing and compiling need the JIT")
def test_the_accessors_compile_nothing_of_their_own():
    """They are typed and lowered in the kernel that calls them: compiling a new
    kernel that uses them compiles that kernel and nothing else (as overloads,
    each was a compile of its own per array type)."""

    @numba.njit
    def kernel(q, v, s, seg, out4, out3, out1, out_seg):
        for i in range(s.shape[0]):
            store4(out4, i, load4(q, i))
            store3(out3, i, load3(v, i))
            store1(out1, i, load1(s, i))
        stores(out_seg, 0, loads(seg, 0, 5))
        stores_at(out_seg, 0, 2, loads_at(seg, 1, 2, 2))

    args = (np.zeros((4, 4), np.float32), np.zeros((4, 3), np.float32), np.zeros(4, np.float32), np.zeros(5),
            np.empty((4, 4), np.float32), np.empty((4, 3), np.float32), np.empty(4, np.float32), np.empty(5))
    with compiles() as compiled:
        kernel(*args)
    assert compiled == ["kernel"]


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_streamed_rows_are_the_stored_ones(dtype):
    """stream4 writes what store4 does: into flat and (n, 4) C-contiguous outputs (the
    non-temporal vector stores) and, as store4, into the other layouts and into rows
    that are not 16-byte aligned (where the vector stores would fault)."""
    q = np.random.default_rng(4).normal(size=(41, 4)).astype(dtype)
    for out in (np.full((41, 4), np.nan, dtype), np.full(4 * 41, np.nan, dtype)):
        assert out.ctypes.data % 16 == 0
        _stream_rows(q, out)
        np.testing.assert_array_equal(out.reshape(41, 4), q)
    for layout in ("F", "strided"):
        out = _layouts(np.full((41, 4), np.nan, dtype))[layout]
        _stream_rows(q, out)
        np.testing.assert_array_equal(out, q)
    # a C-contiguous buffer a few bytes off 16-byte alignment: stored as store4 does
    raw = np.zeros(q.nbytes + 16, np.uint8)
    for shift in (4, 8, 12):
        off = (-raw.ctypes.data) % 16 + shift
        out = raw[off:off + q.nbytes].view(dtype).reshape(q.shape)
        _stream_rows(q, out)
        np.testing.assert_array_equal(out, q)


def test_which_outputs_stream(monkeypatch):
    """Only large, C-contiguous float outputs aligned to 16 bytes are streamed."""
    monkeypatch.setattr(_access, "STREAM_MIN_BYTES", 1024)
    assert streams(np.empty((64, 4)))
    assert streams(np.empty((64, 4), np.float32))
    assert not streams(np.empty((31, 4)))  # 992 bytes: left in the cache
    assert not streams(np.empty((64, 8))[:, ::2])  # strided
    assert not streams(np.empty((64, 4), np.int64))
    raw = np.empty(8 * 4 * 64 + 16, np.uint8)
    off = (-raw.ctypes.data) % 16 + 8  # an address 8 bytes past a 16-byte boundary
    misaligned = raw[off:off + 8 * 4 * 64].view(np.float64).reshape(64, 4)
    assert misaligned.flags.c_contiguous and not streams(misaligned)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_prefetch_is_a_hint_only(dtype):
    """prefetch changes no result and never faults, also far past the array's end."""

    @numba.njit
    def total(a):
        s = a[0] * 0
        for i in range(a.shape[0]):
            prefetch(a, i + 64)
            prefetch(a, 10**9)
            s += a[i]
        return s

    a = np.arange(100, dtype=dtype)
    assert total(a) == a.sum()
