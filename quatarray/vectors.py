"""Rotating vectors by quaternions: :func:`rotate`.

The module was called ``quatarray.rotation`` before; that import path still
works (it is this module object)."""

import numpy as np

from . import _elements as E
from ._jit import element, prange, prefer_no_gather, rowloop, second_pass, specialise
from ._validate import as_float, elementwise


# The row loop computes the formula on q as it is and takes the max of
# E.far_excess(|q|²) on the way (two integer SIMD instructions per vector of
# rows); only when a row was far from unit scale (or zero, inf, nan) a second,
# serial kernel redoes those rows on the scaled q (E.qscaled). The body is
# written out in the loop: as a function called per row (rowloop(far=...)) and with
# a stored per-row flag the float32 loop ran 20-25 % slower than without far
# rows.
#
# `out` = `v` has a copy of the loop of its own (compiled only for that case),
# which stores into v itself: LLVM then sees each row read before it is
# written, and vectorises the loop (with `out` a second array that may overlap
# v it checks their ranges at run time and runs the scalar loop, 4-6x slower).
# It leaves the far rows holding v (a select per component) for the second pass,
# which is why rotate keeps this copy rather than the generic RowLoop.into copy
# (elementwise's route for `out` an input), which would store over them.

INTO_V = False  # rebound to True in _rotate_into


def _rotate_rows(q, v, out):
    acc = E.far_start(q)
    for i in prange(q.shape[0]):
        prefer_no_gather()
        a = E.load4(q, i)
        x = E.load3(v, i)
        n2 = E.qdot(a, a)
        r = E.qrotate_raw(a, x, n2)
        if INTO_V:  # a constant: numba keeps one branch
            E.store3(v, i, E.pick3(E.far_scale(n2), x, r))
        else:
            E.store3(out, i, r)
        acc = max(acc, E.far_excess(n2))
    return E.far_any(acc)


_rotate_new = rowloop(_rotate_rows)
_rotate_into = rowloop(specialise(_rotate_rows, "_into", INTO_V=True))


@element
def _rotate_scaled(i, args):
    q, v, out = args
    a = E.load4(q, i)
    if E.far_scale(E.qdot(a, a)):
        E.store3(out, i, E.qrotate(a, E.load3(v, i)))


_rotate_again = second_pass(_rotate_scaled, "rotate")


def _rotate(q, v, out):
    """The batched rotate (for :func:`quatarray._validate.elementwise`): row i of
    `out` from rows i of `q` and `v`; `out` may be `v` (no other overlap)."""
    far = (_rotate_into if np.may_share_memory(v, out) else _rotate_new)(q, v, out)
    if far:
        _rotate_again(q, v, out)
    return far


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
