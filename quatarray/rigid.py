"""Rigid transforms (poses): dual quaternions, exponential coordinates, screw interpolation.

A pose is a rotation and a translation, x ↦ R(q) x + t, held as two arrays:
``q (..., 4)`` quaternions in (w, x, y, z) order and ``t (..., 3)``
translations, whose leading dimensions broadcast like numpy. The
quaternions may have any non-zero scale (each row is divided by its norm,
after an exact power-of-two scaling, so 1e-300 and 1e300 work too); the
quaternions returned are unit. float32 stays float32, mixed types give float64.

Layouts
-------
dual quaternion ``(..., 8)``
    The real part q then the dual part ½ (0, t) ⊗ q, each scalar first
    (``scalar_first=False`` puts each part's scalar last, as scipy's default).
exponential coordinates ``(..., 6)``
    The rotation vector φ (angle in [0, π]) then the translational part u
    with t = V(φ) u, scipy's ``RigidTransform.as_exp_coords`` layout.

Screw interpolation (:func:`sclerp`) moves along the one screw motion that
joins two poses: ``T0 · exp(s · log(T0⁻¹ T1))``, the shorter way round
(rotation angle at most π).
"""

import numpy as np

from . import _elements as E
from ._jit import element, like, prange, rowloop, select
from ._trig import half_arc
from ._validate import (
    as_float,
    check_core,
    elementwise,
    integer,
    key_times,
    result_dtype,
)

Q = (4,)
V = (3,)

# --------------------------------------------------------------------------
# per-element math


@element
def unit(q):
    """q / |q| (no scaling: moderate |q| only)."""
    n = np.sqrt(E.qdot(q, q))
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


@element
def unit_any(q):
    """q / |q| for any non-zero scale of q (:func:`quatarray._elements.qscaled` first:
    exact powers of two, branch-free); zero gives nan."""
    return unit(E.qscaled(q)[0])


@element
def matrix_sign(q):
    """±q with the sign scipy's ``from_matrix`` gives: the component of largest
    magnitude positive, ties going to x, then y, then z, then w (the first of
    scipy's candidates m₀₀, m₁₁, m₂₂, trace)."""
    w, x, y, z = q
    aw, ax, ay, az = w * w, x * x, y * y, z * z
    c_xz = select(ax >= az, select(ax >= aw, x, w), select(az >= aw, z, w))
    c_yz = select(ay >= az, select(ay >= aw, y, w), select(az >= aw, z, w))
    c = select(ax >= ay, c_xz, c_yz)
    return select(c < like(w, 0.0), (-w, -x, -y, -z), (w, x, y, z))


@element
def rotate_unit(a, v):
    """R(a) v for a unit quaternion a."""
    return E.qrotate_raw(a, v, like(a[0], 1.0))


# series of the exponential's and logarithm's coefficients below this angle
# (their closed forms cancel for small angles: relative error ε/θ² there)
SERIES_BELOW = 0.25


@element
def log_rotation(a):
    """(φ, h, c, s) of a unit quaternion a: its rotation vector φ (angle 2h, h in
    [0, π/2]) and c = |w| = cos h, s = |u| = sin h. At a half turn (w = 0) the
    axis's sign is scipy's (:func:`matrix_sign`)."""
    a = matrix_sign(a)
    w = a[0]
    flip = w < like(w, 0.0)
    w = abs(w)
    v = select(flip, (-a[1], -a[2], -a[3]), (a[1], a[2], a[3]))
    s = E.vnorm(v)
    h = half_arc(s, w)
    pos = s > like(s, 0.0)
    f = select(pos, like(s, 2.0) * h / select(pos, s, like(s, 1.0)), like(s, 2.0) / select(pos, like(s, 1.0), w))
    return E.vscale(v, f), h, w, s


