"""``Rotation``: scipy 1.17's ``scipy.spatial.transform.Rotation`` on quatarray's kernels.

One storage, two faces: a ``Rotation`` holds one house array of shape
``(..., 4)`` in (w, x, y, z) order (float32 or float64; float32 in stays
float32) and a ``single`` flag; every method is a thin shell over the
functional layer (:func:`quatarray.multiply`, :func:`quatarray.rotate`, ...).
``r.wxyz`` gives that array and ``Rotation.from_wxyz(a)`` wraps one, both
without a copy.
"""

import inspect
import math
import operator
import warnings

import numpy as np

from .. import _elements as E
from .. import algebra as _alg
from .. import align as _align
from .. import conversions as _conv
from .. import davenport as _dav
from .. import euler as _eul
from .. import layouts as _lay
from .. import symmetry as _sym
from .. import vectors as _vec
from .._jit import FarRows, prange, rowloop
from .._validate import as_float, check_core, elementwise

_F32 = np.dtype(np.float32)
_F64 = np.dtype(np.float64)
_FLOATS = (_F32, _F64)
_Q = (4,)

# --------------------------------------------------------------------------
# kernels of the class: the layout changes fused with the normalising and
# composing scipy does, so that each is one pass over memory


# The layout kernels only stream memory. Into a new array, a second thread halves
# the time on a quiet 2-core machine (the fresh pages' faults run on both cores):
# _quat_out and inv take the parallel loop above the row threshold; _quat_in keeps
# its far-row flag as a serial reduction.


@rowloop(parallel=False)
def _quat_in(a, first, out):
    # (x, y, z, w) or (w, x, y, z) rows → unit (w, x, y, z); 1 when a row was far
    # from unit scale (or zero, inf, nan): the caller redoes those
    far = np.int32(0)
    for i in prange(a.shape[0]):
        x = E.load4(a, i)
        q = x if first else (x[3], x[0], x[1], x[2])
        n2 = E.qdot(q, q)
        nn = np.sqrt(n2)
        E.store4(out, i, (q[0] / nn, q[1] / nn, q[2] / nn, q[3] / nn))
        far = max(far, E.far_scale(n2))
    return far


@rowloop
def _quat_out(q, first, canonical, out):
    # (w, x, y, z) → (x, y, z, w) (or kept), with scipy's canonical sign if asked
    for i in prange(q.shape[0]):
        a = E.load4(q, i)
        if canonical:
            a = E.qneg(a) if E.canonical_flip(a) else a
        E.store4(out, i, a if first else (a[1], a[2], a[3], a[0]))


@rowloop
def _compose(p, q, out):
    # p ⊗ q normalised, as scipy's `__mul__`
    for i in prange(p.shape[0]):
        m = E.qmul(E.load4(p, i), E.load4(q, i))
        nn = np.sqrt(E.qdot(m, m))
        E.store4(out, i, (m[0] / nn, m[1] / nn, m[2] / nn, m[3] / nn))


@rowloop
def _rotate_inv(q, v, out):
    # the vectors rotated by q⁻¹ (unit q): the transposed matrix of q
    for i in prange(q.shape[0]):
        a = E.load4(q, i)
        E.store3(out, i, E.qrotate_raw(E.qconj(a), E.load3(v, i), E.qdot(a, a)))


def _house_in(a, first, name):
    """Unit (w, x, y, z) quaternions from the float array `a` (..., 4) in (x, y, z, w)
    order (``first=False``) or (w, x, y, z); a zero or nan one raises scipy's error."""
    flat = a.reshape(-1, 4)
    out = np.empty(flat.shape, a.dtype)
    if flat.shape[0] and _quat_in(flat, first, out):
        q = flat if first else flat[:, [3, 0, 1, 2]]
        n = _alg.norm(q)
        if not np.all(n > 0):  # zero or nan
            raise ValueError(f"Found zero norm quaternions in `{name}`.")
        out = _alg.normalize(q)
    return out.reshape(a.shape)


def _map(kernel, a, cin, cout):
    """``kernel(rows of a, rows of out)`` on the float array `a` of shape ``lead + cin``
    (the arrays the class holds: no validation), giving ``lead + cout``; a 0-d result
    as a numpy scalar."""
    if a.ndim == len(cin):  # one row: the serial loop, called directly
        out = np.empty((1,) + cout, a.dtype)
        one = a[None]
        if type(kernel) is FarRows:
            if kernel.first.serial(one, out):
                kernel.again(one, out)
        else:
            kernel.serial(one, out)
        return out[0]
    lead = a.shape[: a.ndim - len(cin)]
    flat = a.reshape((-1,) + cin)
    out = np.empty((flat.shape[0],) + cout, a.dtype)
    kernel(flat, out)
    res = out.reshape(lead + cout)
    return res[()] if res.ndim == 0 else res


def _from_scipy(other):
    """A scipy ``Rotation`` as quatarray's (``TypeError`` for anything else)."""
    try:
        from scipy.spatial.transform import Rotation as SR
    except ImportError:  # pragma: no cover - scipy is a test dependency only
        SR = ()
    if not isinstance(other, SR):
        raise TypeError(f"Expected `other` to be a Rotation, got {type(other).__name__}.")
    q = np.asarray(other.as_quat(scalar_first=True))
    return Rotation._from_house(q, q.ndim == 1)


def _floats(x, name):
    """`x` as a C-contiguous float32/float64 ndarray (the lean paths hand it to the
    serial kernels as it is): the arrays the class holds pass as they are."""
    if type(x) is np.ndarray and (x.dtype is _F64 or x.dtype is _F32) and x.flags.c_contiguous:
        return x
    try:
        a = as_float(x, name)
    except TypeError as exc:  # scipy: a ValueError for values that are not real numbers
        raise ValueError(str(exc)) from None
    return a if a.flags.c_contiguous else np.ascontiguousarray(a)


