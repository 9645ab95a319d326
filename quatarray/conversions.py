"""Conversions between quaternions (w, x, y, z) and the other
parameterisations of a rotation: rotation matrices, rotation vectors,
axis–angle pairs, modified Rodrigues parameters (MRP) and Gibbs vectors
(scipy's ``as_*``/``from_*`` of a rotation).

The rule between this module and :mod:`quatarray.layouts`: a *conversion*
goes to another parameterisation of the rotation, so every conversion from
a quaternion accepts any non-zero scale (the rotation of q/|q| is meant) and
a zero quaternion gives nan; a *layout* (scalar-last xyzw, scipy
``Rotation`` objects, the 4×4 multiplication matrices, SU(2)) holds the same
four quaternion numbers arranged otherwise. Euler and Davenport angles have
modules of their own (:mod:`quatarray.euler`, :mod:`quatarray.davenport`).
Leading dimensions broadcast like numpy; float32 stays float32 and float64
stays float64.

The element functions of the rotation-vector and axis-angle kernels are
inlined by LLVM (``_jit.element``) and use the branch-free
polynomial sine, cosine and arctangent of :mod:`quatarray._trig`, so their
row loops compile to SIMD code (about 3× faster than with libm calls).
"""

import math

import numpy as np

from . import _elements as E
from ._jit import element, like, prange, rowloop
from ._mat33 import cofactor33, det33
from ._trig import half_arc, sincos, sincos_limit
from ._validate import as_float, elementwise, is_weak, where

Q = (4,)
V = (3,)
M3 = (3, 3)

_TO_DEG = 180.0 / math.pi
_FROM_DEG = math.pi / 180.0

# --------------------------------------------------------------------------
# per-element formulas


@element(how="call")
def sumsq9(a):
    s = a[0] * a[0]
    for k in range(1, 9):
        s += a[k] * a[k]
    return s


@element(how="call")
def max9abs(a):
    m = abs(a[0])
    for k in range(1, 9):
        m = max(m, abs(a[k]))
    return m


@element(how="call")
def near_orthogonal(a):
    """scipy's test ``np.isclose(a aᵀ, I, atol=1e-12)`` (default rtol 1e-5)."""
    atol = like(a[0], 1e-12)
    dtol = atol + like(a[0], 1e-5)
    one = like(a[0], 1.0)
    g00 = a[0] * a[0] + a[1] * a[1] + a[2] * a[2]
    g11 = a[3] * a[3] + a[4] * a[4] + a[5] * a[5]
    g22 = a[6] * a[6] + a[7] * a[7] + a[8] * a[8]
    g01 = a[0] * a[3] + a[1] * a[4] + a[2] * a[5]
    g02 = a[0] * a[6] + a[1] * a[7] + a[2] * a[8]
    g12 = a[3] * a[6] + a[4] * a[7] + a[5] * a[8]
    return (
        abs(g00 - one) <= dtol
        and abs(g11 - one) <= dtol
        and abs(g22 - one) <= dtol
        and abs(g01) <= atol
        and abs(g02) <= atol
        and abs(g12) <= atol
    )


@element(how="call")
def polar33(a, eps):
    """Orthogonal polar factor of a (det > 0): the nearest rotation, U Vᵀ of an SVD.

    Newton's iteration X ← (ζX + X⁻ᵀ/ζ)/2 with Higham's Frobenius-norm
    scaling ζ; quadratic convergence, so once a step moves less than √eps
    the iterate is exact to rounding.
    """
    half = like(eps, 0.5)
    tol = np.sqrt(eps)
    x = a
    for _ in range(40):
        c = cofactor33(x)
        d = det33(x)
        # ‖X⁻¹‖_F / ‖X‖_F = ‖cof X‖_F / (|det X| ‖X‖_F)
        zeta = np.sqrt(np.sqrt(sumsq9(c) / sumsq9(x)) / abs(d))
        f = half * zeta
        g = half / (zeta * d)
        nx = (
            f * x[0] + g * c[0], f * x[1] + g * c[1], f * x[2] + g * c[2],
            f * x[3] + g * c[3], f * x[4] + g * c[4], f * x[5] + g * c[5],
            f * x[6] + g * c[6], f * x[7] + g * c[7], f * x[8] + g * c[8],
        )  # fmt: skip
        step = sumsq9((
            nx[0] - x[0], nx[1] - x[1], nx[2] - x[2],
            nx[3] - x[3], nx[4] - x[4], nx[5] - x[5],
            nx[6] - x[6], nx[7] - x[7], nx[8] - x[8],
        ))  # fmt: skip
        x = nx
        if not step > tol * tol:  # also stops on nan
            break
    return x


