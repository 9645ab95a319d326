"""``spline(method="cubic")``: scipy's :class:`~scipy.spatial.transform.RotationSpline`.

The curve of segment n (times t_n ≤ t ≤ t_{n+1}, τ = t − t_n) is
q_n ⊗ Exp(ρ(τ)) with ρ a cubic in τ, ρ(0) = 0 and ρ(h_n) = r_n = Log(q_n* ⊗ q_{n+1})
(the shortest rotation vector between the keys). Its coefficients follow from
the body angular rates ω_k at the keys, chosen so that the angular rate and
acceleration are continuous (C² in time): the end rates are r_0/h_0 and
r_{K−2}/h_{K−2}, the interior ones solve scipy's block-tridiagonal system

    2/h_{k−1} J(r_{k−1}) ω_{k−1} + 4(1/h_{k−1} + 1/h_k) ω_k + 2/h_k J(r_k)⁻¹ ω_{k+1}
        = 6(r_{k−1}/h_{k−1}² + r_k/h_k²) − N(r_{k−1}, J(r_{k−1})⁻¹ ω_k)

(J the right Jacobian, N its quadratic term: see :mod:`quatarray._rates`),
whose right side depends on the rates: as scipy does, the system is solved up
to 10 times, each time with the right side of the last rates, until no rate
moves by more than 1e-9·(1 + |ω|). Float64 whatever the keys' type, as scipy
computes (:func:`coefficients`). From FUSED_MIN_KEYS keys, three kernels, one
pass over the keys each (:func:`_setup_fused`): :func:`_system` makes what is the same for every pass (the rotation vectors,
the functions of their angles, J(r)⁻¹, the matrix and the right side without
its rate term; a dozen numpy passes did this, 60 % of the set-up at 1.25·10⁵
keys); :func:`_factor` factors the block-tridiagonal matrix (3×3 blocks, block
diagonally dominant), held as a band of 11 diagonals, once by LU, and
:func:`_rate_pass` makes each pass: the right side of a block as the forward
substitution reaches it, the back substitution, and scipy's test, reading each
array once; :func:`_coefs` gives the segments' coefficients. They are kept to
few statements, since each costs compile time on the first call (a setup of
many small 3×3 element functions took 3 s of it); below FUSED_MIN_KEYS keys
:func:`_system` and :func:`_coefs` are numpy passes instead (:func:`_setup_numpy`,
vectorised over the steps), which compile nothing. Then
ρ(τ) = c2 τ + c1 τ² + c0 τ³ with
c2 = ω_n, c1 = (3r − 2hω_n − hρ'_n)/h², c0 = (−2r + hω_n + hρ'_n)/h³,
ρ'_n = J(r_n)⁻¹ ω_{n+1}.

Evaluation (``_eval_cubic`` in :mod:`quatarray.splines`, one kernel per
order, in the keys' float type): the value is q_n ⊗ Exp(ρ), the angular
velocity J(ρ)ρ' and the angular acceleration J(ρ)ρ'' + N(ρ, ρ') (body frame,
radians per time unit: scipy's ``RotationSpline(t, r)(new_t, order)``).
"""

import math

import numpy as np

from ._jit import element, rowloop


MAX_ITER = 10  # scipy's RotationSpline.MAX_ITER
TOL = 1e-9  # and its TOL
NCOEF = 9  # c0, c1, c2 of a segment
KL = 5  # the half width of the system's band: row 3j + a couples columns 3(j − 1) … 3(j + 1) + 2
SMALL = 0.01  # the angle below which the step coefficients take their series (see _steps, _system)
# From this many keys the set-up runs as kernels (_system, _coefs: 2x faster at 1.25·10⁵
# keys); fewer keys take numpy for it, which compiles nothing: the two kernels cost about
# 1.5 s of a first call, and at a few thousand keys the numpy passes take a millisecond or two.
FUSED_MIN_KEYS = 4097

# The numpy part works on components: a vector per step is a column of a (3, K−1) array,
# a scalar per step a (K−1,) array, so that every operation runs on whole contiguous rows.


