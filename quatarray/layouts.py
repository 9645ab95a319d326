"""Other layouts of the same quaternion numbers (w, x, y, z): the scalar-last
(x, y, z, w) layout, ``scipy.spatial.transform.Rotation`` objects, the 4×4
left/right multiplication matrices and 2×2 complex (SU(2)) matrices.

The rule between this module and :mod:`quatarray.conversions`: a *layout*
holds the same four numbers (w, x, y, z) of the quaternion, arranged
otherwise (only a scipy ``Rotation`` normalises them), while a *conversion*
goes to another parameterisation of the rotation (rotation matrices,
rotation vectors, axis–angle, modified Rodrigues parameters, Gibbs vectors:
scipy's ``as_*``/``from_*`` of a rotation). Leading dimensions broadcast
like numpy; float32 stays float32 and float64 stays float64.
"""

import numpy as np

from . import _elements as E
from ._compat import rotation_as_wxyz, rotation_from_wxyz, scipy_nd_stacks
from ._jit import element, like, prange, prefer_no_gather, rowloop
from ._validate import as_float, check_core, elementwise, refuse_masked, shape_error

Q = (4,)
M4 = (4, 4)

# --------------------------------------------------------------------------
# per-element formulas


@element(how="call")
def store44(out, i, m):
    for k in range(16):
        out[i, k // 4, k % 4] = m[k]


@element(how="call")
def left_matrix(q):
    """L (row-major 16-tuple) with L @ p = q ⊗ p."""
    w, x, y, z = q
    return (
        w, -x, -y, -z,
        x, w, -z, y,
        y, z, w, -x,
        z, -y, x, w,
    )  # fmt: skip


@element(how="call")
def right_matrix(q):
    """R (row-major 16-tuple) with R @ p = p ⊗ q."""
    w, x, y, z = q
    return (
        w, -x, -y, -z,
        x, w, z, -y,
        y, -z, w, x,
        z, y, -x, w,
    )  # fmt: skip


# --------------------------------------------------------------------------
# batched loops


@rowloop
def _as_xyzw(q, out):
    for i in prange(q.shape[0]):
        w, x, y, z = E.load4(q, i)
        E.store4(out, i, (x, y, z, w))


@rowloop
def _from_xyzw(a, out):
    for i in prange(a.shape[0]):
        x, y, z, w = E.load4(a, i)
        E.store4(out, i, (w, x, y, z))


@rowloop
def _as_left_matrix(q, out):
    for i in prange(q.shape[0]):
        store44(out, i, left_matrix(E.load4(q, i)))


@rowloop
def _as_right_matrix(q, out):
    for i in prange(q.shape[0]):
        store44(out, i, right_matrix(E.load4(q, i)))


@rowloop
def _as_su2(q, out):
    # out: the float view (n, 2, 4) of a complex (n, 2, 2) array: re, im, re, im.
    for i in prange(q.shape[0]):
        w, x, y, z = E.load4(q, i)
        out[i, 0, 0], out[i, 0, 1], out[i, 0, 2], out[i, 0, 3] = w, x, y, z
        out[i, 1, 0], out[i, 1, 1], out[i, 1, 2], out[i, 1, 3] = -y, z, w, -x


@rowloop
def _from_su2(m, out):
    # m: float view (n, 2, 4) of complex (n, 2, 2); averages the two copies of
    # each component (the orthogonal projection onto [[a, b], [−b̄, ā]]).
    for i in prange(m.shape[0]):
        prefer_no_gather()
        half = like(m, 0.5)
        E.store4(
            out,
            i,
            (
                half * (m[i, 0, 0] + m[i, 1, 2]),
                half * (m[i, 0, 1] - m[i, 1, 3]),
                half * (m[i, 0, 2] - m[i, 1, 0]),
                half * (m[i, 0, 3] + m[i, 1, 1]),
            ),
        )


# --------------------------------------------------------------------------
# layouts and other libraries


def as_xyzw(q, out=None):
    """Scalar-last layout (x, y, z, w), as used by ROS and scipy's default.

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.as_xyzw([1, 2, 3, 4])
    array([2., 3., 4., 1.])
    """
    return elementwise(_as_xyzw, [(q, "q", Q)], [Q], out)


def from_xyzw(a, out=None):
    """Quaternions (w, x, y, z) from the scalar-last layout (x, y, z, w).

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.from_xyzw([2, 3, 4, 1])
    array([1., 2., 3., 4.])
    """
    return elementwise(_from_xyzw, [(a, "a", Q)], [Q], out)


def to_scipy(q):
    """A ``scipy.spatial.transform.Rotation`` holding the rotations of `q`.

    scipy normalises the quaternions (float64) and raises ``ValueError`` for a
    zero quaternion.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> r = qa.to_scipy(qa.from_rotvec([0, 0, 0.5]))
    >>> np.round(r.as_rotvec(), 12)
    array([0. , 0. , 0.5])
    """
    a = check_core(as_float(q, "q"), "q", Q)
    if a.ndim > 2 and not scipy_nd_stacks():
        import scipy

        raise ValueError(f"Expected `q` to have shape (4,) or (N, 4), got {a.shape}: scipy {scipy.__version__}'s "
                         "Rotation holds no stacks of more dimensions (scipy 1.17 and later do).")
    return rotation_from_wxyz(a)


def from_scipy(rotation):
    """Quaternions (w, x, y, z), float64, of a ``scipy.spatial.transform.Rotation``.

    The sign is the one scipy stores (``as_quat(canonical=False)``).

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> from scipy.spatial.transform import Rotation
    >>> np.round(qa.from_scipy(Rotation.from_rotvec([0, np.pi, 0])), 12)
    array([0., 0., 1., 0.])
    """
    from scipy.spatial.transform import Rotation

    if not isinstance(rotation, Rotation):
        raise TypeError(
            "Expected `rotation` to be a scipy.spatial.transform.Rotation, " f"got {type(rotation).__name__}."
        )
    return np.asarray(rotation_as_wxyz(rotation), dtype=np.float64)


# --------------------------------------------------------------------------
# matrix representations of the algebra


def as_left_matrix(q, out=None):
    """4×4 real matrices L with ``L @ p == multiply(q, p)``.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> p, q = [1, 2, 3, 4], [5, 6, 7, 8]
    >>> np.array_equal(qa.as_left_matrix(q) @ p, qa.multiply(q, p))
    True
    """
    return elementwise(_as_left_matrix, [(q, "q", Q)], [M4], out)


def as_right_matrix(q, out=None):
    """4×4 real matrices R with ``R @ p == multiply(p, q)``.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> p, q = [1, 2, 3, 4], [5, 6, 7, 8]
    >>> np.array_equal(qa.as_right_matrix(q) @ p, qa.multiply(p, q))
    True
    """
    return elementwise(_as_right_matrix, [(q, "q", Q)], [M4], out)


def as_su2(q):
    """2×2 complex matrices [[w + xi, y + zi], [−y + zi, w − xi]].

    The map is multiplicative: ``as_su2(p) @ as_su2(q) == as_su2(multiply(p, q))``;
    unit quaternions give SU(2) matrices. float32 → complex64, float64 → complex128.

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.as_su2([1, 2, 3, 4])
    array([[ 1.+2.j,  3.+4.j],
           [-3.+4.j,  1.-2.j]])
    """
    f = elementwise(_as_su2, [(q, "q", Q)], [(2, 4)])
    return f.view(np.complex64 if f.dtype == np.float32 else np.complex128)


def from_su2(m, out=None):
    """Quaternions of 2×2 complex matrices [[w + xi, y + zi], [−y + zi, w − xi]].

    Each component appears twice in the matrix; the two copies are averaged,
    which is exact for matrices of this form and the nearest quaternion
    matrix (Frobenius) for any other. complex64 → float32, complex128 (and
    real input, read as having zero imaginary part) → float64.

    Parameters
    ----------
    m : array_like, shape (..., 2, 2)
    out : ndarray, optional
        Result array of shape ``(..., 4)``.

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.from_su2([[1 + 2j, 3 + 4j], [-3 + 4j, 1 - 2j]])
    array([1., 2., 3., 4.])
    """
    refuse_masked(m, "m")
    try:
        a = np.asarray(m)
    except (ValueError, TypeError) as exc:
        raise TypeError(f"Expected `m` to be an array of complex or real numbers: {exc}") from None
    kind = a.dtype.kind
    if kind == "c":  # complex64 in either byte order stays complex64
        ctype = np.complex64 if a.dtype.itemsize <= 8 else np.complex128
    elif kind == "f" and a.dtype.itemsize <= 4:
        ctype = np.complex64
    elif kind in "fbiu":
        ctype = np.complex128
    else:
        raise TypeError(f"Expected `m` to have a complex or real dtype, got {a.dtype}.")
    if a.ndim < 2 or a.shape[-2:] != (2, 2):
        raise shape_error("m", "(..., 2, 2)", a.shape)
    a = np.ascontiguousarray(a, dtype=ctype)
    f = a.view(np.float32 if ctype == np.complex64 else np.float64)
    return elementwise(_from_su2, [(f, "m", (2, 4))], [Q], out)