@element
def shepperd_raw(a):
    """The quaternion of a rotation matrix (9-tuple), unnormalised (its norm is 4
    times the largest of |w|, |x|, |y|, |z| for a rotation), choosing on the largest
    of the diagonal and the trace exactly as scipy's ``_from_matrix_orthogonal``:
    the component picked comes out positive. Branch-free (the four candidates
    share their sums; selects pick one), so the row loops vectorise."""
    one = like(a[0], 1.0)
    two = like(a[0], 2.0)
    tr = a[0] + a[4] + a[8]
    d10, s10, s20, d20, s21, d21 = a[3] - a[1], a[3] + a[1], a[6] + a[2], a[2] - a[6], a[7] + a[5], a[7] - a[5]
    c1 = a[4] > a[0]  # the first largest of a[0], a[4], a[8], tr, as scipy's argmax
    b1 = a[4] if c1 else a[0]
    c2 = a[8] > b1
    c3 = tr > (a[8] if c2 else b1)
    q0 = (d21, one - tr + two * a[0], s10, s20)
    q1 = (d20, s10, one - tr + two * a[4], s21)
    q2 = (d10, s20, s21, one - tr + two * a[8])
    return E.pick4(c3, (one + tr, d21, d20, d10), E.pick4(c2, q2, E.pick4(c1, q1, q0)))


@element
def shepperd_unit(a):
    """(:func:`shepperd_raw` normalised, its |q|² before): on q as it is, exact where
    that |q|² is in range (E.far_scale), as for every rotation matrix (4 to 16).
    One division, not four."""
    q = shepperd_raw(a)
    n2 = E.qdot(q, q)
    r = like(n2, 1.0) / np.sqrt(n2)
    return (q[0] * r, q[1] * r, q[2] * r, q[3] * r), n2


@element
def qrotvec(q):
    """Rotation vector θ·axis of q/|q| on scipy's canonical sign, with
    θ = 2 atan2(|u|, |w|) in [0, π]; any scale of q (:func:`_elements.qscaled`)."""
    return qrotvec_raw(E.qscaled(q)[0])[0]


@element
def qrotvec_raw(q):
    """(:func:`qrotvec` on q as it is, |q|²): no scaling, see :func:`_elements.far_scale`
    (|q|² from the squares |u| is taken from, for the range flag)."""
    w, x, y, z = q
    u2 = x * x + y * y + z * z
    un = np.sqrt(u2)  # E.vnorm((x, y, z))
    aw = abs(w)
    two = like(w, 2.0)
    f = two * half_arc(un, aw) / un
    f = (two / aw) if un == like(w, 0.0) else f  # identity: 0·f = 0; zero q: 0·inf = nan
    f = -f if E.canonical_flip(q) else f
    return (f * x, f * y, f * z), u2 + w * w


@element
def qaxis_angle(q):
    """(unit axis, angle in [0, π]); identity → ((1, 0, 0), 0); zero q → nan;
    any scale of q (:func:`_elements.qscaled`)."""
    u, a, _ = qaxis_angle_raw(E.qscaled(q)[0])
    return u, a