@element
def log_pose(a, x):
    """(φ, u): exponential coordinates of the pose (a, x), a a unit quaternion.

    φ is the rotation vector (angle θ in [0, π]); u = V(φ)⁻¹ x with
    V⁻¹ = I − ½ [φ]× + k [φ]×², k = (1 − (θ/2) cot(θ/2)) / θ² (its series
    below :data:`SERIES_BELOW`)."""
    phi, h, w, s = log_rotation(a)
    h2 = h * h
    if like(h, 2.0) * h < like(h, SERIES_BELOW):
        k = like(h, 1.0 / 12.0) + h2 * (
            like(h, 1.0 / 180.0) + h2 * (
                like(h, 1.0 / 1890.0) + h2 * (
                    like(h, 1.0 / 18900.0) + h2 * (like(h, 1.0 / 187110.0) + h2 * like(h, 1382.0 / 2554051500.0)))))
    else:
        k = (like(h, 1.0) - h * w / s) / (like(h, 4.0) * h2)
    c1 = E.cross(phi, x)
    c2 = E.cross(phi, c1)
    half = like(h, 0.5)
    u = (x[0] - half * c1[0] + k * c2[0], x[1] - half * c1[1] + k * c2[1], x[2] - half * c1[2] + k * c2[2])
    return phi, u


@element
def exp_pose(phi, u):
    """(q, t): the pose of exponential coordinates (φ, u): q = exp(φ/2),
    t = V(φ) u, V = I + k₁ [φ]× + k₂ [φ]×², k₁ = (1 − cos θ)/θ² = ½ sinc²(θ/2),
    k₂ = (θ − sin θ)/θ³ (its series below :data:`SERIES_BELOW`)."""
    theta = E.vnorm(phi)
    h = like(theta, 0.5) * theta
    sh = np.sin(h)
    ch = np.cos(h)
    if h < like(h, 1e-4):
        h2 = h * h
        sc = like(h, 1.0) - h2 / like(h, 6.0) + h2 * h2 / like(h, 120.0)
    else:
        sc = sh / h
    hs = like(h, 0.5) * sc
    q = (ch, hs * phi[0], hs * phi[1], hs * phi[2])
    k1 = hs * sc
    if theta < like(theta, SERIES_BELOW):
        t2 = theta * theta
        k2 = like(h, 1.0 / 6.0) - t2 * (
            like(h, 1.0 / 120.0) - t2 * (
                like(h, 1.0 / 5040.0) - t2 * (
                    like(h, 1.0 / 362880.0) - t2 * (like(h, 1.0 / 39916800.0) - t2 * like(h, 1.0 / 6227020800.0)))))
    else:
        k2 = (theta - like(h, 2.0) * sh * ch) / (theta * theta * theta)
    c1 = E.cross(phi, u)
    c2 = E.cross(phi, c1)
    t = (u[0] + k1 * c1[0] + k2 * c2[0], u[1] + k1 * c1[1] + k2 * c2[1], u[2] + k1 * c1[2] + k2 * c2[2])
    return q, t


@element
def power_pose(a, x, k):
    """(a, x) to the real power k (a unit): exp(k log(a, x)); k = 0 gives the identity."""
    if k == like(k, 0.0):
        zero = like(k, 0.0)
        return (like(k, 1.0), zero, zero, zero), (zero, zero, zero)
    phi, u = log_pose(a, x)
    return exp_pose(E.vscale(phi, k), E.vscale(u, k))


@element
def signed(q, sign):
    return matrix_sign(q) if sign else q


# --------------------------------------------------------------------------
# batched loops; `sign` (int): 1 gives each result quaternion scipy's sign (matrix_sign).
# Every loop runs serial: those of a few dozen flops a row (compose, inverse,
# apply, the matrix and dual-quaternion layouts) are memory-bound (measured at
# 10⁶ poses on two cores: the threaded variant as fast or up to 2x slower), and
# for those with trigonometry (exp, log, power, ScLERP) the threaded variant
# gained 0-12 % while its compile added 1.4-2.8 s to the first call.


@rowloop(parallel=False)
def _compose(qa, ta, qb, tb, sign, qo, to):
    for i in prange(qa.shape[0]):
        a = unit_any(E.load4(qa, i))
        b = unit_any(E.load4(qb, i))
        t = E.vadd(rotate_unit(a, E.load3(tb, i)), E.load3(ta, i))
        q = signed(E.qmul(a, b), sign)
        E.store4(qo, i, q)
        E.store3(to, i, t)


