"""``quatarray bench``: quatarray side by side with scipy, numpy-quaternion and
quaternionic, in one run on the same arrays.

Every operation is timed on the same unit quaternions (float64 unless the row
says float32) for every library that has it; the candidates of one row are
timed in interleaved rounds and the best round counts, so a burst of load on
a shared machine hits them alike. Rates are in Mquat/s (millions of
quaternions, or output samples for resampling, per second); ratios are
quatarray's rate over the other library's.

The memory-stream ceiling is the rate of a STREAM "triad" (two arrays read,
one written, as a quaternion product does) expressed in Mquat/s of the
96-byte float64 product (32 bytes read from each operand, 32 written). A
memory-bound kernel cannot beat it; the ``%stream`` column gives each
quatarray rate as a fraction of it, counting the bytes that operation moves.
The triads are timed again in each row's interleaved rounds and the
fraction uses that row's triad rate, so a change of load between rows (a
shared machine) does not move it. An operation returning a new array also
pays for the fresh pages of its result (the system zeroes each one on first
touch: an ``np.empty(...).fill()`` of the same size shows that cost), which
the triad, writing into an existing array, does not. Such rows are also timed
against the plainest function making a new array of the same shape
(:func:`fresh_fill`): the ``notes`` give the row's rate as a fraction of
that one, the ceiling of a function returning a new array on this machine.

Use :func:`run` (the command line calls it) or the pieces: :func:`ceiling`,
:func:`triads`, :func:`cases` and :func:`measure`.
"""

import json
import math
import os
import platform
import subprocess
import sys
import time

import numpy as np

from .._compat import rotation_as_wxyz, rotation_from_wxyz

LIBS = ("quatarray", "scipy", "numpy-quaternion", "quaternionic")
DEFAULT_N = 2_000_000
NOT_AVAILABLE = "n/a: not available"


# --------------------------------------------------------------------------
# timing


def _once(fn):
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


FEW_CALLS = 4  # batches of this many calls or fewer follow an untimed call (see measure)


def measure(fns, budget=1.5, min_rounds=3, max_rounds=25, slow=3.0):
    """Best time per call of each of ``fns`` (a dict), timed in interleaved rounds.

    Each callable is called once to warm up (numba compiles or loads its
    cache then), and once more when that took over 20 ms; a round calls every
    candidate ``reps`` times, ``reps`` chosen from the last of those calls so
    a call batch lasts at least ~20 ms. Where that is a few calls, each
    batch follows one untimed call: the first call after another library's
    may find the memory it frees handed back to the system and pay for fresh
    pages (for a spline's temporaries, up to 3× the call), which a batch of
    one or two calls would count in full and a longer batch mostly not.
    Rounds continue until ``budget`` seconds are spent (at least
    ``min_rounds``). A candidate whose second call takes more than ``slow``
    seconds is timed by that call alone.
    """
    reps, best, done = {}, {}, set()
    for name, fn in fns.items():
        t = _once(fn)  # warm-up: may include numba compiling or loading its cache
        if t > 0.02:  # a batch of one call, or a compile: the second call sets reps
            t = _once(fn)
            if t > slow:  # one call says enough; keep the rounds for the others
                done.add(name)
        reps[name] = max(1, min(10_000, int(0.02 / max(t, 1e-7))))
        best[name] = t if name in done else math.inf
    start = time.perf_counter()
    for r in range(max_rounds):
        for name, fn in fns.items():
            if name in done:
                continue
            k = reps[name]
            if k <= FEW_CALLS:
                fn()
            t0 = time.perf_counter()
            for _ in range(k):
                fn()
            best[name] = min(best[name], (time.perf_counter() - t0) / k)
        if r + 1 >= min_rounds and time.perf_counter() - start > budget:
            break
    return best


# --------------------------------------------------------------------------
# the machine's memory-stream ceiling