@element
def qaxis_angle_raw(q):
    """(:func:`qaxis_angle` on q as it is, |q|²): no scaling, see
    :func:`_elements.far_scale` (|q|² from the squares |u| is taken from)."""
    w, x, y, z = q
    zero = like(w, 0.0)
    u2 = x * x + y * y + z * z
    un = np.sqrt(u2)  # E.vnorm((x, y, z))
    aw = abs(w)
    n2 = u2 + w * w
    ang = like(w, 2.0) * half_arc(un, aw)
    if un == zero:
        if aw > zero:
            return (like(w, 1.0), zero, zero), ang, n2
        nan = like(w, np.nan)
        return (nan, nan, nan), nan, n2
    k = -un if E.canonical_flip(q) else un
    return (x / k, y / k, z / k), ang, n2


@element
def half_sinc(h, s):
    """sin(h)/(2h) given s = sin h; a series for tiny h (exact to rounding)."""
    h2 = h * h
    series = like(h, 0.5) - h2 * (like(h, 1.0 / 12.0) - h2 * like(h, 1.0 / 240.0))
    return series if h < like(h, 1e-4) else like(h, 0.5) * s / h


@element
def rotvec_quat(v):
    """exp of (0, v/2): (cos(θ/2), sin(θ/2)/θ · v), θ = |v|; exact for tiny θ."""
    h = like(v[0], 0.5) * E.vnorm(v)
    s, c = sincos(h)
    k = half_sinc(h, s)
    return (c, k * v[0], k * v[1], k * v[2])


# --------------------------------------------------------------------------
# batched loops


# The loops over |q|-dependent formulas (rowloop(far=...)) compute them on q as it is;
# a second kernel redoes the rare rows outside the range where that is exact,
# on the scaled q (E.qscaled), only when there are some.


@element
def _as_matrix_plain(i, args):
    q, out = args
    a = E.load4(q, i)
    n2 = E.qdot(a, a)
    E.store33(out, i, E.qmatrix_raw(a, n2))
    return E.far_scale(n2)


_as_matrix = rowloop(_as_matrix_plain, far=E.redo(E.store33, E.qmatrix, "as_matrix"))


@rowloop
def _from_matrix(m, out):
    # Returns the first row with det ≤ 0 (its output is nan), or -1.
    n = m.shape[0]
    # the float type's machine epsilon, |(4/3 - 1)·3 - 1| in that type (exact for binary floats;
    # LLVM folds it to a constant: cheaper to compile than np.finfo)
    one = like(m, 1.0)
    eps = abs((like(m, 4.0 / 3.0) - one) * like(m, 3.0) - one)
    bad = n
    for i in prange(n):
        a = E.load33(m, i)
        d = det33(a)
        s = a
        if not ((abs(d) > like(d, 1e-8)) & (abs(d) < like(d, 1e8))):
            # far from unit scale (or zero, inf, nan): the determinant's sign and the
            # projection on a scaled by its largest entry, so that no product
            # overflows or underflows whatever the scale
            c = max9abs(a)
            c = c if (c > like(c, 0.0)) & (c < like(c, np.inf)) else like(c, 1.0)
            s = (a[0] / c, a[1] / c, a[2] / c, a[3] / c, a[4] / c, a[5] / c, a[6] / c, a[7] / c, a[8] / c)
            d = det33(s)
        nan = like(d, np.nan)
        if d <= like(d, 0.0):
            bad = min(bad, i)
            q = (nan, nan, nan, nan)
        elif not np.isfinite(d):
            q = (nan, nan, nan, nan)
        elif near_orthogonal(a):  # a rotation matrix, or a projected one: unit scale
            q = shepperd_unit(a)[0]
        else:
            q = shepperd_unit(polar33(s, eps))[0]
        E.store4(out, i, q)
    return bad if bad < n else -1


@element
def _from_matrix_valid_plain(i, args):
    m, out = args
    q, n2 = shepperd_unit(E.load33(m, i))
    E.store4(out, i, q)
    return E.far_scale(n2)


