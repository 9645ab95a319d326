"""Per-element 3×3 matrix functions: a matrix is a row-major 9-tuple
``(m00, m01, m02, m10, …, m22)``, a vector a 3-tuple.

Shared by :mod:`quatarray.conversions` (rotation matrices),
:mod:`quatarray.transforms` (the VQM group) and :mod:`quatarray._cubic`. Like :mod:`quatarray._elements`
they never allocate, validate or raise and keep the float type of their
arguments.
"""


from ._jit import element


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
