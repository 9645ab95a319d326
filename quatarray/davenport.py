"""Davenport angles: rotations about three (or fewer) arbitrary axes.

Davenport angles generalise Euler angles: the axes need not be the
coordinate axes, only each one orthogonal to the next (the first and the
third may be equal, or not). ``order`` says whether the rotations are about
the fixed axes (``"e"``/``"extrinsic"``) or about the moving ones
(``"i"``/``"intrinsic"``), as in scipy's ``Rotation.from_davenport`` and
``Rotation.as_davenport``, whose results these functions give.

:func:`as_davenport` follows Bernardes & Viollet's general method
("Quaternion to Euler angles conversion: a direct, general and
computationally efficient method", PLoS ONE 17(11), 2022), as scipy does,
with scipy's angle ranges and gimbal-lock rule: the first and third angles
in [-π, π], the second in [-π/2, π/2] shifted by the angle between the first
and the third axis; at gimbal lock (the second angle within 1e-7 rad of its
singular values) the third angle is 0.
"""

import math
import warnings

import numpy as np

from . import _elements as E
from ._jit import like, prange, rowloop
from ._validate import as_float, elementwise

_GIMBAL = (
    "Gimbal lock detected in {n} of {total} rotations. Setting third angle to zero "
    "since it is not possible to uniquely determine all angles."
)


def _order(order):
    """True for an extrinsic `order` (``"e"``, ``"extrinsic"``), False for an intrinsic one."""
    if isinstance(order, str) and order in ("e", "extrinsic"):
        return True
    if isinstance(order, str) and order in ("i", "intrinsic"):
        return False
    raise ValueError(
        "Davenport order should be 'e'/'extrinsic' for extrinsic sequences or "
        f"'i'/'intrinsic' for intrinsic sequences (argument `order`), got {order!r}."
    )


def _unit_axes(axes, k_fixed=None):
    """`axes` as a float array ``(..., k, 3)`` of unit vectors (a ``(3,)`` axis is one
    axis), with 1 ≤ k ≤ 3 (or k = `k_fixed`)."""
    a = as_float(axes, "axes")
    if a.ndim == 0 or a.shape[-1] != 3:
        raise ValueError(f"Expected `axes` to be vectors of length 3, shape (..., k, 3), got {a.shape}.")
    if a.ndim == 1:
        a = a[None]
    k = a.shape[-2]
    if k_fixed is not None and k != k_fixed:
        raise ValueError(f"Expected {k_fixed} axes in `axes`, shape (..., {k_fixed}, 3), got {k} (shape {a.shape}).")
    if not 1 <= k <= 3:
        raise ValueError(f"Expected 1 to 3 axes in `axes`, got {k} (shape {a.shape}).")
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


def _check_orthogonal(a, signed=False):
    """Each axis orthogonal to the next within 1e-7 (scipy's test; `signed`: its
    test in ``as_davenport``, which refuses only positive dot products)."""
    for i in range(a.shape[-2] - 1):
        d = np.einsum("...i,...i->...", a[..., i, :], a[..., i + 1, :])
        bad = d >= 1e-7 if signed else np.abs(d) > 1e-7
        if np.any(bad):
            raise ValueError(
                f"Consecutive axes must be orthogonal (a dot product within 1e-7 of 0); "
                f"axes {i} and {i + 1} of `axes` have dot product {float(np.max(np.abs(d))):.6g}."
            )


# --------------------------------------------------------------------------
# batched loops


@rowloop(parallel=False)
def _from_davenport(angles, axes, extrinsic, out):
    # angles (n, 3), axes (n, 3, 3): the product of the three axis rotations,
    # e_2 e_1 e_0 (extrinsic) or e_0 e_1 e_2 (intrinsic)
    for r in prange(angles.shape[0]):
        half = like(angles, 0.5)
        q = (like(angles, 1.0), like(angles, 0.0), like(angles, 0.0), like(angles, 0.0))
        for i in range(3):
            h = angles[r, i] * half
            s = np.sin(h)
            e = (np.cos(h), s * axes[r, i, 0], s * axes[r, i, 1], s * axes[r, i, 2])
            q = E.qmul(e, q) if extrinsic else E.qmul(q, e)
        E.store4(out, r, q)