@element
def _from_matrix_valid_scaled(i, args):
    m, out = args
    q = shepperd_raw(E.load33(m, i))
    if E.far_scale(E.qdot(q, q)):
        # rare rows: divided by the largest |component| first (plain divisions, so that
        # this pass compiles little: no E.qscaled), then normalised; inf and nan give nan
        c = max(max(abs(q[0]), abs(q[1])), max(abs(q[2]), abs(q[3])))
        q = (q[0] / c, q[1] / c, q[2] / c, q[3] / c)
        n = np.sqrt(E.qdot(q, q))
        E.store4(out, i, (q[0] / n, q[1] / n, q[2] / n, q[3] / n))


_from_matrix_valid = rowloop(_from_matrix_valid_plain, far=_from_matrix_valid_scaled)


@element
def _as_rotvec_plain(i, args):
    q, out = args
    rv, n2 = qrotvec_raw(E.load4(q, i))
    E.store3(out, i, rv)
    return E.far_scale(n2)


@element
def _as_rotvec_scaled(i, args):
    q, out = args
    a = E.load4(q, i)
    if E.far_scale(qrotvec_raw(a)[1]):
        E.store3(out, i, qrotvec(a))


_as_rotvec = rowloop(_as_rotvec_plain, far=_as_rotvec_scaled)


# from_rotvec's far rows: half angles beyond the fast sincos range (or inf),
# redone with libm's sin and cos (as quatarray.euler does)


@element
def _from_rotvec_plain(i, args):
    r, out = args
    v = E.load3(r, i)
    h = like(v[0], 0.5) * E.vnorm(v)  # ≥ 0 (or nan)
    s, c = sincos(h)
    k = half_sinc(h, s)
    E.store4(out, i, (c, k * v[0], k * v[1], k * v[2]))  # rotvec_quat(v), with h at hand
    return np.int32(1) if h > sincos_limit(h) else np.int32(0)


@element
def _from_rotvec_scaled(i, args):
    r, out = args
    v = E.load3(r, i)
    h = like(v[0], 0.5) * E.vnorm(v)
    if abs(h) > sincos_limit(h):
        k = half_sinc(h, np.sin(h))
        E.store4(out, i, (np.cos(h), k * v[0], k * v[1], k * v[2]))


_from_rotvec = rowloop(_from_rotvec_plain, far=_from_rotvec_scaled)


@element
def _as_axis_angle_plain(i, args):
    q, axis, ang = args
    u, t, n2 = qaxis_angle_raw(E.load4(q, i))
    E.store3(axis, i, u)
    ang[i] = t
    return E.far_scale(n2)


@element
def _as_axis_angle_scaled(i, args):
    q, axis, ang = args
    a = E.load4(q, i)
    if E.far_scale(qaxis_angle_raw(a)[2]):
        u, t = qaxis_angle(a)
        E.store3(axis, i, u)
        ang[i] = t


_as_axis_angle = rowloop(_as_axis_angle_plain, far=_as_axis_angle_scaled)


@rowloop
def _from_axis_angle(axis, ang, out):
    # Returns the first row whose axis is zero (its output is nan), or -1. Half
    # angles beyond the fast sincos range (or inf) take libm's sin and cos.
    n = axis.shape[0]
    bad = n
    for i in prange(n):
        u = E.load3(axis, i)
        un = E.vnorm(u)
        if un == like(un, 0.0):
            bad = min(bad, i)
        h = like(un, 0.5) * ang[i]
        if abs(h) > sincos_limit(h):
            sn, c = np.sin(h), np.cos(h)
        else:
            sn, c = sincos(h)
        k = sn / un
        if not np.isfinite(un):
            c = like(un, np.nan)  # a nan or inf axis gives nan, not (cos h, nan, …)
        E.store4(out, i, (c, k * u[0], k * u[1], k * u[2]))
    return bad if bad < n else -1


# --------------------------------------------------------------------------
# helpers


def _with_status(kernel, inputs, out_cores, out=None):
    """``elementwise`` that also hands back the kernel's return value."""
    status = []

    def run(*arrays):
        status.append(kernel(*arrays))

    res = elementwise(run, inputs, out_cores, out)
    return res, (status[0] if status else -1)


