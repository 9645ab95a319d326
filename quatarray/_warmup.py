"""Compile every kernel into numba's on-disk cache ahead of time.

:func:`warmup` calls every public function on small inputs of each float
type, in the layouts the kernels specialise on (contiguous, read-only,
strided, one row broadcast against many, ``out=``), once with the serial
and once with the parallel row loops (see ``quatarray._jit.RowLoop``), so
that a later process finds machine code on disk for every call it makes and
compiles nothing. The calls run in worker processes, one per core, each
taking the next job when it is done with one.

The calls come from one table, :data:`TABLE`: a new public function is one
line there (a test checks that every name of ``quatarray.__all__`` has one),
and so is each of the other entry points whose kernels a user meets: clips
(``Clip.world``, ``Clip.resample``, BVH files), trajectory evaluation and
``quatarray eval``. ``tests/test_warmup.py`` walks every public entry point
(functions, methods, command-line verbs) and checks that each call it makes
into a compiled kernel, with its argument types, is one the table makes.

Numba's cache index is not safe against two processes adding entries to the
same function at once (both may pick the same data file name), so inside the
workers every cache write holds an exclusive lock on one file
(``QUATARRAY_CACHE_LOCK``: the caller's own, when it has one, so that the
workers also wait for the other processes that use it).
"""

import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from types import SimpleNamespace
from typing import NamedTuple

import numpy as np

DTYPES = {"float64": ("float64",), "float32": ("float32",), "all": ("float64", "float32")}
VARIANTS = ("serial", "parallel")
_LOCK_ENV = "QUATARRAY_CACHE_LOCK"  # quatarray._jit.CACHE_LOCK_ENV (no numba import here)
try:
    import fcntl  # noqa: F401 - only whether it exists
except ImportError:  # Windows: one worker process
    _CAN_LOCK = False
else:
    _CAN_LOCK = True

# --------------------------------------------------------------------------
# the calls


def _samples(dtype, n=8, k=6):
    """Small inputs of float type `dtype`: quaternions p, q, vectors v, t in [0, 1),
    matrices m, rotation vectors rv, axes and angles, Euler angles, SU(2) matrices,
    k keys with times, sorted and unsorted new times."""
    rng = np.random.default_rng(0)
    d = np.dtype(dtype)

    def unit(rows):
        a = rng.standard_normal((rows, 4))
        return (a / np.linalg.norm(a, axis=1, keepdims=True)).astype(d)

    p, q = unit(n), unit(n)
    big = 1e200 if d == np.float64 else 1e30
    far = p.copy()  # a row far from unit scale: the second pass of the rowloop(far=...) kernels
    far[1] *= big
    w, x, y, z = p.T.astype(np.float64)
    m = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]).transpose(2, 0, 1)  # fmt: skip
    su2 = np.empty((n, 2, 2), np.complex128 if d == np.float64 else np.complex64)
    su2[:, 0, 0], su2[:, 0, 1] = w + 1j * x, y + 1j * z
    su2[:, 1, 0], su2[:, 1, 1] = -y + 1j * z, w - 1j * x
    times = np.cumsum(rng.uniform(0.5, 1.5, k))
    new_t = np.linspace(times[0], times[-1], 2 * k)
    from .splines import PIECES_MIN_KEYS as many  # the spline's piece kernels take this many keys

    return SimpleNamespace(
        dtype=d, p=p, q=q, v=rng.standard_normal((n, 3)).astype(d), t=rng.random(n).astype(d),
        s=rng.uniform(0.5, 2.0, n).astype(d), m=np.ascontiguousarray(m, dtype=d), rv=rng.standard_normal((n, 3)).astype(d),
        axis=rng.standard_normal((n, 3)).astype(d), ang=rng.uniform(0, 3, n).astype(d),
        eul=rng.uniform(-1, 1, (n, 3)).astype(d), su2=su2,
        keys=unit(k), times=times, new_sorted=new_t, new_unsorted=rng.permutation(new_t), far=far,
        many_keys=unit(many), many_times=np.arange(float(many)), many_new=np.linspace(0.0, many - 1.0, 2 * many),
        far_m=np.concatenate([m[:1] * big, m[1:]]).astype(d),
    )


def _read_only(a):
    b = a.copy()
    b.flags.writeable = False
    return b


def _strided(a):
    b = np.zeros((2 * a.shape[0],) + a.shape[1:], a.dtype)[::2]
    b[...] = a
    return b


