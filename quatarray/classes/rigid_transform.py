"""``RigidTransform``: scipy 1.17's ``scipy.spatial.transform.RigidTransform`` on quatarray's kernels.

A ``RigidTransform`` holds two house arrays: unit quaternions ``(..., 4)`` in
(w, x, y, z) order and translations ``(..., 3)`` (one leading shape, float32
or float64: float32 in stays float32, where scipy promotes to float64), and
a ``single`` flag. Every method is a thin shell over :mod:`quatarray.rigid`.
``tf.wxyz`` and ``tf.xyz`` give the stored arrays and
``RigidTransform.from_components_wxyz(t, q)`` wraps two, without a copy.

The quaternions carry the sign scipy's matrix conversion gives (the
component of largest magnitude positive), so ``as_dual_quat`` and
``rotation.as_quat()`` match scipy's arrays, not only their rotations.

Beyond scipy: ``tf * r`` and ``r * tf`` with a ``Rotation`` (quatarray's or
scipy's) compose with the pure rotation, and :meth:`RigidTransform.from_vqs`
/ :meth:`RigidTransform.as_vqs` convert from and to :class:`quatarray.VQS`.
"""

import math

import numpy as np

from .. import rigid as _rg
from .._validate import as_float, check_core, where
from .rotation import Rotation

_F32 = np.dtype(np.float32)
_F64 = np.dtype(np.float64)


def _reals(x, name, dtype=None):
    """`x` as a float32/float64 ndarray (:func:`as_float`), with scipy's exception type:
    ``ValueError`` for input that is not an array of real numbers (ragged, strings,
    complex, objects)."""
    try:
        return as_float(x, name, dtype)
    except TypeError as exc:
        raise ValueError(str(exc)) from None


def _is_rotation(x):
    if isinstance(x, Rotation):
        return True
    try:
        from scipy.spatial.transform import Rotation as SR
    except ImportError:  # pragma: no cover - scipy is a dependency of the tests only
        return False
    return isinstance(x, SR)


def _rotation_wxyz(r):
    """(house quaternions, single) of a quatarray or scipy ``Rotation``."""
    if isinstance(r, Rotation):
        return r.wxyz, r.single
    q = np.asarray(r.as_quat(scalar_first=True))
    return q, q.ndim == 1


