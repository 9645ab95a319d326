"""Quaternion algebra on ``(..., 4)`` arrays in (w, x, y, z) order.

Hamilton convention (i² = j² = k² = ijk = −1). Leading dimensions broadcast
like numpy; float32 stays float32, float64 stays float64, mixed gives
float64. Element-wise functions accept ``out=`` (which may be an input).
"""

import warnings

import numpy as np

from . import _elements as E
from ._jit import element, like, min_rows, prange, rowloop, specialise
from ._validate import as_float, check_core, elementwise, float_dtype, leading_shape, scan, where

Q = (4,)

# --------------------------------------------------------------------------
# batched loops


@rowloop
def _multiply(p, q, out):
    for i in prange(p.shape[0]):
        E.store4(out, i, E.qmul(E.load4(p, i), E.load4(q, i)))


@rowloop
def _conjugate(q, out):
    for i in prange(q.shape[0]):
        E.store4(out, i, E.qconj(E.load4(q, i)))


# The loops over |q|-dependent formulas (rowloop(far=...)) compute them on q as it is;
# a second kernel redoes the rare rows outside the range where that is exact,
# on the scaled q (E.qscaled), only when there are some.


@element
def _inverse_plain(i, args):
    q, out = args
    a = E.load4(q, i)
    n2 = E.qdot(a, a)
    f = E.far_scale(n2)
    E.store4(out, i, E.pick4(f, a, (a[0] / n2, -a[1] / n2, -a[2] / n2, -a[3] / n2)))
    return f


_inverse = rowloop(_inverse_plain, far=E.redo(E.store4, E.qinverse, "inverse"))


@element
def _normalize_plain(i, args):
    q, out = args
    a = E.load4(q, i)
    n2 = E.qdot(a, a)
    f = E.far_scale(n2)
    nn = np.sqrt(n2)
    E.store4(out, i, E.pick4(f, a, (a[0] / nn, a[1] / nn, a[2] / nn, a[3] / nn)))
    return f


_normalize = rowloop(_normalize_plain, far=E.redo(E.store4, E.qnormalize, "normalize"))


@element
def _norm_plain(i, args):
    q, out = args
    a = E.load4(q, i)
    n2 = E.qdot(a, a)
    out[i] = np.sqrt(n2)
    return E.far_scale(n2)


@element
def _norm_scaled(i, args):
    q, out = args
    a = E.load4(q, i)
    if E.far_scale(E.qdot(a, a)):
        out[i] = E.qnorm(a)


_norm = rowloop(_norm_plain, far=_norm_scaled)


@rowloop
def _dot(p, q, out):
    for i in prange(p.shape[0]):
        out[i] = E.qdot(E.load4(p, i), E.load4(q, i))


@rowloop
def _exp(q, out):
    for i in prange(q.shape[0]):
        E.store4(out, i, E.qexp(E.load4(q, i)))


@element
def _log_plain(i, args):
    q, out = args
    a = E.load4(q, i)
    f = E.far_scale(E.qdot(a, a))
    E.store4(out, i, E.pick4(f, a, E.qlog_raw(a)))
    return f


_log = rowloop(_log_plain, far=E.redo(E.store4, E.qlog, "log"))


@rowloop
def _power(q, t, out):
    for i in prange(q.shape[0]):
        ti = t[i]
        if ti == like(ti, 0.0):  # q⁰ = 1 for every q, as numpy's 0.0**0 and nan**0
            E.store4(out, i, (like(ti, 1.0), like(ti, 0.0), like(ti, 0.0), like(ti, 0.0)))
        else:
            E.store4(out, i, E.qexp(E.qscale(E.qlog(E.load4(q, i)), ti)))


@rowloop
def _canonical(q, out):
    for i in prange(q.shape[0]):
        a = E.load4(q, i)
        E.store4(out, i, E.qneg(a) if E.canonical_flip(a) else a)


@element
def _angle_plain(i, args):
    q, out = args
    a = E.load4(q, i)
    out[i] = like(out, 2.0) * E.half_angle_raw(a)
    return E.far_scale(E.qdot(a, a))


@element
def _angle_scaled(i, args):
    q, out = args
    a = E.load4(q, i)
    if E.far_scale(E.qdot(a, a)):
        out[i] = like(out, 2.0) * E.half_angle(E.qscaled(a)[0])


