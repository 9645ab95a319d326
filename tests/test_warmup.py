"""``quatarray.warmup``: after it, a new process compiles nothing.

The cache test warms a fresh ``NUMBA_CACHE_DIR`` in a subprocess and then, in
another new process, makes the warm-up's own calls again and some ordinary
calls, counting numba's compile events (``numba:compile`` is broadcast only
when a dispatcher really compiles, not when it loads from the cache).

It warms a representative part of the table (``WARM``: row loops of
algebra, rotating vectors, conversions and Euler angles, a clip's forward
kinematics, serial and parallel, every layout) in float64 and one function
in float32: 35-45 s on a two-core machine. The interpolation kernels are left
out to keep it so (the whole table takes minutes of warm-up on two cores).
``QUATARRAY_TEST_WARMUP=all`` warms and checks the whole table instead
(float64), and then walks every public entry point (``tests/kernel_calls.py``)
in the new process, which must compile nothing.

That the table reaches every kernel version a public entry point needs is
checked without compiling (``test_table_covers_every_public_entry_point``):
the table's calls and the walk's run as plain Python, recording each call
into a kernel with its argument types.
"""

import json
import os
import subprocess
import sys
from unittest import mock

import numpy as np
import pytest

import quatarray as qa
from quatarray import _warmup

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
WARM = ["multiply", "normalize", "rotate", "as_matrix", "from_matrix", "as_euler", "Clip.world"]
WARM32 = ["multiply"]

# In the new process: the warm-up's calls (each timed, with its compile count),
# then ordinary calls: a batch large enough for the parallel row loops, a
# read-only input, a single quaternion, float32.
_CHECK = r"""
import json, sys, time
import numpy as np
from numba.core import event
import quatarray as qa
from quatarray import _jit, _warmup

names64, names32 = json.loads(sys.argv[1]), json.loads(sys.argv[2])
samples = {d: _warmup._samples(d) for d in ("float64", "float32")}
t0 = time.perf_counter()
qa.multiply(samples["float64"].p, samples["float64"].q)  # numba's own start-up
first = {"start-up": time.perf_counter() - t0}
jobs = []
for names, d in ((names64, "float64"), (names32, "float32")):
    for name in names:
        for variant in _warmup.VARIANTS:
            jobs.append([name, d, variant, *_warmup._run_job(qa, _jit, name, d, variant, samples)])
rec = event.RecordingListener()
with event.install_listener("numba:compile", rec):
    big = qa.random(min(max(_jit.PARALLEL_MIN_ROWS, 10), 10**6), rng=1)  # parallel at the default threshold
    qa.multiply(big, big)
    ro = big[:10].copy()
    ro.flags.writeable = False
    qa.as_matrix(ro)
    qa.multiply(big[0], big[:10])
    m = big[:10].copy()
    qa.multiply(big[0], m, out=m)  # out= an input (RowLoop.into), the other one row against many
    qa.multiply(m, big[0], out=m)
    st = np.zeros((20, 4))[::2]
    st[...] = big[:10]
    qa.normalize(st, out=st)  # out= a strided input itself
    v = big[:10, 1:].copy()
    qa.rotate(big[:1], v, out=v)  # rotate's own loop for out= v, one q of shape (1, 4)
    qa.multiply(big.astype(np.float32)[:10], big.astype(np.float32)[:10])
ordinary = sum(1 for _, ev in rec.buffer if ev.is_start)
walked = {}
if len(sys.argv) > 3:  # the walk of every public entry point (tests/kernel_calls.py), as small and large calls
    sys.path.insert(0, sys.argv[3])
    import warnings
    import kernel_calls
    for name, call in kernel_calls.walk(qa).items():
        for variant in ("serial", "parallel"):
            rec = event.RecordingListener()
            with event.install_listener("numba:compile", rec), _jit.variant(variant), warnings.catch_warnings():
                warnings.simplefilter("ignore")
                call()
            names = [ev.data["dispatcher"].py_func.__qualname__ for _, ev in rec.buffer if ev.is_start]
            if names:
                walked[f"{name} {variant}"] = names
print(json.dumps({"first": first, "jobs": jobs, "ordinary": ordinary, "walked": walked}))
"""