def _radians(x, name, degrees):
    """`x` as a float array, converted from degrees if asked (a Python float
    factor, so float32 stays float32). The kernels work in radians only:
    a unit factor inside a row loop costs more than this extra pass."""
    if not degrees:
        return x
    if is_weak(x):
        return float(x) * _FROM_DEG
    return as_float(x, name) * _FROM_DEG


# --------------------------------------------------------------------------
# public functions: matrices


def as_matrix(q, out=None):
    """Rotation matrices, shape ``(..., 3, 3)``, with ``as_matrix(q) @ v == rotate(q, v)``.

    Any non-zero scale of `q` gives the rotation of q/|q|; a zero quaternion
    gives a nan matrix.

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Quaternions (w, x, y, z).
    out : ndarray, optional
        Result array of shape ``(..., 3, 3)`` and the result dtype.

    Returns
    -------
    ndarray, shape (..., 3, 3)

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> q = qa.from_axis_angle([0, 0, 1], np.pi / 2)  # 90° about z
    >>> np.round(qa.as_matrix(q), 12) + 0.0
    array([[ 0., -1.,  0.],
           [ 1.,  0.,  0.],
           [ 0.,  0.,  1.]])
    """
    return elementwise(_as_matrix, [(q, "q", Q)], [M3], out)


def from_matrix(m, assume_valid=False, out=None):
    """Quaternions of rotation matrices, as scipy's ``Rotation.from_matrix``.

    By default each matrix is checked and, where needed, replaced by the
    nearest rotation exactly as scipy does: a determinant ≤ 0 raises
    ``ValueError`` naming the first such row; a matrix whose Gram matrix
    m mᵀ is not ``np.isclose`` (atol 1e-12, rtol 1e-5) to the identity is
    replaced by its orthogonal polar factor (scipy's U Vᵀ from an SVD,
    computed here by Newton's polar iteration); then the quaternion is read
    off with Shepperd's method. Non-finite matrices give nan.

    ``assume_valid=True`` skips the determinant check and the projection and
    runs only the Shepperd step (fast; for matrices known to be rotations).

    The sign is scipy's, not canonical: the branch is chosen by the largest
    of (m₀₀, m₁₁, m₂₂, trace) and the matching component (x, y, z or w) comes
    out positive. Use :func:`quatarray.canonical` for w ≥ 0.

    Parameters
    ----------
    m : array_like, shape (..., 3, 3)
    assume_valid : bool, optional
    out : ndarray, optional
        Result array of shape ``(..., 4)``. If a ``ValueError`` is raised it
        may already be partly written.

    Returns
    -------
    ndarray, shape (..., 4)
        Unit quaternions (w, x, y, z).

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> m = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]  # 90° about z
    >>> np.round(qa.from_matrix(m), 12)
    array([0.70710678, 0.        , 0.        , 0.70710678])
    >>> np.round(qa.from_matrix(np.diag([2.0, 2.0, 2.0])), 12)  # projected
    array([1., 0., 0., 0.])
    """
    if assume_valid:
        return elementwise(_from_matrix_valid, [(m, "m", M3)], [Q], out)
    res, bad = _with_status(_from_matrix, [(m, "m", M3)], [Q], out)
    if bad >= 0:
        a = as_float(m, "m")
        lead = res.shape[:-1]
        a = np.broadcast_to(a, lead + M3).reshape((-1,) + M3)
        raise ValueError(
            "Expected `m` to hold rotation matrices with a positive determinant; "
            f"{where(bad, lead)} has determinant {np.linalg.det(a[bad]):.6g} "
            f"(left-handed or degenerate): {a[bad].tolist()}."
        )
    return res


# --------------------------------------------------------------------------
# rotation vectors and axis-angle