def _each(f, *args, out=False, **kw):
    """``f(*args, **kw)`` with the array arguments contiguous, read-only and strided;
    with each array argument in turn reduced to its first row (broadcast against
    the others' batch); and with ``out=`` if asked: a new array, a strided one, and
    each array argument of the result's shape and type itself (the loops that know
    `out` is an input, ``RowLoop.into``), contiguous and strided, and contiguous
    with each other array argument reduced to its first row (a scalar parameter,
    one row against many)."""
    batch = [i for i, a in enumerate(args) if isinstance(a, np.ndarray) and a.ndim > 0]
    for layout in (lambda a: a, _read_only, _strided):
        f(*[layout(a) if i in batch else a for i, a in enumerate(args)], **kw)
    if len(batch) > 1:
        for i in batch:
            f(*[a[0] if j == i else a for j, a in enumerate(args)], **kw)
    if out:
        r = f(*args, **kw)
        f(*args, out=np.empty_like(r), **kw)
        f(*args, out=_strided(np.empty_like(r)), **kw)
        for i in batch:
            if args[i].shape == r.shape and args[i].dtype == r.dtype:
                for row, layout in [(None, np.copy), (None, _strided)] + [(j, np.copy) for j in batch if j != i]:
                    b = layout(args[i])
                    f(*[b if j == i else a[0] if j == row else a for j, a in enumerate(args)], out=b, **kw)


def _rotate_into_v(f, q, v):
    """rotate(q, v, out=v) for one q of shape (1, 4): rotate's own loop for `out` = v
    (not a RowLoop.into copy) meets q's broadcast rows as another type than a q of (4,)."""
    b = v.copy()
    f(q, b, out=b)


def _interp(f, s, *extra, **kw):
    """An interpolation function of ``(*quaternions, t)``: N pairs and N t, scalar t,
    one pair and N t."""
    _each(f, s.p, s.q, *extra, s.t, out=True, **kw)
    f(s.p, s.q, *extra, 0.5, **kw)
    f(s.p[0], s.q[0], *[e[0] for e in extra], s.t, **kw)


def _slerp_blocks(f, s):
    """slerp on more rows than one block of its loop (which calls of a block skip), each
    call also with its given output written past the caches."""
    from . import _access
    from .interpolation import SLERP_BLOCK

    reps = SLERP_BLOCK // len(s.t) + 1
    p, q, t = np.tile(s.p, (reps, 1)), np.tile(s.q, (reps, 1)), np.tile(s.t, reps)
    least = _access.STREAM_MIN_BYTES  # (set for a moment: the table runs in the warm-up's worker processes)
    for stream in (least, 0):
        _access.STREAM_MIN_BYTES = stream
        try:
            _each(f, p, q, t, out=True)
            _each(f, p, q, t, out=True, shortest=False)
        finally:
            _access.STREAM_MIN_BYTES = least


def _vqs(qa, s):
    return qa.VQS(s.v, s.p, s.s)


def _vqm(qa, s):
    return qa.VQM(s.v, s.q, s.m * s.s[:, None, None])


def _transform(t, other, s):
    """Every method of the transforms `t` (VQS or VQM), composed also with `other`."""
    _each(t.apply, s.v, out=True)
    _each(type(t)(t.v, s.far, getattr(t, t._field)).apply, s.v, out=True)  # far rows of q
    t[0].apply(s.v), t.apply(s.v[0])  # one transform and many vectors, and the other way round
    type(t)(t.v, s.far, getattr(t, t._field)).apply(s.v[0])
    t @ t, t[0] @ t, t @ other, other @ t, t.inverse(), t.as_matrix()
    type(t).from_matrix(t.as_matrix())
    type(t).identity(3, dtype=s.dtype)


def _interpolate(qa, s):
    a, b = _vqs(qa, s), _vqm(qa, s)
    for x, y in ((a, a), (b, b), (a, b)):
        qa.interpolate(x, y, s.t)
        qa.interpolate(x, y, 0.5)
        qa.interpolate(x[0], y[0], s.t)


def _spline(method, new, order=0):
    """`new`: "new_sorted", "new_unsorted" or "many" (sorted new times over enough keys
    for the piece kernels, :data:`quatarray.splines.PIECES_MIN_KEYS`)."""
    def run(qa, s):
        keys, times, new_t = (s.many_keys, s.many_times, s.many_new) if new == "many" else (
            s.keys, s.times, getattr(s, new))
        for t in (times, times.astype(s.dtype)):
            qa.spline(t, keys, new_t.astype(t.dtype), method=method, order=order)

    return run


def _clip(qa, s):
    """A small clip (float64, as every clip): a root with position channels, a child,
    a hinge (1 rotation channel), a joint of 2 rotation channels, an End Site; its
    frames at the key times."""
    from .skeleton import Clip

    k = len(s.times)
    q = s.keys.astype(np.float64)
    a = np.linspace(-1.0, 2.0, k)
    hinge = np.column_stack([np.cos(a / 2), np.sin(a / 2), np.zeros(k), np.zeros(k)])
    two = qa.from_euler("YX", np.column_stack([a, -a]))
    rot = np.stack([q, q[::-1], hinge, two, np.tile([1.0, 0, 0, 0], (k, 1))], axis=1)
    off = np.array([[0.0, 0, 0], [0, 1, 0], [0, 1, 0], [1, 0, 0], [0, 0.5, 0]])
    trans = np.broadcast_to(off, (k, 5, 3)).copy()
    trans[:, 0] = np.cumsum(np.ones((k, 3)), axis=0)
    chans = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"),
             ("Zrotation", "Xrotation", "Yrotation"), ("Xrotation",), ("Yrotation", "Xrotation"), ()]
    return Clip(["root", "child", "knee", "wrist", "wrist_End"], [-1, 0, 1, 0, 3], off, chans, rot, trans,
                1.0, times=s.times, ends=[False] * 4 + [True])


