"""Row access for the kernels: the one set of loads and stores of a scalar, a
vector, a quaternion and a 3×3 matrix.

=====================  ==============================================================
``load1(a, i)``        element i of a 1-D array; ``store1(out, i, x)``
``load3(a, i)``        row i of an (n, 3) array as a 3-tuple; ``store3(out, i, v)``
``load4(a, i)``        quaternion i as a 4-tuple: row i of an (n, 4) array, or
                       elements 4i … 4i + 3 of a flat (4n,) array; ``store4(out, i, q)``
``load33(a, i)``       matrix i of an (n, 3, 3) array as a row-major 9-tuple;
                       ``store33(out, i, m)``
``load1_ir`` …         ``load1``, ``load4`` and ``store4`` inlined at numba's typed-IR
                       level (below)
=====================  ==============================================================

Compiled, a C-contiguous array is addressed as a flat buffer (``_jit.flat_load``
and ``flat_store``) at a literal stride, without negative-index wraparound, so
LLVM can bound the addresses and vectorise the row loops; other layouts
(strided, broadcast) index ``a[i, j]``. The row length must be exactly the
one named (the front end guarantees it). Without the JIT the plain-Python
bodies run.
"""

import numpy as np

from numba import types
from numba.extending import overload

from ._jit import CACHE, INLINE_OPTIONS, element, flat_load, flat_rows, flat_store


def _flat_vector(a):
    """True (at compile time) for the 1-D C-contiguous arrays of the flat row loops."""
    return isinstance(a, types.Array) and a.ndim == 1 and a.layout == "C"


def _vector(a):
    return isinstance(a, types.Array) and a.ndim == 1


def load1(a, i):
    return a[i]


def store1(out, i, x):
    out[i] = x


def load3(a, i):
    return (a[i, 0], a[i, 1], a[i, 2])


def store3(out, i, v):
    out[i, 0] = v[0]
    out[i, 1] = v[1]
    out[i, 2] = v[2]


def load4(a, i):
    if a.ndim == 1:
        return (a[4 * i], a[4 * i + 1], a[4 * i + 2], a[4 * i + 3])
    return (a[i, 0], a[i, 1], a[i, 2], a[i, 3])


def store4(out, i, q):
    if out.ndim == 1:
        out[4 * i], out[4 * i + 1], out[4 * i + 2], out[4 * i + 3] = q
    else:
        out[i, 0] = q[0]
        out[i, 1] = q[1]
        out[i, 2] = q[2]
        out[i, 3] = q[3]


@element
def load33(a, i):
    """Matrix ``a[i]`` of an ``(n, 3, 3)`` array."""
    return (
        a[i, 0, 0], a[i, 0, 1], a[i, 0, 2],
        a[i, 1, 0], a[i, 1, 1], a[i, 1, 2],
        a[i, 2, 0], a[i, 2, 1], a[i, 2, 2],
    )  # fmt: skip


def store33(out, i, m):
    """``out[i] = m`` for an ``(n, 3, 3)`` array.

    Compiled, a C-contiguous output is written as a flat buffer at the
    literal stride 9 (as ``store4`` does at stride 4), which lets LLVM
    vectorise the row loop: into a freshly allocated output, whose pages the
    system faults in during the loop, about 20 % faster (N = 2·10⁶); into a
    warm ``out=`` the same (memory-bound either way). Other layouts index
    ``out[i, j, k]``.
    """
    out[i, 0, 0], out[i, 0, 1], out[i, 0, 2] = m[0], m[1], m[2]
    out[i, 1, 0], out[i, 1, 1], out[i, 1, 2] = m[3], m[4], m[5]
    out[i, 2, 0], out[i, 2, 1], out[i, 2, 2] = m[6], m[7], m[8]


# ---- scalars: 1-D arrays (LLVM-inlined)


@overload(load1, jit_options=INLINE_OPTIONS)
def _load1(a, i):
    if _flat_vector(a):
        return lambda a, i: flat_load(a, i)
    return lambda a, i: a[i]


@overload(store1, jit_options=INLINE_OPTIONS)
def _store1(out, i, x):
    if _flat_vector(out):
        return lambda out, i, x: flat_store(out, i, x)

    def impl(out, i, x):
        out[i] = x

    return impl


# ---- vectors: (n, 3) rows


