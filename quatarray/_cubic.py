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
computes (:func:`_setup`). Three kernels, one pass over the keys each:
:func:`_system` makes what is the same for every pass (the rotation vectors,
the functions of their angles, J(r)⁻¹, the matrix and the right side without
its rate term; a dozen numpy passes did this, 60 % of the set-up at 1.25·10⁵
keys); :func:`_factor` factors the block-tridiagonal matrix (3×3 blocks, block
diagonally dominant), held as a band of 11 diagonals, once by LU, and
:func:`_rate_pass` makes each pass: the right side of a block as the forward
substitution reaches it, the back substitution, and scipy's test, reading each
array once; :func:`_coefs` gives the segments' coefficients. They are kept to
few statements, since each costs compile time on the first call (a setup of
many small 3×3 element functions took 3 s of it). Then
ρ(τ) = c2 τ + c1 τ² + c0 τ³ with
c2 = ω_n, c1 = (3r − 2hω_n − hρ'_n)/h², c0 = (−2r + hω_n + hρ'_n)/h³,
ρ'_n = J(r_n)⁻¹ ω_{n+1}.

Evaluation (``_eval_cubic`` in :mod:`quatarray.splines`, one kernel per
order, in the keys' float type): the value is q_n ⊗ Exp(ρ), the angular
velocity J(ρ)ρ' and the angular acceleration J(ρ)ρ'' + N(ρ, ρ') (body frame,
radians per time unit: scipy's ``RotationSpline(t, r)(new_t, order)``).
"""

import numpy as np

from ._jit import kernel
from ._trace import traced

MAX_ITER = 10  # scipy's RotationSpline.MAX_ITER
TOL = 1e-9  # and its TOL
NCOEF = 9  # c0, c1, c2 of a segment
KL = 5  # the half width of the system's band: row 3j + a couples columns 3(j − 1) … 3(j + 1) + 2
SMALL = 0.01  # the angle below which the step coefficients take their series (see _system)

# A vector per step is a column of a (3, K−1) array, a scalar per step a (K−1,) array.


@traced
def _mat3(rx, ry, rz, rr, beta, gamma):
    """The 9 entries (row-major) of I + β[r]× + γ[r]×², [r]×² = r rᵀ − |r|² I."""
    d = 1.0 - gamma * rr
    return (d + gamma * rx * rx, gamma * rx * ry - beta * rz, gamma * rx * rz + beta * ry,
            gamma * ry * rx + beta * rz, d + gamma * ry * ry, gamma * ry * rz - beta * rx,
            gamma * rz * rx - beta * ry, gamma * rz * ry + beta * rx, d + gamma * rz * rz)


@kernel
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


@kernel
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


@kernel
def _system(q, dt, r, ki, j1, j2, k2, jinv, band, b0, w):
    """Everything of the rate system that is the same for every pass, in one pass over
    the steps (it was a dozen numpy passes, 60 % of the set-up at 1.25·10⁵ keys):
    for step j of the unit keys q (K, 4), with m = K − 1 steps dt and n = m − 1
    unknown rates, r_j = Log(q_j* ⊗ q_{j+1}) (3, m) and the functions of its angle
    (:func:`_angle_coeffs`: ki, j1, j2, k2 (m,)), J(r_j)⁻¹ (9, n), the band of the
    matrix (:func:`_factor`'s layout, its last KL rows the identity), the right side
    b0 (3, n) with the known end rates moved to it, and the start of the iteration
    w (3, n), the rates of the steps behind the keys."""
    m = dt.shape[0]
    n = m - 1
    W = 2 * KL + 1
    pr = (0.0, 0.0, 0.0)
    first = (0.0, 0.0, 0.0)
    for j in range(m):
        p0, p1, p2, p3 = q[j, 0], q[j, 1], q[j, 2], q[j, 3]
        b0_, b1, b2, b3 = q[j + 1, 0], q[j + 1, 1], q[j + 1, 2], q[j + 1, 3]
        d0 = p0 * b0_ + p1 * b1 + p2 * b2 + p3 * b3
        # vec(p* ⊗ b) = p0 b − b0 p − p × b
        dx = p0 * b1 - b0_ * p1 - (p2 * b3 - p3 * b2)
        dy = p0 * b2 - b0_ * p2 - (p3 * b1 - p1 * b3)
        dz = p0 * b3 - b0_ * p3 - (p1 * b2 - p2 * b1)
        un = np.sqrt(dx * dx + dy * dy + dz * dz)
        th = np.arctan2(un, d0)  # the arc's angle on S³, in [0, π]
        f = 2.0 * th / un if un > 0.0 else 2.0
        rx, ry, rz = dx * f, dy * f, dz * f
        nd = np.sqrt(d0 * d0 + un * un)
        sn, cs = un / nd, d0 / nd
        ang = 2.0 * th
        n2 = ang * ang
        if ang < SMALL:
            kk1 = 0.5 - n2 * (1 / 24 - n2 / 720)
            kk2 = 1 / 6 - n2 * (1 / 120 - n2 / 5040)
            kki = 1 / 12 + n2 * (1 / 720 + n2 / 30240)
            jj1 = 1 / 12 - n2 * (1 / 180 - n2 / 6720)
            jj2 = -1 / 60 + n2 * (1 / 1260 - n2 / 60480)
        else:
            kk1 = 2.0 * sn * sn / (ang * ang)
            kk2 = (ang - 2.0 * sn * cs) / ang**3
            kki = (1.0 - 0.5 * ang * cs / sn) / (ang * ang)
            jj1 = (4.0 * sn * sn - 2.0 * ang * sn * cs) / ang**4
            jj2 = (6.0 * sn * cs - 3.0 * ang + 2.0 * ang * sn * sn) / ang**5
        r[0, j], r[1, j], r[2, j] = rx, ry, rz
        ki[j], j1[j], j2[j], k2[j] = kki, jj1, jj2, kk2
        rr = rx * rx + ry * ry + rz * rz
        h = dt[j]
        # J(r) = I − k1 [r]× + k2 [r]×², J(r)⁻¹ = I + ½ [r]× + ki [r]×²; [r]×² = r rᵀ − |r|² I
        jac = _mat3(rx, ry, rz, rr, -kk1, kk2)
        inv = _mat3(rx, ry, rz, rr, 0.5, kki)
        if j < n:  # block row j (key j + 1): its rows zeroed, the left block and the diagonal
            for a in range(3):
                for c in range(W):
                    band[3 * j + a, c] = 0.0
                band[3 * j + a, KL] = 4.0 * (1.0 / h + 1.0 / dt[j + 1])
            if j > 0:
                g = 2.0 / h
                for a in range(3):
                    for c in range(3):
                        band[3 * j + a, KL - 3 - a + c] = g * jac[3 * a + c]
            for a in range(9):
                jinv[a, j] = inv[a]
            w[0, j], w[1, j], w[2, j] = rx / h, ry / h, rz / h
        if j > 0:  # block row j − 1: its right block and right side
            if j < n:
                g = 2.0 / h
                for a in range(3):
                    for c in range(3):
                        band[3 * j - 3 + a, KL + 3 - a + c] = g * inv[3 * a + c]
            hp = dt[j - 1]
            b0[0, j - 1] = 6.0 * (pr[0] / hp**2 + rx / h**2)
            b0[1, j - 1] = 6.0 * (pr[1] / hp**2 + ry / h**2)
            b0[2, j - 1] = 6.0 * (pr[2] / hp**2 + rz / h**2)
        # the known end rates r_0/h_0 and r_{m−1}/h_{m−1}, to the right side: the first
        # kept until its block's right side is written (at j = 1)
        g = 2.0 / h
        ex, ey, ez = rx / h, ry / h, rz / h
        if j == 0:
            first = (g * (jac[0] * ex + jac[1] * ey + jac[2] * ez), g * (jac[3] * ex + jac[4] * ey + jac[5] * ez),
                     g * (jac[6] * ex + jac[7] * ey + jac[8] * ez))
        if j == 1:
            b0[0, 0] -= first[0]
            b0[1, 0] -= first[1]
            b0[2, 0] -= first[2]
        if j == m - 1 and j > 0:
            b0[0, n - 1] -= g * (inv[0] * ex + inv[1] * ey + inv[2] * ez)
            b0[1, n - 1] -= g * (inv[3] * ex + inv[4] * ey + inv[5] * ez)
            b0[2, n - 1] -= g * (inv[6] * ex + inv[7] * ey + inv[8] * ez)
        pr = (rx, ry, rz)
    for i in range(3 * n, 3 * n + KL):
        for c in range(W):
            band[i, c] = 0.0
        band[i, KL] = 1.0


@kernel
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
        coef[j, 0] = (-2.0 * rx + h * sx + h * dx) / h**3
        coef[j, 1] = (-2.0 * ry + h * sy + h * dy) / h**3
        coef[j, 2] = (-2.0 * rz + h * sz + h * dz) / h**3
        coef[j, 3] = (3.0 * rx - 2.0 * h * sx - h * dx) / h**2
        coef[j, 4] = (3.0 * ry - 2.0 * h * sy - h * dy) / h**2
        coef[j, 5] = (3.0 * rz - 2.0 * h * sz - h * dz) / h**2
        coef[j, 6], coef[j, 7], coef[j, 8] = sx, sy, sz


def _setup(q, dt, coef):
    """Segment coefficients (K−1, 9) = (c0, c1, c2) of scipy's RotationSpline through
    the unit, unflipped keys q (K, 4) with steps dt (K−1,), all float64, into `coef`.
    Returns the number of passes the rate iteration took (0 for two keys).

    The rate iteration is scipy's: up to MAX_ITER passes, each an exact solve of the
    system whose right side b0 − N(r_j, J(r_j)⁻¹ ω_{j+1}) comes from the last pass's
    rates, until no rate moves by more than TOL·(1 + |ω|). The matrix is factored once.
    Three kernels (:func:`_system`, :func:`_factor` with :func:`_rate_pass`, :func:`_coefs`)
    and no numpy pass over the keys."""
    m = len(dt)
    n = m - 1  # unknown rates: keys 1 … K−2
    r = np.empty((3, m))
    ki, j1, j2, k2 = np.empty(m), np.empty(m), np.empty(m), np.empty(m)
    jinv = np.empty((9, max(n, 0)))
    band = np.empty((3 * max(n, 0) + KL, 2 * KL + 1))
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


def coefficients(t, q):
    """(K−1, 9) float64 coefficients of the cubic spline through unit, unflipped keys
    `q` at float64 times `t`, and the number of rate passes."""
    q64 = np.ascontiguousarray(q, np.float64)
    coef = np.empty((q.shape[0] - 1, NCOEF))
    passes = _setup(q64, np.diff(t), coef)
    return coef, passes