@rowloop(parallel=False)
def _as_davenport(q, axes, extrinsic, scale, out, locked):
    # Bernardes & Viollet's method for the axes n1, n2, n3 of each row (scipy's
    # `_compute_davenport_from_quat` and `_get_angles`, non-symmetric form).
    two = like(out, 2.0)
    pi = like(out, math.pi)
    for r in prange(q.shape[0]):
        n1 = (axes[r, 0, 0], axes[r, 0, 1], axes[r, 0, 2])
        n2 = (axes[r, 1, 0], axes[r, 1, 1], axes[r, 1, 2])
        n3 = (axes[r, 2, 0], axes[r, 2, 1], axes[r, 2, 2])
        if not extrinsic:  # the intrinsic angles are the extrinsic ones of the reversed axes
            n1, n3 = n3, n1
        nc = E.cross(n1, n2)
        t = E.vdot(n3, nc)
        # n3 = ±n1 (a symmetric sequence) leaves rounding noise of either sign in
        # t, which would pick either angle set: taken as 0, the set of as_euler
        t = like(t, 0.0) if abs(t) <= like(t, 4.0) * np.finfo(out.dtype).eps else t
        lamb = np.arctan2(t, E.vdot(n3, n1))
        flip = lamb < like(lamb, 0.0)
        if flip:  # the other set of angles, in the ranges of as_euler
            n2 = (-n2[0], -n2[1], -n2[2])
            nc = (-nc[0], -nc[1], -nc[2])
            lamb = -lamb
        sl = np.sin(lamb / two)
        qt = E.qmul((np.cos(lamb / two), sl * n2[0], sl * n2[1], sl * n2[2]), E.load4(q, r))
        u = (qt[1], qt[2], qt[3])
        a = qt[0]
        b = E.vdot(u, n1)
        c = E.vdot(u, n2)
        d = E.vdot(u, nc)
        half_sum = np.arctan2(b, a)
        half_diff = np.arctan2(d, c)
        mid = two * np.arctan2(np.hypot(c, d), np.hypot(a, b))
        eps = like(out, 1e-7)
        case1 = abs(mid) <= eps
        case2 = abs(mid - pi) <= eps
        lock = case1 or case2
        a0 = two * half_sum if case1 else (-two * half_diff if extrinsic else two * half_diff)
        ang0 = a0
        ang2 = like(out, 0.0)
        if not lock:
            if extrinsic:
                ang0 = half_sum - half_diff
                ang2 = half_sum + half_diff
            else:
                ang2 = half_sum - half_diff
                ang0 = half_sum + half_diff
        ang1 = mid - lamb
        full = two * pi
        r0 = (ang0 + pi) % full - pi
        r1 = (ang1 + pi) % full - pi
        r2 = (ang2 + pi) % full - pi
        if flip:
            r1 = -r1
        E.store3(out, r, (r0 * scale, r1 * scale, r2 * scale))
        locked[r] = lock


# --------------------------------------------------------------------------
# public functions