def _clip_resample(method):
    """Clip.resample by `method`: joint by joint (a small clip) and in one pass over
    the joints (``quatarray._spline_lanes``, which Clip.resample takes from
    ``LANES_MIN_SAMPLES`` joint-samples on), at a rate and at new times."""
    def run(qa, s):
        from ._spline_lanes import resample_streams

        clip = _clip(qa, s)
        clip.resample(rate=3.0, method=method)
        r = clip.resample(times=s.new_sorted, method=method)
        cols = [j for j, o in enumerate(clip.orders) if o]
        resample_streams(clip.times, r.times, clip.rotations, cols, method, np.empty_like(r.rotations))

    return run


def _spline_class(name, orders=(0,)):  # one order an entry: each a first call of its own
    """A spline class of quatarray (``Slerp``, ``RotationSpline``, ``BezierSpline``) built
    on the sample keys and called on sorted and unsorted new times, in each `order`."""
    def run(qa, s):
        spl = getattr(qa, name)(s.times, qa.Rotation.from_wxyz(s.keys))
        for new in (s.new_sorted, s.new_unsorted):
            for order in orders:
                spl(new, order) if order else spl(new)

    return run


def _bvh(qa, s):
    """write_bvh (exact Euler angles, a hinge's and 2 axes' angles) and read_bvh of a clip."""
    from .io import bvh

    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "clip.bvh")
        bvh.write_bvh(path, _clip(qa, s))
        bvh.read_bvh(path).world()


def _poses(qa, s, timed=True):
    from .trajectory import poses

    n = len(s.p)
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.5, 1.5, n)) if timed else None
    ref = poses(t, np.cumsum(rng.standard_normal((n, 3)), axis=0), s.p)
    est = poses(t, ref.pos + 0.1 * rng.standard_normal((n, 3)), s.q)
    return ref, est


def _trajectory(metric):
    """quatarray.trajectory.evaluate: every alignment and pose relation; for APE
    streams with and without times and the estimate resampled at the reference
    times; for RPE every unit of delta, consecutive and all pairs."""
    def run(qa, s):
        from . import trajectory as T

        ref, est = _poses(qa, s)
        kw = [dict(interpolate=False), dict(interpolate=True), dict(untimed=True)] if metric == "ape" else [
            dict(delta=1, delta_unit="frames"), dict(delta=2, delta_unit="m"), dict(delta=1.5, delta_unit="s"),
            dict(delta=1, delta_unit="frames", all_pairs=True), dict(delta=2, delta_unit="m", all_pairs=True)]
        for o in kw:
            r, e = _poses(qa, s, timed=False) if o.pop("untimed", False) else (ref, est)
            for align in T.ALIGNMENTS:
                for relation in T.RELATIONS:
                    T.evaluate(r, e, metric=metric, align=align, relation=relation, t_max_diff=10.0, **o)

    return run


def _eval_verb(qa, s):
    """``quatarray eval`` on two small TUM files: the chunked path (and the in-memory one)."""
    from .app import eval_verb as evaluate  # the verb's chunked path (imported only by this entry)

    ref, est = _poses(qa, s)
    with tempfile.TemporaryDirectory() as d, open(os.devnull, "w") as null:
        names = []
        for name, p in (("ref.txt", ref), ("est.txt", est)):
            names.append(os.path.join(d, name))
            np.savetxt(names[-1], np.column_stack([p.t, p.pos, p.q[:, 1:], p.q[:, :1]]))
        for metric in ("ape", "rpe"):
            for align in ("none", "sim3"):
                evaluate.run(*names, metric=metric, align=align, chunk=3, stdout=null, stderr=null)
                evaluate.run(*names, metric=metric, align=align, fmt="tum", stdout=null, stderr=null)


def _rotation_class(R, s):
    """Every method of ``quatarray.Rotation`` on a stack and a single rotation."""
    xyzw = s.p[:, [1, 2, 3, 0]]
    for r, v in ((R.from_quat(xyzw), s.v), (R.from_quat(xyzw[0]), s.v[0])):
        r.as_quat(), r.as_quat(True, scalar_first=True), r.as_matrix(), r.as_rotvec(), r.as_mrp()
        r.as_euler("xyz", suppress_warnings=True), r.magnitude(), r.inv(), r * r, r ** 0.5
        r.apply(v), r.apply(v, inverse=True), r.approx_equal(r), r.mean()
    R.from_quat(xyzw, scalar_first=True), R.from_rotvec(s.rv), R.from_rotvec(s.rv[0]), R.from_mrp(s.rv)
    R.from_mrp(s.rv[0]), R.from_euler("xyz", s.eul), R.from_euler("xyz", s.eul[0]), R.from_matrix(s.m)
    R.from_matrix(s.m[0])
    R.from_quat(xyzw).apply(s.v[0]), R.from_quat(xyzw[0]).apply(s.v)


