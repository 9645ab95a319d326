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

import math

import numpy as np

from . import _elements as E
from ._jit import element, inline, kernel, specialise
from ._mat33 import cofactor33, det33, matmul, matvec, scale9
from ._rates import acc_coeffs, inv_coeff, jac_coeffs, jac_dot, log_arc

MAX_ITER = 10  # scipy's RotationSpline.MAX_ITER
TOL = 1e-9  # and its TOL
NCOEF = 9  # c0, c1, c2 of a segment


@inline
def _jmat(r, k1, k2, sgn):
    """I + sgn·k1[r]× + k2[r]×² as a row-major 9-tuple (sgn = −1: J(r); +1 with
    k1 = ½: J(r)⁻¹)."""
    x, y, z = r
    a = sgn * k1
    xx, yy, zz, xy, xz, yz = x * x, y * y, z * z, x * y, x * z, y * z
    return (1.0 - k2 * (yy + zz), -a * z + k2 * xy, a * y + k2 * xz,
            a * z + k2 * xy, 1.0 - k2 * (xx + zz), -a * x + k2 * yz,
            -a * y + k2 * xz, a * x + k2 * yz, 1.0 - k2 * (xx + yy))  # fmt: skip


@element
def _inv33(m):
    c = cofactor33(m)
    d = 1.0 / det33(m)
    return (c[0] * d, c[3] * d, c[6] * d, c[1] * d, c[4] * d, c[7] * d, c[2] * d, c[5] * d, c[8] * d)


@element
def _sub9(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3], a[4] - b[4], a[5] - b[5], a[6] - b[6], a[7] - b[7],
            a[8] - b[8])




# the keys' steps through libm's atan2: the setup loop is not SIMD, and the polynomial
# atan2 of the evaluation loops took LLVM 0.5 s more to compile here
_log_step = inline(specialise(getattr(log_arc, "py_func", log_arc), "_libm", atan2=math.atan2))  # plain: no JIT


@element
def _geometry(p, q):
    """(r, J(r), J(r)⁻¹, (j1, j2, k2)) of the segment from key p to key q: r = Log(p* ⊗ q),
    the Jacobians as 9-tuples and the coefficients of N(r, ·) (:func:`jac_dot`)."""
    r, n2, s, c = _log_step(p, q)
    k1, k2 = jac_coeffs(n2, s, c)
    j1, j2 = acc_coeffs(n2, s, c)
    return r, _jmat(r, k1, k2, -1.0), _jmat(r, 0.5, inv_coeff(n2, s, c), 1.0), (j1, j2, k2)


@element
def _ld9(a, i):
    return (a[i, 0], a[i, 1], a[i, 2], a[i, 3], a[i, 4], a[i, 5], a[i, 6], a[i, 7], a[i, 8])


@element
def _st9(a, i, m):
    for c in range(9):
        a[i, c] = m[c]




