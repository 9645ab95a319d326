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
moves by more than 1e-9·(1 + |ω|). Here the block-tridiagonal matrix (3×3
blocks, block diagonally dominant) is factored once by block elimination and
every pass is two sweeps (:func:`_setup`, one kernel, float64 whatever the
keys' type, as scipy computes). Then ρ(τ) = c2 τ + c1 τ² + c0 τ³ with
c2 = ω_n, c1 = (3r − 2hω_n − hρ'_n)/h², c0 = (−2r + hω_n + hρ'_n)/h³,
ρ'_n = J(r_n)⁻¹ ω_{n+1}.

Evaluation (``_eval_cubic`` in :mod:`quatarray.splines`, one kernel per
order, in the keys' float type): the value is q_n ⊗ Exp(ρ), the angular
velocity J(ρ)ρ' and the angular acceleration J(ρ)ρ'' + N(ρ, ρ') (body frame,
radians per time unit: scipy's ``RotationSpline(t, r)(new_t, order)``).
"""

import numpy as np

from ._jit import kernel

MAX_ITER = 10  # scipy's RotationSpline.MAX_ITER
TOL = 1e-9  # and its TOL
NCOEF = 9  # c0, c1, c2 of a segment
KL = 5  # the half width of the system's band: row 3j + a couples columns 3(j − 1) … 3(j + 1) + 2
SMALL = 0.01  # the angle below which the step coefficients take their series (see _steps)


def _steps(q):
    """(r, J, J⁻¹, (j1, j2, k2)) of every step k of the unit keys q (K, 4), float64 and
    vectorised (no compiling): r_k = Log(q_k* ⊗ q_{k+1}) on the plain great arc, the
    Jacobians (K−1, 3, 3) and the coefficients of N(r_k, ·) (:func:`quatarray._rates.jac_dot`).

    The functions of the angle n = |r| are the closed forms of :mod:`quatarray._rates`
    (from s, c = sin, cos of n/2) above n = 0.01 and their Taylor series to n⁴ below:
    what the closed forms lose there to cancellation is at most ε/n² relative, and each
    multiplies a power of r that makes up for it (j2, the worst, ends up ε/n absolute)."""
    p, b = q[:-1], q[1:]
    d0 = np.einsum("ij,ij->i", p, b)
    dv = p[:, :1] * b[:, 1:] - b[:, :1] * p[:, 1:] - np.cross(p[:, 1:], b[:, 1:])
    un = np.sqrt(np.einsum("ij,ij->i", dv, dv))
    th = np.arctan2(un, d0)  # the arc's angle on S³, in [0, π]
    r = dv * np.where(un > 0.0, 2.0 * th / np.where(un > 0.0, un, 1.0), 2.0)[:, None]
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
    sk = np.zeros((len(r), 3, 3))  # [r]×
    sk[:, 0, 1], sk[:, 0, 2], sk[:, 1, 2] = -r[:, 2], r[:, 1], -r[:, 0]
    sk[:, 1, 0], sk[:, 2, 0], sk[:, 2, 1] = r[:, 2], -r[:, 1], r[:, 0]
    sq = sk @ sk
    eye = np.eye(3)
    jm = eye - k1[:, None, None] * sk + k2[:, None, None] * sq
    ji = eye + 0.5 * sk + ki[:, None, None] * sq
    return r, jm, ji, np.stack([j1, j2, k2], axis=1)


@kernel
def _solve(band, b0, r, kn, ji, w):
    """scipy's rate iteration on the interior rates w (3n,) (those of keys 1 … K−2, in
    and out): up to MAX_ITER passes, each an exact solve of the block-tridiagonal system
    whose right side b0 − N(r_j, J(r_j)⁻¹ w_j) comes from the last pass's rates, until no
    rate moves by more than TOL·(1 + |w|). `band` (3n, 2KL + 1) holds the matrix by
    diagonals (``band[i, c − i + KL]`` = entry (i, c)); it is factored in place (LU
    without pivoting: the matrix is block diagonally dominant), once. `ji` (n, 9) is
    J(r_j)⁻¹ row-major, `kn` (n, 3) the coefficients of N. Returns the number of passes.

    Plain loops over small arrays, no calls: the setup's one compiled function."""
    n3 = band.shape[0]
    for i in range(n3):
        for k in range(i + 1, min(n3, i + KL + 1)):
            f = band[k, i - k + KL] / band[i, KL]
            band[k, i - k + KL] = f
            for c in range(i + 1, min(n3, i + KL + 1)):
                band[k, c - k + KL] -= f * band[i, c - i + KL]
    x = np.empty(n3)
    v = np.empty(3)
    cp = np.empty(3)
    passes = 0
    for it in range(MAX_ITER):
        passes += 1
        for j in range(n3 // 3):  # the right side: b0 − N(r_j, J(r_j)⁻¹ w_j)
            for a in range(3):
                v[a] = ji[j, 3 * a] * w[3 * j] + ji[j, 3 * a + 1] * w[3 * j + 1] + ji[j, 3 * a + 2] * w[3 * j + 2]
            dp = r[j, 0] * v[0] + r[j, 1] * v[1] + r[j, 2] * v[2]
            for a in range(3):
                cp[a] = r[j, (a + 1) % 3] * v[(a + 2) % 3] - r[j, (a + 2) % 3] * v[(a + 1) % 3]
            for a in range(3):
                a1, a2 = (a + 1) % 3, (a + 2) % 3
                ccp = r[j, a1] * cp[a2] - r[j, a2] * cp[a1]
                dccp = v[a1] * cp[a2] - v[a2] * cp[a1]
                x[3 * j + a] = b0[3 * j + a] - (dp * (kn[j, 0] * cp[a] + kn[j, 1] * ccp) + kn[j, 2] * dccp)
        for i in range(n3):  # L y = b
            e = x[i]
            for c in range(max(0, i - KL), i):
                e -= band[i, c - i + KL] * x[c]
            x[i] = e
        done = True
        for i in range(n3 - 1, -1, -1):  # U w = y, and the convergence test
            e = x[i]
            for c in range(i + 1, min(n3, i + KL + 1)):
                e -= band[i, c - i + KL] * x[c]
            e /= band[i, KL]
            x[i] = e
            if not abs(e - w[i]) < TOL * (1.0 + abs(e)):
                done = False
        for i in range(n3):  # (a loop: a slice assignment compiles numba's shape-error message)
            w[i] = x[i]
        if done:
            break
    return passes


def _setup(q, dt, coef):
    """Segment coefficients (K−1, 9) = (c0, c1, c2) of scipy's RotationSpline through
    the unit, unflipped keys q (K, 4) with steps dt (K−1,), all float64, into `coef`.
    Returns the number of passes the rate iteration took (0 for two keys)."""
    r, jm, ji, kn = _steps(q)
    m = len(dt)
    rate = np.empty((m + 1, 3))  # the body rates at the keys: the ends r_0/h_0, r_{K−2}/h_{K−2}
    rate[0] = r[0] / dt[0]
    rate[1:] = r / dt[:, None]  # the start of the iteration: the rates of the steps behind
    passes = 0
    n = m - 1  # unknown rates: keys 1 … K−2
    if n > 0:
        # row j (key j + 1): left 2/h_j J(r_j), diagonal 4(1/h_j + 1/h_{j+1}) I, right 2/h_{j+1} J(r_{j+1})⁻¹
        band = np.zeros((n, 3, 2 * KL + 1))
        g = 2.0 / dt[1:n, None]
        for a in range(3):
            band[1:, a, 2 - a : 5 - a] = g * jm[1:n, a]
            band[:, a, KL] = 4.0 * (1.0 / dt[:-1] + 1.0 / dt[1:])
            band[:-1, a, 8 - a : 11 - a] = g * ji[1:n, a]
        b0 = 6.0 * (r[:-1] / dt[:-1, None] ** 2 + r[1:] / dt[1:, None] ** 2)
        b0[0] -= 2.0 / dt[0] * (jm[0] @ rate[0])  # the known end rates, to the right side
        b0[-1] -= 2.0 / dt[-1] * (ji[-1] @ rate[-1])
        w = np.ascontiguousarray(rate[1:-1]).reshape(-1)
        passes = _solve(band.reshape(3 * n, -1), b0.reshape(-1), r, kn, ji.reshape(m, 9), w)
        rate[1:-1] = w.reshape(n, 3)
    ws, rd, h = rate[:-1], np.einsum("kab,kb->ka", ji, rate[1:]), dt[:, None]  # ρ'(0), ρ'(h)
    coef[:, 0:3] = (-2.0 * r + h * ws + h * rd) / h**3
    coef[:, 3:6] = (3.0 * r - 2.0 * h * ws - h * rd) / h**2
    coef[:, 6:9] = ws
    return passes


def coefficients(t, q):
    """(K−1, 9) float64 coefficients of the cubic spline through unit, unflipped keys
    `q` at float64 times `t`, and the number of rate passes."""
    q64 = np.ascontiguousarray(q, np.float64)
    coef = np.empty((q.shape[0] - 1, NCOEF))
    passes = _setup(q64, np.diff(t), coef)
    return coef, passes