def _f(name, call):
    """A table entry calling the public function `name` as ``call(f, s)``."""
    return lambda qa, s: call(getattr(qa, name), s)


# name → call(qa, samples). Every public function has a line; the spline's
# methods and its sorted/unsorted paths have one each (they are separate kernels).
TABLE = {
    # algebra
    "multiply": _f("multiply", lambda f, s: _each(f, s.p, s.q, out=True)),
    "conjugate": _f("conjugate", lambda f, s: _each(f, s.p, out=True)),
    "inverse": _f("inverse", lambda f, s: (_each(f, s.p, out=True), _each(f, s.far, out=True))),
    "norm": _f("norm", lambda f, s: (_each(f, s.p), _each(f, s.far))),
    "normalize": _f("normalize", lambda f, s: (_each(f, s.p, out=True), _each(f, s.far, out=True))),
    "dot": _f("dot", lambda f, s: _each(f, s.p, s.q)),
    "exp": _f("exp", lambda f, s: _each(f, s.p, out=True)),
    "log": _f("log", lambda f, s: (_each(f, s.p, out=True), _each(f, s.far, out=True))),
    "power": _f("power", lambda f, s: (_each(f, s.p, s.t, out=True), f(s.p, 0.5))),
    "cumprod": _f("cumprod", lambda f, s: (_each(f, s.p), f(s.p.reshape(2, -1, 4), axis=1))),
    "identity": _f("identity", lambda f, s: f(3, dtype=s.dtype)),
    "random": _f("random", lambda f, s: f(3, rng=0, dtype=s.dtype)),
    "canonical": _f("canonical", lambda f, s: _each(f, s.p, out=True)),
    "angle": _f("angle", lambda f, s: (_each(f, s.p), _each(f, s.far))),
    "distance": _f("distance", lambda f, s: (_each(f, s.p, s.q), _each(f, s.far, s.q))),
    "mean": _f("mean", lambda f, s: (_each(f, s.p), f(s.p, weights=s.s))),
    # rotation
    "rotate": _f("rotate", lambda f, s: (
        _each(f, s.p, s.v, out=True), _each(f, s.far, s.v, out=True), _rotate_into_v(f, s.p[:1], s.v))),
    # conversions
    "as_matrix": _f("as_matrix", lambda f, s: (_each(f, s.p, out=True), _each(f, s.far, out=True))),
    "from_matrix": _f("from_matrix", lambda f, s: (
        _each(f, s.m, out=True), _each(f, s.m, assume_valid=True, out=True), f(2 * s.m),
        _each(f, s.far_m, assume_valid=True, out=True))),
    "as_rotvec": _f("as_rotvec", lambda f, s: (
        _each(f, s.p, out=True), f(s.p, degrees=True), _each(f, s.far, out=True))),
    "from_rotvec": _f("from_rotvec", lambda f, s: (
        _each(f, s.rv, out=True), f(s.rv, degrees=True), _each(f, 1e7 * s.rv, out=True))),
    "as_axis_angle": _f("as_axis_angle", lambda f, s: (_each(f, s.p), f(s.p, degrees=True), _each(f, s.far))),
    "from_axis_angle": _f("from_axis_angle", lambda f, s: (
        _each(f, s.axis, s.ang, out=True), f(s.axis, 0.5), f(s.axis, s.ang, degrees=True))),
    "as_xyzw": _f("as_xyzw", lambda f, s: _each(f, s.p, out=True)),
    "from_xyzw": _f("from_xyzw", lambda f, s: _each(f, s.p, out=True)),
    "to_scipy": _f("to_scipy", lambda f, s: f(s.p)),
    "from_scipy": lambda qa, s: qa.from_scipy(qa.to_scipy(s.p)),
    "as_left_matrix": _f("as_left_matrix", lambda f, s: _each(f, s.p, out=True)),
    "as_right_matrix": _f("as_right_matrix", lambda f, s: _each(f, s.p, out=True)),
    "as_su2": _f("as_su2", lambda f, s: _each(f, s.p)),
    "from_su2": _f("from_su2", lambda f, s: _each(f, s.su2, out=True)),
    # Euler angles (proper and Tait-Bryan, extrinsic and intrinsic; far angles take a second kernel)
    "as_euler": _f("as_euler", lambda f, s: [
        (_each(f, s.p, seq), f(s.p, seq, degrees=True), _each(f, s.far, seq)) for seq in ("xyz", "ZYX", "zxz", "XZX")]),
    "from_euler": _f("from_euler", lambda f, s: [
        (_each(f, seq, s.eul), f(seq, s.eul, degrees=True), f(seq, 1e7 * s.eul)) for seq in ("xyz", "ZXZ")]),
    "as_mrp": _f("as_mrp", lambda f, s: (_each(f, s.p, out=True), _each(f, s.far, out=True))),
    "from_mrp": _f("from_mrp", lambda f, s: _each(f, s.rv, out=True)),
    "as_gibbs": _f("as_gibbs", lambda f, s: _each(f, s.p, out=True)),
    "from_gibbs": _f("from_gibbs", lambda f, s: _each(f, s.rv, out=True)),
    "approx_equal": _f("approx_equal", lambda f, s: (_each(f, s.p, s.q), f(s.p, s.q, atol=0.1))),
    # vector alignment
    "align_vectors": _f("align_vectors", lambda f, s: (
        f(s.v, s.rv), f(s.v, s.rv, weights=s.s, return_sensitivity=True), f(s.v[:1], s.rv[:1]),
        f(s.v.reshape(2, -1, 3), s.rv.reshape(2, -1, 3)))),
    "rotation_between": _f("rotation_between", lambda f, s: _each(f, s.v, s.rv)),
    # interpolation
    "lerp": _f("lerp", lambda f, s: _interp(f, s)),
    "nlerp": _f("nlerp", lambda f, s: (_interp(f, s), _interp(f, s, shortest=False))),
    "slerp": _f("slerp", lambda f, s: (_interp(f, s), _interp(f, s, shortest=False))),
    # rows slerp's main loop leaves to a kernel of their own (identical and antipodal ends)
    "slerp[rare rows]": _f("slerp", lambda f, s: (_each(f, s.p, s.p, s.t, out=True),
                                                  _each(f, s.p, -s.p, s.t, out=True, shortest=False))),
    # calls of more than one block (slerp's block loop, serial and parallel) and of outputs
    # written past the caches (their own loop, for large outputs: here made to stream)
    "slerp[blocks]": lambda qa, s: _slerp_blocks(qa.slerp, s),
    "double": _f("double", lambda f, s: _each(f, s.p, s.q, out=True)),
    "bisect": _f("bisect", lambda f, s: _each(f, s.p, s.q, out=True)),
    "bezier_controls": _f("bezier_controls", lambda f, s: (_each(f, s.keys), f(s.keys, s.times))),
    "bezier": _f("bezier", lambda f, s: _interp(lambda q0, q1, a, b, t, **kw: f(q0, a, b, q1, t, **kw), s, s.p, s.q)),
    "squad": _f("squad", lambda f, s: _interp(lambda q0, q1, a, b, t, **kw: f(q0, a, b, q1, t, **kw), s, s.p, s.q)),
    "unflip": _f("unflip", lambda f, s: (_each(f, s.p), f(s.p.reshape(2, -1, 4), axis=1))),
    "spline[bezier]": _spline("bezier", "new_sorted"),
    "spline[bezier, unsorted]": _spline("bezier", "new_unsorted"),
    "spline[slerp]": _spline("slerp", "new_sorted"),
    "spline[slerp, unsorted]": _spline("slerp", "new_unsorted"),
    "spline[nlerp]": _spline("nlerp", "new_sorted"),
    "spline[nlerp, unsorted]": _spline("nlerp", "new_unsorted"),
    "spline[squad]": _spline("squad", "new_sorted"),
    "spline[squad, unsorted]": _spline("squad", "new_unsorted"),
    **{f"spline[{m}, many keys]": _spline(m, "many") for m in ("bezier", "slerp", "nlerp", "squad")},
    "spline[cubic]": _spline("cubic", "new_sorted"),
    "spline[cubic, unsorted]": _spline("cubic", "new_unsorted"),
    # the rate loops serve sorted and unsorted new times alike
    **{f"spline[{m}, order={o}]": _spline(m, "new_unsorted", o)
       for m in ("bezier", "slerp", "nlerp", "squad", "cubic") for o in (1, 2)},
    # sorted new times over many keys: the rates piece by piece (splines._RATE_PIECES)
    **{f"spline[{m}, many keys, order={o}]": _spline(m, "many", o)
       for m in ("bezier", "slerp", "nlerp", "squad") for o in (1, 2)},
    # the spline classes (their kernels are the spline's: these compile what their calls add)
    "Slerp": _spline_class("Slerp"),
    **{f"{c}{'' if o == 0 else f'[order={o}]'}": _spline_class(c, (o,))
       for c in ("RotationSpline", "BezierSpline") for o in (0, 1, 2)},
    "angular_velocity": _f("angular_velocity", lambda f, s: [f(s.keys, s.times, frame=fr) for fr in ("space", "body")]),
    "integrate_angular_velocity": _f("integrate_angular_velocity", lambda f, s: [
        f(s.v[: len(s.times)], s.times, frame=fr, hold=h) for fr in ("space", "body") for h in ("mean", "start")]),
    # Davenport angles, symmetry groups
    "from_davenport": _f("from_davenport", lambda f, s: [
        f(np.eye(3, dtype=s.dtype)[[2, 0, 2]], o, s.eul) for o in ("e", "i")]),
    "as_davenport": _f("as_davenport", lambda f, s: [
        f(s.p, np.eye(3, dtype=s.dtype)[[2, 0, 1]], o, suppress_warnings=True) for o in ("e", "i")]),
    "create_group": _f("create_group", lambda f, s: f("O", dtype=s.dtype)),
    "reduce": _f("reduce", lambda f, s: (f(s.p, s.q[:3], s.q[3:]), f(s.p, s.q))),
    # the scipy-compatible class (its own kernels and its one-row paths)
    "Rotation": lambda qa, s: _rotation_class(qa.Rotation, s),
    # transforms
    "VQS": lambda qa, s: _transform(_vqs(qa, s), _vqm(qa, s), s),
    "VQM": lambda qa, s: _transform(_vqm(qa, s), _vqs(qa, s), s),
    "interpolate": _interpolate,
    # skeletons (quatarray.skeleton, quatarray.io.bvh): always float64
    "Clip.world": lambda qa, s: _clip(qa, s).world(),
    **{f"Clip.resample[{m}]": _clip_resample(m) for m in ("bezier", "slerp", "nlerp", "squad", "cubic")},
    "read_bvh, write_bvh": _bvh,
    # trajectory evaluation (quatarray.trajectory, ``quatarray eval``): always float64
    "trajectory[ape]": _trajectory("ape"),
    "trajectory[rpe]": _trajectory("rpe"),
    "eval": _eval_verb,
    # rigid transforms (poses)
    "pose_compose": _f("pose_compose", lambda f, s: _each(f, s.p, s.v, s.q, s.rv)),
    "pose_inverse": _f("pose_inverse", lambda f, s: _each(f, s.p, s.v)),
    "pose_apply": _f("pose_apply", lambda f, s: (
        _each(f, s.p, s.v, s.rv, out=True), _each(f, s.p, s.v, s.rv, inverse=True, out=True))),
    "pose_as_matrix": _f("pose_as_matrix", lambda f, s: _each(f, s.p, s.v, out=True)),
    "pose_from_matrix": lambda qa, s: qa.pose_from_matrix(qa.pose_as_matrix(s.p, s.v)),
    "as_dual_quat": _f("as_dual_quat", lambda f, s: (
        _each(f, s.p, s.v, out=True), f(s.p, s.v, scalar_first=False))),
    "from_dual_quat": lambda qa, s: [
        _each(qa.from_dual_quat, qa.as_dual_quat(s.p, s.v, scalar_first=sf), scalar_first=sf) for sf in (True, False)],
    "as_exp_coords": _f("as_exp_coords", lambda f, s: _each(f, s.p, s.v, out=True)),
    "from_exp_coords": lambda qa, s: _each(qa.from_exp_coords, qa.as_exp_coords(s.p, s.v)),
    "sclerp": _f("sclerp", lambda f, s: (_each(f, s.p, s.v, s.q, s.rv, s.t), f(s.p, s.v, s.q, s.rv, 0.5))),
    "pose_power": _f("pose_power", lambda f, s: (_each(f, s.p, s.v, s.t), f(s.p, s.v, 0.5))),
    "pose_mean": _f("pose_mean", lambda f, s: (f(s.p, s.v), f(s.p, s.v, weights=s.s))),
    "pose_spline": _f("pose_spline", lambda f, s: [
        f(s.times, s.keys, s.v[: len(s.times)], s.new_sorted, method=m, poses=r)
        for m, r in (("slerp", "split"), ("bezier", "split"), ("slerp", "screw"))]),
    "RigidTransform": lambda qa, s: _rigid_transform(qa, s),
}


