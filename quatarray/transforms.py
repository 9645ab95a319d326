"""VQS and VQM transforms: translation, rotation and scale as one batched group.

After "The VQM-Group and its Applications". A VQS transform ``[v, q, s]`` maps
a point r to q (s r) q⁻¹ + v; a VQM transform ``[v, q, M]`` replaces the
uniform scale s by a 3×3 matrix M (non-uniform scale, shear), r ↦ q (M r) q⁻¹ + v.

Containers hold structure-of-arrays: ``v (..., 3)``, ``q (..., 4)`` in
(w, x, y, z) order, ``s (...)`` or ``M (..., 3, 3)``; the leading dimensions of
the parts broadcast like numpy and give the container's ``shape``. Containers
are immutable (their arrays are read-only); float32 stays float32.

q need not be unit: conjugation by any non-zero quaternion is a rotation, so
the rotation R(q) is what counts (a zero quaternion is rejected).

Composition follows the paper's product::

    [v_a, q_a, M_a] ∘ [v_b, q_b, M_b]
        = [q_a (M_a v_b) q_a⁻¹ + v_a,  q_a q_b,  R_bᵀ M_a R_b M_b]

where R_b = R(q_b) (the paper's (q_b⁻¹·M_a·q_b)(q_b·M_b·q_b⁻¹), with q·M·q⁻¹
rotating each column of M, i.e. R(q) M). For VQS, M = s I and the scale of
the composite is s_a s_b.
"""

import math

import numpy as np

from . import _elements as E
from ._jit import element, like, prange, prefer_no_gather, rowloop, select
from ._validate import as_float, check_core, elementwise, float_dtype, is_weak, result_dtype, where
from ._mat33 import cofactor33, det33, lerp9, matmul, matvec, scale9, transpose
from .conversions import from_matrix

_F64 = np.dtype(np.float64)
_F32 = np.dtype(np.float32)

# --------------------------------------------------------------------------
# per-element helpers; 3×3 matrices are row-major 9-tuples (quatarray._mat33)


@element
def _mat_inverse(m):
    """(M⁻¹, |det M| / (|r0| |r1| |r2|)) for rows r_k of M.

    The ratio is 1 for orthogonal rows and 0 for a singular M (Hadamard's
    bound), a scale-free measure of how close M is to singular.
    """
    det = det33(m)
    inv = scale9(transpose(cofactor33(m)), like(det, 1.0) / det)
    den = E.vnorm((m[0], m[1], m[2])) * E.vnorm((m[3], m[4], m[5])) * E.vnorm((m[6], m[7], m[8]))
    ratio = abs(det) / den
    ratio = select(den == like(den, 0.0), like(den, 0.0), ratio)  # a zero row: singular (not 0/0 = nan)
    return inv, ratio


# --------------------------------------------------------------------------
# batched loops


# The loops over |q|-dependent formulas (rowloop(far=...)) compute them on q as it is;
# a second kernel redoes the rare rows outside the range where that is exact,
# on the scaled q (E.qscaled), only when there are some. `out` may be `p` or `v`: the first
# pass leaves those rows holding the input that `out` is, for the second to read.


@element
def _apply_vqs_plain(i, args):
    v, q, s, p, out = args
    a = E.load4(q, i)
    x = E.load3(p, i)
    t = E.load3(v, i)
    n2 = E.qdot(a, a)
    f = E.far_scale(n2)
    keep_v = np.int32(out.ctypes.data == v.ctypes.data)  # int32 like f: one pick3 compiled
    E.store3(out, i, E.pick3(f, E.pick3(keep_v, t, x), E.vadd(E.qrotate_raw(a, E.vscale(x, s[i]), n2), t)))
    return f


@element
def _apply_vqs_scaled(i, args):
    v, q, s, p, out = args
    a = E.load4(q, i)
    if E.far_scale(E.qdot(a, a)):
        r = E.vscale(E.load3(p, i), s[i])
        E.store3(out, i, E.vadd(E.qrotate(a, r), E.load3(v, i)))


_apply_vqs = rowloop(_apply_vqs_plain, far=_apply_vqs_scaled)


@rowloop
def _apply_vqm(v, q, m, p, out):
    for i in prange(p.shape[0]):
        r = matvec(E.load33(m, i), E.load3(p, i))
        E.store3(out, i, E.vadd(E.qrotate(E.load4(q, i), r), E.load3(v, i)))