def as_rotvec(q, degrees=False, out=None):
    """Rotation vectors θ·axis with θ = |r| in [0, π] (as scipy's ``as_rotvec``).

    Computed as 2·atan2(|u|, |w|)·u/|u| on the canonical sign, so it is
    accurate for tiny angles and for any non-zero scale of `q`. At exactly
    180° the direction follows scipy (first non-zero component positive).
    The identity gives 0, a zero quaternion nan.

    Parameters
    ----------
    q : array_like, shape (..., 4)
    degrees : bool, optional
        Return |r| in degrees.
    out : ndarray, optional
        Result array of shape ``(..., 3)``.

    Returns
    -------
    ndarray, shape (..., 3)

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> qa.as_rotvec([np.cos(0.25), 0, 0, np.sin(0.25)])  # 0.5 rad about z
    array([0. , 0. , 0.5])
    >>> np.round(qa.as_rotvec([0, 1, 0, 0], degrees=True), 12)
    array([180.,   0.,   0.])
    """
    res = elementwise(_as_rotvec, [(q, "q", Q)], [V], out)
    if degrees:
        res *= _TO_DEG
    return res


def from_rotvec(r, degrees=False, out=None):
    """Unit quaternions (cos(θ/2), sin(θ/2)·r/θ) of rotation vectors r, θ = |r|.

    Accurate for tiny vectors (a series replaces sin(θ/2)/θ near 0). Vectors
    longer than π are accepted (w < 0 then), as in scipy; beyond the range of
    the fast branch-free sine and cosine (|r| above 2·10⁶ rad, float32 65536
    rad) the rows are redone with libm's, so the result is a unit quaternion
    for any finite angle.

    Parameters
    ----------
    r : array_like, shape (..., 3)
    degrees : bool, optional
        |r| is in degrees.
    out : ndarray, optional
        Result array of shape ``(..., 4)``.

    Returns
    -------
    ndarray, shape (..., 4)

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> np.round(qa.from_rotvec([0, 0, 180], degrees=True), 12)
    array([0., 0., 0., 1.])
    >>> qa.from_rotvec([1e-12, 0, 0])
    array([1.e+00, 5.e-13, 0.e+00, 0.e+00])
    """
    return elementwise(_from_rotvec, [(_radians(r, "r", degrees), "r", V)], [Q], out)


def as_axis_angle(q, degrees=False):
    """Unit rotation axis and angle in [0, π] of each quaternion.

    The axis is that of the canonical sign (w ≥ 0), so the angle never
    exceeds π; the identity gives axis (1, 0, 0) and angle 0; a zero
    quaternion gives nan.

    Parameters
    ----------
    q : array_like, shape (..., 4)
    degrees : bool, optional

    Returns
    -------
    axis : ndarray, shape (..., 3)
    angle : ndarray, shape (...)

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> axis, angle = qa.as_axis_angle([0, 0, -1, 0], degrees=True)
    >>> axis + 0.0, float(np.round(angle, 12))
    (array([0., 1., 0.]), 180.0)
    >>> qa.as_axis_angle(qa.identity())
    (array([1., 0., 0.]), np.float64(0.0))
    """
    axis, ang = elementwise(_as_axis_angle, [(q, "q", Q)], [V, ()])
    return axis, (ang * _TO_DEG if degrees else ang)


def from_axis_angle(axis, angle, degrees=False, out=None):
    """Unit quaternions (cos(θ/2), sin(θ/2)·a/|a|) of axes `a` and angles θ.

    The axis is normalised; a zero axis raises ``ValueError`` naming the row
    (a nan axis gives nan). `axis` and `angle` broadcast against each other;
    any real angle is accepted.

    Parameters
    ----------
    axis : array_like, shape (..., 3)
    angle : array_like, shape (...)
    degrees : bool, optional
    out : ndarray, optional
        Result array of shape ``(..., 4)``.

    Returns
    -------
    ndarray, shape (..., 4)

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> np.round(qa.from_axis_angle([0, 0, 2], 90, degrees=True), 12)
    array([0.70710678, 0.        , 0.        , 0.70710678])
    >>> qa.from_axis_angle([[1, 0, 0], [0, 1, 0]], [0, np.pi]).round(12) + 0.0
    array([[1., 0., 0., 0.],
           [0., 0., 1., 0.]])
    """
    inputs = [(axis, "axis", V), (_radians(angle, "angle", degrees), "angle", ())]
    res, bad = _with_status(_from_axis_angle, inputs, [Q], out)
    if bad >= 0:
        raise ValueError(
            f"Expected `axis` to be non-zero vectors; {where(bad, res.shape[:-1])} is (0, 0, 0)."
        )
    return res