# entries whose calls are float64 whatever the samples' type (a clip, a pose stream):
# one job of one float type each (the first asked for), not one per type
FLOAT64_ONLY = {"Clip.world", "Clip.resample[bezier]", "Clip.resample[slerp]", "Clip.resample[nlerp]",
                "Clip.resample[squad]", "Clip.resample[cubic]", "read_bvh, write_bvh", "trajectory[ape]",
                "trajectory[rpe]", "eval"}


def _rigid_transform(qa, s):
    """Every method of ``RigidTransform`` that runs a kernel of its own (the class's
    kernels give each quaternion scipy's sign: other specialisations than the functions')."""
    T = qa.RigidTransform
    a = T.from_matrix(qa.pose_as_matrix(s.p, s.v))
    b = T.from_components_wxyz(s.rv, s.q, normalize=True)
    a * b, a[0] * b, a.inv(), a**0.5, a.apply(s.rv), a.apply(s.rv, inverse=True), a[0].apply(s.rv)
    T.from_dual_quat(a.as_dual_quat()), T.from_dual_quat(a.as_dual_quat(scalar_first=True), scalar_first=True)
    T.from_exp_coords(a.as_exp_coords()), a.as_matrix(), a.mean(), a.mean(weights=s.s)
    T.from_components(s.v, qa.Rotation.from_wxyz(s.p)), T.from_translation(s.v)


