"""Kinematics: the orientation stream of a sampled angular velocity.

:func:`integrate_angular_velocity` is the inverse of
:func:`quatarray.angular_velocity`: each step between two samples holds a
constant rate and applies its exact exponential, so a constant angular
velocity is integrated without error (to rounding), whatever the step.

The integration is a scan (each orientation is the one before times the
step's exponential), so in one thread it is bounded by the latency of the
dependent chain of quaternion products, about four multiply-adds deep per
step; the step exponentials themselves (a square root, a sincos) do not
depend on the chain and overlap with it. Long streams are cut into one block
per thread: each block's local products run in parallel, a short serial pass
carries the block ends, and a parallel pass multiplies the carried
orientation into every later block (:func:`_scan`).
"""

import numba
import numpy as np

from . import _elements as E
from . import _jit
from ._jit import like, prange, rowloop, specialise
from ._trig import sincos_limit
from ._validate import as_float, as_times, check_core, result_dtype
from .conversions import half_sinc, rotvec_quat
from .interpolation import _check_times, _first_not_increasing, _not_increasing

FRAMES = ("space", "body")
HOLDS = ("mean", "start")
TILE = 4096  # steps per task of the parallel fix-up; block lengths are multiples of it

# --------------------------------------------------------------------------
# kernels (float64 inside, whatever the dtype of the stream: the chain of
# products carries no float32 rounding)


MEAN = True  # rebound in each copy of _exponentials (see _EXPONENTIALS)


def _exponentials(omega, h, out):
    """out[k+1] = exp(r h_k / 2), r = (ω_k + ω_{k+1})/2 (MEAN) or ω_k, in out's
    float type; branch-free, so the loop vectorises. Returns how many steps have a
    half angle beyond the fast sincos (or inf): :func:`_exponentials_far` redoes
    those with libm."""
    far = 0
    for k in prange(out.shape[0] - 1):
        a = E.load3(omega, k)
        if MEAN:
            b = E.load3(omega, k + 1)
            half = like(a[0], 0.5)
            a = (half * (a[0] + b[0]), half * (a[1] + b[1]), half * (a[2] + b[2]))
        hk = like(a[0], h[k])
        v = (a[0] * hk, a[1] * hk, a[2] * hk)
        E.store4(out, k + 1, rotvec_quat(v))
        far += like(v[0], 0.5) * E.vnorm(v) > sincos_limit(v[0])
    return far


_EXPONENTIALS = {m: rowloop(rows=2)(specialise(_exponentials, "_mean" if m else "_start", MEAN=m))
                 for m in (True, False)}


@rowloop(rows=3, parallel=False)
def _exponentials_far(omega, h, mean, out):
    for k in range(out.shape[0] - 1):
        a = E.load3(omega, k)
        if mean:
            b = E.load3(omega, k + 1)
            half = like(a[0], 0.5)
            a = (half * (a[0] + b[0]), half * (a[1] + b[1]), half * (a[2] + b[2]))
        hk = like(a[0], h[k])
        v = (a[0] * hk, a[1] * hk, a[2] * hk)
        half = like(v[0], 0.5) * E.vnorm(v)
        if not half <= sincos_limit(half):
            s = half_sinc(half, np.sin(half))
            E.store4(out, k + 1, (np.cos(half), s * v[0], s * v[1], s * v[2]))


@rowloop
def _scan(out, q0, body, unit, nblocks, ends):
    """out[0] = q0, out[k+1] = e_k ⊗ out[k] (space) or out[k] ⊗ e_k (body), in place:
    out[k+1] holds e_k on entry. Carried in float64; with `unit` (float32 rows) each
    e_k is normalised in float64 first, so the norm does not drift by the float32
    rounding of the steps.

    The N − 1 steps are cut into `nblocks` blocks of a multiple of TILE steps.
    Each block's products run from the identity (block 0 from q0) and its last
    one goes to ``ends``; the block ends are then made global serially (a few
    products), and each later block is multiplied by the orientation where it
    starts, TILE rows a task.
    """
    n = out.shape[0]
    steps = n - 1
    tiles = (steps + TILE * nblocks - 1) // (TILE * nblocks)  # per block
    size = tiles * TILE
    start = (np.float64(q0[0]), np.float64(q0[1]), np.float64(q0[2]), np.float64(q0[3]))
    E.store4(out, 0, start)
    for b in prange(nblocks):
        acc = start if b == 0 else (1.0, 0.0, 0.0, 0.0)
        for k in range(b * size, min((b + 1) * size, steps)):
            f = E.load4(out, k + 1)
            e = (np.float64(f[0]), np.float64(f[1]), np.float64(f[2]), np.float64(f[3]))
            if unit:
                e = E.qscale(e, 1.0 / np.sqrt(E.qdot(e, e)))
            acc = E.qmul(acc, e) if body else E.qmul(e, acc)
            E.store4(out, k + 1, acc)
        E.store4(ends, b, acc)
    # block ends made global in turn: ends[b] = the orientation where block b + 1 starts
    for b in range(1, nblocks - 1):
        local = E.load4(ends, b)
        prev = E.load4(ends, b - 1)
        E.store4(ends, b, E.qmul(prev, local) if body else E.qmul(local, prev))
    for t in prange((nblocks - 1) * tiles):
        b = 1 + t // tiles
        c = E.load4(ends, b - 1)
        lo = b * size + (t % tiles) * TILE
        for k in range(lo, min(lo + TILE, (b + 1) * size, steps)):
            f = E.load4(out, k + 1)
            g = (np.float64(f[0]), np.float64(f[1]), np.float64(f[2]), np.float64(f[3]))
            E.store4(out, k + 1, E.qmul(c, g) if body else E.qmul(g, c))