_angle = rowloop(_angle_plain, far=_angle_scaled)


# distance's far rows: |p⁻¹q|² = |p|²|q|² outside the range (the squares of the
# product's components could over- or underflow)


@element
def _distance_plain(i, args):
    p, q, out = args
    d = E.qmul(E.qconj(E.load4(p, i)), E.load4(q, i))
    out[i] = like(out, 2.0) * E.half_angle_raw(d)
    return E.far_scale(E.qdot(d, d))


@element
def _distance_scaled(i, args):
    p, q, out = args
    a, b = E.load4(p, i), E.load4(q, i)
    d = E.qmul(E.qconj(a), b)
    if E.far_scale(E.qdot(d, d)):
        out[i] = like(out, 2.0) * E.half_angle(E.qmul(E.qconj(E.qscaled(a)[0]), E.qscaled(b)[0]))


_distance = rowloop(_distance_plain, far=_distance_scaled)


@rowloop(parallel=False)
def _cumprod(q, out):
    # q, out: (K, M, 4); the scan runs along axis 0 for each of the M columns.
    for m in range(q.shape[1]):
        acc = (q[0, m, 0], q[0, m, 1], q[0, m, 2], q[0, m, 3])
        out[0, m, 0], out[0, m, 1], out[0, m, 2], out[0, m, 3] = acc
        for k in range(1, q.shape[0]):
            acc = E.qmul(acc, (q[k, m, 0], q[k, m, 1], q[k, m, 2], q[k, m, 3]))
            out[k, m, 0], out[k, m, 1], out[k, m, 2], out[k, m, 3] = acc


MEAN_BLOCK = 16384  # rows per partial sum of _outer_sum (blocks run in parallel)


UNIT = False  # rebound to True in _outer_sum_unit


def _outer_sum_rows(q, w, part):
    # For each group g and block b of its rows: part[g, b] (10,) float64 the sums
    # Σ w_i q_i q_iᵀ / |q_i|² (its 10 distinct entries, in the order of _PAIRS) over
    # the rows i of q[g] (G, M, 4), w (G, M) in that block, accumulated in float64.
    # A row far from unit scale (or zero, inf, nan) is first divided by its largest
    # |component| (no overflow or underflow in the squares; zero, inf and nan rows
    # make the sums nan). Ten scalar accumulators per block stay in registers.
    # UNIT (the copy _outer_sum_unit, for Rotation.mean, whose quaternions are unit
    # as scipy's are): Σ w_i q_i q_iᵀ, without the division (a third of the time).
    m = q.shape[1]
    nb = part.shape[1]
    for g in range(q.shape[0]):
        for b in prange(nb):
            s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = s8 = s9 = 0.0
            for i in range(b * MEAN_BLOCK, min(m, (b + 1) * MEAN_BLOCK)):
                a0, a1, a2, a3 = np.float64(q[g, i, 0]), np.float64(q[g, i, 1]), np.float64(q[g, i, 2]), np.float64(q[g, i, 3])
                if UNIT:
                    k = np.float64(w[g, i])
                else:
                    n2 = a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3
                    if E.far_scale(n2):
                        mx = max(max(abs(a0), abs(a1)), max(abs(a2), abs(a3)))
                        a0, a1, a2, a3 = a0 / mx, a1 / mx, a2 / mx, a3 / mx
                        n2 = a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3
                    k = np.float64(w[g, i]) / n2
                s0 += k * a0 * a0
                s1 += k * a0 * a1
                s2 += k * a0 * a2
                s3 += k * a0 * a3
                s4 += k * a1 * a1
                s5 += k * a1 * a2
                s6 += k * a1 * a3
                s7 += k * a2 * a2
                s8 += k * a2 * a3
                s9 += k * a3 * a3
            p = part[g, b]
            p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9] = s0, s1, s2, s3, s4, s5, s6, s7, s8, s9


# serial and parallel dispatchers (the parallel one compiles only for a large sum)
_outer_sum = rowloop(_outer_sum_rows)
_outer_sum_unit = rowloop(specialise(_outer_sum_rows, "_unit", UNIT=True))

_PAIRS = [(0, 0), (0, 1), (0, 2), (0, 3), (1, 1), (1, 2), (1, 3), (2, 2), (2, 3), (3, 3)]