def _cross(a, b):
    """a × b, component-wise (3, n)."""
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _steps(q):
    """(r, rr, (k1, k2, ki, j1, j2)) of every step k of the unit keys q (K, 4), float64
    and vectorised (no compiling): r_k = Log(q_k* ⊗ q_{k+1}) on the plain great arc
    (3, K−1), rr = |r_k|² and the functions of n = |r_k| that make J(r) = I − k1[r]× + k2[r]×²,
    J(r)⁻¹ = I + ½[r]× + ki[r]×² and N(r, ·) (j1, j2, k2: :func:`quatarray._rates.jac_dot`).

    They are the closed forms of :mod:`quatarray._rates` (from s, c = sin, cos of n/2)
    above n = 0.01 and their Taylor series to n⁴ below: what the closed forms lose there
    to cancellation is at most ε/n² relative, and each multiplies a power of r that
    makes up for it (j2, the worst, ends up ε/n absolute)."""
    qt = np.ascontiguousarray(q.T)
    p, b = qt[:, :-1], qt[:, 1:]
    d0 = np.einsum("ij,ij->j", p, b)
    dv = p[0] * b[1:] - b[0] * p[1:] - _cross(p[1:], b[1:])
    un = np.sqrt(np.einsum("ij,ij->j", dv, dv))
    th = np.arctan2(un, d0)  # the arc's angle on S³, in [0, π]
    r = dv * np.where(un > 0.0, 2.0 * th / np.where(un > 0.0, un, 1.0), 2.0)
    nd = np.sqrt(d0 * d0 + un * un)
    s, c = un / nd, d0 / nd
    n = 2.0 * th
    small = n < SMALL
    m = np.where(small, 1.0, n)  # no 0/0 in the closed forms where they are not used
    n2 = n * n
    k1 = np.where(small, 0.5 - n2 * (1 / 24 - n2 / 720), 2.0 * s * s / (m * m))
    k2 = np.where(small, 1 / 6 - n2 * (1 / 120 - n2 / 5040), (m - 2.0 * s * c) / m**3)
    ki = np.where(small, 1 / 12 + n2 * (1 / 720 + n2 / 30240), (1.0 - 0.5 * m * c / np.where(small, 1.0, s)) / (m * m))
    j1 = np.where(small, 1 / 12 - n2 * (1 / 180 - n2 / 6720), (4.0 * s * s - 2.0 * m * s * c) / m**4)
    j2 = np.where(small, -1 / 60 + n2 * (1 / 1260 - n2 / 60480), (6.0 * s * c - 3.0 * m + 2.0 * m * s * s) / m**5)
    return r, np.einsum("ij,ij->j", r, r), (k1, k2, ki, j1, j2)


def _matrices(r, rr, coeffs):
    """The matrices α I + β [r]× + γ [r]×² of every step, (len(coeffs), 9, n) (row-major
    entries), for vectors r (3, n), rr = |r|² and `coeffs` a list of (α, β, γ) (scalars
    or (n,)); [r]×² = r rᵀ − |r|² I."""
    outer = (r[:, None] * r[None]).reshape(9, -1)
    out = np.empty((len(coeffs), 9, r.shape[1]))
    for m, (alpha, beta, gamma) in zip(out, coeffs):
        m[...] = gamma * outer
        m[::4] += alpha - gamma * rr
        bx, by, bz = beta * r
        m[1] -= bz
        m[2] += by
        m[3] += bz
        m[5] -= bx
        m[6] -= by
        m[7] += bx
    return out




@element
def _mat3(rx, ry, rz, beta, gamma):
    """The 9 entries (row-major) of I + β[r]× + γ[r]×², [r]×² = r rᵀ − |r|² I."""
    d = 1.0 - gamma * (rx * rx + ry * ry + rz * rz)
    return (d + gamma * rx * rx, gamma * rx * ry - beta * rz, gamma * rx * rz + beta * ry,
            gamma * ry * rx + beta * rz, d + gamma * ry * ry, gamma * ry * rz - beta * rx,
            gamma * rz * rx - beta * ry, gamma * rz * ry + beta * rx, d + gamma * rz * rz)


@rowloop(parallel=False)
def _factor(band):
    """Replace the block-tridiagonal matrix held by diagonals in `band` (N + KL, 2KL + 1:
    entry (i, c) at ``band[i, c − i + KL]``, its last KL rows the identity, so that no
    loop needs a bound) by its LU factors, in place, without pivoting (the matrix is
    block diagonally dominant), the pivots' reciprocals on the diagonal."""
    for i in range(band.shape[0] - KL):
        band[i, KL] = 1.0 / band[i, KL]
        for k in range(1, KL + 1):
            f = band[i + k, KL - k] * band[i, KL]
            band[i + k, KL - k] = f
            for c in range(1, KL + 1):
                band[i + k, KL - k + c] -= f * band[i, KL + c]