# --------------------------------------------------------------------------
# front end


def _steps(times, n, index0=0):
    """The steps h_k = t_{k+1} − t_k (float64), taken in the times' own type (exact for
    int64 nanoseconds), or the ValueError naming the first time that is not larger than
    the one before (its index counted from `index0`)."""
    t = as_times(times, "times")
    _check_times(t, n, "times")
    i = _first_not_increasing(t)
    if i is not None:
        raise _not_increasing("times", index0 + i, t[i], t[i + 1])
    return np.diff(t).astype(np.float64)


def _check_options(frame, hold):
    if frame not in FRAMES:
        raise ValueError(f"Expected `frame` to be 'space' or 'body', got {frame!r}.")
    if hold not in HOLDS:
        raise ValueError(f"Expected `hold` to be 'mean' or 'start', got {hold!r}.")


def _blocks(n):
    """Blocks of the scan: one per thread for long streams, else one."""
    if n < _jit.PARALLEL_MIN_ROWS:
        return 1
    return max(1, min(numba.get_num_threads(), (n - 1) // TILE))


def integrate_angular_velocity(omega, times, q0=None, frame="space", hold="mean", _index0=0):
    """The orientation stream whose angular velocity is `omega`.

    Starting from q[0] = `q0`, each step k from ``times[k]`` to ``times[k+1]``
    (h_k long) holds the constant rate r = (ω_k + ω_{k+1})/2 (``hold="mean"``,
    second order) or ω_k (``hold="start"``) and applies its exact exponential:

    - ``"space"`` (ω in the fixed frame's axes): q[k+1] = exp(r h_k / 2) ⊗ q[k]
    - ``"body"`` (ω in the moving frame's axes): q[k+1] = q[k] ⊗ exp(r h_k / 2)

    where exp(v / 2) is the unit quaternion of the rotation vector v (as
    :func:`quatarray.from_rotvec`, accurate for tiny angles). A constant rate ω
    gives ``from_rotvec(ω (t − t₀)) ⊗ q0`` to rounding, whatever the steps, and
    with ``hold="start"`` the step rates of the result, as
    :func:`quatarray.angular_velocity` computes them (the rotation vector of
    each step over h_k), are ω_k again (while |ω_k h_k| < π). The rate is in
    radians per unit of `times`: rad/s for times in seconds, rad/ns for int64
    nanosecond stamps.

    Parameters
    ----------
    omega : array_like, shape (N, 3)
        Angular velocity at each sample time.
    times : array_like, shape (N,)
        Strictly increasing sample times. Steps are taken in the times' own
        type before converting to float, so int64 nanoseconds since the epoch
        give exact steps.
    q0 : array_like, shape (4,), optional
        The orientation at ``times[0]`` (default the identity). It is not
        normalised: the stream keeps its norm.
    frame : {"space", "body"}
    hold : {"mean", "start"}

    Returns
    -------
    ndarray, shape (N, 4)
        float32 when `omega` (and `q0`, if given) are float32, else float64.

    Notes
    -----
    The products are carried in float64 whatever the dtype, and not
    renormalised: each product of unit quaternions changes the norm by about
    one rounding, so after N steps |q| is 1 within about √N · 1e-16 (1e-13
    for a million steps). Long streams run on all threads as a blocked scan
    (see the module docstring); the grouping of the products then differs
    from the serial order by rounding only.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> t = np.array([0.0, 0.1, 0.3, 0.6])
    >>> w = np.tile([0, 0, 2.0], (4, 1))  # 2 rad/s about z
    >>> q = qa.integrate_angular_velocity(w, t)
    >>> np.allclose(q, qa.from_rotvec(np.outer(t, [0, 0, 2.0])))
    True
    >>> np.allclose(qa.angular_velocity(q, t), w)
    True
    """
    _check_options(frame, hold)
    w = check_core(as_float(omega, "omega"), "omega", (3,))
    if w.ndim != 2:
        raise ValueError(f"Expected `omega` to have shape (N, 3), got {w.shape}.")
    n = w.shape[0]
    h = _steps(times, n, _index0)
    if q0 is None:
        start = np.array([1.0, 0.0, 0.0, 0.0])
        dtype = w.dtype
    else:
        q = check_core(as_float(q0, "q0"), "q0", (4,))
        if q.ndim != 1:
            raise ValueError(f"Expected `q0` to have shape (4,), got {q.shape}.")
        start = q.astype(np.float64)
        dtype = result_dtype([w, q])
    out = np.empty((n, 4), dtype)
    if n == 0:
        return out
    nblocks = _blocks(n)
    w = w.astype(dtype, copy=False)
    mean = hold == "mean"
    if _EXPONENTIALS[mean](w, h, out):
        _exponentials_far(w, h, mean, out)
    _scan(out, start, frame == "body", dtype == np.float32, nblocks, np.empty((nblocks, 4)))
    return out