def triads(n):
    """The two STREAM triad candidates on ``n`` float64 quaternions (``4n`` doubles):
    a dict of callables and the bytes each call moves.

    numpy (``np.add(b, c, out=a)``, one thread) and a numba ``prange`` triad
    (all threads); the faster one is the ceiling.
    """
    import numba

    @numba.njit(parallel=True, cache=False)
    def triad(a, b, c, s):
        for i in numba.prange(a.shape[0]):
            a[i] = b[i] + s * c[i]

    b = np.random.default_rng(0).random(4 * n)
    c = b[::-1].copy()
    a = np.empty_like(b)
    return {"triad numpy": lambda: np.add(b, c, out=a), "triad numba": lambda: triad(a, b, c, 3.0)}, 3 * a.nbytes


def ceiling(n, budget=1.0):
    """STREAM triad rate on ``n`` float64 quaternions: bytes/s and Mquat/s of a 96-byte product
    (see :func:`triads`)."""
    fns, nbytes = triads(n)
    t = measure(fns, budget)
    res = {k: nbytes / v for k, v in t.items()}
    best = max(res.values())
    return {
        "triad_GBps_numpy_1thread": res["triad numpy"] / 1e9,
        "triad_GBps_numba_threads": res["triad numba"] / 1e9,
        "GBps": best / 1e9,
        "Mquat_s_product": best / 96 / 1e6,
    }


_FILLS = {}


def fresh_fill(p, width):
    """A new ``(len(p), width)`` float64 array, allocated as quatarray's functions allocate
    their results (``np.empty``) and filled by a numba ``prange`` loop that reads one float
    of each quaternion and writes its row (on every thread from the size where
    quatarray's row loops go parallel, on one below it). The ceiling of a function
    returning a new array of that size on this machine: the system zeroes each fresh
    page on its first touch, a cost the triad, writing into an existing array, does not pay."""
    from quatarray import _jit

    parallel = p.shape[0] >= _jit.min_rows()  # as quatarray's row loops choose
    fill = _FILLS.get((width, parallel))
    if fill is None:
        import numba

        @numba.njit(parallel=parallel, cache=False)
        def fill(out, p):
            for i in numba.prange(p.shape[0]):
                x = p[i, 0]
                for j in range(width):  # a constant of this compiled copy: the stores vectorise
                    out[width * i + j] = x

        _FILLS[width, parallel] = fill
    out = np.empty((p.shape[0], width))
    fill(out.reshape(-1), p)
    return out


# --------------------------------------------------------------------------
# the operations


def _qa(name):
    """A public quatarray function, or None while it is not written yet."""
    import quatarray

    try:
        return getattr(quatarray, name)
    except (AttributeError, ImportError):
        return None


def _optional(module):
    try:
        return __import__(module)
    except ImportError:
        return None


# A peer's call that kills the interpreter on some set-ups (quaternionic 1.0's slerp
# gufunc, also behind its squad, segfaults with numba 0.68 and numpy 2.4): each is
# tried once in a child process, and a row leaves that peer out where it crashed.
PROBES = {
    "quaternionic.slerp": "import numpy as np, quaternionic as qn\n"
                          "a = qn.array(np.eye(4)[:2])\nqn.slerp(a, a, np.array([0.25, 0.5]))",
}
_PROBED = {}


def peer_crashes(call):
    """True when the peer call `call` (a key of :data:`PROBES`) crashes a fresh
    interpreter here (by a signal, or any non-zero exit)."""
    if call not in _PROBED:
        try:
            res = subprocess.run([sys.executable, "-c", PROBES[call]], capture_output=True, timeout=600)
            _PROBED[call] = res.returncode != 0
        except subprocess.TimeoutExpired:
            _PROBED[call] = True
        if _PROBED[call]:
            print(f"note: {call} crashed a test process on this set-up: left out of the table", file=sys.stderr)
    return _PROBED[call]