@rowloop(parallel=False)
def _invert(q, t, sign, qo, to):
    for i in prange(q.shape[0]):
        c = E.qconj(unit_any(E.load4(q, i)))
        x = rotate_unit(c, E.load3(t, i))
        E.store4(qo, i, signed(c, sign))
        E.store3(to, i, (-x[0], -x[1], -x[2]))


@rowloop(parallel=False)
def _apply(q, t, v, inverse, out):
    for i in prange(q.shape[0]):
        a = E.qscaled(E.load4(q, i))[0]
        n2 = E.qdot(a, a)
        x = E.load3(v, i)
        d = E.load3(t, i)
        if inverse:
            r = E.qrotate_raw(E.qconj(a), E.vsub(x, d), n2)
        else:
            r = E.vadd(E.qrotate_raw(a, x, n2), d)
        E.store3(out, i, r)


@rowloop
def _as_matrix(q, t, out):
    for i in prange(q.shape[0]):
        a = E.qscaled(E.load4(q, i))[0]
        m = E.qmatrix_raw(a, E.qdot(a, a))
        x = E.load3(t, i)
        zero = like(m[0], 0.0)
        out[i, 0, 0], out[i, 0, 1], out[i, 0, 2], out[i, 0, 3] = m[0], m[1], m[2], x[0]
        out[i, 1, 0], out[i, 1, 1], out[i, 1, 2], out[i, 1, 3] = m[3], m[4], m[5], x[1]
        out[i, 2, 0], out[i, 2, 1], out[i, 2, 2], out[i, 2, 3] = m[6], m[7], m[8], x[2]
        out[i, 3, 0], out[i, 3, 1], out[i, 3, 2], out[i, 3, 3] = zero, zero, zero, like(m[0], 1.0)


@rowloop(parallel=False)
def _as_dual_quat(q, t, sign, last, out):
    for i in prange(q.shape[0]):
        a = signed(unit_any(E.load4(q, i)), sign)
        x = E.load3(t, i)
        half = like(a[0], 0.5)
        c = E.cross(x, (a[1], a[2], a[3]))
        d = (
            -half * E.vdot(x, (a[1], a[2], a[3])),
            half * (x[0] * a[0] + c[0]),
            half * (x[1] * a[0] + c[1]),
            half * (x[2] * a[0] + c[2]),
        )
        if last:
            out[i, 0], out[i, 1], out[i, 2], out[i, 3] = a[1], a[2], a[3], a[0]
            out[i, 4], out[i, 5], out[i, 6], out[i, 7] = d[1], d[2], d[3], d[0]
        else:
            out[i, 0], out[i, 1], out[i, 2], out[i, 3] = a[0], a[1], a[2], a[3]
            out[i, 4], out[i, 5], out[i, 6], out[i, 7] = d[0], d[1], d[2], d[3]


@rowloop(parallel=False)
def _from_dual_quat(dq, last, sign, qo, to):
    for i in prange(dq.shape[0]):
        if last:
            r = (dq[i, 3], dq[i, 0], dq[i, 1], dq[i, 2])
            d = (dq[i, 7], dq[i, 4], dq[i, 5], dq[i, 6])
        else:
            r = (dq[i, 0], dq[i, 1], dq[i, 2], dq[i, 3])
            d = (dq[i, 4], dq[i, 5], dq[i, 6], dq[i, 7])
        a, c = E.qscaled(r)  # r = c·a exactly, c a power of two: |r| = c·|a| for any scale
        n = np.sqrt(E.qdot(a, a))
        zero = like(n, 0.0)
        one = like(n, 1.0)
        if n == zero:  # scipy: a zero real part is the identity
            a = (one, zero, zero, zero)
            n = one
            c = one
        r = (a[0] / n, a[1] / n, a[2] / n, a[3] / n)
        k = one / c
        d = (d[0] * k / n, d[1] * k / n, d[2] * k / n, d[3] * k / n)
        p = E.qdot(r, d)
        d = (d[0] - p * r[0], d[1] - p * r[1], d[2] - p * r[2], d[3] - p * r[3])
        m = E.qmul(d, E.qconj(r))
        two = like(n, 2.0)
        E.store4(qo, i, signed(r, sign))
        E.store3(to, i, (two * m[1], two * m[2], two * m[3]))


