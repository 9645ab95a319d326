"""Per-element 3×3 matrix functions: a matrix is a row-major 9-tuple
``(m00, m01, m02, m10, …, m22)``, a vector a 3-tuple.

Shared by :mod:`quatarray.conversions` (rotation matrices) and
:mod:`quatarray.transforms` (the VQM group). Like :mod:`quatarray._elements`
they never allocate, validate or raise and keep the float type of their
arguments.
"""

from numba import types
from numba.extending import overload

from ._jit import CACHE, element, flat_store


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
    literal stride 9 (as ``_elements.store4`` does at stride 4), which lets
    LLVM vectorise the row loop: into a freshly allocated output, whose pages
    the system faults in during the loop, about 20 % faster (N = 2·10⁶);
    into a warm ``out=`` the same (memory-bound either way). Other layouts
    index ``out[i, j, k]``.
    """
    out[i, 0, 0], out[i, 0, 1], out[i, 0, 2] = m[0], m[1], m[2]
    out[i, 1, 0], out[i, 1, 1], out[i, 1, 2] = m[3], m[4], m[5]
    out[i, 2, 0], out[i, 2, 1], out[i, 2, 2] = m[6], m[7], m[8]


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


@element
def det33(a):
    return (
        a[0] * (a[4] * a[8] - a[5] * a[7])
        - a[1] * (a[3] * a[8] - a[5] * a[6])
        + a[2] * (a[3] * a[7] - a[4] * a[6])
    )


@element
def cofactor33(a):
    """Cofactor matrix: equals det(a)·a⁻ᵀ."""
    return (
        a[4] * a[8] - a[5] * a[7], a[5] * a[6] - a[3] * a[8], a[3] * a[7] - a[4] * a[6],
        a[2] * a[7] - a[1] * a[8], a[0] * a[8] - a[2] * a[6], a[1] * a[6] - a[0] * a[7],
        a[1] * a[5] - a[2] * a[4], a[2] * a[3] - a[0] * a[5], a[0] * a[4] - a[1] * a[3],
    )  # fmt: skip


@element
def matvec(m, r):
    """M r."""
    return (
        m[0] * r[0] + m[1] * r[1] + m[2] * r[2],
        m[3] * r[0] + m[4] * r[1] + m[5] * r[2],
        m[6] * r[0] + m[7] * r[1] + m[8] * r[2],
    )


@element
def matmul(a, b):
    """A B."""
    return (
        a[0] * b[0] + a[1] * b[3] + a[2] * b[6],
        a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
        a[0] * b[2] + a[1] * b[5] + a[2] * b[8],
        a[3] * b[0] + a[4] * b[3] + a[5] * b[6],
        a[3] * b[1] + a[4] * b[4] + a[5] * b[7],
        a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
        a[6] * b[0] + a[7] * b[3] + a[8] * b[6],
        a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
        a[6] * b[2] + a[7] * b[5] + a[8] * b[8],
    )


@element
def transpose(a):
    return (a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8])


@element
def scale9(a, s):
    return (a[0] * s, a[1] * s, a[2] * s, a[3] * s, a[4] * s, a[5] * s, a[6] * s, a[7] * s, a[8] * s)


@element
def lerp9(a, b, u, t):
    """u A + t B."""
    return (
        a[0] * u + b[0] * t, a[1] * u + b[1] * t, a[2] * u + b[2] * t,
        a[3] * u + b[3] * t, a[4] * u + b[4] * t, a[5] * u + b[5] * t,
        a[6] * u + b[6] * t, a[7] * u + b[7] * t, a[8] * u + b[8] * t,
    )  # fmt: skip