@rowloop(parallel=False)
def _apply_affine(p, a, t, out):
    # One transform, many points: the 3×3 linear part and translation are
    # computed once by the caller. Serial on purpose: 12 flops a point is
    # memory-bound, and one thread already streams at memory speed (the
    # threaded variant measured 2-4x slower, with two cores sharing one memory bus).
    a00, a01, a02 = a[0, 0], a[0, 1], a[0, 2]
    a10, a11, a12 = a[1, 0], a[1, 1], a[1, 2]
    a20, a21, a22 = a[2, 0], a[2, 1], a[2, 2]
    t0, t1, t2 = t[0], t[1], t[2]
    for i in prange(p.shape[0]):
        x, y, z = E.load3(p, i)
        E.store3(
            out,
            i,
            (
                a00 * x + a01 * y + a02 * z + t0,
                a10 * x + a11 * y + a12 * z + t1,
                a20 * x + a21 * y + a22 * z + t2,
            ),
        )


@rowloop
def _compose_vqs(va, qa, sa, vb, qb, sb, vo, qo, so):
    for i in prange(va.shape[0]):
        qa_ = E.load4(qa, i)
        s_a = sa[i]
        v = E.vadd(E.qrotate(qa_, E.vscale(E.load3(vb, i), s_a)), E.load3(va, i))
        q = E.qmul(qa_, E.load4(qb, i))
        s = s_a * sb[i]
        E.store3(vo, i, v)
        E.store4(qo, i, q)
        so[i] = s


@rowloop
def _compose_vqm(va, qa, ma, vb, qb, mb, vo, qo, mo):
    for i in prange(va.shape[0]):
        qa_ = E.load4(qa, i)
        qb_ = E.load4(qb, i)
        ma_ = E.load33(ma, i)
        rb = E.qmatrix(qb_)
        v = E.vadd(E.qrotate(qa_, matvec(ma_, E.load3(vb, i))), E.load3(va, i))
        q = E.qmul(qa_, qb_)
        m = matmul(transpose(rb), matmul(ma_, matmul(rb, E.load33(mb, i))))  # R_bᵀ M_a R_b M_b
        E.store3(vo, i, v)
        E.store4(qo, i, q)
        E.store33(mo, i, m)


@rowloop
def _inverse_vqs(v, q, s, vo, qo, so):
    for i in prange(v.shape[0]):
        q_ = E.load4(q, i)
        k = like(so, 1.0) / s[i]
        vi = E.qrotate(E.qconj(q_), E.load3(v, i))
        E.store3(vo, i, E.vscale(vi, -k))
        E.store4(qo, i, E.qinverse(q_))
        so[i] = k


@rowloop
def _inverse_vqm(v, q, m, vo, qo, mo, ratio):
    for i in prange(v.shape[0]):
        q_ = E.load4(q, i)
        r = E.qmatrix(q_)
        rt = transpose(r)
        inv, c = _mat_inverse(E.load33(m, i))
        # [v, q, M]⁻¹ = [−M⁻¹ Rᵀ v, q⁻¹, R M⁻¹ Rᵀ]
        vi = matvec(inv, matvec(rt, E.load3(v, i)))
        E.store3(vo, i, E.vscale(vi, like(c, -1.0)))
        E.store4(qo, i, E.qinverse(q_))
        E.store33(mo, i, matmul(r, matmul(inv, rt)))
        ratio[i] = c


@element(how="call")
def _store_homogeneous(out, i, a, v):
    zero = like(v[0], 0.0)
    out[i, 0, 0], out[i, 0, 1], out[i, 0, 2], out[i, 0, 3] = a[0], a[1], a[2], v[0]
    out[i, 1, 0], out[i, 1, 1], out[i, 1, 2], out[i, 1, 3] = a[3], a[4], a[5], v[1]
    out[i, 2, 0], out[i, 2, 1], out[i, 2, 2], out[i, 2, 3] = a[6], a[7], a[8], v[2]
    out[i, 3, 0], out[i, 3, 1], out[i, 3, 2], out[i, 3, 3] = zero, zero, zero, like(v[0], 1.0)


@rowloop
def _matrix_vqs(v, q, s, out):
    for i in prange(v.shape[0]):
        _store_homogeneous(out, i, scale9(E.qmatrix(E.load4(q, i)), s[i]), E.load3(v, i))


@rowloop
def _matrix_vqm(v, q, m, out):
    for i in prange(v.shape[0]):
        _store_homogeneous(out, i, matmul(E.qmatrix(E.load4(q, i)), E.load33(m, i)), E.load3(v, i))


