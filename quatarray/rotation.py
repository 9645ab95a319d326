"""Rotating vectors by quaternions."""

from . import _elements as E
from ._jit import inline, prange, rowloop
from ._validate import as_float, elementwise


# The loops over |q|-dependent formulas (E.FarRows) compute them on q as it is;
# a second kernel redoes the rare rows outside the range where that is exact,
# on the scaled q (E.qscaled), only when there are some. The first pass leaves those rows of
# `out` (which may be `v`) holding v.


@inline
def _rotate_plain(i, args):
    q, v, out = args
    a = E.load4(q, i)
    x = E.load3(v, i)
    n2 = E.qdot(a, a)
    f = E.far_scale(n2)
    E.store3(out, i, E.pick3(f, x, E.qrotate_raw(a, x, n2)))
    return f


@inline
def _rotate_scaled(i, args):
    q, v, out = args
    a = E.load4(q, i)
    if E.far_scale(E.qdot(a, a)):
        E.store3(out, i, E.qrotate(a, E.load3(v, i)))


_rotate = E.FarRows(_rotate_plain, _rotate_scaled, "rotate")


@rowloop
def _rotate_one(v, q, out):
    # One rotation for every row: its matrix once, then a 3×3 product per row.
    if v.shape[0] == 0:
        return
    m = E.qmatrix(E.load4(q, 0))
    for i in prange(v.shape[0]):
        x, y, z = E.load3(v, i)
        E.store3(
            out,
            i,
            (m[0] * x + m[1] * y + m[2] * z, m[3] * x + m[4] * y + m[5] * z, m[6] * x + m[7] * y + m[8] * z),
        )


def rotate(q, v, out=None):
    """Rotate vectors: the vector part of q (0, v) q⁻¹.

    Equal to ``Rotation.from_quat(q, scalar_first=True).apply(v)`` for unit
    `q`, and defined for every non-zero `q` (no normalising needed).

    Parameters
    ----------
    q : array_like, shape (..., 4)
    v : array_like, shape (..., 3)
        Leading dimensions broadcast against those of `q`.
    out : ndarray, optional
        May be `v`.

    Returns
    -------
    ndarray, shape (..., 3)

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> q = qa.from_axis_angle([0, 1, 0], np.pi / 2)
    >>> np.round(qa.rotate(q, [0, 1, 1]), 12)
    array([1., 1., 0.])
    """
    a = as_float(q, "q")
    if a.shape == (4,):
        return elementwise(_rotate_one, [(v, "v", (3,)), (a, "q", (4,))], [(3,)], out)
    return elementwise(_rotate, [(a, "q", (4,)), (v, "v", (3,))], [(3,)], out)