def covered(name):
    """True when `name` (a public name of quatarray) has a line in :data:`TABLE`."""
    return name in TABLE or any(k.startswith(name + "[") for k in TABLE)


# --------------------------------------------------------------------------
# the worker process


def _run_job(qa, jit, name, dtype, variant, samples):
    """Run one table entry: (seconds, number of functions numba compiled (-1: unknown), error
    message or "")."""
    from ._numba_internals import CompileCounter

    counter = CompileCounter()
    error = ""
    t0 = time.perf_counter()
    try:
        with counter, jit.variant(variant if variant == "parallel" else "serial"):
            TABLE[name](qa, samples[dtype])
    except Exception as exc:  # noqa: BLE001 - a kernel that does not compile is reported, the rest goes on
        error = f"{type(exc).__name__}: {str(exc).splitlines()[-1] if str(exc) else ''}"[:300]
    seconds = time.perf_counter() - t0
    return seconds, counter.count if counter.count is not None else -1, error


def _worker():
    """The worker loop: one JSON job ``[name, dtype, variant]`` per line of stdin,
    one JSON result ``[name, dtype, variant, seconds, compiled, error]`` per line of stdout."""
    import warnings

    import quatarray as qa
    from quatarray import _jit

    samples = {d: _samples(d) for d in DTYPES["all"]}
    for line in sys.stdin:
        name, dtype, variant = json.loads(line)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # gimbal lock, far angles, nan rows: the inputs are arbitrary
            result = _run_job(qa, _jit, name, dtype, variant, samples)
        print(json.dumps([name, dtype, variant, *result]), flush=True)