@rowloop(parallel=False)
def _rate_pass(band, x, w, jinv, r, j1, j2, k2, b0):
    """One pass of the rate iteration, in place: the right side b0 − N(r_j, J(r_j)⁻¹ ω_{j+1})
    of the rates `w` (3, n), the two substitutions of the factored `band` (:func:`_factor`)
    into ``x[KL : KL + 3n]`` (padded with KL zeros both sides), then the new rates into
    `w`. Returns whether no rate moved by more than TOL·(1 + |ω|) (scipy's test).

    With v = J(r)⁻¹ω (`jinv` its 9 entries per step, row-major) and c = r × v:
    N(r, v) = (r·ω)(j1 c + j2 r × c) + k2 v × c. The right side of a block is made as
    the forward substitution reaches it, so a pass reads each array once."""
    n = w.shape[1]
    for j in range(n):
        w0, w1, w2 = w[0, j], w[1, j], w[2, j]
        r0, r1, r2 = r[0, j], r[1, j], r[2, j]
        v0 = jinv[0, j] * w0 + jinv[1, j] * w1 + jinv[2, j] * w2
        v1 = jinv[3, j] * w0 + jinv[4, j] * w1 + jinv[5, j] * w2
        v2 = jinv[6, j] * w0 + jinv[7, j] * w1 + jinv[8, j] * w2
        c0, c1, c2 = r1 * v2 - r2 * v1, r2 * v0 - r0 * v2, r0 * v1 - r1 * v0
        f = r0 * w0 + r1 * w1 + r2 * w2
        g1, g2 = f * j1[j], f * j2[j]
        x[KL + 3 * j] = b0[0, j] - (g1 * c0 + g2 * (r1 * c2 - r2 * c1) + k2[j] * (v1 * c2 - v2 * c1))
        x[KL + 3 * j + 1] = b0[1, j] - (g1 * c1 + g2 * (r2 * c0 - r0 * c2) + k2[j] * (v2 * c0 - v0 * c2))
        x[KL + 3 * j + 2] = b0[2, j] - (g1 * c2 + g2 * (r0 * c1 - r1 * c0) + k2[j] * (v0 * c1 - v1 * c0))
        # the nearest neighbour last: each row then waits for the one before by one multiply-add
        for i in range(3 * j, 3 * j + 3):
            e = x[KL + i]
            for c in range(KL, 0, -1):
                e -= band[i, KL - c] * x[KL + i - c]
            x[KL + i] = e
    for i in range(3 * n - 1, -1, -1):
        e = x[KL + i]
        for c in range(KL, 0, -1):
            e -= band[i, KL + c] * x[KL + i + c]
        x[KL + i] = e * band[i, KL]
    done = True
    for j in range(n):
        for a in range(3):
            s = x[KL + 3 * j + a]
            done = done and abs(s - w[a, j]) < TOL * (1.0 + abs(s))
            w[a, j] = s
    return done