# --------------------------------------------------------------------------
# modified Rodrigues parameters and Gibbs vectors


@element
def qmrp(q):
    """s·u / (|q| + |w|), s = −1 for w < 0: scipy's MRP of the shortest of ±q/|q|
    (|p| ≤ 1), for any scale of q (:func:`_elements.qscaled`); zero q gives nan."""
    return qmrp_raw(E.qscaled(q)[0])[0]


@element
def qmrp_raw(q):
    """(:func:`qmrp` on q as it is, |q|²): no scaling, see :func:`_elements.far_scale`."""
    w = q[0]
    n2 = E.qdot(q, q)
    k = like(w, 1.0) / (np.sqrt(n2) + abs(w))
    k = -k if w < like(w, 0.0) else k
    return (k * q[1], k * q[2], k * q[3]), n2


@element
def mrp_quat(p):
    """((1 − |p|²), 2p) / (1 + |p|²): the unit quaternion of an MRP (w < 0 for |p| > 1)."""
    s = p[0] * p[0] + p[1] * p[1] + p[2] * p[2]
    one = like(s, 1.0)
    k = one / (one + s)
    t = k + k
    return ((one - s) * k, t * p[0], t * p[1], t * p[2])


@element(how="call")
def qgibbs(q):
    """u / w = tan(θ/2)·axis; at w = 0 (a half turn) ±inf along the axis's
    non-zero components, signed as the canonical quaternion; zero q gives nan."""
    w, x, y, z = q
    zero = like(w, 0.0)
    if w != zero:
        return (x / w, y / w, z / w)
    if (x == zero) & (y == zero) & (z == zero):
        nan = like(w, np.nan)
        return (nan, nan, nan)
    inf = like(w, np.inf)
    sg = -like(w, 1.0) if E.canonical_flip(q) else like(w, 1.0)
    return (
        zero if x == zero else sg * np.copysign(inf, x),
        zero if y == zero else sg * np.copysign(inf, y),
        zero if z == zero else sg * np.copysign(inf, z),
    )


@element(how="call")
def gibbs_quat(g):
    """(1, g) / sqrt(1 + |g|²), for any scale of g; infinite components (a half
    turn) give (0, the unit direction of the infinite components)."""
    one = like(g[0], 1.0)
    zero = like(g[0], 0.0)
    if np.isinf(g[0]) | np.isinf(g[1]) | np.isinf(g[2]):
        if np.isnan(g[0]) | np.isnan(g[1]) | np.isnan(g[2]):
            nan = like(g[0], np.nan)
            return (nan, nan, nan, nan)
        return E.qnormalize((
            zero,
            np.copysign(one, g[0]) if np.isinf(g[0]) else zero,
            np.copysign(one, g[1]) if np.isinf(g[1]) else zero,
            np.copysign(one, g[2]) if np.isinf(g[2]) else zero,
        ))  # fmt: skip
    return E.qnormalize((one, g[0], g[1], g[2]))


@element
def _as_mrp_plain(i, args):
    q, out = args
    p, n2 = qmrp_raw(E.load4(q, i))
    E.store3(out, i, p)
    return E.far_scale(n2)


# on q as it is, the rows far from unit scale again on the scaled q (rowloop(far=...))
_as_mrp = rowloop(_as_mrp_plain, far=E.redo(E.store3, qmrp, "as_mrp"))


@rowloop
def _from_mrp(p, out):
    for i in prange(p.shape[0]):
        E.store4(out, i, mrp_quat(E.load3(p, i)))