def from_davenport(axes, order, angles, degrees=False):
    """Rotation quaternions from Davenport angles, as scipy's ``Rotation.from_davenport``.

    Parameters
    ----------
    axes : array_like, shape (3,), (k, 3) or (..., k, 3)
        One to three rotation axes (normalised here), each orthogonal to the
        next (within 1e-7 of a zero dot product, else ``ValueError``).
        Leading dimensions broadcast against those of `angles`.
    order : {"e", "extrinsic", "i", "intrinsic"}
        Rotations about the fixed axes (extrinsic) or the moving ones.
    angles : array_like, shape (..., k)
        A scalar is one angle (k = 1).
    degrees : bool, optional

    Returns
    -------
    ndarray, shape (..., 4)
        Unit quaternions (w, x, y, z): e₂ e₁ e₀ (extrinsic) or e₀ e₁ e₂
        (intrinsic), with eᵢ the rotation by angles[..., i] about axes i.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> axes = [[0, 0, 1], [0, 1, 0], [0, 0, 1]]  # z, y, z
    >>> q = qa.from_davenport(axes, "e", [30, 45, 60], degrees=True)
    >>> np.allclose(q, qa.from_euler("zyz", [30, 45, 60], degrees=True))
    True
    >>> qa.from_davenport([0, 0, 1], "i", [[0.1], [0.2]]).shape
    (2, 4)
    """
    extrinsic = _order(order)
    ax = _unit_axes(axes)
    k = ax.shape[-2]
    _check_orthogonal(ax)
    ang = as_float(angles, "angles")
    if ang.ndim == 0:
        ang = ang[None]
    if ang.shape[-1] != k:
        raise ValueError(
            f"Expected `angles` to have shape (..., {k}) to match the {k} axes, got {ang.shape}."
        )
    if degrees:
        ang = ang * ang.dtype.type(math.pi / 180.0)
    if k < 3:  # zero angles about further axes: exact identity factors
        ang = np.concatenate([ang, np.zeros(ang.shape[:-1] + (3 - k,), ang.dtype)], axis=-1)
        pad = np.broadcast_to(np.eye(3, dtype=ax.dtype)[: 3 - k], ax.shape[:-2] + (3 - k, 3))
        ax = np.concatenate([ax, pad], axis=-2)

    def run(a, x, out):
        _from_davenport(a, x, extrinsic, out)

    return elementwise(run, [(ang, "angles", (3,)), (ax, "axes", (3, 3))], [(4,)])


def as_davenport(q, axes, order, degrees=False, suppress_warnings=False):
    """Davenport angles of rotation quaternions, as scipy's ``Rotation.as_davenport``.

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Quaternions (w, x, y, z), any non-zero scale.
    axes : array_like, shape (3, 3) or (..., 3, 3)
        Three axes (rows, normalised here), the second orthogonal to the first
        and to the third (as scipy, a positive dot product of 1e-7 or more
        raises ``ValueError``). Leading dimensions broadcast against `q`'s.
    order : {"e", "extrinsic", "i", "intrinsic"}
    degrees : bool, optional
    suppress_warnings : bool, optional
        Do not warn at gimbal lock.

    Returns
    -------
    ndarray, shape (..., 3)
        The first and third angle in [-π, π], the second in
        [-π/2, π/2] shifted by λ, the angle between the first and the third
        axis about the second (λ = 0 for equal first and third axes). At gimbal
        lock the third angle is 0 and a ``UserWarning`` is issued once.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> axes = np.array([[1, 1, 0], [-1, 1, 0], [0, 0, 1]]) / np.sqrt(2) * [[1], [1], [np.sqrt(2)]]
    >>> q = qa.from_davenport(axes, "i", [0.1, 0.2, 0.3])
    >>> np.round(qa.as_davenport(q, axes, "i"), 12)
    array([0.1, 0.2, 0.3])
    """
    extrinsic = _order(order)
    ax = _unit_axes(axes, k_fixed=3)
    _check_orthogonal(ax, signed=True)
    scale = 180.0 / math.pi if degrees else 1.0
    box = []

    def run(a, x, out):
        locked = np.zeros(a.shape[0], np.bool_)
        _as_davenport(a, x, extrinsic, out.dtype.type(scale), out, locked)
        box.append((int(locked.sum()), a.shape[0]))

    res = elementwise(run, [(q, "q", (4,)), (ax, "axes", (3, 3))], [(3,)])
    n, total = box[0]
    if n and not suppress_warnings:
        warnings.warn(_GIMBAL.format(n=n, total=total), UserWarning, stacklevel=2)
    return res
