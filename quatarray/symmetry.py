"""Symmetry groups of rotations and the reduction of rotations by them.

:func:`create_group` gives the finite rotation groups of 3-D space (the
cyclic groups Cn, the dihedral groups Dn and the rotation groups of the
tetrahedron, octahedron and icosahedron) in the order of scipy's
``Rotation.create_group``; :func:`reduce` picks, for each rotation p, the
member l·p·r of its double coset with the smallest rotation angle (the
largest |w|), as scipy's ``Rotation.reduce`` does.
"""

import math

import numpy as np

from . import _elements as E
from ._jit import like, prange, rowloop
from ._validate import as_float, check_core, float_dtype

Q = (4,)

# --------------------------------------------------------------------------
# groups

_PHI = (1 + math.sqrt(5)) / 2


def _tetrahedral():
    # scipy's rows (x, y, z, w): the identity and the half turns about x, y, z (the
    # rows of the 4×4 identity), then the eight third turns (c, ±c, ±c, ±c)
    c = 0.5
    xyzw = np.concatenate([np.eye(4), [[c, -c, -c, +c], [c, -c, +c, +c], [c, +c, -c, +c], [c, +c, +c, +c],
                                       [c, -c, -c, -c], [c, -c, +c, -c], [c, +c, -c, -c], [c, +c, +c, -c]]])
    return xyzw[:, [3, 0, 1, 2]]


def _octahedral():
    c = math.sqrt(2) / 2
    xyzw = np.array([[+c, 0, 0, +c], [0, +c, 0, +c], [0, 0, +c, +c], [0, 0, -c, +c], [0, -c, 0, +c],
                     [-c, 0, 0, +c], [0, +c, +c, 0], [0, -c, +c, 0], [+c, 0, +c, 0], [-c, 0, +c, 0],
                     [+c, +c, 0, 0], [-c, +c, 0, 0]])  # fmt: skip
    return np.concatenate([_tetrahedral(), xyzw[:, [3, 0, 1, 2]]])


def _icosahedral():
    a, b, c = 0.5, 0.5 / _PHI, _PHI / 2
    # scipy's 48 rows (x, y, z, w), generated in its order: the even permutations
    # of (±a, ±b, ±c, 0) grouped by the first component
    table = [
        (a, b, c, 0), (a, b, -c, 0), (a, c, 0, b), (a, c, 0, -b), (a, -b, c, 0), (a, -b, -c, 0),
        (a, -c, 0, b), (a, -c, 0, -b), (a, 0, b, c), (a, 0, b, -c), (a, 0, -b, c), (a, 0, -b, -c),
        (b, a, 0, c), (b, a, 0, -c), (b, c, a, 0), (b, c, -a, 0), (b, -a, 0, c), (b, -a, 0, -c),
        (b, -c, a, 0), (b, -c, -a, 0), (b, 0, c, a), (b, 0, c, -a), (b, 0, -c, a), (b, 0, -c, -a),
        (c, a, b, 0), (c, a, -b, 0), (c, b, 0, a), (c, b, 0, -a), (c, -a, b, 0), (c, -a, -b, 0),
        (c, -b, 0, a), (c, -b, 0, -a), (c, 0, a, b), (c, 0, a, -b), (c, 0, -a, b), (c, 0, -a, -b),
        (0, a, c, b), (0, a, c, -b), (0, a, -c, b), (0, a, -c, -b), (0, b, a, c), (0, b, a, -c),
        (0, b, -a, c), (0, b, -a, -c), (0, c, b, a), (0, c, b, -a), (0, c, -b, a), (0, c, -b, -a),
    ]  # fmt: skip
    rows = np.array(table)[:, [3, 0, 1, 2]]
    return np.concatenate([_tetrahedral(), rows])


def _cyclic(n, axis):
    h = np.linspace(0, 2 * np.pi, n, endpoint=False) / 2
    q = np.zeros((n, 4))
    q[:, 0] = np.cos(h)
    q[:, 1 + axis] = np.sin(h)
    return q


def _dihedral(n, axis):
    # scipy's order and signs: the cyclic group's rotation vectors (the turns
    # beyond π as the shorter turn the other way: w >= 0), then the half turns
    # about the axes (0, cos t, sin t) rolled by `axis`, as scipy's quaternions
    # of the rotation vectors π (0, cos t, sin t): w = cos(|v|/2) is ±1e-16 by
    # the rounding of |v|, and its sign picks the direction of the rotation
    # vector (as_rotvec, powers) of these half turns, so it is computed as scipy does
    c = _cyclic(n, axis)
    c[c[:, 0] < 0] *= -1
    t = np.linspace(0, np.pi, n, endpoint=False)
    v = np.pi * np.roll(np.stack([np.zeros(n), np.cos(t), np.sin(t)], axis=1), axis, axis=1)
    angle = np.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2])
    half = np.column_stack([np.cos(angle / 2), (np.sin(angle / 2) / angle)[:, None] * v])
    return np.concatenate([c, half])


