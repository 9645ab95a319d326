"""Kinematics: the orientation stream of a sampled angular velocity.

:func:`integrate_angular_velocity` is the inverse of
:func:`quatarray.angular_velocity`: each step between two samples holds a
constant rate and applies its exact exponential, so a constant angular
velocity is integrated without error (to rounding), whatever the step.

The integration is a scan (each orientation is the one before times the
step's exponential), so in one thread it is bounded by the latency of the
dependent chain of quaternion products, about four multiply-adds deep per
step (about 5 ns a step measured on the 2-core CI machine). The step
exponentials (a square root, a sincos) are a separate vectorised pass
before it (about 10 ns a step there).
Streams of at least ``QUATARRAY_PARALLEL_MIN_ROWS`` samples are cut into one
block per numba thread, run in Python threads (the kernels release the GIL;
no numba parallel loop, whose compilation would cost seconds of a cold first
call): each block's exponentials and its local products from the identity
(block 0 from q0), then the block ends are carried in turn and multiplied
into the later blocks by :func:`quatarray.multiply` (multi-threaded):
see :func:`_integrate`.
"""

import threading

import numba
import numpy as np

from . import _elements as E
from . import _jit
from ._jit import inline, kernel, like, prange, specialise
from ._trig import sincos_limit
from ._validate import as_float, as_times, check_core, result_dtype
from .algebra import multiply as qa_multiply
from .conversions import half_sinc, rotvec_quat
from .interpolation import _check_times, _first_not_increasing, _not_increasing

FRAMES = ("space", "body")
HOLDS = ("mean", "start")
TILE = 4096  # the fewest steps a block of the threaded scan takes

# --------------------------------------------------------------------------
# kernels (float64 inside, whatever the dtype of the stream: the chain of
# products carries no float32 rounding)


MEAN = True  # rebound in each copy of _exponentials (see _EXPONENTIALS)


@inline
def step_rotvec(omega, h, k, mean):
    """The rotation vector r h_k of step k: r = (ω_k + ω_{k+1})/2 (`mean`) or ω_k."""
    a = E.load3(omega, k)
    if mean:
        b = E.load3(omega, k + 1)
        half = like(a[0], 0.5)
        a = (half * (a[0] + b[0]), half * (a[1] + b[1]), half * (a[2] + b[2]))
    hk = like(a[0], h[k])
    return (a[0] * hk, a[1] * hk, a[2] * hk)


def _exponentials(omega, h, out):
    """out[k+1] = exp(r h_k / 2), r = (ω_k + ω_{k+1})/2 (MEAN) or ω_k, in out's
    float type; branch-free, so the loop vectorises. Returns how many steps have a
    half angle beyond the fast sincos (or inf): :func:`_exponentials_far` redoes
    those with libm."""
    far = 0
    for k in prange(out.shape[0] - 1):
        v = step_rotvec(omega, h, k, MEAN)
        E.store4(out, k + 1, rotvec_quat(v))
        far += like(v[0], 0.5) * E.vnorm(v) > sincos_limit(v[0])
    return far


_EXPONENTIALS = {m: kernel(specialise(_exponentials, "_mean" if m else "_start", MEAN=m)) for m in (True, False)}


@kernel
def _exponentials_far(omega, h, mean, out):
    for k in range(out.shape[0] - 1):
        v = step_rotvec(omega, h, k, mean)
        half = like(v[0], 0.5) * E.vnorm(v)
        if not half <= sincos_limit(half):
            s = half_sinc(half, np.sin(half))
            E.store4(out, k + 1, (np.cos(half), s * v[0], s * v[1], s * v[2]))


@kernel
def _scan(out, q0, body, unit):
    """In place, out[k] = e_k ⊗ out[k−1] (space) or out[k−1] ⊗ e_k (body) from
    out[−1] = q0: out[k] holds the step exponential e_k on entry. Carried in
    float64 (``np.float64``: numba's ``float()`` keeps float32); with `unit`
    (float32 rows) each e_k is normalised in float64 first, so the norm does not
    drift by the float32 rounding of the steps."""
    acc = (np.float64(q0[0]), np.float64(q0[1]), np.float64(q0[2]), np.float64(q0[3]))
    for k in range(out.shape[0]):
        f = E.load4(out, k)
        e = (np.float64(f[0]), np.float64(f[1]), np.float64(f[2]), np.float64(f[3]))
        if unit:
            e = E.qscale(e, 1.0 / np.sqrt(E.qdot(e, e)))
        acc = E.qmul(acc, e) if body else E.qmul(e, acc)
        E.store4(out, k, acc)


def _block(w, h, out, q0, mean, body):
    """Rows [1, n) of `out` for steps [0, n − 1) of the block: exponentials, then the scan."""
    if _EXPONENTIALS[mean](w, h, out):
        _exponentials_far(w, h, mean, out)
    _scan(out[1:], q0, body, out.dtype == np.float32)


def _integrate(w, h, out, q0, mean, body):
    """The whole stream into `out` (row 0 = q0): one block, or, for long streams, one
    block per thread (Python threads: the kernels release the GIL), each from the
    identity but the first; then the block ends are carried and multiplied into the
    later blocks (:func:`quatarray.multiply`, itself multi-threaded)."""
    out[0] = q0
    steps = out.shape[0] - 1
    nb = _blocks(out.shape[0])
    size = -(-steps // nb)
    cuts = [min(b * size, steps) for b in range(nb + 1)]
    one = np.array([1.0, 0.0, 0.0, 0.0])
    jobs = [(w[a:c + 1], h[a:c], out[a:c + 1], q0 if b == 0 else one, mean, body)
            for b, (a, c) in enumerate(zip(cuts[:-1], cuts[1:]))]
    threads = [threading.Thread(target=_block, args=job) for job in jobs[1:]]
    for th in threads:
        th.start()
    _block(*jobs[0])
    for th in threads:
        th.join()
    carry = out[cuts[1]].astype(np.float64)  # where block 1 starts
    for a, c in zip(cuts[1:-1], cuts[2:]):
        local = out[a + 1 : c + 1]
        cq = carry.astype(out.dtype)
        qa_multiply(cq, local, out=local) if body else qa_multiply(local, cq, out=local)
        carry = out[c].astype(np.float64)


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
    if n < max(_jit.min_rows(), 2 * TILE):
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
    _integrate(w.astype(dtype, copy=False), h, out, start, hold == "mean", frame == "body")
    return out
