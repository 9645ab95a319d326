"""``Rotation``: scipy 1.17's ``scipy.spatial.transform.Rotation`` on quatarray's kernels.

One storage, two faces: a ``Rotation`` holds one house array of shape
``(..., 4)`` in (w, x, y, z) order (float32 or float64; float32 in stays
float32) and a ``single`` flag; every method is a thin shell over the
functional layer (:func:`quatarray.multiply`, :func:`quatarray.rotate`, ...).
``r.wxyz`` gives that array and ``Rotation.from_wxyz(a)`` wraps one, both
without a copy.
"""

import numpy as np

from .. import algebra as _alg
from .. import representations as _rep
from ..rotation import rotate as _rotate
from .._validate import as_float, check_core

_F32 = np.dtype(np.float32)
_F64 = np.dtype(np.float64)


class Rotation:
    """Rotations in 3 dimensions, with the public API of scipy 1.17's
    ``scipy.spatial.transform.Rotation``.

    Switch by the import line: ``from quatarray import Rotation``. The stored
    array is the house layout (w, x, y, z): see :attr:`wxyz` and
    :meth:`from_wxyz`.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import Rotation as R
    >>> r = R.from_quat([0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)])
    >>> np.round(r.apply([1, 0, 0]), 12) + 0.0
    array([0., 1., 0.])
    """

    __slots__ = ("_q", "_single")

    # ------------------------------------------------------------------
    # the zero-copy interface

    @classmethod
    def _from_house(cls, q, single):
        """Wrap the house array `q` (``(..., 4)``, native float32/float64, unit) as it
        is: no check, no copy. `single` only with ``q.shape == (4,)``."""
        r = object.__new__(cls)
        r._q = q
        r._single = single
        return r

    @classmethod
    def from_wxyz(cls, a, *, copy=False, normalize=False):
        """Wrap a house array of (w, x, y, z) quaternions, without a copy by default.

        Parameters
        ----------
        a : array_like, shape (..., 4) or (4,)
            ``(4,)`` gives a single rotation. float32 and float64 are kept;
            other real dtypes become float64 (a copy).
        copy : bool, optional
            Copy the array first (default False: the object holds `a` itself).
        normalize : bool, optional
            Divide by the norms (a new array). Without it the quaternions are
            taken as unit, as given.

        Examples
        --------
        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> a = np.array([[1.0, 0, 0, 0], [0, 0, 0, 1]])
        >>> r = Rotation.from_wxyz(a)
        >>> r.wxyz is a
        True
        >>> r.as_quat()
        array([[0., 0., 0., 1.],
               [0., 0., 1., 0.]])
        """
        q = check_core(as_float(a, "a"), "a", (4,))
        if normalize:
            q = _normalized(q, "a")
        elif copy:
            q = q.copy()
        return cls._from_house(q, q.ndim == 1)

    @property
    def wxyz(self):
        """The stored ``(..., 4)`` (w, x, y, z) array itself (``(4,)`` for a single rotation), no copy.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.identity(2).wxyz
        array([[1., 0., 0., 0.],
               [1., 0., 0., 0.]])
        """
        return self._q

    # ------------------------------------------------------------------
    # shape

    @property
    def single(self):
        """Whether this holds a single rotation (shape ``()``).

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.identity().single, Rotation.identity(1).single
        (True, False)
        """
        return self._single

    @property
    def shape(self):
        """The leading shape of the stack, ``()`` for a single rotation.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.identity(shape=(2, 3)).shape
        (2, 3)
        """
        return self._q.shape[:-1]

    def __len__(self):
        """The length of the first axis; a single rotation raises ``TypeError``.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> len(Rotation.identity(3))
        3
        """
        if self._single:
            raise TypeError("Single rotation has no len().")
        return self._q.shape[0]

    def __bool__(self):
        return True

    # ------------------------------------------------------------------
    # constructors and converters

    @classmethod
    def from_quat(cls, quat, *, scalar_first=False):
        """Rotations from quaternions, scalar-last (x, y, z, w) by default as in scipy.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.from_quat([0, 0, 0, 2]).as_quat()
        array([0., 0., 0., 1.])
        """
        a = check_core(as_float(quat, "quat"), "quat", (4,))
        q = a if scalar_first else _rep.from_xyzw(a)
        return cls._from_house(_normalized(q, "quat"), q.ndim == 1)

    def as_quat(self, canonical=False, *, scalar_first=False):
        """The quaternions, scalar-last (x, y, z, w) by default as in scipy.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.from_quat([0, 0, 0, -1]).as_quat(canonical=True)
        array([0., 0., 0., 1.])
        """
        q = _alg.canonical(self._q) if canonical else self._q
        return q.copy() if scalar_first and q is self._q else (q if scalar_first else _rep.as_xyzw(q))

    @classmethod
    def identity(cls, num=None, *, shape=None):
        """Identity rotations: one (``num=None``), `num` of them or a stack of `shape`.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.identity().as_quat()
        array([0., 0., 0., 1.])
        """
        if num is not None and shape is not None:
            raise ValueError("Only one of `num` or `shape` can be specified.")
        lead = () if num is None and shape is None else (shape if num is None else num)
        q = _alg.identity(lead)
        return cls._from_house(q, q.ndim == 1)

    # ------------------------------------------------------------------
    # operations

    def apply(self, vectors, inverse=False):
        """Rotate vectors (``inverse=True``: by the inverse rotations).

        Examples
        --------
        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> r = Rotation.from_rotvec([0, 0, np.pi / 2])
        >>> np.round(r.apply([1, 0, 0]), 12) + 0.0
        array([0., 1., 0.])
        """
        q = _alg.conjugate(self._q) if inverse else self._q
        return _rotate(q, vectors)

    def __mul__(self, other):
        """Composition ``self * other``: `other` applied first.

        Examples
        --------
        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> r = Rotation.from_rotvec([0, 0, 0.25]) * Rotation.from_rotvec([0, 0, 0.5])
        >>> np.round(r.as_rotvec(), 12) + 0.0
        array([0.  , 0.  , 0.75])
        """
        if not isinstance(other, Rotation):
            return NotImplemented
        q = _alg.normalize(_alg.multiply(self._q, other._q))
        return Rotation._from_house(q, self._single and other._single)

    def inv(self):
        """The inverse rotations.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.from_quat([0, 0, 1, 1]).inv().as_quat(canonical=True).round(6)
        array([-0.      , -0.      , -0.707107,  0.707107])
        """
        return Rotation._from_house(_alg.conjugate(self._q), self._single)


def _normalized(q, name):
    """`q` divided by its norms; a zero quaternion raises scipy's ``ValueError``."""
    n = _alg.norm(q)
    if np.any(n == 0):
        raise ValueError(f"Found zero norm quaternions in `{name}`.")
    return _alg.normalize(q)