@rowloop(parallel=False)
def _system(q, dt, r, ki, j1, j2, k2, jinv, band, b0, w):
    """Everything of the rate system that is the same for every pass, in one pass over
    the steps (it was a dozen numpy passes, 60 % of the set-up at 1.25·10⁵ keys):
    for step j of the unit keys q (K, 4), with m = K − 1 steps dt and n = m − 1
    unknown rates, r_j = Log(q_j* ⊗ q_{j+1}) (3, m) and the functions of its angle
    (ki, j1, j2, k2 (m,): closed forms from sin and cos of half the angle above SMALL,
    Taylor series below), J(r_j)⁻¹ (9, n), the band of the matrix (:func:`_factor`'s
    layout, its last KL rows the identity), the right side b0 (3, n) with the known
    end rates moved to it, and the start of the iteration w (3, n), the rates of the
    steps behind the keys. The band's other entries are the zeros of its array."""
    m = dt.shape[0]
    n = m - 1
    for i in range(3 * n, 3 * n + KL):
        band[i, KL] = 1.0
    for j in range(m):
        d0 = q[j, 0] * q[j + 1, 0] + q[j, 1] * q[j + 1, 1] + q[j, 2] * q[j + 1, 2] + q[j, 3] * q[j + 1, 3]
        # vec(p* ⊗ b) = p0 b − b0 p − p × b
        for a in range(3):
            u, v = (a + 1) % 3 + 1, (a + 2) % 3 + 1
            r[a, j] = q[j, 0] * q[j + 1, a + 1] - q[j + 1, 0] * q[j, a + 1] - (q[j, u] * q[j + 1, v] - q[j, v] * q[j + 1, u])
        un = math.sqrt(r[0, j] * r[0, j] + r[1, j] * r[1, j] + r[2, j] * r[2, j])
        th = math.atan2(un, d0)  # the arc's angle on S³, in [0, π]
        f = 2.0 * th / un if un > 0.0 else 2.0
        for a in range(3):
            r[a, j] *= f
        nd = math.sqrt(d0 * d0 + un * un)
        sn, cs = un / nd, d0 / nd
        x = 2.0 * th
        x2 = x * x
        if x < SMALL:
            kk1 = 0.5 - x2 * (1 / 24 - x2 / 720)
            k2[j] = 1 / 6 - x2 * (1 / 120 - x2 / 5040)
            ki[j] = 1 / 12 + x2 * (1 / 720 + x2 / 30240)
            j1[j] = 1 / 12 - x2 * (1 / 180 - x2 / 6720)
            j2[j] = -1 / 60 + x2 * (1 / 1260 - x2 / 60480)
        else:
            kk1 = 2.0 * sn * sn / x2
            k2[j] = (x - 2.0 * sn * cs) / (x2 * x)
            ki[j] = (1.0 - 0.5 * x * cs / sn) / x2
            j1[j] = (4.0 * sn * sn - 2.0 * x * sn * cs) / (x2 * x2)
            j2[j] = (6.0 * sn * cs - 3.0 * x + 2.0 * x * sn * sn) / (x2 * x2 * x)
        h = dt[j]
        rx, ry, rz = r[0, j], r[1, j], r[2, j]
        if j < n:  # block row j (key j + 1): its left block 2/h_j J(r_j), diagonal, start rate
            e = _mat3(rx, ry, rz, -kk1, k2[j])
            g = 2.0 / h if j > 0 else 0.0  # (row 0 has no left block: the known end rate)
            i = 3 * j
            band[i, 2], band[i, 3], band[i, 4] = g * e[0], g * e[1], g * e[2]
            band[i + 1, 1], band[i + 1, 2], band[i + 1, 3] = g * e[3], g * e[4], g * e[5]
            band[i + 2, 0], band[i + 2, 1], band[i + 2, 2] = g * e[6], g * e[7], g * e[8]
            dg = 4.0 * (1.0 / h + 1.0 / dt[j + 1])
            band[i, KL], band[i + 1, KL], band[i + 2, KL] = dg, dg, dg
            w[0, j], w[1, j], w[2, j] = rx / h, ry / h, rz / h
        e = _mat3(rx, ry, rz, 0.5, ki[j])  # J(r_j)⁻¹
        if j < n:
            jinv[0, j], jinv[1, j], jinv[2, j], jinv[3, j], jinv[4, j] = e[0], e[1], e[2], e[3], e[4]
            jinv[5, j], jinv[6, j], jinv[7, j], jinv[8, j] = e[5], e[6], e[7], e[8]
        if 0 < j < n:  # block row j − 1: its right block 2/h_j J(r_j)⁻¹
            g = 2.0 / h
            i = 3 * j - 3
            band[i, 8], band[i, 9], band[i, 10] = g * e[0], g * e[1], g * e[2]
            band[i + 1, 7], band[i + 1, 8], band[i + 1, 9] = g * e[3], g * e[4], g * e[5]
            band[i + 2, 6], band[i + 2, 7], band[i + 2, 8] = g * e[6], g * e[7], g * e[8]
        if j > 0:  # block row j − 1: its right side
            for a in range(3):
                b0[a, j - 1] = 6.0 * (r[a, j - 1] / (dt[j - 1] * dt[j - 1]) + r[a, j] / (h * h))
    # the known end rates r_0/h_0 and r_{m−1}/h_{m−1}, to the right side:
    # 2/h_0 J(r_0) r_0/h_0 = 2 r_0/h_0² (J(r) r = r), and 2/h J(r)⁻¹ r/h = 2 r/h² likewise
    if n > 0:
        for a in range(3):
            b0[a, 0] -= 2.0 / dt[0] * (r[a, 0] / dt[0])
            b0[a, n - 1] -= 2.0 / dt[m - 1] * (r[a, m - 1] / dt[m - 1])