def _shape_check(a, name, core, text):
    if a.ndim < len(core) or a.shape[a.ndim - len(core):] != core:
        raise ValueError(f"Expected `{name}` to have shape {text}, got {a.shape}.")
    return a


def _check_seq(seq, three):
    """scipy's checks (and messages) of an Euler sequence that is not one of the valid
    ones: 1 to 3 axes (exactly 3 when `three`), one case, no axis twice in a row."""
    n = len(seq)  # (a TypeError for a non-sequence, as scipy)
    if three and n != 3:
        raise ValueError(f"Expected 3 axes, got {seq}.")
    if not 1 <= n <= 3:
        raise ValueError(f"Expected axis specification to be a non-empty string of upto 3 characters, got {seq}")
    if not isinstance(seq, str):  # scipy: a TypeError (its pattern match of a non-string)
        raise TypeError(f"Expected `seq` to be a string, got {type(seq).__name__} {seq!r}.")
    if not (set(seq) <= set("xyz") or set(seq) <= set("XYZ")):
        raise ValueError(f"Expected axes from `seq` to be from ['x', 'y', 'z'] or ['X', 'Y', 'Z'], got {seq}")
    if any(seq[i] == seq[i + 1] for i in range(n - 1)):
        raise ValueError(f"Expected consecutive axes to be different, got {seq}")


def _int_dim(n, name):
    """A size argument (`num`) as scipy reads it: integers, and floats of integer value."""
    if isinstance(n, (float, np.floating)) and float(n).is_integer():
        return int(n)
    try:
        return operator.index(n)
    except TypeError:
        raise TypeError(f"Expected `{name}` to be an integer, got {type(n).__name__} {n!r}.") from None


def _lead_shape(num, shape):
    if num is not None and shape is not None:
        raise ValueError("Only one of `num` or `shape` can be specified.")
    if num is not None:
        return (_int_dim(num, "num"),)
    if shape is None:
        return ()
    if isinstance(shape, (int, np.integer)) and not isinstance(shape, bool):
        return (int(shape),)
    if isinstance(shape, tuple):
        try:
            return tuple(operator.index(k) for k in shape)
        except TypeError:  # scipy: a TypeError for a float in the tuple
            raise TypeError(f"Expected `shape` to be a tuple of integers, got {shape!r}.") from None
    raise ValueError(f"`shape` must be an int or a tuple of ints, got {shape!r}.")