@rowloop(parallel=False)
def _as_exp_coords(q, t, out):
    for i in prange(q.shape[0]):
        phi, u = log_pose(unit_any(E.load4(q, i)), E.load3(t, i))
        out[i, 0], out[i, 1], out[i, 2] = phi
        out[i, 3], out[i, 4], out[i, 5] = u


@rowloop(parallel=False)
def _from_exp_coords(e, sign, qo, to):
    for i in prange(e.shape[0]):
        q, t = exp_pose((e[i, 0], e[i, 1], e[i, 2]), (e[i, 3], e[i, 4], e[i, 5]))
        E.store4(qo, i, signed(q, sign))
        E.store3(to, i, t)


@rowloop(parallel=False)
def _power(q, t, k, sign, qo, to):
    for i in prange(q.shape[0]):
        a, x = power_pose(unit_any(E.load4(q, i)), E.load3(t, i), k[i])
        E.store4(qo, i, signed(a, sign))
        E.store3(to, i, x)


@rowloop(parallel=False)
def _components(t, q, sign, qo, to):
    for i in prange(q.shape[0]):
        x = E.load3(t, i)
        a = signed(unit_any(E.load4(q, i)), sign)
        E.store4(qo, i, a)
        E.store3(to, i, x)


@rowloop(parallel=False)
def _sclerp(q0, t0, q1, t1, s, sign, qo, to):
    for i in prange(q0.shape[0]):
        a = unit_any(E.load4(q0, i))
        b = unit_any(E.load4(q1, i))
        x0 = E.load3(t0, i)
        c = E.qconj(a)
        qr = E.qmul(c, b)  # T0⁻¹ T1
        tr = rotate_unit(c, E.vsub(E.load3(t1, i), x0))
        qe, te = power_pose(qr, tr, s[i])
        q = signed(E.qmul(a, qe), sign)
        t = E.vadd(rotate_unit(a, te), x0)
        E.store4(qo, i, q)
        E.store3(to, i, t)


# --------------------------------------------------------------------------
# front end


def _bind(loop, k, *flags):
    """``loop`` with the integer `flags` inserted after its first `k` (array) arguments."""
    return lambda *a: loop(*a[:k], *flags, *a[k:])


def pose_compose(q1, t1, q2, t2):
    """The pose T₁ T₂ (T₂ first, then T₁): (q₁ q₂, t₁ + R(q₁) t₂).

    Parameters
    ----------
    q1, t1, q2, t2 : array_like, shapes (..., 4), (..., 3), (..., 4), (..., 3)
        Two poses; leading dimensions broadcast.

    Returns
    -------
    q : ndarray, shape (..., 4)
        Unit quaternions.
    t : ndarray, shape (..., 3)

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> qz = [np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)]  # 90° about z
    >>> q, t = qa.pose_compose(qz, [1, 0, 0], [1, 0, 0, 0], [1, 0, 0])
    >>> np.round(t, 12)
    array([1., 1., 0.])
    """
    return elementwise(_bind(_compose, 4, 0), [(q1, "q1", Q), (t1, "t1", V), (q2, "q2", Q), (t2, "t2", V)], [Q, V])


def pose_inverse(q, t):
    """The inverse pose T⁻¹ = (q*, −R(q)ᵀ t), q normalised.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> q, t = qa.pose_inverse([0, 0, 0, 1], [1, 2, 3])  # 180° about z
    >>> np.round(t, 12)
    array([ 1.,  2., -3.])
    """
    return elementwise(_bind(_invert, 2, 0), [(q, "q", Q), (t, "t", V)], [Q, V])