@rowloop(parallel=False)
def _coefs(r, ki, dt, w, coef):
    """coef (m, 9) = (c0, c1, c2) of every step from r (3, m), ki, dt and the interior
    rates w (3, m − 1) (the end rates are r_0/h_0 and r_{m−1}/h_{m−1}):
    c2 = ω_n, c1 = (3r − 2hω_n − hρ'_n)/h², c0 = (−2r + hω_n + hρ'_n)/h³, with
    ρ'_n = J(r_n)⁻¹ ω_{n+1} = ω_{n+1} + ½ r × ω_{n+1} + ki r × (r × ω_{n+1})."""
    m = dt.shape[0]
    for j in range(m):
        h = dt[j]
        rx, ry, rz = r[0, j], r[1, j], r[2, j]
        if j == 0:
            sx, sy, sz = rx / h, ry / h, rz / h
        else:
            sx, sy, sz = w[0, j - 1], w[1, j - 1], w[2, j - 1]
        if j == m - 1:
            ex, ey, ez = rx / h, ry / h, rz / h
        else:
            ex, ey, ez = w[0, j], w[1, j], w[2, j]
        cx, cy, cz = ry * ez - rz * ey, rz * ex - rx * ez, rx * ey - ry * ex
        ccx, ccy, ccz = ry * cz - rz * cy, rz * cx - rx * cz, rx * cy - ry * cx
        k = ki[j]
        dx, dy, dz = ex + 0.5 * cx + k * ccx, ey + 0.5 * cy + k * ccy, ez + 0.5 * cz + k * ccz
        coef[j, 0] = (-2.0 * rx + h * sx + h * dx) / (h * h * h)
        coef[j, 1] = (-2.0 * ry + h * sy + h * dy) / (h * h * h)
        coef[j, 2] = (-2.0 * rz + h * sz + h * dz) / (h * h * h)
        coef[j, 3] = (3.0 * rx - 2.0 * h * sx - h * dx) / (h * h)
        coef[j, 4] = (3.0 * ry - 2.0 * h * sy - h * dy) / (h * h)
        coef[j, 5] = (3.0 * rz - 2.0 * h * sz - h * dz) / (h * h)
        coef[j, 6], coef[j, 7], coef[j, 8] = sx, sy, sz


def _setup_fused(q, dt, coef):
    """Segment coefficients (K−1, 9) = (c0, c1, c2) of scipy's RotationSpline through
    the unit, unflipped keys q (K, 4) with steps dt (K−1,), all float64, into `coef`.
    Returns the number of passes the rate iteration took (0 for two keys).

    The rate iteration is scipy's: up to MAX_ITER passes, each an exact solve of the
    system whose right side b0 − N(r_j, J(r_j)⁻¹ ω_{j+1}) comes from the last pass's
    rates, until no rate moves by more than TOL·(1 + |ω|). The matrix is factored once.
    Three kernels (:func:`_system`, :func:`_factor` with :func:`_rate_pass`, :func:`_coefs`)
    and no numpy pass over the keys (FUSED_MIN_KEYS keys or more)."""
    m = len(dt)
    n = m - 1  # unknown rates: keys 1 … K−2
    r = np.empty((3, m))
    ki, j1, j2, k2 = np.empty(m), np.empty(m), np.empty(m), np.empty(m)
    jinv = np.empty((9, max(n, 0)))
    band = np.zeros((3 * max(n, 0) + KL, 2 * KL + 1))
    b0 = np.empty((3, max(n, 0)))
    w = np.empty((3, max(n, 0)))
    _system(q, dt, r, ki, j1, j2, k2, jinv, band, b0, w)
    passes = 0
    if n > 0:
        x = np.zeros(3 * n + 2 * KL)
        _factor(band)
        while passes < MAX_ITER:
            passes += 1
            if _rate_pass(band, x, w, jinv, r, j1, j2, k2, b0):
                break
    _coefs(r, ki, dt, w, coef)
    return passes


def _blocks(band, first, shape, strides):
    """The entries ``band.flat[first + Σ strides·index]`` as an array of `shape` (writable)."""
    flat = band.reshape(-1)
    return np.lib.stride_tricks.as_strided(flat[first:], shape, [k * flat.strides[0] for k in strides])