def _outer_sums(qg, wg, unit=False):
    """``(G, 4, 4)`` float64: the symmetric sums of :func:`_outer_sum` for each group."""
    groups, count = qg.shape[:2]
    part = np.zeros((groups, max(1, -(-count // MEAN_BLOCK)), 10))
    if count:
        loop = _outer_sum_unit if unit else _outer_sum
        (loop.parallel if groups * count >= min_rows() else loop.serial)(qg, wg, part)
    s = part.sum(axis=1)
    acc = np.empty((groups, 4, 4))
    for k, (r, c) in enumerate(_PAIRS):
        acc[:, r, c] = acc[:, c, r] = s[:, k]
    return acc


# --------------------------------------------------------------------------
# public functions


def multiply(p, q, out=None):
    """Hamilton product p⊗q.

    Parameters
    ----------
    p, q : array_like, shape (..., 4)
        Quaternions (w, x, y, z); leading dimensions broadcast.
    out : ndarray, optional
        Result array of the broadcast shape and result dtype; may be `p` or `q`.

    Returns
    -------
    ndarray, shape (..., 4)

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.multiply([0, 1, 0, 0], [0, 0, 1, 0])  # i j = k
    array([0., 0., 0., 1.])
    """
    return elementwise(_multiply, [(p, "p", Q), (q, "q", Q)], [Q], out)


def conjugate(q, out=None):
    """Conjugate (w, −x, −y, −z).

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.conjugate([1, 2, 3, 4])
    array([ 1., -2., -3., -4.])
    """
    return elementwise(_conjugate, [(q, "q", Q)], [Q], out)


def inverse(q, out=None):
    """Inverse q* / |q|²; a zero quaternion gives nan.

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.inverse([0, 0, 2, 0])
    array([ 0. ,  0. , -0.5, -0. ])
    """
    return elementwise(_inverse, [(q, "q", Q)], [Q], out)


def norm(q):
    """Norm |q| (not |q|²), shape ``(...)``.

    Examples
    --------
    >>> import quatarray as qa
    >>> float(qa.norm([1, 1, 1, 1]))
    2.0
    """
    return elementwise(_norm, [(q, "q", Q)], [()])


def normalize(q, out=None):
    """q / |q|; a zero quaternion gives nan.

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.normalize([0, 0, 0, 2])
    array([0., 0., 0., 1.])
    """
    return elementwise(_normalize, [(q, "q", Q)], [Q], out)


def dot(p, q):
    """4-D inner product w_p w_q + x_p x_q + y_p y_q + z_p z_q, shape ``(...)``.

    Examples
    --------
    >>> import quatarray as qa
    >>> float(qa.dot([1, 2, 3, 4], [1, 1, 1, 1]))
    10.0
    """
    return elementwise(_dot, [(p, "p", Q), (q, "q", Q)], [()])


def exp(q, out=None):
    """Quaternion exponential e^w (cos|u|, sin|u| u/|u|) of q = (w, u).

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> np.round(qa.exp([0, np.pi / 2, 0, 0]), 12)  # exp(iπ/2) = i
    array([0., 1., 0., 0.])
    """
    return elementwise(_exp, [(q, "q", Q)], [Q], out)


def log(q, out=None):
    """Principal logarithm (log|q|, θ u/|u|), θ = atan2(|u|, w) ∈ [0, π].

    A negative real quaternion (no unique axis) gives (log|w|, π, 0, 0); zero
    gives −inf in w.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> np.allclose(qa.log([0, 1, 0, 0]), [0, np.pi / 2, 0, 0])
    True
    """
    return elementwise(_log, [(q, "q", Q)], [Q], out)


def power(q, t, out=None):
    """q^t = exp(t log q); `t` broadcasts against the leading shape of `q`.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> q = qa.from_rotvec([0, 0, np.pi / 2])
    >>> np.allclose(qa.power(q, 2), qa.multiply(q, q))
    True
    """
    return elementwise(_power, [(q, "q", Q), (t, "t", ())], [Q], out)


def canonical(q, out=None):
    """The sign scipy's ``as_quat(canonical=True)`` picks: w > 0, ties broken by
    the first non-zero of x, y, z being positive. Magnitudes are kept.

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.canonical([-1, 0, 0, 0])
    array([ 1., -0., -0., -0.])
    >>> qa.canonical([0, 0, -1, 0])
    array([-0., -0.,  1., -0.])
    """
    return elementwise(_canonical, [(q, "q", Q)], [Q], out)


def angle(q):
    """Rotation angle in [0, π], 2 atan2(|u|, |w|): accurate for tiny angles and
    independent of the sign and scale of q.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> float(qa.angle(qa.from_rotvec([0, 1e-12, 0])))
    1e-12
    """
    return elementwise(_angle, [(q, "q", Q)], [()])


def distance(p, q):
    """Rotation angle of p⁻¹q in [0, π]: 0 for the same rotation whatever the signs.

    Examples
    --------
    >>> import quatarray as qa
    >>> float(qa.distance([1, 0, 0, 0], [-1, 0, 0, 0]))
    0.0
    """
    return elementwise(_distance, [(p, "p", Q), (q, "q", Q)], [()])


def cumprod(q, axis=0):
    """Running product out[0] = q[0], out[i] = out[i−1]⊗q[i] along a leading axis.

    `axis` counts the leading (non-quaternion) axes, so ``axis=-1`` is the last
    leading axis, never the quaternion axis.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> step = qa.from_rotvec([0, 0, np.pi / 4])
    >>> np.allclose(qa.cumprod(np.tile(step, (4, 1)))[-1], qa.from_rotvec([0, 0, np.pi]))
    True
    """
    return scan(_cumprod, q, axis, "cumprod")


def identity(shape=(), dtype=np.float64):
    """Identity quaternions (1, 0, 0, 0) of leading shape `shape`.

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.identity(2, dtype="float32")
    array([[1., 0., 0., 0.],
           [1., 0., 0., 0.]], dtype=float32)
    """
    dtype = float_dtype(dtype)
    out = np.zeros(leading_shape(shape, "shape") + Q, dtype)
    out[..., 0] = 1
    return out


def random(n=None, rng=None, dtype=np.float64):
    """Uniformly distributed rotations (Haar measure), as unit quaternions.

    Normalised 4-D standard normal samples are uniform on S³.

    Parameters
    ----------
    n : int or tuple, optional
        Leading shape; None gives a single ``(4,)`` quaternion.
    rng : numpy.random.Generator or int, optional
        A generator or a seed.
    dtype : float32 or float64

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.random(3, rng=0).shape
    (3, 4)
    """
    dtype = float_dtype(dtype)
    gen = np.random.default_rng(rng)
    shape = () if n is None else leading_shape(n, "n")
    q = gen.standard_normal(shape + Q)
    nrm = np.linalg.norm(q, axis=-1, keepdims=True)
    while np.any(nrm < 1e-6):  # probability ~0; redraw rather than divide by ~0
        bad = (nrm < 1e-6)[..., 0]
        q[bad] = gen.standard_normal((int(bad.sum()), 4))
        nrm = np.linalg.norm(q, axis=-1, keepdims=True)
    return (q / nrm).astype(dtype)


def _reduce_axes(axis, nlead):
    """scipy 1.17's `axis` of ``Rotation.mean`` as a sorted tuple of leading axes."""
    if axis is None:
        return tuple(range(nlead))
    if isinstance(axis, (int, np.integer)) and not isinstance(axis, bool):
        axis = (int(axis),)
    if not isinstance(axis, tuple) or not all(isinstance(k, (int, np.integer)) for k in axis):
        raise ValueError(f"Expected `axis` to be None, an int or a tuple of ints, got {axis!r}.")
    if any(not -nlead <= k < nlead for k in axis):
        raise ValueError(f"Expected `axis` in [{-nlead}, {nlead - 1}] (the leading axes of `q`), got {axis}.")
    return tuple(sorted({k % nlead for k in axis}))


def mean(q, weights=None, axis=None):
    """Rotation mean as scipy's ``Rotation.mean``: the eigenvector of the largest
    eigenvalue of Σ wᵢ qᵢqᵢᵀ/|qᵢ|² (sign-invariant), over the leading axes `axis`.

    Returns the canonical sign (see :func:`canonical`). Weights that are all
    zero give the identity, as in scipy. A zero, inf or nan quaternion, or a
    negative, inf or nan weight, raises ``ValueError`` naming the first such
    row (scipy refuses zero and nan quaternions and fails to converge on the
    others).

    Parameters
    ----------
    q : array_like, shape (..., 4)
    weights : array_like, optional
        Non-negative, broadcasting against the leading shape of `q`.
    axis : None, int or tuple of int, optional
        The leading axes to average over, as scipy 1.17: None (default) all of
        them, ``()`` none (each rotation is its own mean). A single ``(4,)``
        quaternion counts as one leading axis of length 1 (``axis=0`` or
        ``-1`` give it back), as a single scipy ``Rotation`` does.

    Returns
    -------
    ndarray, shape (..., 4)
        The leading shape of `q` without the axes in `axis`.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> q = qa.from_rotvec([[0, 0, 0.1], [0, 0, -0.1]])
    >>> np.allclose(qa.mean(q), [1, 0, 0, 0])
    True
    >>> qa.mean(qa.random((3, 5), rng=0), axis=1).shape
    (3, 4)
    """
    a, w, red = mean_inputs(q, weights, axis)
    return mean_solve(mean_sums(a, w, red), a.dtype)


# mean in steps: the checked inputs, the sums and the solve. quatarray.dask.mean runs
# the sums on each block and the solve once on the sum of the blocks' sums;
# Rotation.mean takes the sums of unit quaternions and solves in scipy's order.


def mean_inputs(q, weights=None, axis=None):
    """:func:`mean`'s arguments checked: ``(a, w, red)``, the quaternions (..., 4), the
    float64 weights of their leading shape and the sorted leading axes to reduce."""
    a = check_core(as_float(q, "q"), "q", Q)
    if a.ndim == 1 and (axis is not None or np.ndim(weights) > 0):
        a = a[None]  # one quaternion has one leading axis of length 1 for `axis` and weights, as in scipy
    red = mean_axes(a.shape, axis)
    w = mean_weights(weights, a.shape[:-1])
    if weights is not None:
        mean_check_weights(w)
    return a, w, red


def mean_axes(shape, axis):
    """The leading axes :func:`mean` reduces for `q` of `shape` (a sorted tuple);
    ValueError for a bad `axis` or nothing to average."""
    nlead = len(shape) - 1
    red = _reduce_axes(axis, nlead)
    count = int(np.prod([shape[k] for k in red]))
    if int(np.prod(shape)) == 0 or count == 0:
        raise ValueError("Expected `q` to hold at least one quaternion to average, got shape " f"{tuple(shape)}.")
    return red


def mean_weights(weights, lead):
    """:func:`mean`'s `weights` as float64 of the leading shape `lead` (ones for None)."""
    if weights is None:
        return np.broadcast_to(1.0, lead)
    w = as_float(weights, "weights", np.float64)
    try:
        return np.broadcast_to(w, lead)
    except ValueError:
        raise ValueError(f"Expected `weights` to broadcast to {lead}, got {w.shape}.") from None


def mean_check_weights(w):
    """ValueError naming the first negative weight of `w` (the leading shape of q)."""
    if np.any(w < 0):
        k = int(np.argmax((w < 0).reshape(-1)))
        raise ValueError(f"Expected `weights` to be non-negative; {where(k, w.shape)} has weight {w.reshape(-1)[k]}.")


def mean_sums(a, w, red, unit=False):
    """Σ wᵢ qᵢqᵢᵀ/|qᵢ|² (float64, shape ``(kept leading axes) + (4, 4)``, (w, x, y, z)
    order) over the leading axes `red` of the quaternions `a` (..., 4), `w` the
    (non-negative) weights of a's leading shape. `unit`: the quaternions are unit
    (Σ wᵢ qᵢqᵢᵀ, faster). A zero, inf or nan quaternion or weight raises ``ValueError``
    naming the first such row of `a`."""
    lead = a.shape[:-1]
    keep = tuple(k for k in range(len(lead)) if k not in red)
    order = keep + red
    out_lead = tuple(lead[k] for k in keep)
    groups = int(np.prod(out_lead))
    count = int(np.prod([lead[k] for k in red]))
    qg = np.transpose(a, order + (len(lead),)).reshape(groups, count, 4)
    wg = np.transpose(w, order).reshape(groups, count)
    acc = _outer_sums(qg, wg, unit)
    if not np.isfinite(acc).all():
        raise _mean_bad_row(a.reshape(-1, 4), np.broadcast_to(w, lead).reshape(-1), lead)
    return acc.reshape(out_lead + (4, 4))


def mean_solve(acc, dtype):
    """The mean rotations (canonical sign, `dtype`) of the sums `acc` (..., 4, 4) of
    :func:`mean_sums`: the eigenvectors of their largest eigenvalues; all-zero sums (all
    weights zero) give the identity, as in scipy. (`acc`, float64, is changed in place.)"""
    if not np.isfinite(acc).all():  # finite sums of blocks whose total overflows
        raise ValueError("Expected `weights` whose sum is finite; the weighted sum overflows.")
    zero = ~acc.any(axis=(-2, -1))
    acc[zero] = np.diag([1.0, 0.0, 0.0, 0.0])  # all weights zero: scipy's answer, the identity
    vecs = np.linalg.eigh(acc)[1][..., -1]
    return canonical(vecs.astype(dtype))


def _mean_bad_row(flat, w, lead):
    """The ``ValueError`` naming the first row that made :func:`mean`'s sum non-finite."""
    finite = np.isfinite(flat).all(axis=1)
    bad_q = ~finite | ~(flat != 0).any(axis=1)
    bad_w = ~np.isfinite(w)
    k = int(np.argmax(bad_q | bad_w)) if (bad_q | bad_w).any() else None
    if k is None:
        return ValueError("Expected `weights` whose sum is finite; the weighted sum overflows.")
    if bad_q[k]:
        what = "zero" if finite[k] else "not finite"
        return ValueError(f"Expected `q` to be finite and non-zero; {where(k, lead)} is {what}: {flat[k].tolist()}.")
    return ValueError(f"Expected `weights` to be finite; {where(k, lead)} has weight {w[k]}.")


def approx_atol(atol, degrees, stacklevel=3):
    """:func:`approx_equal`'s tolerance in radians, as scipy's: 1e-8 rad by default
    (with a warning when `degrees` is asked without an `atol`), `atol` in degrees
    converted. `stacklevel` points the warning at the caller's caller."""
    if atol is None:
        if degrees:
            warnings.warn("atol must be set to use the degrees flag, defaulting to 1e-8 radians.",
                          stacklevel=stacklevel)
        return 1e-8
    return np.deg2rad(atol) if degrees else atol


def approx_equal(p, q, atol=None, degrees=False):
    """Whether p and q are the same rotation within `atol`, as scipy's
    ``Rotation.approx_equal``: ``distance(p, q) <= atol``. (scipy tests ``<``:
    the two differ only at a distance of exactly `atol`, e.g. ``atol=0`` for
    the same rotation, which is equal here and not in scipy.)

    Sign-blind (q and −q are the same rotation) and scale-blind; leading
    dimensions broadcast. The same rotation given twice (``approx_equal(q, q)``,
    also ``q`` and ``-q``) is equal at any tolerance, ``atol=0`` included: its
    distance is exactly 0.

    float32 quaternions are compared in float64, as scipy compares them (it
    holds every rotation in float64): the distance is then that of the given
    float32 numbers to about 1e-16 rad, where float32 arithmetic would add a
    rounding error of up to about 1e-7 rad, ten times the default `atol`, and
    decide by rounding whether two nearby float32 rotations are equal. This
    costs a float64 copy of float32 inputs; :func:`distance` itself keeps
    float32.

    Parameters
    ----------
    p, q : array_like, shape (..., 4)
    atol : float, optional
        Largest angle between the two; scipy's default 1e-8 rad.
    degrees : bool, optional
        `atol` is in degrees. Without an `atol` this warns and uses 1e-8 rad,
        as scipy does.

    Returns
    -------
    ndarray of bool, shape (...)

    Examples
    --------
    >>> import quatarray as qa
    >>> bool(qa.approx_equal([1, 0, 0, 0], [-2, 0, 0, 0]))
    True
    >>> qa.approx_equal(qa.from_rotvec([[0, 0, 0.01], [0, 0, 0.1]]), qa.identity(), atol=1, degrees=True)
    array([ True, False])
    >>> q = qa.random(1000, rng=0, dtype="float32")
    >>> bool(qa.approx_equal(q, q, atol=0).all() and qa.approx_equal(q, -q).all())
    True
    """
    atol = approx_atol(atol, degrees)
    # float32 in float64 (see above); float64 arrays are not copied
    return np.less_equal(distance(as_float(p, "p", np.float64), as_float(q, "q", np.float64)), atol)
