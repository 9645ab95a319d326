"""Rotating vectors by quaternions."""

from . import _elements as E
from ._jit import prange, rowloop
from ._validate import elementwise


@rowloop
def _rotate(q, v, out):
    for i in prange(q.shape[0]):
        E.store3(out, i, E.qrotate(E.load4(q, i), E.load3(v, i)))


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
    return elementwise(_rotate, [(q, "q", (4,)), (v, "v", (3,))], [(3,)], out)
