"""Rotations fitted to vectors: Wahba's problem and the shortest arc.

Quaternions are ``(..., 4)`` arrays in (w, x, y, z) order, active rotations
(``rotate(q, b) ≈ a``). :func:`align_vectors` solves many independent
problems at once, one numba kernel pass per problem: it accumulates
B = Σ wᵢ aᵢ bᵢᵀ (in float64), builds Davenport's symmetric 4×4 matrix K
from it and takes the eigenvector of K's largest eigenvalue, found by a
cyclic Jacobi iteration. That eigenvector is the optimal *proper* rotation
(the Kabsch solution with scipy's determinant correction: never a
reflection), and K's other eigenvalues give scipy's ``rssd`` and
sensitivity matrix without an SVD. A pair with infinite weight, or a single
pair, takes scipy's other path: the shortest arc between the primary
vectors, then the best turn about them for the other pairs.

:func:`rotation_between` is that shortest arc, element-wise.
"""

import warnings

import numpy as np

from . import _elements as E
from ._jit import element, exponent_scales, like, prange, rowloop
from ._validate import as_float, elementwise, result_dtype, shape_error, where

V = (3,)
Q = (4,)

# flags set by the kernel, one byte per problem
_SEVERAL_INF = 1  # more than one infinite weight (scipy raises)
_ZERO_PRIMARY = 2  # the primary (infinite-weight or only) pair has a zero vector (scipy raises)
_FIXED = 4  # solved by the primary-pair path (no sensitivity matrix)
_NOT_UNIQUE = 8  # the optimum is not unique (scipy warns)

# s₁ + s₂ below this times s₀ (B's singular values) counts as not unique. scipy tests
# 1e-16 on its SVD, below the rounding of either method: it warns on about 85 % of
# exactly collinear sets. The gaps of davenport's eigenvalues are exact to about 3ε·s₀
# (at most 6.9e-16·s₀ on 2000 random collinear sets), so this warns on all of them.
NOT_UNIQUE = 2e-15

# --------------------------------------------------------------------------
# per-element math


@element(how="call")
def perpendicular(v):
    """scipy's axis for a half turn away from unit `v` (``_align_vectors_fixed``):
    with i the index of v's smallest |component|, r[i−1] = v[i−2], r[i−2] = −v[i−1]."""
    zero = like(v[0], 0.0)
    i = 0
    if abs(v[1]) < abs(v[0]):
        i = 1
    if abs(v[2]) < abs(v[i]):
        i = 2
    if i == 0:
        return (zero, -v[2], v[1])
    if i == 1:
        return (v[2], zero, -v[0])
    return (-v[1], v[0], zero)


@element(how="call")
def vlength(v):
    """|v| without overflow or underflow in the squares (scaled by the largest
    |component|); 0, inf and nan as the plain formula."""
    m = max(max(abs(v[0]), abs(v[1])), abs(v[2]))
    if m > like(m, 0.0) and m < like(m, np.inf):
        x, y, z = v[0] / m, v[1] / m, v[2] / m
        return m * np.sqrt(x * x + y * y + z * z)
    return E.vnorm(v)


@element(how="call")
def shortest_arc(b, a):
    """The rotation of least angle taking the direction of `b` to that of `a`,
    as scipy's ``align_vectors`` builds it for one pair: the turn by
    θ = atan2(|c|, a·b) about c = b × a (of the unit vectors), written
    (cos(θ/2), sin(θ/2) c/|c|): a unit quaternion to rounding, accurate at
    any angle, a half turn included (exactly antiparallel vectors: a half
    turn about :func:`perpendicular` of `a`; equal directions: the
    identity), at any length of `a` and `b` (:func:`vlength`). A zero, inf
    or nan vector gives nan."""
    na = vlength(a)
    nb = vlength(b)
    a = (a[0] / na, a[1] / na, a[2] / na)
    b = (b[0] / nb, b[1] / nb, b[2] / nb)
    c = E.cross(b, a)
    cn = vlength(c)  # near a half turn |c| may be far below the square root of the smallest float
    d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    half = like(cn, 0.5)
    zero = like(cn, 0.0)
    # sin(θ/2) and cos(θ/2) = sin((π − θ)/2), each from an angle that is small where it is:
    # accurate near θ = 0 and near a half turn alike (w exactly 0 for antiparallel vectors)
    sh = np.sin(half * np.arctan2(cn, d))
    ch = np.sin(half * np.arctan2(cn, -d))
    if cn == zero and d < zero:
        c = perpendicular(a)
        cn = E.vnorm(c)
    k = sh / cn if cn > zero else sh * zero  # θ = 0: the identity (nan stays nan)
    return (ch, k * c[0], k * c[1], k * c[2])