def _setup_numpy(q, dt, coef):
    """Segment coefficients (K−1, 9) = (c0, c1, c2) of scipy's RotationSpline through
    the unit, unflipped keys q (K, 4) with steps dt (K−1,), all float64, into `coef`.
    Returns the number of passes the rate iteration took (0 for two keys).
    Fewer than FUSED_MIN_KEYS keys: what is the same for every pass in numpy (no
    compiling), as :func:`_system` does it in one pass for more keys.

    The rate iteration is scipy's: up to MAX_ITER passes, each an exact solve of the
    system whose right side b0 − N(r_j, J(r_j)⁻¹ ω_{j+1}) comes from the last pass's
    rates, until no rate moves by more than TOL·(1 + |ω|). The matrix is factored once."""
    r, rr, (k1, k2, ki, j1, j2) = _steps(q)
    m = len(dt)
    rate = np.empty((3, m + 1))  # the body rates at the keys: the ends r_0/h_0, r_{K−2}/h_{K−2}
    rate[:, 0] = r[:, 0] / dt[0]
    rate[:, 1:] = r / dt  # the start of the iteration: the rates of the steps behind
    passes = 0
    n = m - 1  # unknown rates: keys 1 … K−2
    if n > 0:
        jac, jinv = _matrices(r, rr, [(1.0, -k1, k2), (1.0, 0.5, ki)])  # J(r), J(r)⁻¹
        # row j (key j + 1): left 2/h_j J(r_j), diagonal 4(1/h_j + 1/h_{j+1}) I, right 2/h_{j+1} J(r_{j+1})⁻¹;
        # block j's row a, column b of each is band.flat[3Wj + (W − 1)a + b + KL − 3], [3Wj + Wa + KL],
        # [3Wj + (W − 1)a + b + KL + 3] (W = 2KL + 1 entries a row)
        W = 2 * KL + 1
        band = np.zeros((3 * n + KL, W))
        band[3 * n :, KL] = 1.0
        g = 2.0 / dt[1:n]
        _blocks(band, KL - 3, (n, 3, 3), (3 * W, W - 1, 1))[1:] = (g * jac[:, 1:n]).T.reshape(n - 1, 3, 3)
        _blocks(band, KL, (n, 3), (3 * W, W))[...] = (4.0 * (1.0 / dt[:-1] + 1.0 / dt[1:]))[:, None]
        _blocks(band, KL + 3, (n, 3, 3), (3 * W, W - 1, 1))[:-1] = (g * jinv[:, 1:n]).T.reshape(n - 1, 3, 3)
        b0 = 6.0 * (r[:, :-1] / dt[:-1] ** 2 + r[:, 1:] / dt[1:] ** 2)
        b0[:, 0] -= 2.0 / dt[0] * (jac[:, 0].reshape(3, 3) @ rate[:, 0])  # the known end rates, to the right side
        b0[:, -1] -= 2.0 / dt[-1] * (jinv[:, -1].reshape(3, 3) @ rate[:, -1])
        x = np.zeros(3 * n + 2 * KL)
        _factor(band)
        w = np.ascontiguousarray(rate[:, 1:-1])
        args = (np.ascontiguousarray(jinv[:, :-1]), np.ascontiguousarray(r[:, :-1]), j1[:-1], j2[:-1], k2[:-1], b0)
        while passes < MAX_ITER:
            passes += 1
            if _rate_pass(band, x, w, *args):
                break
        rate[:, 1:-1] = w
    ws, h = rate[:, :-1], dt
    c1 = _cross(r, rate[:, 1:])
    rd = rate[:, 1:] + 0.5 * c1 + ki * _cross(r, c1)  # ρ'(h) = J(r)⁻¹ ω_{n+1}; ρ'(0) = ω_n
    coef[:, 0:3] = ((-2.0 * r + h * ws + h * rd) / h**3).T
    coef[:, 3:6] = ((3.0 * r - 2.0 * h * ws - h * rd) / h**2).T
    coef[:, 6:9] = ws.T
    return passes


def coefficients(t, q):
    """(K−1, 9) float64 coefficients of the cubic spline through unit, unflipped keys
    `q` at float64 times `t`, and the number of rate passes."""
    q64 = np.ascontiguousarray(q, np.float64)
    coef = np.empty((q.shape[0] - 1, NCOEF))
    setup = _setup_fused if q.shape[0] >= FUSED_MIN_KEYS else _setup_numpy
    passes = setup(q64, np.diff(t), coef)
    return coef, passes