# --------------------------------------------------------------------------
# the driver


class Job(NamedTuple):
    """One warm-up job: a table entry, a float type, the row-loop variant, its
    wall time in seconds, how many functions numba compiled for it (0: all
    loaded from the cache) and the error that stopped it ("" if none)."""

    name: str
    dtype: str
    variant: str
    seconds: float
    compiled: int
    error: str = ""


class Summary(NamedTuple):
    """What :func:`warmup` did: the jobs (slowest first), the wall time and the
    number of worker processes."""

    jobs: list
    wall: float
    processes: int

    @property
    def failed(self):
        """The jobs that raised (a kernel that does not compile, say)."""
        return [j for j in self.jobs if j.error]

    @property
    def compiled(self):
        """Number of functions numba compiled (0 when everything was in the cache)."""
        return sum(j.compiled for j in self.jobs)

    def table(self):
        """The report as text: one line per job, then the totals."""
        lines = [f"{'function':<26} {'dtype':<8} {'loops':<9} {'seconds':>8} {'compiled':>9}"]
        for j in self.jobs:
            lines.append(f"{j.name:<26} {j.dtype:<8} {j.variant:<9} {j.seconds:>8.2f} {j.compiled:>9}")
        lines += [f"FAILED {j.name} {j.dtype} {j.variant}: {j.error}" for j in self.failed]
        busy = sum(j.seconds for j in self.jobs)
        lines.append(
            f"{len(self.jobs)} jobs ({len(self.failed)} failed), {self.compiled} functions compiled, "
            f"{busy:.1f} s of work in {self.wall:.1f} s wall on {self.processes} process(es)"
        )
        return "\n".join(lines)


def _start_worker(env, stdout, stderr):
    return subprocess.Popen([sys.executable, "-c", "from quatarray._warmup import _worker; _worker()"],
                            stdin=subprocess.PIPE, stdout=stdout, stderr=stderr, text=True, env=env)


def _jobs(dtypes, names):
    order = [n for n in names if n.startswith("spline")] + [n for n in names if not n.startswith("spline")]
    return [(n, d, v) for n in order for d in (dtypes[:1] if n in FLOAT64_ONLY else dtypes) for v in VARIANTS]