@element(how="call")
def davenport(bm, m):
    """Optimal rotation for B = Σ w a bᵀ (row-major 9-tuple, float64); `m` a
    scratch array of 32 float64 (the caller's, so that no kernel allocates).

    Returns ``(q, lam, zeta, kappa, gmin)``: q the unit eigenvector of the
    largest eigenvalue `lam` of Davenport's K (Horn's form, rotating b onto
    a), signed as scipy's Shepperd step signs it (the component of largest
    magnitude positive, ties to x, y, z, then w). The gaps gᵢ = (lam − λᵢ)/2
    to K's other eigenvalues are the pair sums s₁+s₂, s₀+s₂, s₀+s₁ of B's
    singular values (s₂ negated when det B < 0, as scipy's correction), so
    sᵢ = lam − gᵢ: ζ = Πgᵢ and κ = s₀s₁ + s₁s₂ + s₂s₀ of scipy's sensitivity
    matrix, and gmin = s₁ + s₂ for its uniqueness test.
    """
    # B scaled to a largest entry of 1 (K's sums then neither overflow nor underflow)
    c = 0.0
    finite = True
    for x in bm:
        c = abs(x) if abs(x) > c else c
        finite = finite and abs(x) < np.inf
    if not finite:  # a nan or inf in B: no rotation (the iteration would stop at once)
        nan = np.nan
        return (nan, nan, nan, nan), nan, nan, nan, nan
    if not c > 0.0:
        c = 1.0
    sxx, syx, szx = bm[0] / c, bm[1] / c, bm[2] / c  # S = Bᵀ: S_ij = Σ w b_i a_j
    sxy, syy, szy = bm[3] / c, bm[4] / c, bm[5] / c
    sxz, syz, szz = bm[6] / c, bm[7] / c, bm[8] / c
    k01, k02, k03 = syz - szy, szx - sxz, sxy - syx
    k12, k13, k23 = sxy + syx, szx + sxz, syz + szy
    k = (
        sxx + syy + szz, k01, k02, k03,
        k01, sxx - syy - szz, k12, k13,
        k02, k12, -sxx + syy - szz, k23,
        k03, k13, k23, -sxx - syy + szz,
    )  # fmt: skip
    # m: K (of the scaled B), then the eigenvectors V (columns), from the identity
    for i in range(16):
        m[i] = k[i]
        m[16 + i] = 1.0 if i % 5 == 0 else 0.0
    for _ in range(30):
        off = 0.0
        for i in range(3):
            for j in range(i + 1, 4):
                off += m[4 * i + j] * m[4 * i + j]
        if not off > 1e-40:  # converged (quadratically), or nan
            break
        for p in range(3):
            for r in range(p + 1, 4):
                # one Jacobi rotation zeroing entry (p, r) of K (row-major in m[:16]),
                # applied to it (JᵀKJ) and to the eigenvector columns in m[16:] (VJ)
                apr = m[4 * p + r]
                if apr == 0.0:
                    continue
                tau = (m[5 * r] - m[5 * p]) / (2.0 * apr)
                if abs(tau) > 1e150:
                    t = 0.5 / tau
                else:
                    t = 1.0 / (abs(tau) + np.sqrt(1.0 + tau * tau))
                    t = -t if tau < 0.0 else t
                cs = 1.0 / np.sqrt(1.0 + t * t)
                sn = t * cs
                for k in range(8):  # columns p, r of K (k < 4) and of V
                    base = 16 * (k // 4) + 4 * (k % 4)
                    x, y = m[base + p], m[base + r]
                    m[base + p] = cs * x - sn * y
                    m[base + r] = sn * x + cs * y
                for k in range(4):  # rows p, r of K
                    x, y = m[4 * p + k], m[4 * r + k]
                    m[4 * p + k] = cs * x - sn * y
                    m[4 * r + k] = sn * x + cs * y
    top = 0
    for i in range(1, 4):
        if m[5 * i] > m[5 * top]:
            top = i
    lam = m[5 * top] * c
    # the gaps gᵢ = (lam − λᵢ)/2 and the singular values sᵢ = lam − gᵢ
    zeta = 1.0
    gmin = np.inf
    ssum = 0.0
    ssq = 0.0
    for i in range(4):
        if i != top:
            gi = 0.5 * (lam - m[5 * i] * c)
            si = lam - gi
            zeta *= gi
            gmin = min(gmin, gi)
            ssum += si
            ssq += si * si
    kappa = 0.5 * (ssum * ssum - ssq)
    big = 1
    for j in range(2, 5):  # x, y, z, then w
        if abs(m[16 + 4 * (j % 4) + top]) > abs(m[16 + 4 * big + top]):
            big = j % 4
    f = -1.0 if m[16 + 4 * big + top] < 0.0 else 1.0
    q = (f * m[16 + top], f * m[20 + top], f * m[24 + top], f * m[28 + top])
    return q, lam, zeta, kappa, gmin


@element(how="call")
def load_pair(a, b, w, p, i, ra, rb):
    """Pair i of problem p as float64, its vectors times `ra` and `rb` (see
    :func:`pair_scale`): (ra a_i, rb b_i, w_i). (``np.float64``: numba's ``float()``
    of a float32 stays float32.)"""
    f = np.float64
    return (
        (ra * f(a[p, i, 0]), ra * f(a[p, i, 1]), ra * f(a[p, i, 2])),
        (rb * f(b[p, i, 0]), rb * f(b[p, i, 1]), rb * f(b[p, i, 2])),
        f(w[p, i]),
    )


# The range of a problem's Σ wᵢ|aᵢ|² and Σ wᵢ|bᵢ|² in which its sums of products (B,
# whose entries they bound) are formed on the vectors as they are: outside (or 0, inf,
# nan), they are formed again on a and b each scaled by a power of two (pair_scale),
# lest they have overflowed or underflowed. The common case costs one pass.
SAFE = (2.0**-600, 2.0**600)


@element(how="call")
def pair_scale(x, p, skip):
    """A power of two r (exact) that brings the largest |component| m of problem p's
    vectors in `x` (a or b) into [2, 4): sums of products of r_a·a and r_b·b (B,
    |a|², |b|²) then neither overflow nor underflow whatever the vectors' magnitudes;
    B and the singular values of the scaled problem are r_a r_b times its own. A
    subnormal m (below 2.2e-308; float32 vectors are read as float64, where none of
    theirs is subnormal) gets 2^1023, the largest power of two (2^(1−E) would
    overflow), which brings it into [2^-51, 2): still far from underflow in the
    squares. 1 when m is 0, inf or nan. Pair `skip` does not count (−1: none)."""
    m = 0.0
    for i in range(x.shape[1]):
        if i != skip:
            for j in range(3):
                m = max(m, abs(np.float64(x[p, i, j])))
    r, c = exponent_scales(m)
    if (c > 0.0) & (r > 0.0) & (m < np.inf):
        return r
    if m > 0.0 and m < TINY:  # subnormal: 2^(1−E) would overflow
        return 2.0**1023
    return 1.0


TINY = 2.0**-1022  # the smallest normal float64


@element(how="call")
def unscale(ra, rb):
    """(t, x, y) with 1/ra = t·x and 1/rb = t·y, t = max(1/ra, 1/rb) (powers of two):
    a sum of squares of the unscaled problem, Σ|a − b|² = t²·Σ|x·ra·a − y·rb·b|², is
    then formed without overflow and its square root taken as t·sqrt(…)."""
    t = max(1.0 / ra, 1.0 / rb)
    return t, 1.0 / ra / t, 1.0 / rb / t


@element(how="call")
def accumulate(a, b, w, p, ra, rb):
    """(B, Σ wᵢ|aᵢ|², Σ wᵢ|bᵢ|², Σ wᵢ, the number of infinite weights, the first one's
    pair) of problem p, its vectors a times `ra` and b times `rb`; B = Σ wᵢ aᵢ bᵢᵀ row-major."""
    bm = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    ssa = 0.0
    ssb = 0.0
    wsum = 0.0
    ninf = 0
    kinf = 0
    for i in range(a.shape[1]):
        ai, bi, wi = load_pair(a, b, w, p, i, ra, rb)
        if wi == np.inf:
            if ninf == 0:
                kinf = i
            ninf += 1
        wa = (wi * ai[0], wi * ai[1], wi * ai[2])
        bm = (
            bm[0] + wa[0] * bi[0], bm[1] + wa[0] * bi[1], bm[2] + wa[0] * bi[2],
            bm[3] + wa[1] * bi[0], bm[4] + wa[1] * bi[1], bm[5] + wa[1] * bi[2],
            bm[6] + wa[2] * bi[0], bm[7] + wa[2] * bi[1], bm[8] + wa[2] * bi[2],
        )  # fmt: skip
        ssa += wi * (ai[0] * ai[0] + ai[1] * ai[1] + ai[2] * ai[2])
        ssb += wi * (bi[0] * bi[0] + bi[1] * bi[1] + bi[2] * bi[2])
        wsum += wi
    return bm, ssa, ssb, wsum, ninf, kinf


@element(how="call")
def fixed_fit(a, b, w, p, k):
    """scipy's ``_align_vectors_fixed`` for problem p with primary pair k:
    the shortest arc between the primary vectors, then the turn φ about the
    primary direction that best aligns the other pairs. Returns (q, rssd).

    The primary pair enters only through directions (:func:`shortest_arc`,
    :func:`vlength`); the other pairs are read scaled by powers of two of their
    own (:func:`pair_scale`), which leaves φ as it is, so no magnitude of either
    underflows the other's turn."""
    n = a.shape[1]
    skip = k if n > 1 else -1
    ra = pair_scale(a, p, skip)
    rb = pair_scale(b, p, skip)
    ak, bk, wk = load_pair(a, b, w, p, k, 1.0, 1.0)
    q = shortest_arc(bk, ak)
    if n > 1:
        if max(max(abs(ak[0]), abs(ak[1])), abs(ak[2])) < TINY:
            # a subnormal a_k's length keeps too few digits to divide by: its direction from
            # a_k times 2^1023 (exact)
            ak = (2.0**1023 * ak[0], 2.0**1023 * ak[1], 2.0**1023 * ak[2])
        na = vlength(ak)
        u = (ak[0] / na, ak[1] / na, ak[2] / na)
        sin_sum = 0.0
        cos_sum = 0.0
        for i in range(n):
            if i != k:
                ai, bi, wi = load_pair(a, b, w, p, i, ra, rb)
                ci = E.qrotate(q, bi)
                ca = E.cross(ci, ai)
                sin_sum += wi * (ca[0] * u[0] + ca[1] * u[1] + ca[2] * u[2])
                cd = ci[0] * ai[0] + ci[1] * ai[1] + ci[2] * ai[2]
                cu = ci[0] * u[0] + ci[1] * u[1] + ci[2] * u[2]
                au = ai[0] * u[0] + ai[1] * u[1] + ai[2] * u[2]
                cos_sum += wi * (cd - cu * au)
        h = 0.5 * np.arctan2(sin_sum, cos_sum)
        sh = np.sin(h)
        q = E.qmul((np.cos(h), sh * u[0], sh * u[1], sh * u[2]), q)
    t, x, y = unscale(ra, rb)  # Σ w|a − R b|² of the unscaled pairs: t²·Σ w|x a' − y R b'|²
    ssd = 0.0
    for i in range(n):
        ai, bi, wi = load_pair(a, b, w, p, i, ra, rb)
        if (n > 1 or wi == np.inf) and i == k:
            continue  # the primary pair is held exactly: it counts 0
        e = E.qrotate(q, bi)
        d0, d1, d2 = x * ai[0] - y * e[0], x * ai[1] - y * e[1], x * ai[2] - y * e[2]
        ssd += wi * (d0 * d0 + d1 * d1 + d2 * d2)
    return q, t * np.sqrt(ssd)


# --------------------------------------------------------------------------
# batched loops


ALIGN_BLOCK = 256  # problems per block of _align (one scratch row each)


@rowloop
def _align(a, b, w, q_out, rssd_out, aux_out, flags, scratch):
    # a, b: (P, n, 3); w: (P, n); q_out (P, 4); rssd_out (P,); aux_out (P, 11): for the
    # sensitivity matrix mean(w)/ζ (κ I + B Bᵀ), B (row-major) and κ of the problem scaled
    # by ra, rb (pair_scale) and F = ra rb mean(w)/ζ of it, so that the matrix is
    # F (κ I + B Bᵀ); scratch (ceil(P / ALIGN_BLOCK), 32) for davenport
    n = a.shape[1]
    m = a.shape[0]
    for blk in prange(scratch.shape[0]):
        for p in range(blk * ALIGN_BLOCK, min(m, (blk + 1) * ALIGN_BLOCK)):
            bm, ssa, ssb, wsum, ninf, kinf = accumulate(a, b, w, p, 1.0, 1.0)
            ra = rb = 1.0
            if not (ssa > SAFE[0] and ssa < SAFE[1] and ssb > SAFE[0] and ssb < SAFE[1]):
                ra = pair_scale(a, p, -1)  # rare: redone on the scaled vectors
                rb = pair_scale(b, p, -1)
                bm, ssa, ssb, wsum, ninf, kinf = accumulate(a, b, w, p, ra, rb)
            nan = np.nan
            flag = 0
            aux = (nan, nan, nan, nan, nan, nan, nan, nan, nan, nan, nan)
            if ninf > 1:
                flag = _SEVERAL_INF
                q = (nan, nan, nan, nan)
                rssd = nan
            elif ninf == 1 or n == 1:  # solved by _align_fixed (compiled only when some problem needs it)
                ak, bk, wk = load_pair(a, b, w, p, kinf, 1.0, 1.0)
                if (ak[0] == 0.0 and ak[1] == 0.0 and ak[2] == 0.0) or (bk[0] == 0.0 and bk[1] == 0.0 and bk[2] == 0.0):
                    flag = _ZERO_PRIMARY
                flag |= _FIXED
                q = (nan, nan, nan, nan)
                rssd = nan
            else:
                q, lam, zeta, kappa, gmin = davenport(bm, scratch[blk])
                t, x, y = unscale(ra, rb)  # sqrt(Σw|a|² + Σw|b|² − 2λ) of the unscaled problem
                rssd = t * np.sqrt(max(ssa * x * x + ssb * y * y - 2.0 * lam * x * y, 0.0))
                if gmin < NOT_UNIQUE * (lam - gmin):
                    flag = _NOT_UNIQUE
                # what scipy's sensitivity matrix mean(w)/ζ (κ I + B Bᵀ) needs (see davenport;
                # formed by the front end only when asked for)
                aux = bm + (kappa, wsum / n / zeta * (ra * rb))
            flags[p] = flag
            E.store4(q_out, p, q)
            rssd_out[p] = rssd
            for j in range(11):
                aux_out[p, j] = aux[j]


@rowloop
def _align_fixed(problems, a, b, w, q_out, rssd_out):
    """Problems with one infinite weight or one pair (``_FIXED`` from :func:`_align`),
    by scipy's primary-pair path (:func:`fixed_fit`)."""
    n = a.shape[1]
    for i in prange(problems.shape[0]):
        p = problems[i]
        k = 0
        for j in range(n - 1, -1, -1):  # the primary pair: the (only) infinite weight, else pair 0
            if w[p, j] == np.inf:
                k = j
        q, rssd = fixed_fit(a, b, w, p, k)
        E.store4(q_out, p, q)
        rssd_out[p] = rssd


@rowloop
def _rotation_between(u, v, out):
    # in float64 whatever the inputs' type: near a half turn the axis u × v loses what
    # float32 arithmetic would round away (5e-5 rad at 1e-3 rad from antiparallel)
    for i in prange(u.shape[0]):
        a = E.load3(u, i)
        b = E.load3(v, i)
        f = np.float64
        E.store4(out, i, shortest_arc((f(a[0]), f(a[1]), f(a[2])), (f(b[0]), f(b[1]), f(b[2]))))


# --------------------------------------------------------------------------
# public functions


def _pairs(x, name):
    """`x` as a float array of shape (..., n, 3); a single vector (3,) is one pair."""
    a = as_float(x, name)
    if a.ndim == 1 and a.shape == V:
        a = a[None]
    if a.ndim < 2 or a.shape[-1] != 3:
        raise shape_error(name, "(..., n, 3)", a.shape)
    return a


def align_vectors(a, b, weights=None, return_sensitivity=False):
    """The rotation q minimising Σ wᵢ‖aᵢ − rotate(q, bᵢ)‖², as scipy's
    ``Rotation.align_vectors(a, b, weights)`` (a ≈ R b), for a batch of problems.

    Davenport's q-method (equivalent to the Kabsch algorithm with scipy's
    determinant correction) on B = Σ wᵢ aᵢ bᵢᵀ, accumulated in float64: the
    result is always a proper rotation, never a reflection. scipy's special
    rules hold:

    - a single vector pair gives the shortest arc from b to a (see
      :func:`rotation_between`);
    - one infinite weight holds that pair exactly (shortest arc between the
      two), and the other pairs fix the turn about it; its pair adds 0 to
      `rssd` (unless it is the only pair).

    More than one infinite weight in a problem, a zero vector in the primary
    (infinite-weight or only) pair, or a negative weight raise ``ValueError``
    naming the problem, as scipy does (scipy also raises for a primary vector
    whose squared norm underflows, below about 1e-162; here such vectors are
    aligned, as are vectors of any other magnitude, subnormal ones included:
    the optimum does not depend on the scale). When the optimum is not unique
    (collinear vectors in `a` or in `b`: s₁ + s₂ < 2·10⁻¹⁵ s₀ for B's
    singular values, see :data:`NOT_UNIQUE`) one ``UserWarning`` per call
    says how many problems are affected, as scipy warns; the rotation
    returned is then one of the optimal ones, with scipy's `rssd`, but not
    necessarily scipy's rotation (which is whichever LAPACK's SVD picks). A
    nan or inf in a problem's vectors or weights gives nan for it.

    Parameters
    ----------
    a, b : array_like, shape (..., n, 3)
        Vectors observed in frames A and B (pairs aᵢ, bᵢ); a single vector
        ``(3,)`` is one pair. Leading dimensions broadcast; both must have the
        same n.
    weights : array_like, shape (..., n), optional
        Non-negative weights (default 1); at most one ``inf`` per problem.
        Cast to the result dtype; they broadcast with the leading dimensions.
    return_sensitivity : bool, optional
        Also return scipy's sensitivity matrix (not for single pairs or
        infinite weights: ``ValueError``, as in scipy).

    Returns
    -------
    q : ndarray, shape (..., 4)
        Unit quaternions (w, x, y, z) with ``rotate(q, b) ≈ a``; the sign is
        scipy's.
    rssd : ndarray, shape (...)
        sqrt(Σ wᵢ ‖aᵢ − rotate(q, bᵢ)‖²) at the optimum.
    sensitivity : ndarray, shape (..., 3, 3)
        Only with ``return_sensitivity=True``.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> a = [[0, 1, 0], [0, 1, 1], [0, 1, 1]]
    >>> b = [[1, 0, 0], [1, 1.1, 0], [1, 0.9, 0]]
    >>> q, rssd = qa.align_vectors(a, b)
    >>> np.round(qa.as_matrix(q), 12) + 0.0
    array([[0., 0., 1.],
           [1., 0., 0.],
           [0., 1., 0.]])
    >>> round(float(rssd), 12)
    0.141421356237

    One pair gives the shortest arc; a batch of two problems:

    >>> q, rssd = qa.align_vectors([1, 0, 0], [0, 1, 0])
    >>> np.round(qa.as_rotvec(q), 12) + 0.0
    array([ 0.        ,  0.        , -1.57079633])
    >>> a = np.random.default_rng(0).standard_normal((2, 5, 3))  # 2 problems of 5 pairs
    >>> q, rssd = qa.align_vectors(a, a)
    >>> np.allclose(qa.distance(q, qa.identity()), 0), rssd.shape
    (True, (2,))
    """
    av = _pairs(a, "a")
    bv = _pairs(b, "b")
    n = av.shape[-2]
    if bv.shape[-2] != n:
        raise ValueError(
            f"Expected `a` and `b` to hold the same number of vectors, got shapes {av.shape} and {bv.shape}."
        )
    core = (n, 3)
    dtype = result_dtype([av, bv])
    if weights is None:
        w = np.ones((n,), dtype)
    else:
        w = as_float(weights, "weights")
        if w.ndim == 0:
            w = w[None]
        if w.shape[-1] != n:
            raise shape_error("weights", f"(..., {n})", w.shape)
        if np.any(w < 0):
            raise ValueError("Expected `weights` to be non-negative; got a negative weight.")
    status = []

    def run(a2, b2, w2, q2, r2, s2):
        if n == 1:
            # single pairs: every problem takes the primary-pair path, and _align (the
            # Davenport kernel) would only set the flags: set here, it is not compiled
            zero = (a2[:, 0] == 0).all(axis=1) | (b2[:, 0] == 0).all(axis=1)  # as _align
            flags = np.where(zero, _ZERO_PRIMARY | _FIXED, _FIXED).astype(np.uint8)
            for x in (q2, r2, s2):
                x.fill(np.nan)
        else:
            if not w2.flags.c_contiguous:  # the default or broadcast weights: one compiled signature serves
                w2 = np.ascontiguousarray(w2)
            flags = np.zeros(a2.shape[0], np.uint8)
            _align(a2, b2, w2, q2, r2, s2, flags, np.empty((-(-a2.shape[0] // ALIGN_BLOCK), 32)))
        fixed = np.flatnonzero((flags & (_FIXED | _ZERO_PRIMARY)) == _FIXED)
        if fixed.size:
            _align_fixed(fixed, a2, b2, w2, q2, r2)
        status.append(flags)

    inputs = [(av, "a", core), (bv, "b", core), (w, "weights", (n,))]
    q, rssd, aux = elementwise(run, inputs, [Q, (), (11,)], result=dtype)
    flags = status[0]
    lead = q.shape[:-1]
    for bit, text in (
        (_SEVERAL_INF, "Expected at most one infinite weight per problem; {} has several."),
        (_ZERO_PRIMARY, "Cannot align zero length primary vectors; {} has one."),
    ):
        if (hit := np.flatnonzero(flags & bit)).size:
            raise ValueError(text.format(where(hit[0], lead)))
    if return_sensitivity and (hit := np.flatnonzero(flags & _FIXED)).size:
        raise ValueError(
            "Cannot return sensitivity matrix with an infinite weight or one vector pair; "
            f"{where(hit[0], lead)} has one."
        )
    if (count := np.count_nonzero(flags & _NOT_UNIQUE)):
        warnings.warn(
            f"Optimal rotation is not uniquely or poorly defined for the given sets of vectors "
            f"({count} of {flags.size} problems).",
            UserWarning,
            stacklevel=2,
        )
    if not return_sensitivity:
        return q, rssd
    # scipy's sensitivity matrix mean(w)/ζ (κ I + B Bᵀ), as F (κ I + B Bᵀ) of the scaled problem (see _align)
    bm = aux[..., :9].reshape(aux.shape[:-1] + (3, 3))
    kappa, f = aux[..., 9, None, None], aux[..., 10, None, None]
    sens = f * (kappa * np.eye(3, dtype=aux.dtype) + bm @ np.swapaxes(bm, -1, -2))
    return q, rssd, sens


def rotation_between(u, v, out=None):
    """The shortest-arc rotation taking the direction of `u` to that of `v`.

    The same rotation as ``align_vectors(v, u)`` for one pair (scipy's rule):
    the rotation by the angle θ between them about u × v. Antiparallel
    vectors get a half turn about an axis perpendicular to v: with i the index
    of v's smallest |component| (the first of equals) and v̂ = v/|v|, the axis
    is (0, −v̂_z, v̂_y) for i = 0, (v̂_z, 0, −v̂_x) for i = 1 and
    (−v̂_y, v̂_x, 0) for i = 2. Zero, inf or nan vectors give nan.
    The lengths of `u` and `v` do not matter. Computed in float64 whatever
    the inputs' type (float32 results are the float64 ones rounded).

    Parameters
    ----------
    u, v : array_like, shape (..., 3)
        Leading dimensions broadcast.
    out : ndarray, optional
        Result array of shape ``(..., 4)``.

    Returns
    -------
    ndarray, shape (..., 4)
        Unit quaternions (w, x, y, z) with w ≥ 0 (w = 0 for a half turn), so
        that ``rotate(q, u)`` points along `v`.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> q = qa.rotation_between([1, 0, 0], [0, 2, 0])
    >>> np.round(qa.rotate(q, [1, 0, 0]), 12) + 0.0
    array([0., 1., 0.])
    >>> np.round(qa.rotation_between([0, 0, 1], [0, 0, -1]), 12) + 0.0  # half turn about y
    array([0., 0., 1., 0.])
    """
    return elementwise(_rotation_between, [(u, "u", V), (v, "v", V)], [Q], out)