def pose_apply(q, t, v, inverse=False, out=None):
    """The points v moved by the poses: R(q) v + t (``inverse=True``: R(q)ᵀ (v − t)).

    Parameters
    ----------
    q, t : array_like, shapes (..., 4), (..., 3)
    v : array_like, shape (..., 3)
        Leading dimensions broadcast with those of the poses.
    inverse : bool, optional
    out : ndarray, optional
        Result array of shape ``(..., 3)``; may be `v` or `t`.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> qa.pose_apply([0, 0, 0, 1], [1, 0, 0], [1, 0, 0])  # 180° about z, then +x
    array([0., 0., 0.])
    """
    return elementwise(_bind(_apply, 3, int(bool(inverse))), [(q, "q", Q), (t, "t", V), (v, "v", V)], [V], out)


def pose_as_matrix(q, t, out=None):
    """4×4 homogeneous matrices [[R(q), t], [0, 0, 0, 1]].

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.pose_as_matrix([1, 0, 0, 0], [1, 2, 3])[:3, 3]
    array([1., 2., 3.])
    """
    return elementwise(_as_matrix, [(q, "q", Q), (t, "t", V)], [(4, 4)], out)


def pose_from_matrix(m, assume_valid=False, *, _name="m"):
    """(q, t) of 4×4 homogeneous matrices, as scipy's ``RigidTransform.from_matrix``.

    The last row must be exactly [0, 0, 0, 1] (else ``ValueError`` naming the
    row); the 3×3 part goes through :func:`quatarray.from_matrix` (projected
    onto the nearest rotation where it is not orthogonal, unless
    `assume_valid`), so the quaternions have scipy's sign.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> q, t = qa.pose_from_matrix(np.eye(4))
    >>> q, t
    (array([1., 0., 0., 0.]), array([0., 0., 0.]))
    """
    from ._validate import where
    from .conversions import from_matrix

    a = check_core(as_float(m, _name), _name, (4, 4))
    last = a[..., 3, :]
    bad = ~np.all(last == np.array([0.0, 0.0, 0.0, 1.0], a.dtype), axis=-1)
    if bad.any():
        k = int(np.argmax(bad.reshape(-1)))
        raise ValueError(
            f"Expected the last row of transformation matrix `{_name}` to be exactly [0, 0, 0, 1], got "
            f"{last.reshape(-1, 4)[k].tolist()} at {where(k, a.shape[:-2])}."
        )
    q = from_matrix(a[..., :3, :3], assume_valid=assume_valid)
    return q, np.array(a[..., :3, 3])


def as_dual_quat(q, t, scalar_first=True, out=None):
    """Unit dual quaternions (..., 8) of poses: the real part q/|q| then the
    dual part ½ (0, t) ⊗ q/|q|, each scalar first (``scalar_first=False``: each
    part's scalar last, scipy's default layout).

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.as_dual_quat([1, 0, 0, 0], [2, 4, 6]) + 0.0
    array([1., 0., 0., 0., 0., 1., 2., 3.])
    """
    return elementwise(_bind(_as_dual_quat, 2, 0, int(not scalar_first)), [(q, "q", Q), (t, "t", V)], [(8,)], out)


def from_dual_quat(dq, scalar_first=True):
    """Poses (q, t) of dual quaternions (..., 8), normalised as scipy does: the
    real part r and dual part d are divided by |r| (a zero r becomes the
    identity), d loses its component along r, and t = 2 vec(d ⊗ r*).

    Examples
    --------
    >>> import quatarray as qa
    >>> q, t = qa.from_dual_quat([2, 0, 0, 0, 0, 2, 4, 6])
    >>> q, t
    (array([1., 0., 0., 0.]), array([2., 4., 6.]))
    """
    return elementwise(_bind(_from_dual_quat, 1, int(not scalar_first), 0), [(dq, "dq", (8,))], [Q, V])