@rowloop
def _lerp_vs(va, sa, vb, sb, t, vo, so):
    # v by lerp (exact at both ends), s by elerp s_a (s_b/s_a)^t = s_a^(1−t) s_b^t.
    for i in prange(va.shape[0]):
        prefer_no_gather()
        t_ = t[i]
        u = like(t_, 1.0) - t_
        E.store3(vo, i, E.vadd(E.vscale(E.load3(va, i), u), E.vscale(E.load3(vb, i), t_)))
        so[i] = sa[i] ** u * sb[i] ** t_


@rowloop
def _lerp_vm(va, ma, vb, mb, t, vo, mo):
    for i in prange(va.shape[0]):
        t_ = t[i]
        u = like(t_, 1.0) - t_
        E.store3(vo, i, E.vadd(E.vscale(E.load3(va, i), u), E.vscale(E.load3(vb, i), t_)))
        E.store33(mo, i, lerp9(E.load33(ma, i), E.load33(mb, i), u, t_))


# --------------------------------------------------------------------------
# helpers for the wrappers


def _shape_arg(n):
    if n is None:
        return ()
    if isinstance(n, (int, np.integer)):
        return (int(n),)
    return tuple(int(k) for k in n)


def _broadcast(shapes, what):
    try:
        return np.broadcast_shapes(*shapes)
    except ValueError:
        raise ValueError(f"Expected the shapes of {what} to broadcast, got {' and '.join(map(str, shapes))}.") from None


def _freeze(*arrays):
    for a in arrays:
        a.flags.writeable = False
    return arrays


def _default_rtol(dtype):
    return 1e-4 if dtype == _F32 else 1e-6


def _polar(m4, rtol):
    """Split homogeneous matrices into translation, rotation factor and symmetric factor.

    Returns ``lead, dtype, v (n,3), q (n,4), P (n,3,3), sig (n,3), reflected (n,), finite (n,)``
    where the linear part A = R(q) P with P symmetric. For a reflection
    (det A < 0), R(q) is the rotation nearest to A and P has one negative
    eigenvalue (on A's smallest singular direction).
    """
    m = as_float(m4, "m4")
    if m.ndim < 2 or m.shape[-1] != 4 or m.shape[-2] not in (3, 4):
        raise ValueError(f"Expected `m4` to have shape (..., 4, 4) or (..., 3, 4), got {m.shape}.")
    lead = m.shape[:-2]
    n = math.prod(lead)
    flat = m.reshape((n,) + m.shape[-2:])
    dtype = m.dtype
    tol = _default_rtol(dtype) if rtol is None else float(rtol)
    finite = np.isfinite(flat).all(axis=(1, 2))
    if m.shape[-2] == 4:
        bottom = flat[:, 3, :]
        bad = np.flatnonzero(finite & np.any(np.abs(bottom - np.array([0, 0, 0, 1], dtype)) > tol, axis=1))
        if bad.size:
            k = bad[0]
            raise ValueError(
                f"Expected `m4` to be affine with last row (0, 0, 0, 1); {where(k, lead)} "
                f"has {tuple(float(x) for x in bottom[k])}."
            )
    a = np.array(flat[:, :3, :3], dtype=dtype)
    a[~finite] = np.eye(3, dtype=dtype)
    w, sig, vt = np.linalg.svd(a)  # A = W Σ Vᵀ, σ descending
    # A reflection (det A < 0): A = (W D Vᵀ)(V D Σ Vᵀ) with D = diag(1, 1, −1),
    # so U = W D Vᵀ is the rotation nearest to A and P takes the sign on its
    # smallest singular direction.
    reflected = np.linalg.det(w) * np.linalg.det(vt) < 0
    w[reflected, :, 2] *= -1
    signed = sig.copy()
    signed[reflected, 2] *= -1
    u = w @ vt
    p = (np.swapaxes(vt, -1, -2) * signed[:, None, :]) @ vt
    p = 0.5 * (p + np.swapaxes(p, -1, -2))
    q = np.asarray(from_matrix(u, assume_valid=True), dtype=dtype)
    v = np.array(flat[:, :3, 3], dtype=dtype)
    if not finite.all():
        bad = ~finite
        q[bad] = np.nan
        p[bad] = np.nan
        sig[bad] = np.nan
        v[bad] = np.where(np.isfinite(v[bad]), np.nan, v[bad])
    return lead, dtype, v, q, p.astype(dtype, copy=False), sig, reflected, finite, tol


# --------------------------------------------------------------------------
# the containers


