"""quatarray._numba_internals: each numba or llvmlite internal taken away in turn.

Each case runs in a new process (import time matters) with an empty numba cache:
a prelude breaks one internal the way a numba release might (removed, renamed,
another signature), then quatarray is imported and computes a few results, which
must be bitwise those of this process, with exactly one NumbaInternalsWarning.
"""

import inspect
import json
import os
import subprocess
import sys
import threading
import warnings

import numpy as np
import pytest

from quatarray import _jit, _numba_internals, _trace

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# Computed here and in each child: far-range rows (as_mrp, norm: the specialised
# copies), a row loop (multiply), a 3x3 output (as_matrix: prefer_no_gather), an
# element function called from Python (its wrapped twin), float32 and float64, and a
# kernel's work array (scratch).
WORK = """
import numba
import numpy as np
import quatarray as qa
from quatarray import _access, _jit


def work():
    rng = np.random.default_rng(7)
    q = rng.normal(size=(9, 4))
    p = rng.normal(size=(9, 4))
    out = []
    for t, big in ((np.float64, 1e200), (np.float32, 1e30)):
        a, b = q.astype(t), p.astype(t)
        a[0] *= big  # squares overflow: the far-range pass
        a[1] /= big
        out += [qa.as_mrp(a), qa.norm(a), qa.multiply(a, b), qa.as_matrix(b)]
    m = rng.normal(size=(2, 3, 3))
    out.append(np.array(_access.load33(m, 1)))
    out.append(zeros(5, q))
    return [np.asarray(x).tobytes().hex() for x in out]


@numba.njit
def zeros(n, like):  # a kernel's work array (quatarray._jit.scratch)
    return _jit.scratch(n, like)
"""

CHILD = """
import json, os, sys, warnings
warnings.simplefilter("always")
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
{prelude}
    import quatarray
    from quatarray import _jit, _numba_internals
{after}
    exec(compile({work!r}, "<work>", "exec"))
    results = work()
ours = [str(w.message) for w in caught if issubclass(w.category, _numba_internals.NumbaInternalsWarning)]
cached = sum(len(files) for _, _, files in os.walk(os.environ["NUMBA_CACHE_DIR"]))
print(json.dumps({{"results": results, "warnings": ours, "missing": _numba_internals.missing(),
                  "cache": _jit.CACHE, "cached_files": cached}}))
"""


def _indent(code):
    return "\n".join("    " + line for line in code.strip().splitlines()) if code.strip() else "    pass"


def run_child(tmp_path, prelude="", after="", env=None):
    code = CHILD.format(prelude=_indent(prelude), after=_indent(after), work=WORK)
    e = {k: v for k, v in os.environ.items() if k not in ("QUATARRAY_CACHE_LOCK", "NUMBA_DISABLE_JIT")}
    e.update(NUMBA_CACHE_DIR=str(tmp_path / "cache"), PYTHONPATH=ROOT, **(env or {}))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, env=e, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def expected():
    scope = {}
    exec(compile(WORK, "<work>", "exec"), scope)
    return scope["work"]()


# each case: (prelude before `import quatarray`, code after it, the feature expected off, cache kept)
CASES = {
    "ensure_blas": (
        "import numba.np.linalg as L\n"
        "_real = L.ensure_blas\n"
        "L.ensure_blas = lambda *args: _real()",
        "", "deferred BLAS probe", True),
    "locator_classes": (
        "from numba.core.caching import CacheImpl\n"
        "CacheImpl._locator_classes = tuple(CacheImpl._locator_classes)",
        "", "package stamp of the cache", False),
    "cache_save": (
        "from numba.core import caching\n"
        "_save = caching.IndexDataCacheFile.save\n"
        "caching.IndexDataCacheFile.save = lambda self, key, data, overwrite=True: _save(self, key, data)",
        "", "cache write lock", False),
    "get_call_template": (
        "from numba.core.registry import CPUDispatcher\n"
        "_get = CPUDispatcher.get_call_template\n"
        "CPUDispatcher.get_call_template = lambda self, args, kws, *more: _get(self, args, kws)",
        "", "plain-type calls between kernels", True),
    "dispatcher_layout": (
        "import numba.core.registry as R\n"
        "R.CPUDispatcher = type('CPUDispatcher', (R.CPUDispatcher,), {'__slots__': ('extra',)})",
        "", "dispatcher subclass", True),
    "wrapper_options": (
        # a numba without the options, whose own overloads do not ask for them
        "from numba.core import extending\n"
        "from numba.core.cpu import CPUTargetOptions\n"
        "from numba.core.typing import templates\n"
        "def subclasses(c):\n"
        "    for s in c.__subclasses__():\n"
        "        yield s\n"
        "        yield from subclasses(s)\n"
        "for name in ('no_cpython_wrapper', 'no_cfunc_wrapper'):\n"
        "    extending._overload_default_jit_options.pop(name, None)\n"
        "    for t in [*subclasses(templates.FunctionTemplate), *subclasses(templates.AttributeTemplate)]:\n"
        "        if isinstance(vars(t).get('_jit_options'), dict):\n"
        "            t._jit_options.pop(name, None)\n"
        "    for c in CPUTargetOptions.__mro__:\n"
        "        if name in vars(c):\n"
        "            delattr(c, name)",
        "", "numba option no_cpython_wrapper", True),
    "tm_features": (
        "from numba.core import codegen\n"
        "_init = codegen.CPUCodegen._init\n"
        "def _renamed(self, m):\n"
        "    _init(self, m)\n"
        "    self._features_v2 = self.__dict__.pop('_tm_features')\n"
        "codegen.CPUCodegen._init = _renamed\n"
        "codegen.CPUCodegen.magic_tuple = lambda self: (self._llvm_module.triple, self._get_host_cpu_name(), "
        "self._features_v2)",
        "", "prefer_no_gather", True),
    "populate_array": (
        # another signature (numba's own allocations, which pass the array by position, still work)
        "import numba.np.arrayobj as A\n"
        "_populate = A.populate_array\n"
        "A.populate_array = lambda ary, **fields: _populate(ary, **fields)",
        "", "scratch arrays", True),
    "attribute_set": (
        "from llvmlite.ir import values\n"
        "_to_list = values.AttributeSet._to_list\n"
        "values.AttributeSet._to_list = lambda self, typ: [a for a in _to_list(self, typ) if a in self._known]",
        "", "prefer_no_gather", True),
}