def _env(lock):
    """The workers' environment: this one, with this process's import path (as
    multiprocessing's spawn does), so they import the same quatarray, and the
    cache lock (this process's own if it has one, else `lock`)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p or os.getcwd() for p in sys.path)
    env[_LOCK_ENV] = env.get(_LOCK_ENV) or lock
    return env


def warmup(dtype="all", processes=None, verbose=False, names=None):
    """Compile every kernel into numba's on-disk cache, in parallel worker processes.

    Every public function is called on small inputs of each float type, in
    the layouts the kernels specialise on (contiguous, read-only, strided,
    one row broadcast against many, ``out=``), with the serial and with the
    parallel row loops. Afterwards a new process compiles nothing: its first
    call of any function loads machine code from the cache. Run it once when
    building a container image, in CI before the tests, or on each machine of
    a cluster (``client.run(qa.warmup)`` on Dask workers); see the README.
    The cache is numba's: ``NUMBA_CACHE_DIR`` if set, else ``__pycache__``
    beside the sources (or the user's cache folder when those are read-only).

    Parameters
    ----------
    dtype : {"all", "float64", "float32"}, optional
        Float types to compile for (default both).
    processes : int, optional
        Worker processes (default: one per core, ``os.cpu_count()``).
    verbose : bool, optional
        Print each job as it ends (to stderr).
    names : iterable of str, optional
        Only these entries of :data:`TABLE` (default all).

    Returns
    -------
    Summary
        ``jobs`` (one :class:`Job` per table entry, float type and row-loop
        variant, slowest first), ``wall`` seconds, ``processes``;
        ``summary.table()`` is the printable report. A job that raises (a
        kernel that fails to compile) does not stop the others: it is listed
        in ``summary.failed`` with its error.

    Raises
    ------
    RuntimeError
        A worker process died (its last output is in the message).

    Examples
    --------
    >>> import quatarray as qa
    >>> s = qa.warmup(dtype="float32", names=["multiply"], processes=1)
    >>> [(j.name, j.dtype, j.variant) for j in sorted(s.jobs)]
    [('multiply', 'float32', 'parallel'), ('multiply', 'float32', 'serial')]
    """
    if dtype not in DTYPES:
        raise ValueError(f"Expected `dtype` to be one of {sorted(DTYPES)}, got {dtype!r}.")
    names = list(TABLE) if names is None else list(names)
    unknown = [n for n in names if n not in TABLE]
    if unknown:
        raise ValueError(f"Expected `names` from quatarray._warmup.TABLE, got {unknown[0]!r}.")
    todo = _jobs(DTYPES[dtype], names)
    processes = max(1, min(int(processes or os.cpu_count() or 1), len(todo)))
    if not _CAN_LOCK:
        processes = 1  # no file lock to make numba's cache writes safe across processes
    pending = list(reversed(todo))
    pending_lock = threading.Lock()
    done, errors = [], []

    def next_job():
        with pending_lock:
            return pending.pop() if pending else None

    def drive(env):
        log = tempfile.TemporaryFile("w+")  # not a pipe: nobody reads it until the end
        proc = _start_worker(env, subprocess.PIPE, log)
        try:
            while (job := next_job()) is not None:
                proc.stdin.write(json.dumps(job) + "\n")
                proc.stdin.flush()
                line = proc.stdout.readline()
                if not line:
                    proc.wait()
                    log.seek(0)
                    raise RuntimeError(f"warm-up worker failed on {job}: {log.read()[-2000:]}")
                res = Job(*json.loads(line))
                done.append(res)
                if verbose:
                    print(f"{res.name} {res.dtype} {res.variant}: {res.seconds:.2f} s, "
                          f"{res.compiled} compiled {res.error}", file=sys.stderr, flush=True)
        except BaseException as exc:  # noqa: BLE001 - reported below, in the caller's thread
            errors.append(exc)
            with pending_lock:
                pending.clear()
        finally:
            proc.stdin.close()
            proc.wait()
            log.close()

    t0 = time.perf_counter()
    with tempfile.NamedTemporaryFile(prefix="quatarray-warmup-", suffix=".lock") as lock:
        env = _env(lock.name)
        threads = [threading.Thread(target=drive, args=(env,), daemon=True) for _ in range(processes)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    if errors:
        raise errors[0]
    return Summary(sorted(done, key=lambda j: -j.seconds), time.perf_counter() - t0, processes)


def in_background(names, dtype="float64", variants=VARIANTS):
    """Compile the table entries `names` into the cache in one worker process that
    runs beside the caller, which goes on meanwhile; returns the process (None
    where cache writes cannot be locked: no ``fcntl``).

    For a program that knows which kernels it will need later (``quatarray
    demo``'s throughput section): they compile on another core while it works,
    and its later first calls load them from the cache (or, if it gets there
    first, compile them itself, as without this). From now on this process's
    own cache writes hold the worker's lock, since numba's cache index is not
    safe against two writers.

    Parameters
    ----------
    names : iterable of str
        Entries of :data:`TABLE`.
    dtype : {"float64", "float32", "all"}, optional
    variants : tuple of str, optional
        Row-loop variants, of ``("serial", "parallel")`` (default both).

    Examples
    --------
    >>> from quatarray import _warmup
    >>> proc = _warmup.in_background(["multiply"], dtype="float32", variants=("serial",))
    >>> proc.wait()
    0
    """
    names = list(names)
    unknown = [n for n in names if n not in TABLE] + [v for v in variants if v not in VARIANTS]
    if unknown or dtype not in DTYPES:
        raise ValueError(f"Expected `names` from quatarray._warmup.TABLE, `variants` from {VARIANTS} and "
                         f"`dtype` from {sorted(DTYPES)}, got {unknown[0] if unknown else dtype!r}.")
    if not _CAN_LOCK:
        return None
    from . import _jit, _numba_internals

    lock = (_numba_internals.cache_lock_path() or os.environ.get(_LOCK_ENV)
            or os.path.join(tempfile.gettempdir(), "quatarray-cache.lock"))
    if not _jit.lock_cache_writes(lock):  # this numba's cache cannot be shared safely
        return None
    proc = _start_worker(_env(lock), subprocess.DEVNULL, subprocess.DEVNULL)
    proc.stdin.write("".join(json.dumps([n, d, v]) + "\n" for n in names for d in DTYPES[dtype] for v in variants))
    proc.stdin.close()
    return proc