class _Transform:
    """Shared machinery of VQS and VQM (not public)."""

    __slots__ = ("_v", "_q", "_x")
    __array_ufunc__ = None  # numpy defers `array @ T` etc. to us (and we refuse)
    _field = ""
    _core = ()

    # -- construction ------------------------------------------------------

    def __init__(self, v=None, q=None, x=None, *, copy=True):
        name, core = self._field, self._core
        given = [(v, "v", (3,)), (q, "q", (4,)), (x, name, core)]
        arrays, weak = [], []
        for value, nm, c in given:
            if value is None:
                arrays.append(None)
                continue
            a = as_float(value, nm)
            check_core(a, nm, c)
            arrays.append(a)
            weak.append(is_weak(value))
        present = [a for a in arrays if a is not None]
        dtype = result_dtype(present, weak) if present else _F64
        if arrays[0] is None:
            arrays[0] = np.zeros(3, dtype)
        if arrays[1] is None:
            arrays[1] = np.array([1, 0, 0, 0], dtype)
        if arrays[2] is None:
            arrays[2] = np.eye(3, dtype=dtype) if core else np.ones((), dtype)
        cores = [(3,), (4,), core]
        leads = [a.shape[: a.ndim - len(c)] for a, c in zip(arrays, cores)]
        try:
            lead = np.broadcast_shapes(*leads)
        except ValueError:
            raise ValueError(
                f"Expected the leading dimensions of `v` {arrays[0].shape}, `q` {arrays[1].shape} "
                f"and `{name}` {arrays[2].shape} to broadcast."
            ) from None
        out = []
        for a, c in zip(arrays, cores):
            b = np.broadcast_to(a.astype(dtype, copy=False), lead + tuple(c))
            if copy or not b.flags.c_contiguous:
                b = np.array(b, dtype=dtype, order="C", copy=True)
            else:
                b = b.view()
            out.append(b)
        v_, q_, x_ = out
        self._check(lead, q_, x_)
        object.__setattr__(self, "_v", v_)
        object.__setattr__(self, "_q", q_)
        object.__setattr__(self, "_x", x_)
        _freeze(v_, q_, x_)

    def _check(self, lead, q, x):
        zero = np.flatnonzero(~np.any(q.reshape(-1, 4) != 0, axis=1))
        if zero.size:
            raise ValueError(f"Expected `q` to be non-zero; {where(zero[0], lead)} is the zero quaternion.")

    @classmethod
    def _new(cls, v, q, x):
        """Wrap kernel outputs without validating or copying."""
        obj = object.__new__(cls)
        _freeze(v, q, x)
        object.__setattr__(obj, "_v", v)
        object.__setattr__(obj, "_q", q)
        object.__setattr__(obj, "_x", x)
        return obj

    def __setattr__(self, name, value):
        raise AttributeError(f"{type(self).__name__} is immutable.")

    def __delattr__(self, name):
        raise AttributeError(f"{type(self).__name__} is immutable.")

    def __reduce__(self):
        return (type(self), (self._v, self._q, self._x))

    @classmethod
    def identity(cls, n=None, dtype=np.float64):
        """Identity transforms: v = 0, q = (1, 0, 0, 0), unit scale.

        Parameters
        ----------
        n : int or tuple, optional
            Leading shape; None gives a single transform (``shape == ()``).
        dtype : float32 or float64
        """
        lead = _shape_arg(n)
        dtype = float_dtype(dtype)
        v = np.zeros(lead + (3,), dtype)
        q = np.zeros(lead + (4,), dtype)
        q[..., 0] = 1
        if cls._core:
            x = np.zeros(lead + (3, 3), dtype)
            x[..., [0, 1, 2], [0, 1, 2]] = 1
        else:
            x = np.ones(lead, dtype)
        return cls._new(v, q, x)

    # -- array-like surface ------------------------------------------------

    @property
    def v(self):
        """Translations, ``(..., 3)`` (read-only)."""
        return self._v

    @property
    def q(self):
        """Rotation quaternions (w, x, y, z), ``(..., 4)`` (read-only)."""
        return self._q

    @property
    def shape(self):
        """Leading shape of the batch (``()`` for a single transform)."""
        return self._v.shape[:-1]

    @property
    def ndim(self):
        return self._v.ndim - 1

    @property
    def size(self):
        return math.prod(self.shape)

    @property
    def dtype(self):
        return self._v.dtype

    def __len__(self):
        if self.ndim == 0:
            raise TypeError(f"len() of a single {type(self).__name__} (shape ())")
        return self.shape[0]

    def __iter__(self):
        for i in range(len(self)):
            yield self[i]

    def __getitem__(self, key):
        key = key if isinstance(key, tuple) else (key,)
        count = 0
        ellipsis = False
        for k in key:
            if k is Ellipsis:
                ellipsis = True
            elif k is None:
                pass
            elif isinstance(k, np.ndarray) and k.dtype == bool:
                count += k.ndim
            else:
                count += 1
        if count > self.ndim:
            raise IndexError(
                f"too many indices for {type(self).__name__}: it is {self.ndim}-dimensional, "
                f"but {count} were indexed"
            )

        def take(a, core):
            full = key + (slice(None),) * len(core) if ellipsis else key + (Ellipsis,)
            return a[full]

        return type(self)._new(take(self._v, (3,)), take(self._q, (4,)), take(self._x, self._core))

    def __repr__(self):
        name = type(self).__name__
        parts = [("v", self._v), ("q", self._q), (self._field, self._x)]
        body = ",\n".join(f"    {k}={np.array_repr(a)}".replace("\n", "\n    ") for k, a in parts)
        return f"{name}(\n{body},\n)"

    def astype(self, dtype):
        """The same transforms in float32 or float64."""
        dtype = float_dtype(dtype)
        return type(self)._new(*(a.astype(dtype) for a in (self._v, self._q, self._x)))

    # -- group operations --------------------------------------------------

    def _parts(self):
        return [(self._v, "v", (3,)), (self._q, "q", (4,)), (self._x, self._field, self._core)]

    def apply(self, points, out=None):
        """Transform points: q (M r) q⁻¹ + v (M = s I for VQS).

        Parameters
        ----------
        points : array_like, shape (..., 3)
            Leading dimensions broadcast against ``self.shape``: one transform
            and many points, N transforms and N points, ``(N, 1)`` transforms
            and ``(P,)`` points, ...
        out : ndarray, optional
            Result array (exact shape and dtype); may be `points`.

        Returns
        -------
        ndarray, shape (..., 3)
        """
        p = check_core(as_float(points, "points"), "points", (3,))
        lead = p.shape[:-1]
        if lead != self.shape:
            try:
                lead = np.broadcast_shapes(self.shape, lead)
            except ValueError:
                raise ValueError(
                    f"Expected the leading dimensions of `points` {p.shape} to broadcast against "
                    f"the transform shape {self.shape}."
                ) from None
        dtype = result_dtype([self._v, p])
        if self.size == 1 and math.prod(lead) > 1:
            # One transform to many points: build its 3×4 affine map once.
            h = self.astype(dtype)._single().as_matrix()
            a = np.ascontiguousarray(h[:3, :3])
            t = np.ascontiguousarray(h[:3, 3])
            if p.shape[:-1] != lead:
                p = np.broadcast_to(p, lead + (3,))
            return elementwise(
                lambda pp, oo: _apply_affine(pp, a, t, oo), [(p, "points", (3,))], [(3,)], out, result=dtype
            )
        return elementwise(self._apply_kernel, self._parts() + [(p, "points", (3,))], [(3,)], out, result=dtype)

    def _single(self):
        """The single transform of a size-1 batch, with shape ``()`` (internal helper)."""
        if self.size != 1:
            raise ValueError(f"Expected a batch of one transform, got shape {self.shape}.")
        return type(self)._new(
            self._v.reshape(3), self._q.reshape(4), self._x.reshape(self._core)
        )

    def compose(self, other):
        """a∘b (apply `other` first), by the paper's product.

        ``a.compose(b).apply(r) == a.apply(b.apply(r))``; shapes broadcast.
        A VQS composed with a VQM gives a VQM.
        """
        if not isinstance(other, _Transform):
            raise TypeError(f"Expected a VQS or VQM to compose with, got {type(other).__name__}.")
        a, b = self, other
        if type(a) is not type(b):
            a, b = a._as_vqm(), b._as_vqm()
        _broadcast([a.shape, b.shape], "the two transforms")
        parts = a._parts() + b._parts()
        v, q, x = elementwise(a._compose_kernel, parts, [(3,), (4,), a._core])
        return type(a)._new(*_as_arrays(v, q, x))

    def __matmul__(self, other):
        if not isinstance(other, _Transform):
            return NotImplemented
        return self.compose(other)

    def __rmatmul__(self, other):
        return NotImplemented

    def _as_vqm(self):
        return self

    def inverse(self):
        """The group inverse: ``T @ T.inverse()`` and ``T.inverse() @ T`` are the identity."""
        raise NotImplementedError

    def as_matrix(self):
        """4×4 homogeneous matrices ``[[R(q) M, v], [0, 0, 0, 1]]``, shape ``(..., 4, 4)``."""
        out = elementwise(self._matrix_kernel, self._parts(), [(4, 4)])
        return np.asarray(out)


