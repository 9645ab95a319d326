"""Which compiled kernels a call reaches, and with which argument types, without compiling.

Run as a script under ``NUMBA_DISABLE_JIT=1``: numba's ``njit`` is replaced (before
quatarray is imported) by a wrapper that records every call from Python into a
kernel (a call from another kernel is compiled as part of its caller: not
recorded) as ``(kernel, argument types)`` — numba's ``typeof`` of each argument,
which is what a dispatcher compiles a new version for — and runs the function as
plain Python. So the set of those keys that a call makes is the set of compiled
versions it needs; a process that has them all in the on-disk cache compiles
nothing for it. ``tests/test_warmup.py`` compares the keys of the warm-up's
:data:`quatarray._warmup.TABLE` with those of :data:`WALK`: every public entry
point of quatarray called as a user calls it.

    NUMBA_DISABLE_JIT=1 python tests/kernel_calls.py table float64  # or float32
    NUMBA_DISABLE_JIT=1 python tests/kernel_calls.py walk [NAME ...]

print one JSON object: ``{"calls": {entry: [[kernel, [types…], element], …]}, "errors": {entry: message},
"seconds": {entry: seconds}}``
(``element``: the kernel is an element function, compiled without its Python
wrapper: called from Python it compiles a twin in every process).
"""

import contextlib
import json
import os
import sys
import tempfile
import threading
import time
import warnings

import numpy as np

_calls = set()
_local = threading.local()


def _types(args, kws):
    from numba import typeof

    def ty(a):
        try:
            return str(typeof(a))
        except Exception:  # noqa: BLE001 - an argument numba cannot type: its Python type
            return "python " + type(a).__name__

    return [ty(a) for a in args] + [f"{k}={ty(v)}" for k, v in sorted(kws.items())]


def _recording_njit(*a, **options):
    def wrap(fn):
        element = bool(options.get("no_cpython_wrapper"))

        def call(*args, **kws):
            depth = getattr(_local, "depth", 0)
            if depth == 0:
                _calls.add(json.dumps([f"{fn.__module__}.{fn.__qualname__}", _types(args, kws), element]))
            _local.depth = depth + 1
            try:
                return fn(*args, **kws)
            finally:
                _local.depth = depth

        call.py_func = fn
        call.__name__, call.__qualname__, call.__module__ = fn.__name__, fn.__qualname__, fn.__module__
        call.__doc__ = fn.__doc__
        return call

    if a and callable(a[0]) and not options:
        return wrap(a[0])
    return wrap


def install():
    """Replace numba.njit by the recorder; before quatarray is imported."""
    if os.environ.get("NUMBA_DISABLE_JIT") != "1":
        raise RuntimeError("run with NUMBA_DISABLE_JIT=1")
    if "quatarray" in sys.modules:
        raise RuntimeError("install() must run before quatarray is imported")
    import numba

    numba.njit = _recording_njit


@contextlib.contextmanager
def recording():
    """The keys of the calls made inside the block (a set, filled as they come)."""
    _calls.clear()
    got = set()
    try:
        yield got
    finally:
        got.update(_calls)
        _calls.clear()


# --------------------------------------------------------------------------
# the walk: every public entry point, called as a user calls it


def _inputs(dtype):
    rng = np.random.default_rng(7)
    d = np.dtype(dtype)
    q = rng.standard_normal((6, 4))
    q = (q / np.linalg.norm(q, axis=1, keepdims=True)).astype(d)
    v = rng.standard_normal((6, 3)).astype(d)
    t = np.cumsum(rng.uniform(0.5, 1.5, 6))
    return dict(q=q, p=q[::-1].copy(), v=v, w=rng.standard_normal((6, 3)).astype(d), t=t,
                new=np.linspace(t[0], t[-1], 9), s=rng.uniform(0.1, 0.9, 6).astype(d))