class Case:
    """One row: an operation, its per-library callables, items per call, bytes per item."""

    def __init__(self, op, items, nbytes=None, note=""):
        self.op, self.items, self.nbytes, self.note = op, items, nbytes, note
        self.fns = {}
        self.fresh = None  # it returns a new array: the fresh_fill of its size
        self.missing = []  # quatarray functions not available yet

    def add(self, lib, fn):
        if fn is not None:
            self.fns[lib] = fn


def cases(n, seed=0):
    """Build the benchmark rows on ``n`` random unit quaternions (float64)."""
    from scipy.spatial.transform import Rotation, RotationSpline, Slerp

    import quatarray as qa

    npq = _optional("quaternion")
    qn = _optional("quaternionic")
    rng = np.random.default_rng(seed)
    p = qa.random(n, rng=rng)
    q = qa.random(n, rng=rng)
    v = rng.standard_normal((n, 3))
    t = rng.random(n)
    o4 = np.empty_like(p)
    o3 = np.empty_like(v)
    rp = rotation_from_wxyz(p)
    rq = rotation_from_wxyz(q)
    m = rp.as_matrix()
    rv = rp.as_rotvec()
    eul = rp.as_euler("ZYZ")
    if npq is not None:
        P = npq.as_quat_array(p)
        Q = npq.as_quat_array(q)
        O = np.empty_like(P)
        V = npq.from_vector_part(v)
    if qn is not None:
        QP = qn.array(p)
        QQ = qn.array(q)
        QV = qn.array.from_vector_part(v)
    out = []

    def case(op, items=n, nbytes=None, note="", qa_name=None, qa_fn=None):
        c = Case(op, items, nbytes, note)
        fn = _qa(qa_name) if qa_name else True
        if fn is None:
            c.missing.append(qa_name)
        elif qa_fn is not None:
            c.add("quatarray", qa_fn(fn))
        out.append(c)
        return c

    # --- algebra and rotation
    c = case("multiply (out=)", nbytes=96, qa_name="multiply", qa_fn=lambda f: lambda: f(p, q, out=o4))
    c.add("scipy", lambda: rp * rq)
    if npq is not None:
        c.add("numpy-quaternion", lambda: np.multiply(P, Q, out=O))
    if qn is not None:
        c.add("quaternionic", lambda: QP * QQ)

    c = case("multiply (new array)", nbytes=96, qa_name="multiply", qa_fn=lambda f: lambda: f(p, q))
    c.fresh = lambda: fresh_fill(p, 4)
    if npq is not None:
        c.add("numpy-quaternion", lambda: P * Q)

    c = case("rotate (out=)", nbytes=80, note="npq/qn: q v q̄", qa_name="rotate",
             qa_fn=lambda f: lambda: f(p, v, out=o3))
    c.add("scipy", lambda: rp.apply(v))
    if npq is not None:
        c.add("numpy-quaternion", lambda: P * V * np.conjugate(P))
    if qn is not None:
        c.add("quaternionic", lambda: QP * QV * QP.conj())

    p1 = p[0]
    c = case("rotate (1 q, N vectors)", nbytes=48, note="npq: rotate_vectors; qn: .rotate",
             qa_name="rotate", qa_fn=lambda f: lambda: f(p1, v, out=o3))
    r1 = rotation_from_wxyz(p1)
    c.add("scipy", lambda: r1.apply(v))
    if npq is not None:
        P1 = npq.as_quat_array(p1)
        c.add("numpy-quaternion", lambda: npq.rotate_vectors(P1, v))
    if qn is not None:
        QP1 = qn.array(p1)
        c.add("quaternionic", lambda: QP1.rotate(v))

    c = case("normalize (out=)", nbytes=64, qa_name="normalize", qa_fn=lambda f: lambda: f(p, out=o4))
    if npq is not None:
        c.add("numpy-quaternion", lambda: np.divide(P, np.abs(P), out=O))
    if qn is not None:
        c.add("quaternionic", lambda: QP.normalized)

    c = case("inverse (out=)", nbytes=64, qa_name="inverse", qa_fn=lambda f: lambda: f(p, out=o4))
    c.add("scipy", lambda: rp.inv())
    if npq is not None:
        c.add("numpy-quaternion", lambda: np.reciprocal(P, out=O))
    if qn is not None:
        c.add("quaternionic", lambda: QP.inverse)

    # --- float32 rows (quatarray only; compared with the float64 rows above)
    p32, q32, v32 = p.astype(np.float32), q.astype(np.float32), v.astype(np.float32)
    o432, o332 = np.empty_like(p32), np.empty_like(v32)
    case("multiply float32 (out=)", nbytes=48, qa_name="multiply",
         qa_fn=lambda f: lambda: f(p32, q32, out=o432))
    case("rotate float32 (out=)", nbytes=40, qa_name="rotate", qa_fn=lambda f: lambda: f(p32, v32, out=o332))

    # --- interpolation
    c = case("slerp (pairs, per-row t)", nbytes=104, note="scipy: p·exp(t·log(p⁻¹q)) composed",
             qa_name="slerp", qa_fn=lambda f: lambda: f(p, q, t, out=o4))
    c.add("scipy", lambda: rp * Rotation.from_rotvec((rp.inv() * rq).as_rotvec() * t[:, None]))
    if npq is not None:
        c.add("numpy-quaternion", lambda: np.slerp_vectorized(P, Q, t))
    if qn is not None and not peer_crashes("quaternionic.slerp"):
        c.add("quaternionic", lambda: qn.slerp(QP, QQ, t))

    # resampling a smooth stream: K keys, 4x as many output samples (30 -> 120 fps)
    k = max(n // 16, 8)
    times = np.arange(k) / 30.0
    w = np.cumsum(rng.normal(0, 0.05, (k, 3)), axis=0)
    keys = rotation_as_wxyz(Rotation.from_rotvec(w))
    keys[1::3] *= -1  # real streams carry sign flips
    new_times = np.linspace(times[0], times[-1], 4 * (k - 1) + 1)
    m_out = new_times.size
    rkeys = rotation_from_wxyz(keys)
    for method, other in (("bezier", "RotationSpline"), ("slerp", "Slerp"), ("squad", None)):
        c = case(f"spline {method} ({k} keys -> {m_out})", items=m_out,
                 note=f"scipy: {other}" if other else "npq/qn: squad", qa_name="spline",
                 qa_fn=lambda f, method=method: lambda: f(times, keys, new_times, method=method))
        if method == "bezier":
            c.add("scipy", lambda: RotationSpline(times, rkeys)(new_times))
        elif method == "slerp":
            c.add("scipy", lambda: Slerp(times, rkeys)(new_times))
        else:
            if npq is not None:
                KEYS = npq.as_quat_array(keys)
                c.add("numpy-quaternion", lambda: npq.squad(KEYS, times, new_times, unflip_input_rotors=True))
            if qn is not None and not peer_crashes("quaternionic.slerp"):  # squad runs slerp
                QK = qn.array(keys)
                c.add("quaternionic", lambda: qn.squad(qn.unflip_rotors(QK), times, new_times))
    # scipy's own C² spline, and the rates of the curves (scipy: RotationSpline's order=1, 2;
    # quatarray's order 0 row of the same method is the one above)
    for method, order in (("cubic", 0), ("cubic", 1), ("cubic", 2), ("bezier", 1), ("bezier", 2)):
        label = f"spline {method}" + (f" order={order}" if order else "")
        c = case(f"{label} ({k} keys -> {m_out})", items=m_out,
                 note="scipy: RotationSpline" + (f"(t, r)(t', {order})" if order else "") + (
                     " (another curve)" if method != "cubic" else " (the same curve)"), qa_name="spline",
                 qa_fn=lambda f, method=method, order=order: lambda: f(times, keys, new_times, method=method,
                                                                         order=order))
        c.add("scipy", lambda order=order: RotationSpline(times, rkeys)(new_times, order))

    # --- whole clips (issue 17): 30 joints, n / 30 frames; items are joint-samples
    clip = _clip(max(n // 30, 8), 30, rng)
    c = case(f"clip world ({clip.frames} frames x 30 joints)", items=clip.frames * 30,
             note="scipy: numpy FK, scipy rotations, one joint at a time")
    c.add("quatarray", clip.world)
    c.add("scipy", lambda: _numpy_world(clip, Rotation))
    c = case(f"clip resample 2x ({clip.frames} frames x 30 joints)", items=(2 * clip.frames - 1) * 30,
             note="Bézier, every joint; out: joint-samples")
    c.add("quatarray", lambda: clip.resample(rate=2 / clip.frame_time))

    # --- conversions
    c = case("as_matrix", nbytes=104, qa_name="as_matrix", qa_fn=lambda f: lambda: f(p),
             note="a new array: its fresh pages cost the system's zeroing (see the out= row)")
    c.add("scipy", lambda: rp.as_matrix())
    c.fresh = lambda: fresh_fill(p, 9)
    if npq is not None:
        c.add("numpy-quaternion", lambda: npq.as_rotation_matrix(P))
    if qn is not None:
        c.add("quaternionic", lambda: QP.to_rotation_matrix)
    # the same kernel into an existing array: what the kernel itself reaches
    o33 = np.empty_like(m)
    c = case("as_matrix (out=)", nbytes=104, qa_name="as_matrix", qa_fn=lambda f: lambda: f(p, out=o33))
    c.add("scipy", lambda: rp.as_matrix())

    # numpy-quaternion's and quaternionic's general (non-orthogonal) path solves an
    # eigenproblem per matrix in Python: far too slow to time at this n.
    c = case("from_matrix", nbytes=104, note="npq/qn non-orthogonal path not timed (a Python loop)",
             qa_name="from_matrix", qa_fn=lambda f: lambda: f(m))
    c.add("scipy", lambda: Rotation.from_matrix(m))

    c = case("from_matrix (assume_valid)", nbytes=104, note="npq: nonorthogonal=False",
             qa_name="from_matrix", qa_fn=lambda f: lambda: f(m, assume_valid=True))
    c.add("scipy", _scipy_assume_valid(Rotation, m))
    if npq is not None:
        c.add("numpy-quaternion", lambda: npq.from_rotation_matrix(m, nonorthogonal=False))

    c = case("as_euler ZYZ", nbytes=56, qa_name="as_euler", qa_fn=lambda f: lambda: f(p, "ZYZ"))
    c.add("scipy", lambda: rp.as_euler("ZYZ"))
    if npq is not None:
        c.add("numpy-quaternion", lambda: npq.as_euler_angles(P))
    if qn is not None:
        c.add("quaternionic", lambda: QP.to_euler_angles)

    c = case("as_euler xyz", nbytes=56, qa_name="as_euler", qa_fn=lambda f: lambda: f(p, "xyz"))
    c.add("scipy", lambda: rp.as_euler("xyz"))

    c = case("from_euler ZYZ", nbytes=56, qa_name="from_euler", qa_fn=lambda f: lambda: f("ZYZ", eul))
    c.add("scipy", lambda: Rotation.from_euler("ZYZ", eul))
    if npq is not None:
        c.add("numpy-quaternion", lambda: npq.from_euler_angles(eul))
    if qn is not None:
        c.add("quaternionic", lambda: qn.array.from_euler_angles(eul))

    c = case("as_rotvec", nbytes=56, qa_name="as_rotvec", qa_fn=lambda f: lambda: f(p))
    c.add("scipy", lambda: rp.as_rotvec())
    if npq is not None:
        c.add("numpy-quaternion", lambda: npq.as_rotation_vector(P))
    if qn is not None:
        c.add("quaternionic", lambda: QP.to_rotation_vector)

    c = case("from_rotvec", nbytes=56, qa_name="from_rotvec", qa_fn=lambda f: lambda: f(rv))
    c.add("scipy", lambda: Rotation.from_rotvec(rv))
    if npq is not None:
        c.add("numpy-quaternion", lambda: npq.from_rotation_vector(rv))
    if qn is not None:
        c.add("quaternionic", lambda: qn.array.from_rotation_vector(rv))

    # modified Rodrigues parameters (scipy's Rotation built outside the timing)
    mrp = rp.as_mrp()
    c = case("as_mrp", nbytes=56, qa_name="as_mrp", qa_fn=lambda f: lambda: f(p))
    c.add("scipy", lambda: rp.as_mrp())
    c.fresh = lambda: fresh_fill(p, 3)

    c = case("from_mrp", nbytes=56, qa_name="from_mrp", qa_fn=lambda f: lambda: f(mrp))
    c.add("scipy", lambda: Rotation.from_mrp(mrp))
    return out


def _clip(frames, joints, rng):
    """A smooth random clip: a tree of `joints` joints, ZXY channels, root positions."""
    import quatarray as qa
    from quatarray.skeleton import Clip

    parents = [-1] + [int(rng.integers(max(0, j - 4), j)) for j in range(1, joints)]
    chans = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")] + \
        [("Zrotation", "Xrotation", "Yrotation")] * (joints - 1)
    rot = qa.from_euler("ZXY", np.cumsum(rng.normal(0, 2, (frames, joints, 3)), axis=0), degrees=True)
    off = rng.standard_normal((joints, 3)) * 10
    trans = np.broadcast_to(off, (frames, joints, 3)).copy()
    trans[:, 0] = np.cumsum(rng.normal(0, 0.1, (frames, 3)), axis=0)
    return Clip([f"j{j}" for j in range(joints)], parents, off, chans, rot, trans, 1 / 100)


def _numpy_world(clip, Rotation):
    """Forward kinematics in numpy + scipy: one joint at a time, all frames at once."""
    rw, pw = [], []
    for j in range(len(clip.joints)):
        r = rotation_from_wxyz(clip.rotations[:, j])
        p = clip.parents[j]
        rw.append(r if p < 0 else rw[p] * r)
        pw.append(clip.translations[:, j] if p < 0 else pw[p] + rw[p].apply(clip.translations[:, j]))
    return np.stack([rotation_as_wxyz(r) for r in rw], axis=1), np.stack(pw, axis=1)


def _scipy_assume_valid(Rotation, m):
    try:
        Rotation.from_matrix(m[:1], assume_valid=True)
    except TypeError:  # older scipy: no fast path
        return None
    return lambda: Rotation.from_matrix(m, assume_valid=True)


def overhead():
    """Per-call time in µs for one quaternion (multiply, rotate): the fixed cost of a call."""
    import quatarray as qa

    npq = _optional("quaternion")
    qn = _optional("quaternionic")
    p, q = qa.random(rng=1), qa.random(rng=2)
    v = np.array([0.1, 0.2, 0.3])
    rp, rq = rotation_from_wxyz(p), rotation_from_wxyz(q)
    rows = {}
    fns = {"quatarray": lambda: qa.multiply(p, q), "scipy": lambda: rp * rq}
    if npq is not None:
        P, Q = npq.quaternion(*p), npq.quaternion(*q)
        fns["numpy-quaternion"] = lambda: P * Q
    if qn is not None:
        QP, QQ = qn.array(p), qn.array(q)
        fns["quaternionic"] = lambda: QP * QQ
    rows["multiply, N=1"] = {k: v * 1e6 for k, v in measure(fns, budget=0.5).items()}
    fns = {"quatarray": lambda: qa.rotate(p, v), "scipy": lambda: rp.apply(v)}
    if npq is not None:
        fns["numpy-quaternion"] = lambda: npq.rotate_vectors(P, v)
    if qn is not None:
        fns["quaternionic"] = lambda: QP.rotate(v)
    rows["rotate, N=1"] = {k: v * 1e6 for k, v in measure(fns, budget=0.5).items()}
    return rows


# --------------------------------------------------------------------------
# the report


def _fmt_rate(x):
    if x is None:
        return "—"
    return f"{x:.3g}" if x < 100 else f"{x:.0f}"


def _fmt_ratio(x):
    if x is None:
        return "—"
    return f"{x:.2f}×" if x < 100 else f"{x:.0f}×"


def results(n, budget=1.5, progress=None):
    """Measure every case: a list of dicts (op, items, rates in Mquat/s, ratios, %stream)."""
    ceil = ceiling(n)
    triad_fns, triad_bytes = triads(n)
    rows = []
    for c in cases(n):
        if progress:
            progress(c.op)
        row = {"op": c.op, "items": c.items, "note": c.note, "rates_Mquat_s": {}, "ratios": {}}
        if c.missing:
            row["status"] = f"{NOT_AVAILABLE}: quatarray.{c.missing[0]}"
        if c.fns:
            # The triads run in the same interleaved rounds, so %stream compares
            # rates measured under the same load.
            fresh = {"fresh fill": c.fresh} if c.fresh else {}
            best = measure({**c.fns, **(triad_fns if c.nbytes else {}), **fresh}, budget)
            row["rates_Mquat_s"] = {lib: c.items / best[lib] / 1e6 for lib in LIBS if lib in best}
            if fresh and "quatarray" in best:
                row["fresh_fraction"] = best["fresh fill"] / best["quatarray"]
        rq = row["rates_Mquat_s"].get("quatarray")
        if rq is not None:
            for lib, r in row["rates_Mquat_s"].items():
                if lib != "quatarray":
                    row["ratios"][lib] = rq / r
            if c.nbytes:
                row["stream_GBps"] = triad_bytes / min(best[k] for k in triad_fns) / 1e9
                row["stream_fraction"] = rq * 1e6 * c.nbytes / (row["stream_GBps"] * 1e9)
        rows.append(row)
    by_op = {r["op"]: r for r in rows}
    for op32, op64 in (("multiply float32 (out=)", "multiply (out=)"), ("rotate float32 (out=)", "rotate (out=)")):
        a = by_op.get(op32, {}).get("rates_Mquat_s", {}).get("quatarray")
        b = by_op.get(op64, {}).get("rates_Mquat_s", {}).get("quatarray")
        if a and b:
            by_op[op32]["ratios"]["float64"] = a / b
    return ceil, rows


def table(n, ceil, rows, over=None):
    """The readable report as a string."""
    lines = []
    lines.append(f"quatarray bench: n = {n:,} (float64 unless stated), {os.cpu_count()} CPU(s), "
                 f"{platform.machine()}, Python {platform.python_version()}, numpy {np.__version__}")
    load = _load()
    if load is not None and load > 0.5 * (os.cpu_count() or 1):
        lines.append(f"note: the machine is busy (load average {load:.1f} on {os.cpu_count()} CPUs); "
                     "rates, and most of all multi-threaded ones, are lower than on an idle machine")
    lines.append(
        f"memory-stream ceiling (STREAM triad): {ceil['GBps']:.1f} GB/s "
        f"(numpy 1 thread {ceil['triad_GBps_numpy_1thread']:.1f}, numba threads {ceil['triad_GBps_numba_threads']:.1f})"
        f" = {ceil['Mquat_s_product']:.0f} Mquat/s for a 96-byte float64 product"
    )
    lines.append("rates in Mquat/s (resampling: output samples); ratio = quatarray rate / other rate")
    head = ["operation", "quatarray", "%stream", "scipy", "ratio", "numpy-quat", "ratio", "quaternionic", "ratio"]
    body = []
    for r in rows:
        rates, ratios = r["rates_Mquat_s"], r["ratios"]
        if "status" in r:
            body.append([r["op"], r["status"]] + [""] * 7)
            continue
        sf = r.get("stream_fraction")
        cells = [r["op"], _fmt_rate(rates.get("quatarray")), "—" if sf is None else f"{100 * sf:.0f}%"]
        for lib in LIBS[1:]:
            cells += [_fmt_rate(rates.get(lib)), _fmt_ratio(ratios.get(lib))]
        body.append(cells)
    widths = [max(len(str(x[i])) for x in body + [head]) for i in range(len(head))]
    widths[1] = max(widths[1], 9)

    def fmt(cells):
        if cells[2:] == [""] * 7:
            return f"{cells[0]:<{widths[0]}}  {cells[1]}"
        return "  ".join(f"{c:<{w}}" if i == 0 else f"{c:>{w}}" for i, (c, w) in enumerate(zip(cells, widths)))

    lines.append(fmt(head))
    lines.append("-" * len(fmt(head)))
    lines += [fmt(c) for c in body]
    notes = [f"  {r['op']}: {r['note']}" for r in rows if r.get("note") and "status" not in r]
    notes += [f"  {r['op']}: {r['ratios']['float64']:.2f}× the float64 rate" for r in rows if "float64" in r["ratios"]]
    notes += [f"  {r['op']}: {100 * r['fresh_fraction']:.0f}% of the fresh-array ceiling (np.empty and a "
              "prange fill of the result's shape, timed in the same rounds)" for r in rows if "fresh_fraction" in r]
    if notes:
        lines.append("notes:")
        lines += notes
    if over:
        lines.append("per-call overhead, one quaternion (µs per call):")
        for op, d in over.items():
            lines.append("  " + op + ": " + ", ".join(f"{lib} {d[lib]:.2f}" for lib in LIBS if lib in d))
    return "\n".join(lines)


def run(n=None, json_path=None, budget=1.0, stream=None):
    """Run the side-by-side benchmark, print the table, optionally write JSON.

    Parameters
    ----------
    n : int, optional
        Quaternions per call (default 2,000,000, the size of the performance targets).
    json_path : str or path, optional
        Write the same figures as JSON here.
    budget : float
        Seconds spent timing each row (more gives steadier numbers).
    stream : file, optional
        Where the table goes (default stdout).

    Returns
    -------
    int
        Exit status (0).
    """
    stream = stream or sys.stdout
    n = DEFAULT_N if n is None else int(n)
    if n < 1:
        raise ValueError(f"Expected `n` to be a positive number of quaternions, got {n}.")
    t0 = time.perf_counter()
    progress = None
    if stream is sys.stdout and sys.stderr.isatty():

        def progress(op):
            print(f"\r\033[Kmeasuring {op} ...", end="", file=sys.stderr, flush=True)

    ceil, rows = results(n, budget, progress=progress)
    over = overhead()
    if progress:
        print("\r\033[K", end="", file=sys.stderr, flush=True)
    text = table(n, ceil, rows, over)
    print(text, file=stream)
    print(f"(measured in {time.perf_counter() - t0:.0f} s)", file=stream)
    if json_path is not None:
        import quatarray

        doc = {
            "n": n,
            "dtype": "float64",
            "machine": {"cpus": os.cpu_count(), "arch": platform.machine(), "python": platform.python_version(),
                        "numpy": np.__version__, "quatarray": quatarray.__version__,
                        "load_average_1min": _load()},
            "ceiling": ceil,
            "results": rows,
            "overhead_us": over,
            "libraries": {lib: _version(lib) for lib in LIBS},
        }
        with open(json_path, "w") as f:
            json.dump(doc, f, indent=1)
    return 0


def _load():
    try:
        return os.getloadavg()[0]
    except (AttributeError, OSError):  # not on every platform
        return None


def _version(lib):
    mod = {"quatarray": "quatarray", "scipy": "scipy", "numpy-quaternion": "quaternion",
           "quaternionic": "quaternionic"}[lib]
    m = _optional(mod)
    return None if m is None else getattr(m, "__version__", "?")