def _llvm17():
    from llvmlite import binding

    return tuple(binding.llvm_version_info) >= (17,)


@pytest.mark.needs_cache
def test_unbroken_numba_gives_no_warning(tmp_path, expected):
    got = run_child(tmp_path)
    assert got["warnings"] == [] and got["missing"] == {}
    assert got["results"] == expected
    assert got["cache"] and got["cached_files"] > 0


@pytest.mark.needs_cache
@pytest.mark.parametrize("case", sorted(CASES))
def test_internal_taken_away(tmp_path, expected, case):
    prelude, after, feature, cache = CASES[case]
    if feature == "prefer_no_gather" and not _llvm17():
        pytest.skip("LLVM < 17: prefer_no_gather is off anyway (its flags are LLVM 17's)")
    env = {"QUATARRAY_CACHE_LOCK": str(tmp_path / "lock")} if case == "cache_save" else None
    got = run_child(tmp_path, prelude, after, env)
    assert got["results"] == expected, f"{case}: other numbers without the internal"
    assert len(got["warnings"]) == 1, got["warnings"]
    assert feature in got["missing"], got["missing"]
    assert feature in got["warnings"][0]
    assert got["cache"] is cache
    if not cache:
        assert got["cached_files"] == 0  # nothing written to a cache that cannot be trusted


def test_compile_counter_without_event_api(monkeypatch):
    from numba.core import event

    monkeypatch.setattr(event, "RecordingListener", None)
    monkeypatch.setattr(_numba_internals, "_MISSING", {})
    monkeypatch.setattr(_numba_internals, "_WARNED", [False])
    with pytest.warns(_numba_internals.NumbaInternalsWarning), _numba_internals.CompileCounter() as c:
        pass
    assert c.count is None and "compile events" in _numba_internals.missing()


def test_compile_counter_counts(tmp_path):
    code = ("import numpy as np, quatarray as qa\n"
            "from quatarray._numba_internals import CompileCounter\n"
            "with CompileCounter() as c:\n"
            "    qa.multiply(np.ones((2, 4)), np.ones((2, 4)))\n"
            "print(c.count)")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), PYTHONPATH=ROOT)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, env=env, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert int(r.stdout.split()[-1]) >= 1


def test_one_warning_for_many_missing_features(monkeypatch):
    monkeypatch.setattr(_numba_internals, "_MISSING", {})
    monkeypatch.setattr(_numba_internals, "_WARNED", [False])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        _numba_internals.degrade("a", "gone")
        _numba_internals.degrade("b", "renamed")
        _numba_internals.degrade("a", "gone again")
    assert len(caught) == 1 and issubclass(caught[0].category, _numba_internals.NumbaInternalsWarning)
    assert _numba_internals.missing() == {"a": "gone", "b": "renamed"}


def test_no_llvm_feature_that_llvm_lacks(monkeypatch):
    """Before LLVM 17 no ``prefer-no-gather`` reaches LLVM (it would print that it does
    not know it), and without a warning: nothing of numba is missing."""

    class Builder:
        class function:
            attributes = set()

    monkeypatch.setattr(_numba_internals, "_FEATURES_OK", [])
    monkeypatch.setattr(_numba_internals, "_llvm_version", lambda: (16, 0, 6))
    monkeypatch.setattr(_numba_internals, "_MISSING", {})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _numba_internals.add_target_features(None, Builder)
    assert Builder.function.attributes == set() and _numba_internals.missing() == {}