def as_exp_coords(q, t, out=None):
    """Exponential coordinates (..., 6) of poses: the rotation vector φ (angle
    in [0, π]) then u = V(φ)⁻¹ t, the logarithm of SE(3) (scipy's
    ``as_exp_coords``). Series near zero angle; accurate up to half turns.

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.as_exp_coords([1, 0, 0, 0], [1, 2, 3])
    array([0., 0., 0., 1., 2., 3.])
    """
    return elementwise(_as_exp_coords, [(q, "q", Q), (t, "t", V)], [(6,)], out)


def from_exp_coords(e):
    """Poses (q, t) of exponential coordinates (..., 6): q = exp(φ/2), t = V(φ) u.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> q, t = qa.from_exp_coords([0, 0, np.pi, 0, 0, 1])  # a half turn, 1 along z
    >>> np.round(q, 12), np.round(t, 12)
    (array([0., 0., 0., 1.]), array([0., 0., 1.]))
    """
    return elementwise(_bind(_from_exp_coords, 1, 0), [(e, "e", (6,))], [Q, V])


def pose_power(q, t, a):
    """Poses to real powers a: exp(a · log T) (a = 0 gives the identity, a = −1
    the inverse, a = 1 the pose; the rotation part turns the shorter way).

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> q, t = qa.pose_power([1, 0, 0, 0], [2, 0, 0], 0.5)
    >>> t
    array([1., 0., 0.])
    """
    return elementwise(_bind(_power, 3, 0), [(q, "q", Q), (t, "t", V), (a, "a", ())], [Q, V])


def sclerp(q0, t0, q1, t1, s):
    """Screw linear interpolation: T₀ (T₀⁻¹ T₁)^s, along the screw motion that
    joins the poses T₀ = (q0, t0) and T₁ = (q1, t1); s = 0 gives T₀, s = 1
    T₁, other s extrapolate. The relative rotation turns the shorter way.

    Parameters
    ----------
    q0, t0, q1, t1 : array_like, shapes (..., 4), (..., 3), (..., 4), (..., 3)
    s : array_like, shape (...)
        Leading dimensions of all five broadcast.

    Returns
    -------
    q : ndarray, shape (..., 4)
    t : ndarray, shape (..., 3)

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> qz = [0, 0, 0, 1]  # a half turn about z
    >>> q, t = qa.sclerp([1, 0, 0, 0], [0, 0, 0], qz, [0, 0, 2], 0.5)
    >>> np.round(q, 12), np.round(t, 12)  # a quarter turn, half way up the screw
    (array([0.70710678, 0.        , 0.        , 0.70710678]), array([0., 0., 1.]))
    """
    return elementwise(
        _bind(_sclerp, 5, 0),
        [(q0, "q0", Q), (t0, "t0", V), (q1, "q1", Q), (t1, "t1", V), (s, "s", ())],
        [Q, V],
    )


def pose_mean(q, t, weights=None, axis=None):
    """The mean pose, as scipy 1.17's ``RigidTransform.mean``: the chordal L2
    mean of the rotations (:func:`quatarray.mean`) and the weighted mean of
    the translations, over the leading axes `axis` (None: all).

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> q, t = qa.pose_mean([[1, 0, 0, 0], [1, 0, 0, 0]], [[0, 0, 0], [2, 2, 2]])
    >>> t
    array([1., 1., 1.])
    """
    from .algebra import mean

    qa_ = check_core(as_float(q, "q"), "q", Q)
    ta = check_core(as_float(t, "t"), "t", V)
    dtype = result_dtype([qa_, ta])
    lead = np.broadcast_shapes(qa_.shape[:-1], ta.shape[:-1])
    qa_ = np.broadcast_to(qa_, lead + Q)
    ta = np.broadcast_to(ta, lead + V)
    if weights is not None:
        w = as_float(weights, "weights")
        w = np.broadcast_to(w, lead)
    else:
        w = None
    qm = mean(qa_, weights=w, axis=axis)
    nd = max(len(lead), 1)
    if axis is None:
        ax = tuple(range(nd))
    elif isinstance(axis, tuple):
        ax = tuple(integer(k, "axis") % nd for k in axis)
    else:
        ax = (integer(axis, "axis") % nd,)
    t1 = ta.reshape((1, 3)) if len(lead) == 0 else ta
    if w is None:
        tm = t1.mean(axis=ax, dtype=np.float64)
    else:
        w1 = w.reshape((1,)) if len(lead) == 0 else w
        tm = (t1 * w1[..., None]).sum(axis=ax, dtype=np.float64) / w1[..., None].sum(axis=ax, dtype=np.float64)
    return qm.astype(dtype, copy=False), tm.astype(dtype)


