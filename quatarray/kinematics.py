"""Kinematics: the orientation stream of a sampled angular velocity.

:func:`integrate_angular_velocity` is the inverse of
:func:`quatarray.angular_velocity`: each step between two samples holds a
constant rate and applies its exact exponential, so a constant angular
velocity is integrated without error (to rounding), whatever the step.

The integration is a scan (each orientation is the one before times the
step's exponential). What bounds it (10⁶ steps, float64, one thread, CPU
time, measured): the step exponentials (a square root, a
sincos: a separate vectorised pass) take about 10 ns a step; one chain of
products is bound by its latency (each product waits for the one before,
four multiply-adds deep): about 15 ns a step; the scan therefore runs four
chains interleaved (:func:`_scan`), which the core overlaps: about 6 ns a
step, near the cost of one pass over the output (about 5-8 ns a step for
reading and writing 32 bytes). So a block takes ``SCAN_TILE`` steps at a
time, exponentials then scan, while the tile is in cache (a block of 5·10⁵
steps 9.8 -> 8.1 ms). The rest of a call (the steps from the times and their
check, the output's allocation: about 5 ns a step) runs once, before the
threads.
Streams of at least ``QUATARRAY_PARALLEL_MIN_ROWS`` samples are cut into one
block per numba thread, run in Python threads (the kernels release the GIL;
no numba parallel loop, whose compilation would cost seconds of a cold first
call): pass 1 gives each block's exponentials and its local products from
the identity (block 0 from q0); the block ends are carried in turn (a few
products); pass 2 multiplies the rows of the later blocks by their carry,
every thread taking a share of every block: see :func:`_integrate`.
"""

import threading

import numba
import numpy as np

from . import _elements as E
from . import _jit
from ._jit import element, like, prange, rowloop, specialise
from ._trig import sincos_limit
from ._validate import as_float, as_times, check_core, check_times, first_not_increasing, not_increasing, result_dtype
from .algebra import multiply as qa_multiply
from .conversions import half_sinc, rotvec_quat

FRAMES = ("space", "body")
HOLDS = ("mean", "start")
TILE = 4096  # the fewest steps a block of the threaded scan takes

# --------------------------------------------------------------------------
# kernels (float64 inside, whatever the dtype of the stream: the chain of
# products carries no float32 rounding)


MEAN = True  # rebound in each copy of _exponentials (see _EXPONENTIALS)


@element
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


_EXPONENTIALS = {m: rowloop(specialise(_exponentials, "_mean" if m else "_start", MEAN=m), parallel=False) for m in (True, False)}


@rowloop(parallel=False)
def _exponentials_far(omega, h, mean, out):
    for k in range(out.shape[0] - 1):
        v = step_rotvec(omega, h, k, mean)
        half = like(v[0], 0.5) * E.vnorm(v)
        if not half <= sincos_limit(half):
            s = half_sinc(half, np.sin(half))
            E.store4(out, k + 1, (np.cos(half), s * v[0], s * v[1], s * v[2]))


@element
def scan_step(out, k, acc, body, unit):
    """out[k] = e_k ⊗ acc (space) or acc ⊗ e_k (body), e_k = out[k] on entry, in float64
    (``np.float64``: numba's ``float()`` keeps float32); with `unit` (float32 rows) e_k
    is normalised in float64 first, so the norm does not drift by the float32
    rounding of the steps. Returns the new acc."""
    f = E.load4(out, k)
    e = (np.float64(f[0]), np.float64(f[1]), np.float64(f[2]), np.float64(f[3]))
    if unit:
        e = E.qscale(e, 1.0 / np.sqrt(E.qdot(e, e)))
    acc = E.qmul(acc, e) if body else E.qmul(e, acc)
    E.store4(out, k, acc)
    return acc


CHAINS = 4  # independent product chains per scan (instruction-level parallelism)


@rowloop(parallel=False)
def _scan(out, q0, body, unit):
    """In place, out[k] = e_k ⊗ out[k−1] (space) or out[k−1] ⊗ e_k (body) from
    out[−1] = q0: out[k] holds the step exponential e_k on entry. Returns the last
    product in float64 (the carry of a scan continued in another call).

    One chain of products is bound by its latency (each product waits for the one
    before: four multiply-adds deep). So the rows are cut into ``CHAINS`` parts
    whose local products (the first from q0, the others from the identity) run
    interleaved in one loop, as independent chains the core overlaps; then each
    part but the first is multiplied by the end of the part before it (a loop free
    of the chain)."""
    n = out.shape[0]
    m = n // CHAINS if n >= 4 * CHAINS else 0  # short scans: one chain
    one = (1.0, 0.0, 0.0, 0.0)
    a0 = (np.float64(q0[0]), np.float64(q0[1]), np.float64(q0[2]), np.float64(q0[3]))
    a1 = a2 = one
    a3 = a0 if m == 0 else one  # a short scan is the last part's loop alone, from q0
    for k in range(m):
        a0 = scan_step(out, k, a0, body, unit)
        a1 = scan_step(out, m + k, a1, body, unit)
        a2 = scan_step(out, 2 * m + k, a2, body, unit)
        a3 = scan_step(out, 3 * m + k, a3, body, unit)
    for k in range(4 * m, n):
        a3 = scan_step(out, k, a3, body, unit)
    if m == 0:
        return a3
    carry = a0  # the end of the part before, in float64
    last = a0
    for c in range(1, CHAINS):
        # the last local product is still in float64 (a3 for the last part)
        hi = n if c == CHAINS - 1 else (c + 1) * m
        for k in range(c * m, hi - 1):
            f = E.load4(out, k)
            local = (np.float64(f[0]), np.float64(f[1]), np.float64(f[2]), np.float64(f[3]))
            E.store4(out, k, E.qmul(carry, local) if body else E.qmul(local, carry))
        end = a1 if c == 1 else (a2 if c == 2 else a3)
        last = E.qmul(carry, end) if body else E.qmul(end, carry)
        E.store4(out, hi - 1, last)
        carry = last
    return last