UNARY = ["conjugate", "inverse", "norm", "normalize", "exp", "log", "canonical", "angle", "as_matrix", "as_rotvec",
         "as_axis_angle", "as_xyzw", "from_xyzw", "as_left_matrix", "as_right_matrix", "as_su2", "as_mrp",
         "as_gibbs", "unflip", "cumprod", "mean", "to_scipy"]
BINARY = ["multiply", "dot", "distance", "approx_equal", "double", "bisect"]


def _quaternion_calls(qa, name):
    """Ordinary calls of a function of quatarray.__all__, float64 and float32: a batch,
    one quaternion (4,), a list, a batch of batches."""
    def run():
        for d in ("float64", "float32"):
            x = _inputs(d)
            q, p, v, w, t, s = x["q"], x["p"], x["v"], x["w"], x["t"], x["s"]
            f = getattr(qa, name, None)
            if name in UNARY:
                for a in (q, q.reshape(2, 3, 4)) if name in ("cumprod", "unflip") else (q, q[0], q.reshape(2, 3, 4)):
                    if name == "to_scipy" and a.ndim > 2 and not qa._compat.scipy_nd_stacks():
                        continue  # this scipy's Rotation holds no (2, 3) stack (to_scipy says so)
                    f(a)
                f(q.tolist())
            elif name in BINARY:
                f(q, p), f(q[0], p), f(q, p[0]), f(q.tolist(), p.tolist())
                if name not in ("approx_equal", "dot", "distance"):
                    f(q, p, out=np.empty_like(q))
            elif name == "power":
                f(q, 0.5), f(q, s), f(q[0], 2.0)
            elif name == "rotate":
                f(q, v), f(q[0], v), f(q, v[0]), f(q, v, out=v.copy())
            elif name == "from_matrix":
                f(qa.as_matrix(q)), f(qa.as_matrix(q)[0])
            elif name in ("from_rotvec", "from_mrp", "from_gibbs"):
                f(v), f(v[0])
            elif name == "from_axis_angle":
                f(v, s), f(v[0], 0.5)
            elif name == "as_euler":
                f(q, "ZXY"), f(q, "xyz", degrees=True), f(q[0], "ZYX")
            elif name == "from_euler":
                f("ZXY", v), f("xyz", v, degrees=True), f("ZYX", v[0])
            elif name == "from_su2":
                f(qa.as_su2(q))
            elif name == "from_scipy":
                f(qa.to_scipy(q))
            elif name in ("identity", "random"):
                f(3, dtype=d) if name == "identity" else f(3, rng=0, dtype=d)
            elif name in ("align_vectors", "rotation_between"):
                f(v, w)
                if name == "align_vectors":
                    f(v, w, weights=s)
            elif name in ("lerp", "nlerp", "slerp"):
                f(q, p, s), f(q, p, 0.5), f(q[0], p[0], s)
            elif name in ("bezier", "squad"):
                f(q, p, q, p, s), f(q[0], p[0], q[0], p[0], 0.25)
            elif name == "bezier_controls":
                f(q), f(q, t)
            elif name == "spline":
                for method in ("bezier", "slerp", "nlerp", "squad", "cubic"):
                    f(t, q, x["new"], method=method), f(t, q, x["new"][::-1].copy(), method=method)
                    f(t, q, x["new"], method=method, order=1), f(t, q, x["new"], method=method, order=2)
                f(t.astype(d), q, x["new"].astype(d))
                many = np.arange(float(PIECES_MIN_KEYS + 2))  # enough keys for the piece kernels
                keys = qa.from_rotvec(np.outer(np.sin(many), [0.3, 0.2, 0.1])).astype(d)
                for method in ("bezier", "slerp", "nlerp", "squad", "cubic"):
                    f(many, keys, np.linspace(0.0, many[-1], 30), method=method)
            elif name == "angular_velocity":
                f(q, t), f(q, t, frame="body")
            elif name == "integrate_angular_velocity":
                f(v, t), f(v, t, frame="body", hold="start")
            elif name in ("VQS", "VQM"):
                a = qa.VQS(v, q, s) if name == "VQS" else qa.VQM(v, q, qa.as_matrix(q) * s[:, None, None])
                a.apply(w), a.apply(w[0]), a @ a, a.inverse(), a.as_matrix(), a[0] @ a
                type(a).from_matrix(a.as_matrix())
            elif name == "interpolate":
                a = qa.VQS(v, q, s)
                qa.interpolate(a, a.inverse(), s), qa.interpolate(a, a.inverse(), 0.5)
            else:
                # a public name without ordinary calls here yet is walked by its own table
                # entries (so it is at least in the table: test_table_covers_every_public_function);
                # give it ordinary calls above to check how users call it
                from quatarray import _warmup

                entries = [k for k in _warmup.TABLE if k == name or k.startswith(name + "[")]
                if not entries:
                    raise KeyError(f"no ordinary call of {name} in tests/kernel_calls.py and no entry in "
                                   "quatarray._warmup.TABLE: add both")
                for k in entries:
                    _warmup.TABLE[k](qa, _warmup._samples(d))
    return run