@kernel
def _setup(q, dt, coef):
    """Segment coefficients (K−1, 9) = (c0, c1, c2) of scipy's RotationSpline through
    the unit, unflipped keys q (K, 4) with steps dt (K−1,), all float64. Returns the
    number of passes the rate iteration took (0 for two keys)."""
    m = dt.shape[0]  # segments
    r = np.empty((m, 3))
    jm = np.empty((m, 9))  # J(r_k)
    ji = np.empty((m, 9))  # J(r_k)⁻¹
    kn = np.empty((m, 3))  # the coefficients of N(r_k, ·)
    for k in range(m):
        rk, jk, jik, knk = _geometry(E.load4(q, k), E.load4(q, k + 1))
        E.store3(r, k, rk)
        _st9(jm, k, jk)
        _st9(ji, k, jik)
        E.store3(kn, k, knk)
    w = np.empty((m, 3))  # w[k]: the rate at key k + 1 (w[m − 1] stays r_{m−1}/h_{m−1})
    for k in range(m):
        for c in range(3):
            w[k, c] = r[k, c] / dt[k]
    first = E.load3(w, 0)
    passes = 0
    n = m - 1  # unknown rates: keys 1 … K−2
    if n > 0:
        # block elimination of the matrix: rows j = 0 … n−1 (key j + 1), diagonal
        # 4(1/h_j + 1/h_{j+1}) I, left 2/h_j J(r_j), right 2/h_{j+1} J(r_{j+1})⁻¹
        g = np.empty((n, 9))  # left_j · P_{j−1}⁻¹
        pinv = np.empty((n, 9))  # P_j⁻¹, P_j the eliminated diagonal block
        for j in range(n):
            d = 4.0 * (1.0 / dt[j] + 1.0 / dt[j + 1])
            p = (d, 0.0, 0.0, 0.0, d, 0.0, 0.0, 0.0, d)
            if j > 0:
                gj = matmul(scale9(_ld9(jm, j), 2.0 / dt[j]), _ld9(pinv, j - 1))
                _st9(g, j, gj)
                p = _sub9(p, matmul(gj, scale9(_ld9(ji, j), 2.0 / dt[j])))
            _st9(pinv, j, _inv33(p))
        b0 = np.empty((n, 3))
        for j in range(n):
            for c in range(3):
                b0[j, c] = 6.0 * (r[j, c] / dt[j] ** 2 + r[j + 1, c] / dt[j + 1] ** 2)
        e0 = matvec(_ld9(jm, 0), first)
        e1 = matvec(_ld9(ji, m - 1), E.load3(w, m - 1))
        for c in range(3):
            b0[0, c] -= 2.0 / dt[0] * e0[c]
            b0[n - 1, c] -= 2.0 / dt[m - 1] * e1[c]
        y = np.empty((n, 3))
        for it in range(MAX_ITER):
            passes += 1
            for j in range(n):  # right side with the current rates, forward sweep
                rd = matvec(_ld9(ji, j), E.load3(w, j))
                nb = jac_dot(E.load3(r, j), rd, kn[j, 0], kn[j, 1], kn[j, 2])
                bj = (b0[j, 0] - nb[0], b0[j, 1] - nb[1], b0[j, 2] - nb[2])
                if j > 0:
                    gy = matvec(_ld9(g, j), E.load3(y, j - 1))
                    bj = (bj[0] - gy[0], bj[1] - gy[1], bj[2] - gy[2])
                E.store3(y, j, bj)
            done = True
            nxt = (0.0, 0.0, 0.0)
            for j in range(n - 1, -1, -1):  # back sweep into w, convergence test
                yj = E.load3(y, j)
                if j < n - 1:
                    u = matvec(scale9(_ld9(ji, j + 1), 2.0 / dt[j + 1]), nxt)
                    yj = (yj[0] - u[0], yj[1] - u[1], yj[2] - u[2])
                x = matvec(_ld9(pinv, j), yj)
                for c in range(3):
                    if not abs(x[c] - w[j, c]) < TOL * (1.0 + abs(x[c])):
                        done = False
                    w[j, c] = x[c]
                nxt = x
            if done:
                break
    for k in range(m):
        ws = first if k == 0 else E.load3(w, k - 1)
        rd = matvec(_ld9(ji, k), E.load3(w, k))
        h = dt[k]
        for c in range(3):
            coef[k, 0 + c] = (-2.0 * r[k, c] + h * ws[c] + h * rd[c]) / h ** 3
            coef[k, 3 + c] = (3.0 * r[k, c] - 2.0 * h * ws[c] - h * rd[c]) / h ** 2
            coef[k, 6 + c] = ws[c]
    return passes


def coefficients(t, q):
    """(K−1, 9) float64 coefficients of the cubic spline through unit, unflipped keys
    `q` at float64 times `t`, and the number of rate passes."""
    q64 = np.ascontiguousarray(q, np.float64)
    coef = np.empty((q.shape[0] - 1, NCOEF))
    passes = _setup(q64, np.diff(t), coef)
    return coef, passes