def create_group(group, axis="Z", dtype=np.float64):
    """The rotations of a finite symmetry group, in the order of scipy's
    ``Rotation.create_group``.

    Parameters
    ----------
    group : str
        ``"I"`` (icosahedral, 60 rotations), ``"O"`` (octahedral, 24),
        ``"T"`` (tetrahedral, 12), ``"Dn"`` (dihedral, 2n) or ``"Cn"``
        (cyclic, n), n a positive integer.
    axis : {"X", "Y", "Z"}, optional
        The principal axis of ``Cn`` and ``Dn`` (either case).
    dtype : float32 or float64, optional

    Returns
    -------
    ndarray, shape (K, 4)
        Unit quaternions (w, x, y, z). The groups "I", "O", "T" contain the
        identity, the half turns about x, y, z and the third turns about the
        diagonals of the cube; ``Cn`` the turns by 2πk/n about `axis`;
        ``Dn`` those and n half turns about axes perpendicular to it.

    Examples
    --------
    >>> import quatarray as qa
    >>> qa.create_group("O").shape
    (24, 4)
    >>> qa.create_group("C2", axis="x").round(12) + 0.0
    array([[1., 0., 0., 0.],
           [0., 1., 0., 0.]])
    """
    if not isinstance(group, str):
        raise ValueError(f"`group` must be a string ('I', 'O', 'T', 'Dn' or 'Cn'), got {group!r}.")  # noqa: TRY004 - as scipy
    if axis not in ("x", "y", "z", "X", "Y", "Z"):
        raise ValueError(f"`axis` must be one of x, y, z, X, Y, Z, got {axis!r}.")
    d = float_dtype(dtype)
    k = "xyz".index(axis.lower())
    if group in ("I", "O", "T"):
        q = {"I": _icosahedral, "O": _octahedral, "T": _tetrahedral}[group]()
    elif group[:1] in ("C", "D") and group[1:].isdigit():
        n = int(group[1:])
        if n < 1:
            raise ValueError(f"Group order must be positive, got {n} in `group` {group!r}.")
        q = (_cyclic if group[0] == "C" else _dihedral)(n, k)
    else:
        raise ValueError(f"`group` must be one of 'I', 'O', 'T', 'Dn', 'Cn' (n a positive integer), got {group!r}.")
    return np.ascontiguousarray(q, dtype=d)


# --------------------------------------------------------------------------
# reduction


@rowloop
def _reduce(p, left, right, out, li, ri):
    # For each row p_r: the (i, j) maximising |w(l_i p_r r_j)| (the first in the
    # order i, then j, among values equal within 8 ulp of 1), and l_i (p_r r_j).
    nl = left.shape[0]
    nr = right.shape[0]
    for r in prange(p.shape[0]):
        a = E.load4(p, r)
        best = like(out, -1.0)
        tie = like(out, 8.0) * np.finfo(out.dtype).eps  # equal within rounding: the first stays
        bi = 0
        bj = 0
        for i in range(nl):
            m = E.qmul(E.load4(left, i), a)
            for j in range(nr):
                b = E.load4(right, j)
                s = abs(m[0] * b[0] - m[1] * b[1] - m[2] * b[2] - m[3] * b[3])
                if s > best + tie:
                    best = s
                    bi = i
                    bj = j
        E.store4(out, r, E.qmul(E.load4(left, bi), E.qmul(a, E.load4(right, bj))))
        li[r] = bi
        ri[r] = bj


def reduce(q, left=None, right=None):
    """Reduce rotations by symmetry groups, as scipy's ``Rotation.reduce``.

    For each q, the rotation l⊗q⊗r with l from `left` and r from `right` whose
    scalar part |w| is largest (the smallest rotation angle): the
    representative of q's class under the symmetries.

    Parameters
    ----------
    q : array_like, shape (..., 4)
    left, right : array_like, shape (L, 4) and (R, 4), optional
        The groups (e.g. :func:`create_group`); a missing one is the identity.

    Returns
    -------
    reduced : ndarray, shape (..., 4)
    left_index, right_index : ndarray of int, shape (...)
        The chosen members (0 where that side is missing). Ties (|w| equal
        within 8 ulp, as for groups sharing members) go to the smallest index
        of `left`, then of `right`; scipy's choice among such ties follows its
        rounding, so the indices may differ from scipy's there (the reduced
        rotation is the same).

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> q = qa.from_rotvec([0, 0, 1.7])  # 97° about z
    >>> red, i, j = qa.reduce(q, qa.create_group("C4"))
    >>> np.round(qa.as_rotvec(red), 12) + 0.0, int(i)
    (array([0.        , 0.        , 0.12920367]), 3)
    """
    a = check_core(as_float(q, "q"), "q", Q)
    sides = []
    for g, name in ((left, "left"), (right, "right")):
        if g is None:
            g = np.array([[1.0, 0.0, 0.0, 0.0]], a.dtype)
        g = check_core(as_float(g, name), name, Q)
        if g.ndim == 1:
            g = g[None]
        if g.ndim != 2 or g.shape[0] == 0:
            raise ValueError(f"Expected `{name}` to have shape (K, 4) with K >= 1, got {g.shape}.")
        sides.append(g)
    dtype = np.result_type(a, *sides)
    flat = np.ascontiguousarray(a.reshape(-1, 4), dtype)
    n = flat.shape[0]
    out = np.empty((n, 4), dtype)
    li = np.zeros(n, np.intp)
    ri = np.zeros(n, np.intp)
    if n:
        _reduce(flat, sides[0].astype(dtype, copy=False), sides[1].astype(dtype, copy=False), out, li, ri)
    lead = a.shape[:-1]
    return out.reshape(lead + Q), li.reshape(lead), ri.reshape(lead)