class RigidTransform:
    """Rigid transforms (rotation and translation) in 3 dimensions, with the
    public API of scipy 1.17's ``scipy.spatial.transform.RigidTransform``.

    Switch by the import line: ``from quatarray import RigidTransform``.

    Differences from scipy: float32 stays float32; the transforms are stored as
    unit quaternions and translations, so ``RigidTransform(m, normalize=False)``
    reads the rotation off `m` by Shepperd's method without projecting it (scipy
    keeps such a matrix as given) and ``copy=False`` still makes new arrays (use
    :meth:`from_components_wxyz` to wrap arrays); tuple indices follow numpy's
    rules on the leading shape (scipy 1.17 reads ``tf[0, 1]`` as ``tf[[0, 1]]``);
    ``tf ** n`` is exp(n·log T) to rounding (scipy's agrees with that within
    about 1e-6 for some exponents, such as 1.7); ``mean`` with weights that are
    all zero raises ``ZeroDivisionError`` for N-D stacks too (scipy's gives a
    nan translation there); ``tf[...]`` works and ``mean`` takes weights as a
    list; ``from_dual_quat`` scales the real part before taking its norm, so
    dual quaternions of magnitude below about 1e-154 or above 1e154 are
    normalised as any other (scipy's norm underflows to 0, giving the identity
    rotation, or overflows, giving a zero matrix).

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import RigidTransform as Tf, Rotation as R
    >>> r = R.from_quat([0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)])  # 90° about z
    >>> tf = Tf.from_components([1, 2, 3], r)
    >>> np.round(tf.apply([1, 0, 0]), 12)
    array([1., 3., 3.])
    >>> np.round((tf ** 0.5 * tf ** 0.5).as_matrix() - tf.as_matrix(), 12) + 0.0
    array([[0., 0., 0., 0.],
           [0., 0., 0., 0.],
           [0., 0., 0., 0.],
           [0., 0., 0., 0.]])
    """

    __slots__ = ("_q", "_single", "_t")

    def __init__(self, matrix, normalize=True, copy=True):
        m = self._matrix_arg(matrix)
        try:
            q, t = _rg.pose_from_matrix(m, assume_valid=not normalize, _name="matrix")
        except ValueError as exc:
            if "positive determinant" not in str(exc):
                raise
            lead = m.shape[:-2]
            k = int(np.argmax(~(np.linalg.det(m[..., :3, :3].reshape(-1, 3, 3)) > 0)))
            raise ValueError(  # scipy's words, and the row
                "Non-positive determinant (left-handed or null coordinate frame) in the rotation part of "
                f"transformation matrix `matrix` at {where(k, lead)}: {m.reshape(-1, 4, 4)[k, :3, :3].tolist()}."
            ) from None
        self._q, self._t, self._single = q, t, q.ndim == 1

    @staticmethod
    def _matrix_arg(matrix):
        a = _reals(matrix, "matrix")
        if a.ndim < 2 or a.shape[-2:] != (4, 4):
            raise ValueError(f"Expected `matrix` to have shape (..., 4, 4), got {a.shape}.")
        return a

    # ------------------------------------------------------------------
    # the zero-copy interface

    @classmethod
    def _from_house(cls, q, t, single=None):
        """Wrap house arrays q (..., 4) unit, t (..., 3) of one leading shape and dtype: no check, no copy."""
        tf = object.__new__(cls)
        tf._q, tf._t = q, t
        tf._single = q.ndim == 1 if single is None else single
        return tf

    @classmethod
    def from_components_wxyz(cls, translation, wxyz, *, copy=False, normalize=False):
        """Wrap a translation array ``(..., 3)`` and a quaternion array ``(..., 4)``
        in (w, x, y, z) order, without copying them (by default).

        Both must have one leading shape and one float type (float32 or float64,
        native); ``(3,)`` and ``(4,)`` give a single transform. The quaternions are
        taken as unit as given (``normalize=True``: divided by their norms, a new
        array, with scipy's sign); their sign is kept.

        Examples
        --------
        >>> import numpy as np
        >>> from quatarray import RigidTransform
        >>> q, t = np.array([[1.0, 0, 0, 0]]), np.array([[1.0, 2, 3]])
        >>> tf = RigidTransform.from_components_wxyz(t, q)
        >>> tf.wxyz is q, tf.xyz is t
        (True, True)
        """
        t = check_core(as_float(translation, "translation"), "translation", (3,))
        q = check_core(as_float(wxyz, "wxyz"), "wxyz", (4,))
        if t.shape[:-1] != q.shape[:-1]:
            raise ValueError(
                f"Expected `translation` and `wxyz` to have one leading shape, got {t.shape} and {q.shape}."
            )
        if t.dtype != q.dtype:
            raise TypeError(f"Expected `translation` and `wxyz` of one float type, got {t.dtype} and {q.dtype}.")
        if normalize:
            n = np.linalg.norm(q, axis=-1)
            if np.any(n == 0):
                raise ValueError("Found zero norm quaternions in `wxyz`.")
            q, t = _rg.elementwise(_rg._bind(_rg._components, 2, 1), [(t, "translation", (3,)), (q, "wxyz", (4,))],
                                   [(4,), (3,)])
        elif copy:
            q, t = q.copy(), t.copy()
        return cls._from_house(q, t)

    @property
    def wxyz(self):
        """The stored ``(..., 4)`` unit quaternions (w, x, y, z) themselves, no copy."""
        return self._q

    @property
    def xyz(self):
        """The stored ``(..., 3)`` translations themselves, no copy (:attr:`translation` copies)."""
        return self._t

    # ------------------------------------------------------------------
    # constructors

    @staticmethod
    def from_matrix(matrix):
        """Transforms from 4×4 homogeneous matrices ``(..., 4, 4)``: the last row must be
        exactly [0, 0, 0, 1]; the rotation part is projected onto the nearest rotation
        where it is not orthogonal (as scipy)."""
        return RigidTransform(matrix)

    @staticmethod
    def from_rotation(rotation):
        """Pure rotations (zero translation) from a ``Rotation`` (quatarray's or scipy's)."""
        if not _is_rotation(rotation):
            raise TypeError(f"Expected `rotation` to be a `Rotation` instance, got {type(rotation)}.")
        q, single = _rotation_wxyz(rotation)
        t = np.zeros(q.shape[:-1] + (3,), q.dtype)
        return RigidTransform._components(t, q, single)

    @staticmethod
    def from_translation(translation):
        """Pure translations ``(..., 3)`` (identity rotation)."""
        t = _reals(translation, "translation")
        if t.ndim < 1 or t.shape[-1] != 3:
            raise ValueError(f"Expected `translation` to have shape (..., 3), got {t.shape}.")
        q = np.zeros(t.shape[:-1] + (4,), t.dtype)
        q[..., 0] = 1
        return RigidTransform._from_house(q, np.array(t))

    @staticmethod
    def from_components(translation, rotation):
        """Transforms that rotate by `rotation` first, then translate by
        `translation` ``(..., 3)``; the leading shapes broadcast."""
        if not _is_rotation(rotation):
            raise TypeError(f"Expected `rotation` to be a `Rotation` instance, got {type(rotation)}.")
        t = _reals(translation, "translation")
        if t.ndim < 1 or t.shape[-1] != 3:
            raise ValueError(f"Expected `translation` to have shape (..., 3), got {t.shape}.")
        q, single = _rotation_wxyz(rotation)
        return RigidTransform._components(t, q, single and t.ndim == 1)

    @staticmethod
    def _components(t, q, single):
        qo, to = _rg.elementwise(_rg._bind(_rg._components, 2, 1), [(t, "translation", (3,)), (q, "rotation", (4,))],
                                 [(4,), (3,)])
        return RigidTransform._from_house(qo, to, single and qo.ndim == 1)

    @staticmethod
    def from_exp_coords(exp_coords):
        """Transforms from exponential coordinates ``(..., 6)``: rotation vector, then
        the translational part (see :func:`quatarray.from_exp_coords`)."""
        e = _reals(exp_coords, "exp_coords")
        if e.ndim < 1 or e.shape[-1] != 6:
            raise ValueError(f"Expected `exp_coords` to have shape (..., 6), got {e.shape}.")
        q, t = _rg.elementwise(_rg._bind(_rg._from_exp_coords, 1, 1), [(e, "exp_coords", (6,))], [(4,), (3,)])
        return RigidTransform._from_house(q, t)

    @staticmethod
    def from_dual_quat(dual_quat, *, scalar_first=False):
        """Transforms from dual quaternions ``(..., 8)`` (real part, then dual part; each
        scalar last by default, as scipy), normalised as scipy does for non-unit input."""
        d = _reals(dual_quat, "dual_quat")
        if d.ndim < 1 or d.shape[-1] != 8:
            raise ValueError(f"Expected `dual_quat` to have shape (..., 8), got {d.shape}.")
        q, t = _rg.elementwise(_rg._bind(_rg._from_dual_quat, 1, int(not scalar_first), 1),
                               [(d, "dual_quat", (8,))], [(4,), (3,)])
        return RigidTransform._from_house(q, t)

    @staticmethod
    def from_vqs(vqs):
        """The rigid transforms of a :class:`quatarray.VQS` whose scales are all 1
        (any other scale raises ``ValueError``: it is not rigid)."""
        from ..transforms import VQS

        if not isinstance(vqs, VQS):
            raise TypeError(f"Expected `vqs` to be a `VQS` instance, got {type(vqs)}.")
        s = np.asarray(vqs.s)
        bad = s != 1
        if bad.any():
            k = int(np.argmax(bad.reshape(-1)))
            raise ValueError(
                f"Expected a VQS of unit scale (a rigid transform), got s = {s.reshape(-1)[k].item()} "
                f"at {where(k, s.shape)}."
            )
        lead = vqs.shape
        v = np.broadcast_to(vqs.v, lead + (3,))
        q = np.broadcast_to(vqs.q, lead + (4,))
        return RigidTransform._components(v, q, len(lead) == 0)

    @staticmethod
    def identity(num=None, *, shape=None):
        """Identity transforms: one (``()``), `num` of them, or of leading `shape`."""
        if num is not None and shape is not None:
            raise ValueError("Only one of `num` and `shape` can be specified.")
        if num is None and shape is None:
            shape = ()
        elif num is not None:
            shape = (num,)
        elif isinstance(shape, (int, np.integer)):
            shape = (int(shape),)
        elif not isinstance(shape, tuple):
            raise ValueError("`shape` must be an int or a tuple of ints or None.")
        q = np.zeros(shape + (4,))
        q[..., 0] = 1
        return RigidTransform._from_house(q, np.zeros(shape + (3,)))

    @staticmethod
    def concatenate(transforms):
        """One stack of the transforms given (singles count as one each), along the first axis."""
        if isinstance(transforms, RigidTransform):
            return RigidTransform._from_house(transforms._q.copy(), transforms._t.copy())
        transforms = list(transforms)
        if not transforms:
            raise IndexError("Expected at least one transform to concatenate, got none.")
        if not all(isinstance(x, RigidTransform) for x in transforms):
            raise TypeError("input must contain RigidTransform objects only")
        q = np.concatenate([x._q[None] if x._single else x._q for x in transforms])
        t = np.concatenate([x._t[None] if x._single else x._t for x in transforms])
        return RigidTransform._from_house(q, t, False)

    # ------------------------------------------------------------------
    # conversions

    def as_matrix(self):
        """4×4 homogeneous matrices ``(..., 4, 4)``."""
        return _rg.pose_as_matrix(self._q, self._t)

    def as_components(self):
        """(translation, rotation): copies of the translations and the rotations."""
        return self.translation, self.rotation

    def as_exp_coords(self):
        """Exponential coordinates ``(..., 6)``: rotation vector (angle in [0, π]),
        then the translational part."""
        return _rg.as_exp_coords(self._q, self._t)

    def as_dual_quat(self, *, scalar_first=False):
        """Unit dual quaternions ``(..., 8)``: real part, then dual part, each scalar
        last by default (as scipy)."""
        return _rg.as_dual_quat(self._q, self._t, scalar_first=scalar_first)

    def as_vqs(self):
        """The same transforms as a :class:`quatarray.VQS` of unit scale."""
        from ..transforms import VQS

        return VQS(self._t.copy(), self._q.copy(), np.ones(self._q.shape[:-1], self._q.dtype))

    @property
    def rotation(self):
        """The rotations (a copy), as a :class:`quatarray.Rotation`."""
        return Rotation._from_house(self._q.copy(), self._single)

    @property
    def translation(self):
        """The translations ``(..., 3)`` (a copy; :attr:`xyz` is the stored array)."""
        return self._t.copy()

    @property
    def single(self):
        """Whether this holds a single transform (shape ``()``)."""
        return self._single

    @property
    def shape(self):
        """The leading shape of the stack, ``()`` for a single transform."""
        return () if self._single else self._q.shape[:-1]

    # ------------------------------------------------------------------
    # the group

    def apply(self, vector, inverse=False):
        """The vectors ``(..., 3)`` moved by the transforms (``inverse=True``: by their
        inverses); leading shapes broadcast."""
        v = _reals(vector, "vector", self._q.dtype)
        if v.ndim < 1 or v.shape[-1] != 3:
            raise ValueError(f"Expected vector to have shape (..., 3), got {v.shape}.")
        try:
            return _rg.pose_apply(self._q, self._t, v, inverse=inverse)
        except ValueError:
            raise ValueError("operands could not be broadcast together") from None

    def __mul__(self, other):
        """Composition ``self * other``: `other` applied first; a ``Rotation`` counts as a
        pure rotation."""
        if _is_rotation(other):
            other = RigidTransform.from_rotation(other)
        if not isinstance(other, RigidTransform):
            return NotImplemented
        try:
            np.broadcast_shapes(self._q.shape, other._q.shape)
        except ValueError:
            raise ValueError(
                f"Cannot broadcast {self.shape} transforms in first to {other.shape} transforms in second object."
            ) from None
        q, t = _rg.elementwise(
            _rg._bind(_rg._compose, 4, 1),
            [(self._q, "self", (4,)), (self._t, "self", (3,)), (other._q, "other", (4,)), (other._t, "other", (3,))],
            [(4,), (3,)],
        )
        return RigidTransform._from_house(q, t, self._single and other._single)

    def __rmul__(self, other):
        if _is_rotation(other):
            return RigidTransform.from_rotation(other) * self
        return NotImplemented

    def __pow__(self, n):
        """The transforms to the real power `n` (a scalar): screw motion along the
        transform, ``n`` = 0 the identity, −1 the inverse."""
        if isinstance(n, np.ndarray) and n.ndim != 0:
            raise TypeError(f"Expected the exponent to be a real scalar, got an array of shape {n.shape}.")
        try:
            n = float(n)
        except (TypeError, ValueError):
            raise TypeError(f"Expected the exponent to be a real scalar, got {type(n).__name__}.") from None
        if n == 0:
            return RigidTransform.identity(shape=self.shape)._astype(self._q.dtype)
        if n == -1:
            return self.inv()
        if n == 1:
            return RigidTransform._from_house(self._q.copy(), self._t.copy(), self._single)
        q, t = _rg.elementwise(_rg._bind(_rg._power, 3, 1),
                               [(self._q, "self", (4,)), (self._t, "self", (3,)), (n, "n", ())], [(4,), (3,)])
        return RigidTransform._from_house(q, t, self._single)

    def _astype(self, dtype):
        if self._q.dtype == dtype:
            return self
        return RigidTransform._from_house(self._q.astype(dtype), self._t.astype(dtype), self._single)

    def inv(self):
        """The inverse transforms."""
        q, t = _rg.elementwise(_rg._bind(_rg._invert, 2, 1), [(self._q, "self", (4,)), (self._t, "self", (3,))],
                               [(4,), (3,)])
        return RigidTransform._from_house(q, t, self._single)

    def mean(self, weights=None, axis=None):
        """The mean transform: chordal L2 mean of the rotations and (weighted) mean of
        the translations, over the leading axes `axis` (None: all), as scipy 1.17."""
        q, t = (self._q[None], self._t[None]) if self._single else (self._q, self._t)
        lead = q.shape[:-1]
        if lead[0] == 0:
            raise ValueError("Mean of an empty transform set is undefined.")
        nd = len(lead)
        if axis is None:
            ax = tuple(range(nd))
        elif isinstance(axis, (int, np.integer)):
            ax = (int(axis),)
        elif isinstance(axis, tuple):
            ax = axis
        else:
            raise ValueError("`axis` must be None, int, or tuple of ints.")
        if ax and (min(ax) < -nd or max(ax) > nd - 1):
            raise ValueError(f"axis {ax} is out of bounds for transform with shape {lead}.")
        ax = tuple(sorted({k % nd for k in ax}))
        if weights is not None:
            w = _reals(weights, "weights", _F64)
            if np.any(w < 0):
                raise ValueError("`weights` must be non-negative.")
            if w.shape != lead:
                raise ValueError(
                    f"Expected `weights` to have number of values equal to number of transforms, got "
                    f"{w.size} values and {math.prod(lead)} transforms."
                )
            if not np.any(w):
                raise ZeroDivisionError("The `weights` sum to zero: the mean is undefined.")
        else:
            w = None
        qm, tm = _rg.pose_mean(q, t, weights=w, axis=ax)
        qm = np.ascontiguousarray(qm, self._q.dtype)
        qm, tm = _rg.elementwise(_rg._bind(_rg._components, 2, 1), [(tm, "t", (3,)), (qm, "q", (4,))], [(4,), (3,)])
        return RigidTransform._from_house(qm, tm)

    # ------------------------------------------------------------------
    # the container

    def __len__(self):
        if self._single:
            raise TypeError("Single transform has no len")
        return self._q.shape[0]

    def _rows(self, indexer):
        """The flat row numbers that `indexer` picks from the leading shape (numpy's rules:
        integers, slices, None, Ellipsis, integer and boolean arrays, tuples of them)."""
        lead = self._q.shape[:-1]
        return np.arange(math.prod(lead)).reshape(lead)[indexer]

    def __getitem__(self, indexer):
        if self._single:
            raise TypeError("Single transform is not subscriptable.")
        if isinstance(indexer, np.ndarray) and indexer.dtype.kind in "iu" and self._q.shape[0] == 0:
            raise IndexError("cannot take from an empty array")
        rows = self._rows(indexer)
        q = self._q.reshape(-1, 4)[rows]
        t = self._t.reshape(-1, 3)[rows]
        return RigidTransform._from_house(q, t)

    def __setitem__(self, indexer, value):
        if self._single:
            raise TypeError("Single transform is not subscriptable.")
        if not isinstance(value, RigidTransform):
            raise TypeError("value must be a RigidTransform object")
        rows = self._rows(indexer)
        for name, k in (("_q", 4), ("_t", 3)):
            a = getattr(self, name)
            if not a.flags.writeable or not a.flags.c_contiguous:  # a broadcast or strided array: own a copy
                a = np.ascontiguousarray(a).copy()
                setattr(self, name, a)
            a.reshape(-1, k)[rows] = getattr(value, name)  # numpy's assignment rules (leading 1s drop), as scipy

    def __iter__(self):
        if self._single:
            raise TypeError("Single transform is not iterable.")
        for i in range(self._q.shape[0]):  # singles of a 1-D stack, sub-stacks of an N-D one (as scipy)
            yield RigidTransform._from_house(self._q[i].copy(), self._t[i].copy())

    def __reduce__(self):
        return (RigidTransform._from_house, (self._q, self._t, self._single))

    def __repr__(self):
        m = f"{self.as_matrix()!r}".splitlines()
        m[1:] = [" " * 27 + line for line in m[1:]]
        return "RigidTransform.from_matrix(" + "\n".join(m) + ")"