def _clip_calls(qa, what):
    def run():
        from quatarray import _warmup, io, skeleton
        from quatarray.io import sample_path

        clip = _warmup._clip(qa, _warmup._samples("float64"))
        walk = io.read_bvh(sample_path())
        walk = walk.replace(rotations=walk.rotations[:20], translations=walk.translations[:20],
                            times=walk.times[:20])
        if what == "world":
            clip.world(), walk.world()
        elif what == "resample":
            for lanes in (10**18, 0):  # joint by joint (small clips) and in one pass (large ones)
                old, skeleton.LANES_MIN_SAMPLES = skeleton.LANES_MIN_SAMPLES, lanes
                try:
                    for method in ("bezier", "slerp", "nlerp", "squad", "cubic"):
                        for c in (clip, walk):
                            c.resample(rate=7.0, method=method)
                            c.resample(times=np.linspace(c.times[0], c.times[-1], 5), method=method)
                finally:
                    skeleton.LANES_MIN_SAMPLES = old
            skeleton.few_axes_angles(clip.rotations[:, 2], "X"), skeleton.few_axes_angles(clip.rotations[:, 3], "YX")
        elif what == "bvh":
            with tempfile.TemporaryDirectory() as d:
                for c in (clip, walk):
                    io.write_bvh(os.path.join(d, "c.bvh"), c)
                    io.read_bvh(os.path.join(d, "c.bvh"))
                    io.concat(list(io.open_stream(os.path.join(d, "c.bvh"), fmt="bvh")))
                io.bvh.write_positions(os.path.join(d, "p.npy"), walk)
    return run


def _trajectory_calls(qa, name):
    def run():
        from quatarray import _warmup
        from quatarray import trajectory as T

        s = _warmup._samples("float64")
        ref, est = _warmup._poses(qa, s)
        f = getattr(T, name, None)
        if name == "evaluate":
            for metric in T.METRICS:
                for align in T.ALIGNMENTS:
                    for relation in T.RELATIONS:
                        f(ref, est, metric=metric, align=align, relation=relation, t_max_diff=10.0)
            f(ref, est, interpolate=True), f(ref, est, metric="rpe", delta=2, delta_unit="m", all_pairs=True)
            f(ref, est, metric="rpe", delta=1.5, delta_unit="s")
        elif name == "poses":
            f(ref.t, ref.pos, ref.q), f(None, ref.pos.tolist(), ref.q.astype(np.float32))
        elif name == "match_times":
            f(ref.t, est.t, 10.0)
        elif name == "associate":
            f(ref, est, 10.0), f(ref, est, interpolate=True)
        elif name in ("umeyama",):
            f(ref.pos, est.pos), f(ref.pos, est.pos, with_scale=False)
        elif name in ("fit", "align"):
            for m in T.ALIGNMENTS:
                f(ref, est, m)
        elif name == "fit_moments":
            for m in T.ALIGNMENTS:
                f(T.Moments.of(est.pos, ref.pos), m)
        elif name in ("ape",):
            for r in T.RELATIONS:
                f(ref, est, r)
        elif name in ("rpe", "pairs"):
            for unit, delta in (("frames", 1), ("m", 2.0), ("s", 1.5)):
                for all_pairs in (False, True):
                    if name == "rpe":
                        for r in T.RELATIONS:
                            f(ref, est, r, delta=delta, delta_unit=unit, all_pairs=all_pairs)
                    else:
                        f(est, delta=delta, delta_unit=unit, all_pairs=all_pairs)
        elif name == "rpe_of_pairs":
            for r in T.RELATIONS:
                f(ref, est, np.arange(5), np.arange(1, 6), r)
        elif name == "statistics":
            f(np.arange(5.0))
        else:
            raise KeyError(f"no call of quatarray.trajectory.{name} in tests/kernel_calls.py: add one")
    return run