@overload(load3, jit_options={"cache": CACHE})
def _load3(a, i):
    if flat_rows(a):
        return lambda a, i: (flat_load(a, 3 * i), flat_load(a, 3 * i + 1), flat_load(a, 3 * i + 2))
    return load3


@overload(store3, jit_options={"cache": CACHE})
def _store3(out, i, v):
    if flat_rows(out):

        def impl(out, i, v):
            flat_store(out, 3 * i, v[0])
            flat_store(out, 3 * i + 1, v[1])
            flat_store(out, 3 * i + 2, v[2])

        return impl
    return store3


# ---- quaternions. Two overloads of each name: flat (4n,) arrays (LLVM-inlined,
# for the interpolation loops) and (n, 4) rows; each answers only its own arrays.


@overload(load4, jit_options=INLINE_OPTIONS)
def _load4_flat(a, i):
    if _flat_vector(a):
        # "+ 0" keeps LLVM from folding a select of two loaded values into a
        # load through a selected pointer, which the vectoriser cannot bound
        ftype = np.dtype(str(a.dtype)).type  # not like(a, ·): a call with an array stops the vectoriser

        def impl(a, i):
            z = ftype(0.0)
            j = 4 * i
            return (flat_load(a, j) + z, flat_load(a, j + 1) + z, flat_load(a, j + 2) + z, flat_load(a, j + 3) + z)

        return impl
    if _vector(a):
        return lambda a, i: (a[4 * i], a[4 * i + 1], a[4 * i + 2], a[4 * i + 3])
    return None


def _store4_buffer(out, i, q):
    """Quaternion i into elements 4i … 4i + 3 of a C-contiguous buffer: both layouts."""
    j = 4 * i
    flat_store(out, j, q[0])
    flat_store(out, j + 1, q[1])
    flat_store(out, j + 2, q[2])
    flat_store(out, j + 3, q[3])


@overload(store4, jit_options=INLINE_OPTIONS)
def _store4_flat(out, i, q):
    if _flat_vector(out):
        return _store4_buffer
    if _vector(out):

        def strided(out, i, q):
            out[4 * i], out[4 * i + 1], out[4 * i + 2], out[4 * i + 3] = q

        return strided
    return None


@overload(load4, jit_options={"cache": CACHE})
def _load4_rows(a, i):
    if _vector(a):
        return None
    if flat_rows(a):
        return lambda a, i: (
            flat_load(a, 4 * i), flat_load(a, 4 * i + 1), flat_load(a, 4 * i + 2), flat_load(a, 4 * i + 3)
        )
    return lambda a, i: (a[i, 0], a[i, 1], a[i, 2], a[i, 3])


@overload(store4, jit_options={"cache": CACHE})
def _store4_rows(out, i, q):
    if _vector(out):
        return None
    if flat_rows(out):
        return _store4_buffer

    def rows(out, i, q):
        out[i, 0] = q[0]
        out[i, 1] = q[1]
        out[i, 2] = q[2]
        out[i, 3] = q[3]

    return rows


# ---- 3×3 matrices


@overload(store33, jit_options={"cache": CACHE})
def _store33(out, i, m):
    if isinstance(out, types.Array) and out.ndim == 3 and out.layout == "C" and out.aligned:

        def impl(out, i, m):
            j = 9 * i
            flat_store(out, j, m[0])
            flat_store(out, j + 1, m[1])
            flat_store(out, j + 2, m[2])
            flat_store(out, j + 3, m[3])
            flat_store(out, j + 4, m[4])
            flat_store(out, j + 5, m[5])
            flat_store(out, j + 6, m[6])
            flat_store(out, j + 7, m[7])
            flat_store(out, j + 8, m[8])

        return impl
    return store33


# ---- the same accessors inlined at numba's typed-IR level, for loops that LLVM
# does not vectorise through the LLVM-inlined ones (the Bézier controls: 10
# packed instructions instead of 761). Typed-IR inlining costs compile time per
# call site, so only there. Flat 1-D arrays only.


def load1_ir(a, i):
    return a[i]


def load4_ir(a, i):
    return (a[4 * i], a[4 * i + 1], a[4 * i + 2], a[4 * i + 3])


def store4_ir(out, i, q):
    out[4 * i], out[4 * i + 1], out[4 * i + 2], out[4 * i + 3] = q


for _stub, _impl in ((load1_ir, _load1), (load4_ir, _load4_flat), (store4_ir, _store4_flat)):
    overload(_stub, inline="always", jit_options={"cache": CACHE})(_impl)