def _as_arrays(*xs):
    return tuple(np.asarray(x) if not isinstance(x, np.ndarray) else x for x in xs)


class VQS(_Transform):
    """Batched VQS transforms [v, q, s]: r ↦ q (s r) q⁻¹ + v.

    Parameters
    ----------
    v : array_like, shape (..., 3), optional
        Translations (default 0).
    q : array_like, shape (..., 4), optional
        Rotations as quaternions (w, x, y, z), any non-zero norm (default identity).
    s : array_like, shape (...), optional
        Uniform scales, > 0 (default 1).
    copy : bool, keyword-only
        Copy the inputs (default). ``False`` keeps contiguous inputs of the
        right dtype as read-only views: the caller must not modify them.

    Leading dimensions of `v`, `q` and `s` broadcast to the container's
    ``shape``. float32 parts give a float32 container (Python scalars don't upcast).

    Raises
    ------
    ValueError
        Bad shapes, a zero quaternion or a non-positive scale (naming the row).

    Examples
    --------
    The worked example of the paper (180° about y, scale 3):

    >>> import numpy as np, quatarray as qa
    >>> T = qa.VQS(v=[1, 1, 1], q=[0, 0, 1, 0], s=3)
    >>> np.round(T.apply([-1, 2, -1]), 12)
    array([4., 7., 4.])
    >>> np.round((T @ T.inverse()).apply([-1, 2, -1]), 12)
    array([-1.,  2., -1.])
    """

    __slots__ = ()
    _field = "s"
    _core = ()
    _apply_kernel = staticmethod(_apply_vqs)
    _compose_kernel = staticmethod(_compose_vqs)
    _matrix_kernel = staticmethod(_matrix_vqs)

    def __init__(self, v=None, q=None, s=None, *, copy=True):
        super().__init__(v, q, s, copy=copy)

    def _check(self, lead, q, x):
        super()._check(lead, q, x)
        bad = np.flatnonzero(~(x.reshape(-1) > 0))  # nan too
        if bad.size:
            k = bad[0]
            raise ValueError(f"Expected `s` to be positive; {where(k, lead)} has s = {x.reshape(-1)[k]}.")

    @property
    def s(self):
        """Uniform scales, ``(...)`` (read-only)."""
        return self._x

    def _as_vqm(self):
        m = self._x[..., None, None] * np.eye(3, dtype=self.dtype)
        return VQM._new(self._v, self._q, m)

    def as_vqm(self):
        """The same transforms as VQM (M = s I).

        Examples
        --------
        >>> import quatarray as qa
        >>> qa.VQS(s=2).as_vqm().M
        array([[2., 0., 0.],
               [0., 2., 0.],
               [0., 0., 2.]])
        """
        return self._as_vqm()

    def inverse(self):
        """Group inverse [−(1/s) q⁻¹ v q, q⁻¹, 1/s].

        Examples
        --------
        >>> import numpy as np, quatarray as qa
        >>> T = qa.VQS([1, 2, 3], qa.from_rotvec([0, 0, 1]), 2)
        >>> np.allclose(T.inverse().apply(T.apply([5, 6, 7])), [5, 6, 7])
        True
        """
        v, q, s = elementwise(_inverse_vqs, self._parts(), [(3,), (4,), ()])
        return VQS._new(*_as_arrays(v, q, s))

    def as_matrix(self):
        """4×4 homogeneous matrices ``[[s R(q), v], [0, 0, 0, 1]]``, shape ``(..., 4, 4)``.

        Examples
        --------
        >>> import numpy as np, quatarray as qa
        >>> np.round(qa.VQS([1, 1, 1], [0, 0, 1, 0], 3).as_matrix(), 12)
        array([[-3.,  0.,  0.,  1.],
               [ 0.,  3.,  0.,  1.],
               [ 0.,  0., -3.,  1.],
               [ 0.,  0.,  0.,  1.]])
        """
        return super().as_matrix()

    @classmethod
    def from_matrix(cls, m4, rtol=None):
        """VQS from homogeneous matrices ``(..., 4, 4)`` (or affine ``(..., 3, 4)``).

        The linear part must be a positive uniform scale times a rotation:
        its singular values may differ by at most ``rtol`` times their mean
        (default 1e-6 for float64, 1e-4 for float32), and its determinant must
        be positive; the last row must be (0, 0, 0, 1) within ``rtol``.
        s is the mean singular value and q comes from the rotation factor of
        the polar decomposition.

        Raises
        ------
        ValueError
            Naming the first offending row: non-uniform scale, a reflection,
            a zero scale, or a non-affine last row.

        Examples
        --------
        >>> import numpy as np, quatarray as qa
        >>> T = qa.VQS.from_matrix(np.diag([2.0, 2.0, 2.0, 1.0]))
        >>> float(T.s), T.q.tolist()
        (2.0, [1.0, 0.0, 0.0, 0.0])
        """
        lead, dtype, v, q, p, sig, reflected, finite, tol = _polar(m4, rtol)
        s = sig.mean(axis=1)
        spread = sig[:, 0] - sig[:, 2]
        nonuniform = finite & ~(spread <= tol * s)
        zero = finite & ~(s > 0)
        for bad, what in (
            (zero, "a zero linear part"),
            (reflected & finite, "a reflection (negative determinant)"),
            (nonuniform, "a non-uniform scale"),
        ):
            idx = np.flatnonzero(bad)
            if idx.size:
                k = idx[0]
                sv = ", ".join(f"{x:.6g}" for x in sig[k])
                raise ValueError(
                    "Expected `m4` to be a positive uniform scale times a rotation plus a translation; "
                    f"{where(k, lead)} has {what} (singular values {sv})."
                )
        return cls._new(v.reshape(lead + (3,)), q.reshape(lead + (4,)), s.astype(dtype).reshape(lead))