SCAN_TILE = 16384  # steps whose exponentials are scanned while they are in cache (512 KB of float64 rows)


def _block(w, h, out, q0, mean, body):
    """Rows [1, n) of `out` for steps [0, n − 1) of the block, ``SCAN_TILE`` steps at a
    time: exponentials, then the scan, carried from tile to tile in float64."""
    steps = out.shape[0] - 1
    unit = out.dtype == np.float32
    acc = np.asarray(q0, np.float64)
    for a in range(0, steps, SCAN_TILE):
        c = min(a + SCAN_TILE, steps)
        o = out[a : c + 1]
        if _EXPONENTIALS[mean](w[a : c + 1], h[a:c], o):
            _exponentials_far(w[a : c + 1], h[a:c], mean, o)
        acc = np.array(_scan(o[1:], acc, body, unit))


@rowloop(parallel=False)
def _carry_in(rows, carry, body):
    """In place, rows[k] = carry ⊗ rows[k] (body) or rows[k] ⊗ carry (space), in float64."""
    c = (np.float64(carry[0]), np.float64(carry[1]), np.float64(carry[2]), np.float64(carry[3]))
    for k in range(rows.shape[0]):
        f = E.load4(rows, k)
        x = (np.float64(f[0]), np.float64(f[1]), np.float64(f[2]), np.float64(f[3]))
        E.store4(rows, k, E.qmul(c, x) if body else E.qmul(x, c))


def _threads(jobs):
    """Run ``fn(*args)`` for each (fn, args) of `jobs`: the first in this thread, the
    others in Python threads (the kernels release the GIL)."""
    threads = [threading.Thread(target=fn, args=args) for fn, args in jobs[1:]]
    for th in threads:
        th.start()
    jobs[0][0](*jobs[0][1])
    for th in threads:
        th.join()


def _integrate(w, h, out, q0, mean, body):
    """The whole stream into `out` (row 0 = q0): one block, or, for long streams, a
    blocked scan in two parallel passes. Pass 1: one block per thread (exponentials
    and local products, each block from the identity but the first). Then each
    block's carry (the true end of the block before it: a few products). Pass 2: the
    rows of the later blocks are multiplied by their block's carry, every thread
    taking an equal share of every block."""
    out[0] = q0
    steps = out.shape[0] - 1
    nb = _blocks(out.shape[0])
    size = -(-steps // nb)
    cuts = [min(b * size, steps) for b in range(nb + 1)]
    one = np.array([1.0, 0.0, 0.0, 0.0])
    _threads([(_block, (w[a:c + 1], h[a:c], out[a:c + 1], q0 if b == 0 else one, mean, body))
              for b, (a, c) in enumerate(zip(cuts[:-1], cuts[1:]))])
    if nb == 1:
        return
    carries = [None, out[cuts[1]].astype(np.float64)]  # block 0 ends true
    for b in range(2, nb):  # the true end of block b − 1: its local end, carried in
        end = out[cuts[b]].astype(np.float64)
        carries.append(qa_multiply(carries[-1], end) if body else qa_multiply(end, carries[-1]))
    shares = [[] for _ in range(nb)]
    for b in range(1, nb):
        a, c = cuts[b] + 1, cuts[b + 1] + 1
        part = -(-(c - a) // nb)
        for i in range(nb):
            lo, hi = min(a + i * part, c), min(a + (i + 1) * part, c)
            if hi > lo:
                shares[i].append((out[lo:hi], carries[b]))
    _threads([(_apply_shares, (sh, body)) for sh in shares if sh])


def _apply_shares(shares, body):
    for rows, carry in shares:
        _carry_in(rows, carry, body)


# --------------------------------------------------------------------------
# front end


def _steps(times, n, index0=0):
    """The steps h_k = t_{k+1} − t_k (float64), taken in the times' own type (exact for
    int64 nanoseconds), or the ValueError naming the first time that is not larger than
    the one before (its index counted from `index0`)."""
    t = as_times(times, "times")
    check_times(t, n, "times")
    i = first_not_increasing(t)
    if i is not None:
        raise not_increasing("times", index0 + i, t[i], t[i + 1])
    return np.diff(t).astype(np.float64)


def check_options(frame, hold):
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
    check_options(frame, hold)
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