def _verb_calls(qa, verb):
    """A command-line verb on small files, its usual options."""
    def run():
        from quatarray import _warmup, io
        from quatarray.app.cli import main

        s = _warmup._samples("float64")
        ref, est = _warmup._poses(qa, s)
        with tempfile.TemporaryDirectory() as d, open(os.devnull, "w") as null, \
                contextlib.redirect_stdout(null), contextlib.redirect_stderr(null):
            j = lambda name: os.path.join(d, name)
            np.savetxt(j("ref.txt"), np.column_stack([ref.t, ref.pos, ref.q[:, 1:], ref.q[:, :1]]))
            np.savetxt(j("est.txt"), np.column_stack([est.t, est.pos, est.q[:, 1:], est.q[:, :1]]))
            io.write_bvh(j("clip.bvh"), _warmup._clip(qa, s))  # small: plain Python runs it
            np.save(j("q.npy"), s.p)
            np.save(j("q32.npy"), s.p.astype(np.float32))
            np.save(j("v.npy"), s.v)
            with open(j("w.csv"), "w") as f:
                f.write("t,wx,wy,wz\n" + "".join(",".join(repr(float(x)) for x in row) + "\n" for row in np.column_stack([ref.t, s.v])))
            runs = {
                "convert": [[q, j(f"c{k}.npy"), "--to", to] for k, to in enumerate(
                    ["quat", "xyzw", "matrix", "rotvec", "axis-angle", "euler:ZXY", "euler:zyx"])
                    for q in (j("q.npy"), j("q32.npy"))]
                + [[j("ref.txt"), j("c.csv"), "--to", "rotvec", "--degrees"],
                   [j("clip.bvh"), j("pos.npy"), "--to", "positions"]],
                "resample": [[j("ref.txt"), j(f"r{m}.csv"), "--rate", "3", "--method", m]
                             for m in ("bezier", "slerp", "nlerp", "squad", "cubic")]
                + [[j("clip.bvh"), j("r.bvh"), "--rate", "2.5"], [j("q.npy"), j("rq.npy"), "--in-rate", "10",
                                                                 "--rate", "15"]],
                "unflip": [[j("q.npy"), j("u.npy")], [j("ref.txt"), j("u.csv")]],
                "rotate": [[j("q.npy"), j("v.npy"), j("rot.npy")]],
                "compose": [[j("q.npy"), j("q.npy"), j("cq.npy")], [j("ref.txt"), j("est.txt"), j("cp.csv")]],
                "integrate": [[j("w.csv"), j("i.csv")], [j("w.csv"), j("ib.csv"), "--frame", "body"]],
                "info": [[j("q.npy")], [j("ref.txt")], [j("clip.bvh")]],
                "eval": [[j("ref.txt"), j("est.txt"), "--metric", m, "--align", a]
                         for m in ("ape", "rpe") for a in ("none", "se3", "sim3", "scale")]
                + [[j("ref.txt"), j("est.txt"), "--interpolate"], [j("ref.txt"), j("est.txt"), "--pose-relation",
                                                                  "full", "--metric", "rpe", "--delta-unit", "m"]],
            }.get(verb)
            if runs is None:
                raise KeyError(f"no call of the verb {verb!r} in tests/kernel_calls.py: add one")
            for argv in runs:
                rc = main([verb, *map(str, argv), "--no-progress", "--force"])
                if rc != 0:
                    raise RuntimeError(f"quatarray {' '.join(map(str, argv))} exited {rc}")
    return run