class VQM(_Transform):
    """Batched VQM transforms [v, q, M]: r ↦ q (M r) q⁻¹ + v.

    M is the 3×3 block of the paper's homogeneous quaternion matrix: any
    matrix (non-uniform scale, shear; it must be invertible only for
    :meth:`inverse`). The composite linear map is R(q) M.

    Parameters
    ----------
    v : array_like, shape (..., 3), optional
        Translations (default 0).
    q : array_like, shape (..., 4), optional
        Rotations as quaternions (w, x, y, z), any non-zero norm (default identity).
    M : array_like, shape (..., 3, 3), optional
        Matrices (default I).
    copy : bool, keyword-only
        Copy the inputs (default).

    Examples
    --------
    The worked example of the paper (180° about y, M = diag(2, 1, 2)):

    >>> import numpy as np, quatarray as qa
    >>> T = qa.VQM(v=[1, 1, 1], q=[0, 0, 1, 0], M=np.diag([2, 1, 2]))
    >>> np.round(T.apply([-1, 2, -1]), 12)
    array([3., 3., 3.])
    """

    __slots__ = ()
    _field = "M"
    _core = (3, 3)
    _apply_kernel = staticmethod(_apply_vqm)
    _compose_kernel = staticmethod(_compose_vqm)
    _matrix_kernel = staticmethod(_matrix_vqm)

    def __init__(self, v=None, q=None, M=None, *, copy=True):
        super().__init__(v, q, M, copy=copy)

    @property
    def M(self):
        """Matrices, ``(..., 3, 3)`` (read-only)."""
        return self._x

    def as_vqm(self):
        """``self`` (for symmetry with :meth:`VQS.as_vqm`)."""
        return self

    def inverse(self):
        """Group inverse [−M⁻¹ q⁻¹ v q, q⁻¹, R M⁻¹ Rᵀ].

        Raises
        ------
        ValueError
            If an M is singular (|det M| ≤ 16 ε |m₀||m₁||m₂| for rows mⱼ),
            naming the first such row.

        Examples
        --------
        >>> import numpy as np, quatarray as qa
        >>> T = qa.VQM([1, 2, 3], qa.from_rotvec([0, 0, 1]), np.diag([1.0, 2.0, 4.0]))
        >>> np.allclose(T.inverse().apply(T.apply([5, 6, 7])), [5, 6, 7])
        True
        """
        v, q, m, ratio = elementwise(_inverse_vqm, self._parts(), [(3,), (4,), (3, 3), ()])
        ratio = np.asarray(ratio).reshape(-1)
        bad = np.flatnonzero(~(ratio > 16 * np.finfo(self.dtype).eps) & ~np.isnan(ratio))
        if bad.size:
            k = bad[0]
            raise ValueError(
                f"Expected `M` to be invertible; {where(k, self.shape)} is singular "
                f"(|det M| / (|row0| |row1| |row2|) = {ratio[k]:.3g})."
            )
        return VQM._new(*_as_arrays(v, q, m))

    def as_matrix(self):
        """4×4 homogeneous matrices ``[[R(q) M, v], [0, 0, 0, 1]]``, shape ``(..., 4, 4)``.

        Examples
        --------
        >>> import numpy as np, quatarray as qa
        >>> np.round(qa.VQM([1, 1, 1], [0, 0, 1, 0], np.diag([2, 1, 2])).as_matrix(), 12)
        array([[-2.,  0.,  0.,  1.],
               [ 0.,  1.,  0.,  1.],
               [ 0.,  0., -2.,  1.],
               [ 0.,  0.,  0.,  1.]])
        """
        return super().as_matrix()

    @classmethod
    def from_matrix(cls, m4, rtol=None):
        """VQM from homogeneous matrices ``(..., 4, 4)`` (or affine ``(..., 3, 4)``).

        The linear part A is split by polar decomposition A = U P: q is the
        quaternion of the rotation factor U and M = P is symmetric (positive
        semi-definite). For a reflection (det A < 0) U is the rotation
        nearest to A and the symmetric M takes the sign: one negative
        eigenvalue, on A's smallest singular direction (so diag(−1, 2, 3)
        gives q = 1 and M = diag(−1, 2, 3)). ``as_matrix`` gives `m4` back. The last row must be (0, 0, 0, 1) within ``rtol`` (default 1e-6
        for float64, 1e-4 for float32).

        Examples
        --------
        >>> import numpy as np, quatarray as qa
        >>> T = qa.VQM([1, 1, 1], [0, 0, 1, 0], np.diag([2, 1, 2]))
        >>> U = qa.VQM.from_matrix(T.as_matrix())
        >>> np.allclose(U.M, np.diag([2, 1, 2])), np.allclose(U.apply([-1, 2, -1]), [3, 3, 3])
        (True, True)
        """
        lead, dtype, v, q, p, sig, reflected, finite, tol = _polar(m4, rtol)
        return cls._new(v.reshape(lead + (3,)), q.reshape(lead + (4,)), p.reshape(lead + (3, 3)))