def pose_spline(times, q, t, new_times, method="slerp", poses="split"):
    """Resample a timestamped pose stream at `new_times`.

    ``poses="split"`` interpolates the rotations with :func:`quatarray.spline`
    (`method`) and the translations with the matching curve: linear for
    ``"slerp"`` and ``"nlerp"``, a natural cubic spline for ``"cubic"``,
    ``"squad"`` and ``"bezier"``. ``poses="screw"`` runs screw linear
    interpolation (:func:`sclerp`) between the two keys around each new time
    (translation and rotation coupled; `method` is not used).

    Parameters
    ----------
    times : array_like, shape (K,)
        Strictly increasing key times, K ≥ 2.
    q, t : array_like, shapes (K, 4), (K, 3)
        The key poses.
    new_times : array_like, shape (M,)
        Within [times[0], times[-1]].
    method : str, optional
    poses : {"split", "screw"}, optional

    Returns
    -------
    q : ndarray, shape (M, 4)
    t : ndarray, shape (M, 3)

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> q, t = qa.pose_spline([0, 1], [[1, 0, 0, 0], [0, 0, 0, 1]], [[0, 0, 0], [0, 0, 2]],
    ...                       [0.5], poses="screw")
    >>> np.round(t, 12)
    array([[0., 0., 1.]])
    """
    from .splines import spline

    if poses not in ("split", "screw"):
        raise ValueError(f"Expected `poses` to be 'split' or 'screw', got {poses!r}.")
    qk = check_core(as_float(q, "q"), "q", Q)
    tk = check_core(as_float(t, "t"), "t", V)
    if qk.ndim != 2 or tk.ndim != 2 or qk.shape[0] != tk.shape[0]:
        raise ValueError(f"Expected `q` (K, 4) and `t` (K, 3) of one K, got {qk.shape} and {tk.shape}.")
    if qk.shape[0] < 2:
        raise ValueError(f"Expected at least 2 key poses, got {qk.shape[0]}.")
    tm = key_times(times, qk.shape[0])
    new = np.asarray(new_times)
    if new.ndim != 1:
        raise ValueError(f"Expected `new_times` to have shape (M,), got {new.shape}.")
    if new.size and (not (new.min() >= tm[0]) or not (new.max() <= tm[-1])):
        raise ValueError(
            f"Expected `new_times` within [{tm[0].item()}, {tm[-1].item()}], "
            f"got values in [{new.min().item()}, {new.max().item()}]."
        )
    dtype = result_dtype([qk, tk])
    if poses == "screw":
        k = np.clip(np.searchsorted(tm, new, side="right") - 1, 0, len(tm) - 2)
        t0, t1 = tm[k].astype(np.float64), tm[k + 1].astype(np.float64)
        s = ((new.astype(np.float64) - t0) / (t1 - t0)).astype(dtype)
        qs, ts = qk.astype(dtype, copy=False), tk.astype(dtype, copy=False)
        return sclerp(qs[k], ts[k], qs[k + 1], ts[k + 1], s)
    qo = spline(tm, qk, new, method=method)
    if method in ("slerp", "nlerp"):
        x = tm.astype(np.float64)
        to = np.stack([np.interp(new.astype(np.float64), x, tk[:, j]) for j in range(3)], axis=-1)
    else:
        from scipy.interpolate import CubicSpline

        x = tm.astype(np.float64)
        to = CubicSpline(x, tk.astype(np.float64), axis=0, bc_type="natural")(new.astype(np.float64))
    return qo.astype(dtype, copy=False), to.astype(dtype)