def public_entry_points():
    """Names of the public entry points the walk must cover: quatarray.__all__, the
    public functions of quatarray.trajectory, the clip methods and BVH functions,
    the command-line verbs (but those that run other verbs or none of the library's
    kernels: demo, bench, warmup, plot)."""
    import inspect

    import quatarray as qa
    from quatarray import trajectory as T
    from quatarray.app.cli import build_parser

    names = [n for n in qa.__all__ if n != "warmup"]
    names += [f"trajectory.{n}" for n, f in vars(T).items()
              if not n.startswith("_") and inspect.isfunction(f) and f.__module__ == T.__name__]
    names += ["Clip.world", "Clip.resample", "read_bvh, write_bvh"]
    sub = next(a for a in build_parser()._actions if a.dest == "verb")
    names += [f"verb {v}" for v in sub.choices if v not in ("demo", "bench", "warmup", "plot")]
    return names


def walk(qa):
    """``{entry point: call()}`` for every name of :func:`public_entry_points` (a
    name without a call here gets one that raises, naming what to add)."""
    calls = {}
    for name in public_entry_points():
        if name.startswith("trajectory."):
            calls[name] = _trajectory_calls(qa, name.split(".", 1)[1])
        elif name == "Clip.world":
            calls[name] = _clip_calls(qa, "world")
        elif name == "Clip.resample":
            calls[name] = _clip_calls(qa, "resample")
        elif name == "read_bvh, write_bvh":
            calls[name] = _clip_calls(qa, "bvh")
        elif name.startswith("verb "):
            calls[name] = _verb_calls(qa, name[5:])
        else:
            calls[name] = _quaternion_calls(qa, name)
    return calls


# --------------------------------------------------------------------------


# The spline's piece kernels serve sorted new times over at least
# ``splines.PIECES_MIN_KEYS`` keys; here from this many on (the kernels and their
# argument types are the same, and plain Python runs 10 keys much faster than 4097)
PIECES_MIN_KEYS = 10


def main(argv):
    install()
    import quatarray as qa
    from quatarray import _jit, _warmup, splines

    splines.PIECES_MIN_KEYS = PIECES_MIN_KEYS

    what, rest = argv[0], argv[1:]
    calls, errors = {}, {}
    if what == "table":
        dtype = rest[0]
        samples = {d: _warmup._samples(d) for d in ("float64", "float32")}
        jobs = [(n, d, v) for n, d, v in _warmup._jobs(_warmup.DTYPES[dtype], list(_warmup.TABLE))]
        todo = {f"{n} {d} {v}": (lambda n=n, d=d: _warmup.TABLE[n](qa, samples[d]), v) for n, d, v in jobs}
    else:
        entries = walk(qa)
        names = rest or list(entries)
        # each entry as a small call (by size: serial) and as a large one (parallel)
        todo = {f"{n} {v}": (entries[n], v) for n in names for v in ("serial", "parallel")}
    seconds = {}
    for key, (fn, variant) in todo.items():
        t0 = time.perf_counter()
        with recording() as got, warnings.catch_warnings(), _jit.variant(variant):
            warnings.simplefilter("ignore")
            try:
                fn()
            except Exception as exc:  # noqa: BLE001 - reported by the test
                errors[key] = f"{type(exc).__name__}: {exc}"[:500]
        calls[key] = sorted(json.loads(c) for c in got)
        seconds[key] = round(time.perf_counter() - t0, 3)
    print(json.dumps({"calls": calls, "errors": errors, "seconds": seconds}))


if __name__ == "__main__":
    main(sys.argv[1:])