@rowloop
def _as_gibbs(q, out):
    for i in prange(q.shape[0]):
        E.store3(out, i, qgibbs(E.load4(q, i)))


@rowloop
def _from_gibbs(g, out):
    for i in prange(g.shape[0]):
        E.store4(out, i, gibbs_quat(E.load3(g, i)))


def as_mrp(q, out=None):
    """Modified Rodrigues parameters tan(θ/4)·axis, as scipy's ``Rotation.as_mrp``.

    The shortest of the two MRPs of each rotation (θ ≤ π, so |p| ≤ 1): the
    sign of `q` is chosen with w ≥ 0 first. Any non-zero scale of `q`; a zero
    quaternion gives nan.

    Parameters
    ----------
    q : array_like, shape (..., 4)
    out : ndarray, optional
        Result array of shape ``(..., 3)``.

    Returns
    -------
    ndarray, shape (..., 3)

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> np.round(qa.as_mrp(qa.from_rotvec([0, 0, np.pi])), 12)  # half turn: |p| = 1
    array([0., 0., 1.])
    >>> np.round(qa.as_mrp([0, 0, 0, -2]), 12) + 0.0  # any scale, either sign
    array([ 0.,  0., -1.])
    """
    return elementwise(_as_mrp, [(q, "q", Q)], [V], out)


def from_mrp(p, out=None):
    """Unit quaternions of modified Rodrigues parameters, as scipy's ``Rotation.from_mrp``.

    q = ((1 − |p|²), 2p) / (1 + |p|²); |p| > 1 (the longer of the two MRPs of
    a rotation) gives w < 0, as in scipy (the same rotation).

    Parameters
    ----------
    p : array_like, shape (..., 3)
    out : ndarray, optional
        Result array of shape ``(..., 4)``.

    Returns
    -------
    ndarray, shape (..., 4)

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> qa.from_mrp([0, 0, 1])  # a half turn about z
    array([0., 0., 0., 1.])
    >>> np.allclose(qa.as_mrp(qa.from_mrp([0.1, -0.2, 0.3])), [0.1, -0.2, 0.3])
    True
    """
    return elementwise(_from_mrp, [(p, "p", V)], [Q], out)


def as_gibbs(q, out=None):
    """Gibbs (Rodrigues) vectors g = u/w = tan(θ/2)·axis.

    The same for q and −q and any non-zero scale. A half turn (w = 0) gives
    inf along the axis (signed as the canonical quaternion, 0 for zero
    components of the axis); a zero quaternion gives nan.

    Parameters
    ----------
    q : array_like, shape (..., 4)
    out : ndarray, optional
        Result array of shape ``(..., 3)``.

    Returns
    -------
    ndarray, shape (..., 3)

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> np.round(qa.as_gibbs(qa.from_rotvec([0, np.pi / 2, 0])), 12)  # tan(45°) = 1
    array([0., 1., 0.])
    >>> qa.as_gibbs([0, 0, -1, 0])
    array([ 0., inf,  0.])
    """
    return elementwise(_as_gibbs, [(q, "q", Q)], [V], out)


def from_gibbs(g, out=None):
    """Unit quaternions (1, g)/sqrt(1 + |g|²) of Gibbs vectors, so w ≥ 0.

    Any finite scale of g; infinite components give the half turn (w = 0)
    about the direction of the infinite components (the inverse of
    :func:`as_gibbs` at a half turn about an axis with ≤ 1 non-zero
    component, or with all its components infinite).

    Parameters
    ----------
    g : array_like, shape (..., 3)
    out : ndarray, optional
        Result array of shape ``(..., 4)``.

    Returns
    -------
    ndarray, shape (..., 4)

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> np.round(qa.as_rotvec(qa.from_gibbs([0, 0, 1])), 12)  # tan(θ/2) = 1: θ = 90°
    array([0.        , 0.        , 1.57079633])
    >>> qa.from_gibbs([np.inf, 0, 0])
    array([0., 1., 0., 0.])
    """
    return elementwise(_from_gibbs, [(g, "g", V)], [Q], out)