def _home():
    """A home function: its copy must read this source."""
    return 1


def _body(x):
    return x + 1


def test_copies_have_a_consistent_file_and_line():
    """numba's cache reads a copy's source (inspect.getsourcelines) for the annotation it
    stores: the copy's file and first line are those of a real function (on Python
    3.13, inspect reads a block from exactly that line)."""
    for copy, home in ((_jit.specialise(_body, "_x", home=_home), _home), (_jit.specialise(_body, "_y"), _body)):
        lines, first = inspect.getsourcelines(copy)
        assert (copy.__code__.co_filename, first) == (home.__code__.co_filename, home.__code__.co_firstlineno)
        assert lines == inspect.getsourcelines(home)[0]
        assert copy(1) == 2
    loop = _jit.RowLoop(_body, parallel=False)
    into = _jit._into_copy(loop.py_func, 0, 1, False)
    assert inspect.getsourcelines(into.py_func)[0][0].lstrip().startswith("def _body")


THREADS = """
import sys, threading, numpy as np, quatarray as qa
rng = np.random.default_rng(3)
q = rng.normal(size=(50, 4)); q[0] *= 1e30
a, b = q.astype(np.float32), rng.normal(size=(50, 4))
jobs = {"mrp32": lambda: qa.as_mrp(a), "slerp": lambda: qa.slerp(b[:-1], b[1:], 0.25),
        "euler": lambda: qa.as_euler(b, "zyx"), "mat": lambda: qa.as_matrix(a)}
out = {}
start = threading.Barrier(len(jobs))
def run(name):
    start.wait()
    out[name] = jobs[name]()
threads = [threading.Thread(target=run, args=(n,)) for n in jobs]
[t.start() for t in threads]
[t.join() for t in threads]
print(sorted(out))
print("|".join(np.asarray(out[n]).tobytes().hex() for n in sorted(jobs)))
"""


def test_first_compiles_in_two_threads_at_once(tmp_path):
    """Threads that call new functions at once (each compiling in its own thread)
    get the results of one thread calling them in turn."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), PYTHONPATH=ROOT)
    r = subprocess.run([sys.executable, "-c", THREADS], capture_output=True, text=True, cwd=ROOT, env=env,
                       timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    names, hexes = r.stdout.strip().splitlines()[-2:]
    scope = {}
    exec(THREADS.split("out = {}")[0], scope)
    want = "|".join(np.asarray(scope["jobs"][n]()).tobytes().hex() for n in sorted(scope["jobs"]))
    assert names == str(sorted(scope["jobs"])) and hexes == want


def test_trace_stack_is_per_thread():
    seen = []
    _trace._NOW.append(("context", "builder"))
    try:
        t = threading.Thread(target=lambda: seen.append(_trace._NOW[-1]))
        t.start()
        t.join()
    finally:
        _trace._NOW.pop()
    assert seen == [None] and _trace._NOW[-1] is None


CACHED = """
import numpy as np, quatarray as qa
from quatarray import _access
from quatarray._numba_internals import CompileCounter
q = np.random.default_rng(5).normal(size=(6, 4))
q[0] *= 1e200  # the far-range pass: the specialised copies
m = qa.as_matrix(q[1:])
with CompileCounter() as c:
    r = [qa.as_mrp(q), qa.norm(q), qa.angle(q), qa.distance(q, q[::-1]), qa.from_matrix(m)]
# an element function (load33, which from_matrix's kernel calls) called from Python: its
# twin with the wrappers is not cached, and never loads the element's code from the cache
r.append(np.array(_access.load33(m, 1)))
print(c.count)
print("|".join(np.asarray(x).tobytes().hex() for x in r))
"""


@pytest.mark.needs_cache
def test_first_calls_in_a_new_process_work_and_are_cached(tmp_path):
    """as_mrp, norm, angle and distance on far-range rows (the function copies of
    ``specialise(home=...)``) and from_matrix in a new process with an empty cache, then
    in another: the second compiles nothing and gives the same numbers (Python 3.13:
    issue 35); an element function called from Python in both."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), PYTHONPATH=ROOT)
    env.pop("NUMBA_DISABLE_JIT", None)
    runs = []
    for _ in range(2):
        r = subprocess.run([sys.executable, "-c", CACHED], capture_output=True, text=True, cwd=ROOT, env=env,
                           timeout=600)
        assert r.returncode == 0, r.stderr[-3000:]
        runs.append(r.stdout.split())
    assert int(runs[0][0]) > 0 and int(runs[1][0]) == 0
    assert runs[0][1] == runs[1][1]