class Rotation:
    """Rotations in 3 dimensions, with the public API of scipy 1.17's
    ``scipy.spatial.transform.Rotation``: switch by the import line,
    ``from quatarray import Rotation``.

    Every constructor and converter of scipy's class is here (quaternions
    scalar-last by default, matrices, rotation vectors, modified Rodrigues
    parameters, Euler and Davenport angles), with application to vectors,
    composition ``*``, powers ``**``, inversion, magnitude, means, reduction
    by symmetry groups, alignment of vector sets, N-dimensional stacks with
    broadcasting, indexing, iteration, pickling and ``repr``, giving the same
    numbers (within 1e-12) and raising the same exception types.

    One storage, two faces: a ``Rotation`` holds one house array of shape
    ``(..., 4)`` in (w, x, y, z) order, which every method hands to
    quatarray's batched kernels. :attr:`wxyz` gives that array and
    :meth:`from_wxyz` wraps one, both without copying, so code can mix the
    object and the functional style (``quatarray.rotate(r.wxyz, v)``).

    Beyond scipy: float32 in stays float32 (scipy computes in float64), and
    the ``wxyz``/``from_wxyz`` pair.

    Differences from scipy 1.17, all where scipy's answer is an accident:

    - a tuple index ``r[i, j]`` indexes the stack as numpy does (scipy reads
      the tuple as a list of first-axis indices), and an ``Ellipsis`` may be
      part of an index;
    - ``reduce``: where several members l·p·r have the same smallest angle
      (groups sharing members), the first in the order of `left`, then
      `right`, is taken; scipy's pick among them follows its rounding;
    - ``as_davenport`` with the first axis equal to the third gives the angle
      set of ``as_euler`` (middle angle ≥ 0); scipy picks either set by the
      sign of rounding noise;
    - a non-Rotation argument of ``approx_equal`` or ``reduce`` raises
      ``TypeError`` (scipy: ``AttributeError``); error messages name the
      problem in scipy's words, sometimes with more detail;
    - inputs scipy 1.17 fails on by accident work: read-only arrays, N-D and
      empty stacks in ``reduce``, lists of numpy integers as indices, ``mean``
      weights that broadcast to a 1-D stack (as scipy documents; its 1-D path
      wants one per rotation), quaternions, matrices and vectors of extreme
      scale (scaled before squaring); a nan matrix gives nan rotations
      (scipy: ``LinAlgError``), and so does ``align_vectors`` with nan;
    - complex angles or exponents and a fractional ``num`` raise (scipy drops
      the imaginary part, truncates ``num``);
    - ``Rotation(quat, normalize=False, copy=False)`` holds `quat` itself only
      for scalar-first input (the storage is (w, x, y, z)); scipy holds it only
      for scalar-last input.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import Rotation as R
    >>> r = R.from_quat([0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)])
    >>> np.round(r.apply([1, 0, 0]), 12) + 0.0
    array([0., 1., 0.])
    >>> r.as_euler("zyx", degrees=True).round(12) + 0.0
    array([90.,  0.,  0.])
    >>> (r * r).as_rotvec().round(8) + 0.0
    array([0.        , 0.        , 3.14159265])
    """

    __slots__ = ("_q", "_single", "__weakref__")  # weak references, as to scipy's

    def __init__(self, quat, normalize=True, copy=True, scalar_first=False):
        """From quaternions (scalar-last unless `scalar_first`), as scipy's
        ``Rotation(quat, normalize, copy, scalar_first)``; the ``from_...``
        constructors are the documented way.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation([0, 0, 0, 2]).as_quat()
        array([0., 0., 0., 1.])
        """
        a = _shape_check(_floats(quat, "quat"), "quat", _Q, "(..., 4)")
        if normalize:
            q = _house_in(a, bool(scalar_first), "quat")
        elif scalar_first:
            q = a.copy() if copy else a
        else:
            q = _lay.from_xyzw(a)
        self._q = q
        self._single = q.ndim == 1

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
            Copy the array first (default False: the object holds `a` itself,
            and ``__setitem__`` writes into it).
        normalize : bool, optional
            Divide by the norms (a new array; a zero or nan quaternion raises
            ``ValueError``). Without it the quaternions are taken as they are,
            to be unit.

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
        q = check_core(as_float(a, "a"), "a", _Q)
        if normalize:
            q = _house_in(q, True, "a")
        elif copy:
            q = q.copy()
        return cls._from_house(q, q.ndim == 1)

    @property
    def wxyz(self):
        """The stored ``(..., 4)`` (w, x, y, z) array itself (``(4,)`` for a single
        rotation), no copy: hand it to quatarray's functions.

        Examples
        --------
        >>> import quatarray as qa
        >>> r = qa.Rotation.identity(2)
        >>> r.wxyz
        array([[1., 0., 0., 0.],
               [1., 0., 0., 0.]])
        >>> qa.rotate(r.wxyz, [1, 2, 3])
        array([[1., 2., 3.],
               [1., 2., 3.]])
        """
        return self._q

    @property
    def _quat(self):
        """scipy's internal array (x, y, z, w), ``(1, 4)`` for a single rotation: a
        copy, for code written against scipy's internals (read only).

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.identity()._quat
        array([[0., 0., 0., 1.]])
        """
        q = self.as_quat()
        return q[None] if self._single else q

    # ------------------------------------------------------------------
    # shape, indexing, iteration

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
        """Always True (also for an empty stack), as in scipy.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> bool(Rotation.identity(0))
        True
        """
        return True

    def __getitem__(self, indexer):
        """The rotations at `indexer` along the leading axes (a copy), numpy's rules:
        an integer of a 1-D stack gives a single rotation.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> r = Rotation.from_euler("z", [[0], [90], [180]], degrees=True)
        >>> r[1].as_euler("xyz", degrees=True).round(9) + 0.0
        array([ 0.,  0., 90.])
        >>> r[1:].shape, r[[0, 2]].shape
        ((2,), (2,))
        """
        if self._single:
            raise TypeError("Single rotation is not subscriptable.")
        q = self._q
        if isinstance(indexer, np.ndarray) and indexer.dtype.kind in "iu" and q.shape[0] == 0:
            raise IndexError("cannot do a non-empty take from an empty axes.")
        key = (indexer if isinstance(indexer, tuple) else (indexer,)) + (slice(None),)
        sub = q[key]
        if sub.base is not None:
            sub = sub.copy()
        return Rotation._from_house(sub, sub.ndim == 1)

    def __setitem__(self, indexer, value):
        """Set the rotations at `indexer` (numpy's rules) to those of the Rotation `value`.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> r = Rotation.identity(3)
        >>> r[1] = Rotation.from_rotvec([0, 0, 1.0])
        >>> r.magnitude()
        array([0., 1., 0.])
        """
        if self._single:
            raise TypeError("Single rotation is not subscriptable.")
        if not isinstance(value, Rotation):
            raise TypeError("value must be a Rotation object")
        if not self._q.flags.writeable:
            self._q = self._q.copy()
        key = (indexer if isinstance(indexer, tuple) else (indexer,)) + (slice(None),)
        self._q[key] = value._q

    def __iter__(self):
        """The rotations along the first axis (views of the stack).

        Examples
        --------
        >>> from quatarray import Rotation
        >>> [r.single for r in Rotation.identity(2)]
        [True, True]
        """
        if self._single:
            raise TypeError("Single rotation is not iterable.")
        q = self._q
        for i in range(q.shape[0]):
            sub = q[i]
            yield Rotation._from_house(sub, sub.ndim == 1)

    def __getstate__(self):
        """The stored array and the `single` flag (pickling, ``copy``).

        Examples
        --------
        >>> import pickle
        >>> from quatarray import Rotation
        >>> pickle.loads(pickle.dumps(Rotation.identity(2))).shape
        (2,)
        """
        return (self._q, self._single)

    def __setstate__(self, state):
        """Restore from :meth:`__getstate__` (a copy of the array)."""
        q, single = state
        self._q = np.array(q, copy=True)
        self._single = bool(single)

    def __copy__(self):
        """A rotation holding a copy of the array (as scipy's copies do).

        Examples
        --------
        >>> import copy
        >>> from quatarray import Rotation
        >>> r = Rotation.identity(2)
        >>> copy.copy(r).wxyz is r.wxyz, copy.deepcopy(r).shape
        (False, (2,))
        """
        return Rotation._from_house(self._q.copy(), self._single)

    def __deepcopy__(self, memo):
        """As :meth:`__copy__` (the array holds no references)."""
        return Rotation._from_house(self._q.copy(), self._single)

    def __repr__(self):
        """scipy's: ``Rotation.from_matrix(...)`` with the matrices.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.identity()
        Rotation.from_matrix(array([[1., 0., 0.],
                                    [0., 1., 0.],
                                    [0., 0., 1.]]))
        """
        m = f"{self.as_matrix()!r}".splitlines()
        m[1:] = [" " * 21 + m[i] for i in range(1, len(m))]
        return "Rotation.from_matrix(" + "\n".join(m) + ")"

    # ------------------------------------------------------------------
    # quaternions

    @staticmethod
    def from_quat(quat, *, scalar_first=False):
        """Rotations from quaternions, normalised; scalar-last (x, y, z, w) by default.

        Parameters
        ----------
        quat : array_like, shape (..., 4)
            A ``(4,)`` quaternion gives a single rotation. A zero (or nan) one
            raises ``ValueError``.
        scalar_first : bool, optional
            The order (w, x, y, z) instead.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.from_quat([0, 0, 0, 2]).as_quat()
        array([0., 0., 0., 1.])
        >>> Rotation.from_quat([[1, 0, 0, 0]], scalar_first=True).shape
        (1,)
        """
        a = _floats(quat, "quat")
        if a.ndim == 0 or a.shape[-1] != 4:
            raise ValueError(f"Expected `quat` to have shape (..., 4), got {a.shape}.")
        if a.ndim == 1:  # the lean path of single rotations
            out = np.empty(4, a.dtype)
            if _quat_in.serial(a[None], bool(scalar_first), out[None]):
                out = _house_in(a, bool(scalar_first), "quat")
            r = object.__new__(Rotation)
            r._q = out
            r._single = True
            return r
        q = _house_in(a, bool(scalar_first), "quat")
        return Rotation._from_house(q, False)

    def as_quat(self, canonical=False, *, scalar_first=False):
        """The quaternions (a new array), scalar-last (x, y, z, w) by default.

        Parameters
        ----------
        canonical : bool, optional
            Choose the sign with w > 0 (ties: the first non-zero of x, y, z
            positive), as scipy.
        scalar_first : bool, optional
            The order (w, x, y, z) instead.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.from_quat([0, 0, 0, -1]).as_quat(canonical=True)
        array([0., 0., 0., 1.])
        >>> Rotation.identity().as_quat(scalar_first=True)
        array([1., 0., 0., 0.])
        """
        q = self._q
        out = np.empty(q.shape, q.dtype)
        if q.ndim == 1:
            _quat_out.serial(q[None], bool(scalar_first), bool(canonical), out[None])
        elif q.size:
            _quat_out(q.reshape(-1, 4), bool(scalar_first), bool(canonical), out.reshape(-1, 4))
        return out

    # ------------------------------------------------------------------
    # other parameterisations

    @staticmethod
    def from_matrix(matrix, *, assume_valid=False):
        """Rotations from rotation matrices, projected to the nearest rotation where
        they are not orthogonal (as scipy); a determinant ≤ 0 raises ``ValueError``.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> r = Rotation.from_matrix([[0, -1, 0], [1, 0, 0], [0, 0, 1]])
        >>> r.as_quat().round(8)
        array([0.        , 0.        , 0.70710678, 0.70710678])
        """
        m = _shape_check(_floats(matrix, "matrix"), "matrix", (3, 3), "(..., 3, 3)")
        try:
            q = _conv.from_matrix(m, assume_valid=bool(assume_valid))
        except ValueError:
            flat = m.reshape(-1, 3, 3)
            k = int(np.argmax(~(np.linalg.det(flat) > 0)))
            raise ValueError(
                "Non-positive determinant (left-handed or null coordinate frame) in rotation "
                f"matrix {k}: {flat[k]}."
            ) from None
        return Rotation._from_house(q, q.ndim == 1)

    def as_matrix(self):
        """The rotation matrices, shape ``(..., 3, 3)``.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.from_rotvec([0, 0, 3.141592653589793]).as_matrix().round(12) + 0.0
        array([[-1.,  0.,  0.],
               [ 0., -1.,  0.],
               [ 0.,  0.,  1.]])
        """
        return _map(_conv._as_matrix, self._q, _Q, (3, 3))

    @staticmethod
    def from_rotvec(rotvec, degrees=False):
        """Rotations from rotation vectors (angle × axis).

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.from_rotvec([0, 0, 90], degrees=True).as_quat().round(8)
        array([0.        , 0.        , 0.70710678, 0.70710678])
        """
        v = _shape_check(_floats(rotvec, "rotvec"), "rot_vec", (3,), "(..., 3)")
        if degrees:
            v = v * _RAD
        q = _map(_conv._from_rotvec, v, (3,), _Q)
        return Rotation._from_house(q, q.ndim == 1)

    def as_rotvec(self, degrees=False):
        """Rotation vectors, angle in [0, π] (or degrees).

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.from_euler("x", 30, degrees=True).as_rotvec(degrees=True).round(9) + 0.0
        array([30.,  0.,  0.])
        """
        res = _map(_conv._as_rotvec, self._q, _Q, (3,))
        if degrees:
            res *= _DEG
        return res

    @staticmethod
    def from_mrp(mrp):
        """Rotations from modified Rodrigues parameters.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.from_mrp([0, 0, 1]).as_rotvec().round(8) + 0.0
        array([0.        , 0.        , 3.14159265])
        """
        p = _shape_check(_floats(mrp, "mrp"), "mrp", (3,), "(..., 3)")
        q = _map(_conv._from_mrp, p, (3,), _Q)
        return Rotation._from_house(q, q.ndim == 1)

    def as_mrp(self):
        """Modified Rodrigues parameters (the shorter one, norm ≤ 1).

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.from_rotvec([0, 0, 3.141592653589793]).as_mrp().round(12) + 0.0
        array([0., 0., 1.])
        """
        return _map(_conv._as_mrp, self._q, _Q, (3,))

    @staticmethod
    def from_euler(seq, angles, degrees=False):
        """Rotations from Euler angles: 1 to 3 axes, ``"xyz"`` extrinsic, ``"XYZ"`` intrinsic.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.from_euler("zyx", [90, 0, 0], degrees=True).as_quat().round(8)
        array([0.        , 0.        , 0.70710678, 0.70710678])
        >>> Rotation.from_euler("z", [[10], [20]], degrees=True).shape
        (2,)
        """
        a = _floats(angles, "angles")
        if type(seq) is str and len(seq) == 3 and a.shape == (3,):  # the lean path of single rotations
            params = _eul._SEQS.get(seq)
            if params is not None:
                axes, intrinsic, _ = params
                out = np.empty((1, 4), a.dtype)
                far = np.empty(1, np.bool_)
                args = (a.reshape(1, 3), axes[0], axes[1], axes[2], intrinsic, _RAD if degrees else 1.0, out, far)
                _eul._from_euler.serial(*args)
                if far[0]:
                    _eul._from_euler_far.serial(*args)
                return Rotation._from_house(out[0], True)
        if type(seq) is not str or seq not in _eul._SEQS:
            _check_seq(seq, False)
        k = len(seq)
        if (a.shape[-1] if a.ndim else 1) != k:
            got = a.shape[-1] if a.ndim else 1
            raise ValueError(
                f"Expected last dimension of `angles` to match number of sequence axes specified, got {got}."
            )
        q = _eul.from_euler(seq, a, degrees=bool(degrees))
        return Rotation._from_house(q, q.ndim == 1)

    def as_euler(self, seq, degrees=False, *, suppress_warnings=False):
        """Euler angles for a three-axis `seq` (scipy's ranges and gimbal-lock rule).

        Examples
        --------
        >>> from quatarray import Rotation
        >>> r = Rotation.from_euler("ZXZ", [10, 20, 30], degrees=True)
        >>> r.as_euler("ZXZ", degrees=True).round(9)
        array([10., 20., 30.])
        """
        q = self._q
        if q.ndim == 1 and type(seq) is str:  # the lean path of single rotations
            params = _eul._SEQS.get(seq)
            if params is not None:
                lo, hi = _eul._NEAR[q.dtype]
                out = np.empty((1, 3), q.dtype)
                flags = np.empty(1, np.uint8)
                nl, nf = _eul._as_euler.serial(q[None], *params[2], _DEG if degrees else 1.0, lo, hi, out, flags)
                if not nf:
                    if nl and not suppress_warnings:
                        warnings.warn(_eul._GIMBAL.format(n=1, total=1), UserWarning, stacklevel=2)
                    return out[0]
        if type(seq) is not str or seq not in _eul._SEQS:
            _check_seq(seq, True)
        return _eul.as_euler(q, seq, degrees=bool(degrees), suppress_warnings=bool(suppress_warnings))

    @staticmethod
    def from_davenport(axes, order, angles, degrees=False):
        """Rotations from Davenport angles about 1 to 3 axes, each orthogonal to the next.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> axes = [[0, 0, 1], [1, 0, 0]]
        >>> r = Rotation.from_davenport(axes, "extrinsic", [90, 45], degrees=True)
        >>> r.as_euler("zxy", degrees=True).round(9) + 0.0
        array([90., 45.,  0.])
        """
        q = _dav.from_davenport(_floats(axes, "axes"), order, _floats(angles, "angles"), degrees=bool(degrees))
        return Rotation._from_house(q, q.ndim == 1)

    def as_davenport(self, axes, order, degrees=False, *, suppress_warnings=False):
        """Davenport angles about three axes (the second orthogonal to the others).

        Examples
        --------
        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> axes = np.array([[1, 1, 0], [-1, 1, 0], [0, 0, np.sqrt(2)]]) / np.sqrt(2)
        >>> r = Rotation.from_davenport(axes, "i", [10, 20, 30], degrees=True)
        >>> r.as_davenport(axes, "i", degrees=True).round(9)
        array([10., 20., 30.])
        """
        q = self._q if not self._single else self._q[None]
        ax = _floats(axes, "axes")
        if ax.dtype != q.dtype:  # float32 rotations give float32 angles
            ax = ax.astype(q.dtype)
        small = ax.shape == (3, 3) and ax.dtype == q.dtype and q.ndim == 2 and len(q) <= 64
        if small and isinstance(order, str) and order in _ORDERS:  # a few rotations: no front end
            ax = (ax / np.sqrt((ax * ax).sum(axis=1))[:, None]).astype(q.dtype, copy=False)
            if not ((ax[0] @ ax[1]) < 1e-7 and (ax[1] @ ax[2]) < 1e-7):
                _dav._check_orthogonal(ax, signed=True)
            out = np.empty((len(q), 3), q.dtype)
            locked = np.zeros(len(q), np.bool_)
            axr = np.broadcast_to(ax, (len(q), 3, 3))
            _dav._as_davenport.serial(q, axr, _ORDERS[order], q.dtype.type(_DEG if degrees else 1.0), out, locked)
            n = int(locked.sum())
            if n and not suppress_warnings:
                warnings.warn(_dav._GIMBAL.format(n=n, total=len(q)), UserWarning, stacklevel=2)
            res = out
        else:
            res = _dav.as_davenport(q, ax, order, degrees=bool(degrees), suppress_warnings=bool(suppress_warnings))
        return res[0] if self._single and res.ndim == 2 and res.shape[0] == 1 else res

    # ------------------------------------------------------------------
    # operations

    def apply(self, vectors, inverse=False):
        """Rotate vectors (``inverse=True``: by the inverse rotations). Leading
        dimensions broadcast (a single rotation has none).

        Examples
        --------
        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> r = Rotation.from_rotvec([0, 0, np.pi / 2])
        >>> np.round(r.apply([1, 0, 0]), 12) + 0.0
        array([0., 1., 0.])
        >>> np.round(r.apply([[1, 0, 0], [0, 1, 0]], inverse=True), 12) + 0.0
        array([[ 0., -1.,  0.],
               [ 1.,  0.,  0.]])
        """
        q = self._q
        v = _floats(vectors, "vectors")
        if v.ndim == 0 or v.shape[-1] != 3:
            raise ValueError(f"Expected input of shape (..., 3), got {v.shape}.")
        if q.ndim == 1 and v.ndim == 1 and v.dtype is q.dtype:  # the lean path
            out = np.empty(3, q.dtype)
            (_rotate_inv if inverse else _vec._rotate_one).serial(*((q[None], v[None]) if inverse else (v[None], q[None])), out[None])
            return out
        ql, vl = q.shape[:-1], v.shape[:-1]
        if ql == vl and v.dtype is q.dtype:
            out = np.empty(v.shape, q.dtype)
            if v.size:
                qf, vf, of = q.reshape(-1, 4), v.reshape(-1, 3), out.reshape(-1, 3)
                if inverse:
                    _rotate_inv(qf, vf, of)
                else:
                    _vec._rotate(qf, vf, of)
            return out
        if ql != vl:
            try:
                np.broadcast_shapes(ql, vl)
            except ValueError:
                n = ql if len(ql) != 1 else ql[0]
                m = vl if len(vl) != 1 else vl[0]
                raise ValueError(f"Cannot broadcast {n} rotations to {m} vectors.") from None
        if inverse:
            return elementwise(_rotate_inv, [(q, "rotations", _Q), (v, "vectors", (3,))], [(3,)])
        return _vec.rotate(q, v)

    def __mul__(self, other):
        """Composition ``self * other``: `other` applied first (leading dimensions broadcast).

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
        p, q = self._q, other._q
        if p.ndim == 1 and q.ndim == 1 and p.dtype is q.dtype:  # the lean path
            out = np.empty(4, p.dtype)
            _compose.serial(p[None], q[None], out[None])
            return Rotation._from_house(out, self._single and other._single)
        if p.shape == q.shape and p.dtype is q.dtype:
            out = np.empty(p.shape, p.dtype)
            if p.size:
                _compose(p.reshape(-1, 4), q.reshape(-1, 4), out.reshape(-1, 4))
            return Rotation._from_house(out, self._single and other._single)
        pl, ql = p.shape[:-1] or (1,), q.shape[:-1] or (1,)
        if pl != ql:
            try:
                np.broadcast_shapes(pl, ql)
            except ValueError:
                raise ValueError(
                    f"Cannot broadcast {pl} rotations in first to {ql} rotations in second object."
                ) from None
        out = elementwise(_compose, [(p, "first", _Q), (q, "second", _Q)], [_Q])
        return Rotation._from_house(out, self._single and other._single)

    def __pow__(self, n, modulus=None):
        """The rotations composed with themselves `n` times (any real `n`: the angle
        times `n` about the same axis), as scipy.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> (Rotation.from_rotvec([0, 0, 0.5]) ** 3).as_rotvec().round(12) + 0.0
        array([0. , 0. , 1.5])
        """
        if modulus is not None:
            raise NotImplementedError("modulus not supported")
        if isinstance(n, np.ndarray):
            if n.shape == (1,):
                n = n[0]
            elif n.ndim != 0:
                raise ValueError("Array exponent must be a scalar")
        q = self._q
        if n == 0:
            out = np.zeros(q.shape, q.dtype)
            out[..., 0] = 1
        elif n == -1:
            out = q * _CONJ[q.dtype]
        elif n == 1:
            out = q.copy()
        else:
            rv = n * _map(_conv._as_rotvec, q, _Q, (3,))
            out = _map(_conv._from_rotvec, _floats(rv, "n"), (3,), _Q)
        return Rotation._from_house(out, self._single)

    def inv(self):
        """The inverse rotations.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.from_rotvec([0, 0, 0.5]).inv().as_rotvec().round(12) + 0.0
        array([ 0. ,  0. , -0.5])
        """
        q = self._q
        if q.ndim == 1:
            return Rotation._from_house(q * _CONJ[q.dtype], self._single)
        return Rotation._from_house(_map(_alg._conjugate, q, _Q, _Q), False)

    def magnitude(self):
        """The rotation angles in [0, π].

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.from_rotvec([[0, 0, 0.5], [3, 0, 0]]).magnitude()
        array([0.5, 3. ])
        """
        return _map(_alg._angle, self._q, _Q, ())

    def approx_equal(self, other, atol=None, degrees=False):
        """Whether the rotations equal those of `other` within `atol` (radians, or
        degrees; default 1e-8 rad), broadcasting; a boolean array (also ``(1,)``
        for two single rotations, as scipy).

        Examples
        --------
        >>> from quatarray import Rotation
        >>> r = Rotation.from_rotvec([0, 0, 0.5])
        >>> r.approx_equal(Rotation.from_rotvec([0, 0, 0.5 + 1e-10]))
        array([ True])
        """
        if not isinstance(other, Rotation):
            other = _from_scipy(other)  # scipy's Rotation compares too (``tf.rotation`` against scipy's)
        atol = _alg.approx_atol(atol, degrees)
        p = self._q if self._q.ndim > 1 else self._q[None]
        q = other._q if other._q.ndim > 1 else other._q[None]
        try:
            np.broadcast_shapes(p.shape[:-1], q.shape[:-1])
        except ValueError:
            raise ValueError(
                f"Expected broadcastable shapes in both rotations, got {p.shape[:-1]} rotations in first "
                f"and {q.shape[:-1]} rotations in second object."
            ) from None
        if p.shape == q.shape and p.dtype is q.dtype:  # the kernel on the rows, no front end
            d = np.empty(p.shape[:-1], p.dtype)
            if p.size:
                pf, qf, df = p.reshape(-1, 4), q.reshape(-1, 4), d.reshape(-1)
                if _alg._distance.first.serial(pf, qf, df) if len(pf) == 1 else _alg._distance.first(pf, qf, df):
                    _alg._distance.again(pf, qf, df)
            return np.less(d, atol)
        return np.less(_alg.distance(p, q), atol)

    def mean(self, weights=None, axis=None):
        """The mean rotation (scipy's: the principal eigenvector of Σ wᵢ qᵢqᵢᵀ) over
        the leading axes `axis` (None: all).

        Examples
        --------
        >>> from quatarray import Rotation
        >>> r = Rotation.from_rotvec([[0, 0, 0.1], [0, 0, 0.3]])
        >>> r.mean().as_rotvec().round(12) + 0.0
        array([0. , 0. , 0.2])
        """
        q = self._q if self._q.ndim > 1 else self._q[None]
        if q.size == 0:
            raise ValueError("Mean of an empty rotation set is undefined.")
        if axis is not None:
            if isinstance(axis, (int, np.integer)) and not isinstance(axis, bool):
                axis = (int(axis),)
            if not isinstance(axis, tuple) or not all(isinstance(k, (int, np.integer)) for k in axis):
                raise ValueError("`axis` must be None, int, or tuple of ints.")
            nlead = q.ndim - 1
            if axis and (min(axis) < -nlead or max(axis) > nlead - 1):
                raise ValueError(f"axis {axis} is out of bounds for rotation with shape {q.shape[:-1]}.")
        if weights is None and axis is None and q.ndim == 2 and len(q) <= 64 and np.isfinite(q).all():
            x = q[:, _XYZW].astype(np.float64)  # a few rotations: the sum by one product
            k = (x.T @ x)[None]
            lead, dtype = (), q.dtype
        else:
            a, w, red = _alg.mean_inputs(q, weights, axis)
            acc = _alg.mean_sums(a, w, red, unit=True)
            lead, dtype = acc.shape[:-2], q.dtype
            k = acc.reshape(-1, 4, 4)[:, _XYZW][:, :, _XYZW]  # scipy's order, so that eigh picks scipy's sign
        v = np.linalg.eigh(k)[1][..., -1]
        out = np.ascontiguousarray(v[:, _WXYZ], dtype=dtype).reshape(lead + _Q)
        return Rotation._from_house(out, out.ndim == 1)

    def reduce(self, left=None, right=None, return_indices=False):
        """Each rotation reduced by the symmetry groups `left` and `right`: the member
        l·p·r of smallest angle (see :func:`quatarray.reduce`).

        Examples
        --------
        >>> from quatarray import Rotation
        >>> g = Rotation.create_group("C4")
        >>> p = Rotation.from_euler("z", 100, degrees=True)
        >>> red, i, j = p.reduce(left=g, return_indices=True)
        >>> red.as_euler("xyz", degrees=True).round(9) + 0.0, i, j
        (array([ 0.,  0., 10.]), array([3]), None)
        """
        if left is None and right is None:
            r = Rotation._from_house(self._q.copy(), self._single)
            return (r, None, None) if return_indices else r
        for g, name in ((left, "left"), (right, "right")):
            if g is not None and not isinstance(g, Rotation):
                raise TypeError(f"Expected `{name}` to be a Rotation, got {type(g).__name__}.")
        q = self._q if self._q.ndim > 1 else self._q[None]
        # the groups in the rotations' dtype: float32 stays float32
        red, li, ri = _sym.reduce(q, *(None if g is None else g._q.astype(q.dtype, copy=False) for g in (left, right)))
        if self._single:
            red = red[0]
        r = Rotation._from_house(red, self._single)
        if return_indices:
            return r, (li if left is not None else None), (ri if right is not None else None)
        return r

    @classmethod
    def create_group(cls, group, axis="Z"):
        """A finite symmetry group: ``"I"``, ``"O"``, ``"T"``, ``"Dn"`` or ``"Cn"``
        (see :func:`quatarray.create_group`).

        Examples
        --------
        >>> from quatarray import Rotation
        >>> len(Rotation.create_group("I")), len(Rotation.create_group("D3", axis="x"))
        (60, 6)
        """
        return cls._from_house(_sym.create_group(group, axis), False)

    @staticmethod
    def concatenate(rotations):
        """One stack of the rotations of a Rotation or a sequence of them, along the
        first axis (a single rotation counts as a stack of one).

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.concatenate([Rotation.identity(), Rotation.identity(2)]).shape
        (3,)
        """
        if isinstance(rotations, Rotation):
            return Rotation._from_house(rotations._q.copy(), rotations._single)
        rotations = list(rotations)
        if not all(isinstance(x, Rotation) for x in rotations):
            raise TypeError("input must contain Rotation objects only")
        if not rotations:
            raise IndexError("Expected at least one Rotation to concatenate, got none.")
        q = np.concatenate([x._q if x._q.ndim > 1 else x._q[None] for x in rotations])
        return Rotation._from_house(q, False)

    @staticmethod
    def identity(num=None, *, shape=None):
        """Identity rotations: a single one (by default), `num` of them or a stack of `shape`.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.identity().as_quat()
        array([0., 0., 0., 1.])
        >>> Rotation.identity(shape=(2, 3)).shape
        (2, 3)
        """
        lead = _lead_shape(num, shape)
        q = np.zeros(lead + _Q)
        q[..., 0] = 1.0
        return Rotation._from_house(q, q.ndim == 1)

    @staticmethod
    def random(num=None, *legacy, rng=None, shape=None, random_state=None):
        """Uniformly distributed rotations, the same draws as scipy's for the same seed.

        As scipy 1.17 (its transition from ``random_state`` to ``rng``): a seed
        given by position, ``random(num, seed)``, or as ``random_state=`` seeds a
        legacy ``RandomState`` (a ``Generator`` or ``RandomState`` given so is
        used as it is); ``rng=`` by keyword goes through ``default_rng`` (a
        ``RandomState`` there becomes a ``Generator`` on its bit generator).

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.random(3, rng=0).shape, Rotation.random(rng=0).single
        ((3,), True)
        """
        if len(legacy) > 1:
            raise TypeError(f"random() takes from 0 to 2 positional arguments but {1 + len(legacy)} were given")
        seeds = [x for x in (legacy[0] if legacy else None, random_state) if x is not None]
        if len(seeds) + (rng is not None) > 1:
            raise TypeError("Expected only one of `rng` and `random_state`.")
        old = bool(legacy) or random_state is not None
        seed = seeds[0] if seeds else rng
        lead = _lead_shape(num, shape)
        if not old:  # `rng=` by keyword: scipy normalises it with default_rng (a RandomState
            gen = np.random.default_rng(seed)  # becomes a Generator on its bit generator)
        elif isinstance(seed, (np.random.Generator, np.random.RandomState)):
            gen = seed
        else:
            gen = np.random.mtrand._rand if seed is None else np.random.RandomState(seed)
        sample = gen.normal(size=lead + _Q)
        return Rotation._from_house(_house_in(sample, False, "quat"), sample.ndim == 1)

    @staticmethod
    def align_vectors(a, b, weights=None, return_sensitivity=False):
        """The rotation that best maps the vectors `b` onto `a` (least squares with
        `weights`), its rssd and, if asked, the sensitivity matrix, as scipy.

        Examples
        --------
        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> a = [[0, 1, 0], [0, 0, 1]]
        >>> b = [[1, 0, 0], [0, 0, 1]]
        >>> r, rssd = Rotation.align_vectors(a, b)
        >>> r.as_euler("xyz", degrees=True).round(6) + 0.0, round(float(rssd), 9)
        (array([ 0.,  0., 90.]), 0.0)
        """
        a0, b0 = _floats(a, "a"), _floats(b, "b")
        a2, b2 = np.atleast_2d(a0), np.atleast_2d(b0)
        if a2.shape[-1] != 3:
            raise ValueError(f"Expected input `a` to have shape (3,) or (N, 3), got {a0.shape}")
        if b2.shape[-1] != 3:
            raise ValueError(f"Expected input `b` to have shape (3,) or (N, 3), got {b0.shape}")
        if a2.shape != b2.shape:
            raise ValueError(
                f"Expected inputs `a` and `b` to have same shapes, got {a0.shape} and {b0.shape} respectively."
            )
        if a2.ndim > 2:
            raise ValueError(
                f"Expected inputs `a` and `b` to have shape (3,) or (N, 3), got {a0.shape} and {b0.shape} respectively."
            )
        n = a2.shape[0]
        if weights is not None:
            w = _floats(weights, "weights")
            if w.ndim != 1:
                raise ValueError(f"Expected `weights` to be 1 dimensional, got shape {w.shape}.")
            if n >= 1 and w.shape[0] != n:  # scipy: also for one pair (its matmul's error)
                raise ValueError(
                    "Expected `weights` to have number of values equal to number of input vectors, "
                    f"got {w.shape[0]} values and {n} vectors."
                )
            if np.any(w < 0):
                raise ValueError("`weights` may not contain negative values")
            weights = w
        inf = np.isinf(weights) if weights is not None else np.zeros(n, bool)
        if inf.sum() > 1:
            raise ValueError("Only one infinite weight is allowed")
        if (n == 1 or inf.any()) and return_sensitivity:
            raise ValueError("Cannot return sensitivity matrix with an infinite weight or one vector pair")
        if n == 1 or inf.any():
            k = int(np.argmax(inf)) if inf.any() else 0
            if not (np.any(a2[k] != 0) and np.any(b2[k] != 0)):
                raise ValueError("Cannot align zero length primary vectors")
        with np.errstate(invalid="ignore"):  # nan sensitivity of degenerate sets: silent, as scipy
            res = _align.align_vectors(a2, b2, weights, bool(return_sensitivity))
        r = Rotation._from_house(res[0], True)
        return (r,) + tuple(res[1:])


def _scipy_random_signature():
    """``random``'s signature as scipy shows it: (num=None, rng=None, *, shape=None,
    random_state=None); the implementation takes ``rng`` by position apart (scipy's
    transition from ``random_state``: a positional seed is a legacy one)."""
    P = inspect.Parameter
    return inspect.Signature([
        P("num", P.POSITIONAL_OR_KEYWORD, default=None), P("rng", P.POSITIONAL_OR_KEYWORD, default=None),
        P("shape", P.KEYWORD_ONLY, default=None), P("random_state", P.KEYWORD_ONLY, default=None),
    ])


Rotation.__dict__["random"].__func__.__signature__ = _scipy_random_signature()

_DEG = 180.0 / math.pi
_RAD = math.pi / 180.0
_CONJ = {d: np.array([1, -1, -1, -1], d) for d in _FLOATS}
_XYZW = [1, 2, 3, 0]
_ORDERS = {"e": True, "extrinsic": True, "i": False, "intrinsic": False}
_WXYZ = [3, 0, 1, 2]