def interpolate(a, b, t):
    """Interpolate transforms: v by lerp, q by slerp, s by elerp / M by lerp.

    VQS: s(t) = s_a (s_b/s_a)^t (computed as s_a^(1−t) s_b^t, exact at both
    ends); VQM: M(t) = (1−t) M_a + t M_b. q is slerped along the shorter arc
    after normalising (q and −q are the same rotation). A VQS with a VQM gives
    a VQM. `a`, `b` and `t` broadcast: one pair and M values of t give M
    transforms; N pairs and N values give N.

    Parameters
    ----------
    a, b : VQS or VQM
    t : float or array_like
        0 gives `a`, 1 gives `b` (the rotation with q normalised); values
        outside [0, 1] extrapolate.

    Returns
    -------
    VQS or VQM

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> a = qa.VQS([0, 0, 0], [1, 0, 0, 0], 1)
    >>> b = qa.VQS([2, 0, 0], qa.from_rotvec([0, 0, np.pi / 2]), 4)
    >>> h = qa.interpolate(a, b, 0.5)
    >>> h.v.tolist(), float(h.s), np.allclose(h.q, qa.from_rotvec([0, 0, np.pi / 4]))
    ([1.0, 0.0, 0.0], 2.0, True)
    """
    from .algebra import normalize
    from .interpolation import slerp

    for x, nm in ((a, "a"), (b, "b")):
        if not isinstance(x, _Transform):
            raise TypeError(f"Expected `{nm}` to be a VQS or VQM, got {type(x).__name__}.")
    if type(a) is not type(b):
        a, b = a._as_vqm(), b._as_vqm()
    tt = as_float(t, "t")
    lead = _broadcast([a.shape, b.shape, tt.shape], "`a`, `b` and `t`")
    dtype = result_dtype([a._v, b._v, tt], [False, False, is_weak(t)])
    # t contiguous (a copy of one value a row where it broadcasts) and read-only like
    # the parts: one compiled lerp serves array, scalar and broadcast t (a strided or
    # writeable t compiled it once more each)
    tt = np.broadcast_to(tt.astype(dtype, copy=False), lead)  # a read-only view
    if not tt.flags.c_contiguous:
        tt = _read_only(np.array(tt, order="C"))  # (not ascontiguousarray: it makes a 0-d t 1-d)
    kernel = _lerp_vm if isinstance(a, VQM) else _lerp_vs
    parts = [(a._v, "v", (3,)), (a._x, a._field, a._core), (b._v, "v", (3,)), (b._x, b._field, b._core), (tt, "t", ())]
    v, x = elementwise(kernel, parts, [(3,), a._core], result=dtype)
    q = slerp(normalize(a._q), normalize(b._q), tt)
    return type(a)._new(*_as_arrays(v, q, x))


def _read_only(a):
    """`a` (a copy made here) made read-only like the container's parts: the
    kernels then see one type whether an input was copied or not."""
    a.flags.writeable = False
    return a