def _env(cache):
    env = dict(os.environ)
    env["NUMBA_CACHE_DIR"] = str(cache)
    env["PYTHONPATH"] = os.pathsep.join([ROOT] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
    env.pop("QUATARRAY_NO_CACHE", None)
    return env


def test_table_covers_every_public_function():
    missing = [n for n in qa.__all__ if n != "warmup" and not _warmup.covered(n)]
    assert not missing, f"add a line to quatarray._warmup.TABLE for {missing}"


def _kernel_calls(*args):
    """Start ``tests/kernel_calls.py`` with `args` (its keys of kernel calls, without
    compiling: see that file); returns the process."""
    env = _env(ROOT)
    env["NUMBA_DISABLE_JIT"] = "1"
    return subprocess.Popen([sys.executable, os.path.join(ROOT, "tests", "kernel_calls.py"), *args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _result(proc):
    out, err = proc.communicate()
    assert proc.returncode == 0, err[-3000:]
    return json.loads(out.splitlines()[-1])


def test_table_covers_every_public_entry_point():
    """After a warm-up a new process compiles nothing, whatever public entry point it
    calls: each call from Python into a compiled kernel that the walk of every public
    entry point makes (quatarray.__all__ as users call them, float64 and float32, a
    batch, one quaternion, lists; Clip.world and Clip.resample, small and large; BVH
    files; every function of quatarray.trajectory; every command-line verb but demo,
    bench, warmup and plot, as small and as large inputs), with its argument types,
    is one that the warm-up's table makes, so the cache holds its machine code.

    Nothing compiles here: both run as plain Python (NUMBA_DISABLE_JIT=1) and record
    (kernel, numba types of the arguments), the key numba compiles a version for
    (tests/kernel_calls.py). A new public function, method or verb fails
    ``test_walk_covers_every_public_entry_point`` until kernel_calls.py walks it, and
    this test until the table reaches what it compiles. About 40 s of CPU in three
    processes."""
    procs = [_kernel_calls("table", "float64"), _kernel_calls("table", "float32"), _kernel_calls("walk")]
    table64, table32, walk = (_result(p) for p in procs)
    assert not table64["errors"] and not table32["errors"], (table64["errors"], table32["errors"])
    assert not walk["errors"], walk["errors"]
    have = {json.dumps(c[:2]) for t in (table64, table32) for calls in t["calls"].values() for c in calls}
    missing = {}
    for entry, calls in walk["calls"].items():
        for c in calls:
            if json.dumps(c[:2]) not in have:
                missing.setdefault(f"{c[0]}{tuple(c[1])}", entry)
    assert not missing, (f"{len(missing)} kernel versions that no entry of quatarray._warmup.TABLE compiles "
                         "(kernel(argument types): the entry point that needs it):\n"
                         + "\n".join(f"{k}: {v}" for k, v in sorted(missing.items())))
    # an element function called from Python compiles a twin in every process (not cached)
    twins = {c[0]: entry for entry, calls in walk["calls"].items() for c in calls if c[2]}
    assert not twins, f"element functions called from Python, compiled again in every process: {twins}"
    # the walk reaches what the issue found missing: trajectory, Clip.world, the one-pass resampling
    reached = {c[0] for calls in walk["calls"].values() for c in calls}
    for kernel in ("trajectory._match_sorted", "trajectory._moments_kernel", "trajectory._ape_kernel",
                   "trajectory._rpe_kernel", "skeleton._world",
                   "_spline_lanes._lane_spline_bezier", "_spline_lanes._gather_unit"):
        assert f"quatarray.{kernel}" in reached


def test_walk_covers_every_public_entry_point(monkeypatch):
    """tests/kernel_calls.py has a call for every public entry point (a new one raises
    there, naming what to add)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("kernel_calls", os.path.join(ROOT, "tests", "kernel_calls.py"))
    kc = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(kc)
    names = kc.public_entry_points()
    assert {"multiply", "spline", "trajectory.evaluate", "trajectory.ape", "Clip.world", "Clip.resample",
            "verb eval", "verb resample", "verb convert"} <= set(names)
    assert set(kc.walk(qa)) == set(names)
    for name in ("multiply", "trajectory.statistics"):  # a name with a call and one without: the rule
        assert callable(kc.walk(qa)[name])
    with pytest.raises(KeyError, match="add both"):
        kc._quaternion_calls(qa, "no_such_function")()
    # a public name with table entries but no ordinary calls yet is walked by its entries
    seen = []
    monkeypatch.setitem(_warmup.TABLE, "new_function[a]", lambda qa_, s: seen.append(s.dtype))
    kc._quaternion_calls(qa, "new_function")()
    assert seen == [np.dtype("float64"), np.dtype("float32")]
    with pytest.raises(KeyError, match="add one"):
        kc._trajectory_calls(qa, "no_such_function")()
    with pytest.raises(KeyError, match="add one"):
        kc._verb_calls(qa, "no_such_verb")()


def test_float64_only_entries_run_once():
    """Clips and pose streams are float64 whatever the samples: one job per variant."""
    jobs = _warmup._jobs(("float64", "float32"), ["Clip.world", "multiply"])
    assert sorted(jobs) == sorted([("Clip.world", "float64", v) for v in _warmup.VARIANTS]
                                  + [("multiply", d, v) for d in ("float64", "float32") for v in _warmup.VARIANTS])
    assert _warmup._jobs(("float32",), ["eval"]) == [("eval", "float32", v) for v in _warmup.VARIANTS]
    assert _warmup.FLOAT64_ONLY <= set(_warmup.TABLE)


def test_table_reaches_the_spline_piece_kernels(monkeypatch):
    """Sorted new times over many keys take other kernels (the pieces): the table's
    "many keys" entries reach them, for each method that has them."""
    from quatarray import splines

    seen = []
    for method in splines._PIECES:
        monkeypatch.setitem(splines._PIECES, method, lambda *a, m=method: seen.append(m))
    s = _warmup._samples("float64")
    for method in splines._PIECES:
        _warmup.TABLE[f"spline[{method}, many keys]"](qa, s)
    assert seen == [m for m in splines._PIECES for _ in range(2)]  # float64 and float32 times


def test_table_reaches_the_spline_rate_piece_kernels(monkeypatch):
    """The rates of sorted new times over many keys take the rate piece kernels: the
    table's "many keys, order=…" entries reach each of them."""
    from quatarray import splines

    seen = []
    for key in splines._RATE_PIECES:
        monkeypatch.setitem(splines._RATE_PIECES, key, lambda *a, k=key: seen.append(k))
    s = _warmup._samples("float64")
    for method, order in splines._RATE_PIECES:
        _warmup.TABLE[f"spline[{method}, many keys, order={order}]"](qa, s)
    assert seen == [k for k in splines._RATE_PIECES for _ in range(2)]  # float64 and float32 times


def test_table_reaches_slerps_block_loops(monkeypatch):
    """Calls of one block take the serial loop with a per-thread scratch; the table's
    "slerp[blocks]" entry reaches the block loop and its variant for given outputs
    written past the caches."""
    from quatarray import interpolation

    seen = []
    for name in ("_slerp", "_slerp_stream"):
        monkeypatch.setattr(interpolation, name, lambda *a, n=name: seen.append((n, a[-1].flags.writeable)) or 0)
    _warmup.TABLE["slerp[blocks]"](qa, _warmup._samples("float64"))
    assert {n for n, _ in seen} == {"_slerp", "_slerp_stream"}
    assert seen.count(("_slerp_stream", True)) > 1  # given outputs: a new array, each input


def test_bad_arguments():
    with pytest.raises(ValueError, match="dtype"):
        qa.warmup(dtype="float16")
    with pytest.raises(ValueError, match="names"):
        qa.warmup(names=["no_such_function"])


@pytest.mark.needs_cache
@pytest.mark.slow
def test_after_warmup_a_new_process_compiles_nothing(tmp_path):
    # May take minutes with QUATARRAY_TEST_WARMUP=all (see the module docstring).
    every = os.environ.get("QUATARRAY_TEST_WARMUP") == "all"
    names64 = list(_warmup.TABLE) if every else WARM
    env = _env(tmp_path / "cache")
    warm = (
        "import json, sys, quatarray as qa\n"
        "a = qa.warmup(dtype='float64', names=json.loads(sys.argv[1]))\n"
        "b = qa.warmup(dtype='float32', names=json.loads(sys.argv[2]))\n"
        "print(json.dumps([a.compiled, b.compiled, len(a.jobs), len(b.jobs), a.failed + b.failed]))\n"
    )
    args = [json.dumps(names64), json.dumps(WARM32)]
    out = subprocess.run([sys.executable, "-c", warm, *args], env=env, capture_output=True, text=True, check=True)
    compiled64, compiled32, jobs64, jobs32, failed = json.loads(out.stdout.splitlines()[-1])
    assert not failed
    assert compiled64 > 0 and compiled32 > 0  # it really was cold
    assert (jobs64, jobs32) == (2 * len(names64), 2 * len(WARM32))  # serial and parallel

    # with the whole table warm, the new process also walks every public entry point
    walk = [os.path.join(ROOT, "tests")] if every else []
    out = subprocess.run([sys.executable, "-c", _CHECK, *args, *walk], env=env, capture_output=True, text=True,
                         check=True)
    res = json.loads(out.stdout.splitlines()[-1])
    recompiled = [j for j in res["jobs"] if j[4] or j[5]]
    assert not recompiled, f"compiled again after warm-up: {recompiled}"
    assert res["ordinary"] == 0
    assert not res["walked"], f"public entry points that compiled after the warm-up: {res['walked']}"
    # First calls load machine code only: about 0.01-0.1 s each (the budget is
    # 0.3 s; the bound is loose because the machine is shared). Numba's own
    # start-up (its first call in a process) is timed apart.
    slow = [j for j in res["jobs"] if j[3] > 1.0]
    assert not slow, f"first calls after warm-up slower than 1 s: {slow}"
    assert res["first"]["start-up"] < 3.0


@pytest.mark.needs_cache
def test_in_background_fills_the_cache_beside_the_caller(tmp_path):
    """A worker started by in_background compiles its entries into the cache while
    the caller goes on; the caller's own cache writes take the worker's lock; a new
    process then loads those kernels without compiling."""
    env = _env(tmp_path / "cache")
    env.pop("QUATARRAY_CACHE_LOCK", None)
    start = ("import json, quatarray as qa\n"
             "from quatarray import _warmup\n"
             "from numba.core.caching import IndexDataCacheFile as I\n"
             "p = _warmup.in_background(['multiply'], dtype='float32', variants=('serial',))\n"
             "qa.normalize(qa.random(3))  # the caller compiles too, meanwhile\n"
             "print(json.dumps([p.wait(), I.save.lock_path]))\n")
    out = subprocess.run([sys.executable, "-c", start], env=env, capture_output=True, text=True, check=True)
    rc, lock = json.loads(out.stdout.splitlines()[-1])
    assert rc == 0 and lock.endswith(".lock")
    check = ("import json, quatarray as qa\n"
             "from quatarray import _jit, _warmup\n"
             "s = {'float32': _warmup._samples('float32')}\n"
             "print(json.dumps(_warmup._run_job(qa, _jit, 'multiply', 'float32', 'serial', s)))\n")
    out = subprocess.run([sys.executable, "-c", check], env=env, capture_output=True, text=True, check=True)
    seconds, compiled, error = json.loads(out.stdout.splitlines()[-1])
    assert (compiled, error) == (0, "")


def test_in_background_bad_arguments():
    for kw in ({"names": ["no_such_function"]}, {"names": ["multiply"], "variants": ("threads",)},
               {"names": ["multiply"], "dtype": "float16"}):
        with pytest.raises(ValueError, match="Expected `names`"):
            _warmup.in_background(**kw)


def test_command_line_verb():
    from quatarray.app.cli import build_parser, cmd_warmup

    args = build_parser().parse_args(["warmup", "--dtype", "float32"])
    assert (args.func, args.dtype) == (cmd_warmup, "float32")
    assert build_parser().parse_args(["warmup"]).dtype == "all"


def test_test_workers_lock_their_cache_writes():
    """Under pytest-xdist (the README's ``-n auto``) the workers share numba's cache:
    the root conftest.py sets QUATARRAY_CACHE_LOCK, so their writes hold its lock."""
    if not os.environ.get("PYTEST_XDIST_TESTRUNUID"):
        pytest.skip("not running under pytest-xdist")
    from numba.core.caching import IndexDataCacheFile

    from quatarray import _jit

    assert _jit.CAN_LOCK and os.environ["QUATARRAY_CACHE_LOCK"].endswith(".quatarray-tests.lock")
    assert IndexDataCacheFile.save.lock_path == os.environ["QUATARRAY_CACHE_LOCK"]


@pytest.mark.needs_cache
@pytest.mark.skipif(not _warmup._CAN_LOCK, reason="no file lock on this system")
def test_cache_lock_from_the_environment(tmp_path):
    """QUATARRAY_CACHE_LOCK locks every cache write of a process that uses a kernel
    (a child of a locked process inherits it), and the warm-up's workers take the
    caller's own lock when it has one."""
    lock = str(tmp_path / "cache.lock")
    code = ("import quatarray as qa, numpy as np; from numba.core.caching import IndexDataCacheFile as I\n"
            "qa.multiply(np.ones(4), np.ones(4)); print(getattr(I.save, 'lock_path', None))")
    for value, expect in ((lock, lock), ("", "None")):
        env = dict(_env(tmp_path / "cache"), QUATARRAY_CACHE_LOCK=value)
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
        assert out.stdout.split() == [expect]
    assert os.path.exists(lock)  # the kernel's cache entry was written under it
    with mock.patch.dict(os.environ, {"QUATARRAY_CACHE_LOCK": lock}):
        assert _warmup._env("/other.lock")["QUATARRAY_CACHE_LOCK"] == lock
    with mock.patch.dict(os.environ, {"QUATARRAY_CACHE_LOCK": ""}):
        assert _warmup._env("/other.lock")["QUATARRAY_CACHE_LOCK"] == "/other.lock"
