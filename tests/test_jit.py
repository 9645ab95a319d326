"""quatarray._jit: the serial/parallel choice of the row loops, fused multiply-adds and the cache stamp."""

import json
import os
import threading

import numpy as np
import pytest
from llvmlite import binding as llvm_binding

from quatarray import _jit


def _probe():
    """A RowLoop-like object whose two variants report which one ran."""
    calls = []

    class Probe(_jit.RowLoop):
        def __init__(self):
            self.rows = 0
            self.serial = lambda a: calls.append(("serial", threading.get_ident()))
            self.parallel = lambda a: calls.append(("parallel", threading.get_ident()))

    return Probe(), calls


def test_variant_follows_size_and_context():
    loop, calls = _probe()
    small, large = np.zeros((1, 4)), np.zeros((_jit.PARALLEL_MIN_ROWS, 4))
    loop(small)
    loop(large)
    with _jit.serial():
        loop(large)
        with _jit.variant("parallel"):
            loop(small)
        loop(large)
    loop(large)
    assert [c[0] for c in calls] == ["serial", "parallel", "serial", "parallel", "serial", "parallel"]
    with pytest.raises(ValueError, match="name"):
        with _jit.variant("fast"):
            pass


def test_serial_in_one_thread_leaves_others_parallel():
    # issue 15: dask's serial tasks rewrote a process-wide threshold, so every
    # other thread's calls went serial meanwhile
    loop, calls = _probe()
    large = np.zeros((_jit.PARALLEL_MIN_ROWS, 4))
    inside, done = threading.Event(), threading.Event()

    def task():
        with _jit.serial():
            loop(large)
            inside.set()
            done.wait(10)
            loop(large)

    t = threading.Thread(target=task)
    t.start()
    assert inside.wait(10)
    loop(large)  # this thread, while the other is inside serial()
    done.set()
    t.join()
    mine = threading.get_ident()
    assert [c[0] for c in calls if c[1] == mine] == ["parallel"]
    assert [c[0] for c in calls if c[1] != mine] == ["serial", "serial"]


@pytest.mark.skipif(os.environ.get("NUMBA_DISABLE_JIT") == "1", reason="no parallel variant without the JIT")
def test_serial_thread_beside_a_large_parallel_call():
    # the same with real kernels: a large call in this thread takes the parallel
    # variant (numba's parallel dispatcher compiles for it) while another thread
    # sits inside serial()
    from quatarray import algebra

    q = np.random.default_rng(0).normal(size=(_jit.PARALLEL_MIN_ROWS, 4))
    ran = []
    for name in ("serial", "parallel"):
        d = getattr(algebra._multiply, name)
        orig = d

        class Spy:
            def __init__(self, d, name):
                self.d, self.name = d, name

            def __call__(self, *a):
                ran.append((self.name, threading.get_ident()))
                return self.d(*a)

        setattr(algebra._multiply, name, Spy(orig, name))
    try:
        inside, done = threading.Event(), threading.Event()

        def task():
            with _jit.serial():
                algebra.multiply(q, q)
                inside.set()
                done.wait(60)

        t = threading.Thread(target=task)
        t.start()
        assert inside.wait(120)
        got = algebra.multiply(q, q)
        done.set()
        t.join()
    finally:
        algebra._multiply.serial = algebra._multiply.serial.d
        algebra._multiply.parallel = algebra._multiply.parallel.d
    mine = threading.get_ident()
    assert ("parallel", mine) in ran and ("serial", mine) not in ran
    assert [r[0] for r in ran if r[1] != mine] == ["serial"]
    np.testing.assert_allclose(got[:5], [algebra.multiply(a, a) for a in q[:5]])


_BLAS_SCRIPT = """
import sys
import numba, numpy as np
import quatarray as qa
from numba.np import linalg
qa.multiply(np.ones((3, 4)), np.ones((3, 4)))  # compiles or loads: numba imports its np.arraymath
from numba.np import arraymath
before = "scipy.linalg" in sys.modules
dot = numba.njit(lambda a, b: np.dot(a, b))(np.ones(3), np.ones(3))  # numba's BLAS path still works
print(before, arraymath._HAVE_BLAS, linalg.ensure_blas.__name__, dot)
"""


def test_a_kernel_call_imports_no_scipy_linalg():
    """numba's BLAS probe (an import of scipy.linalg, 0.25 s of a process's start) is
    answered without importing it; np.dot in a kernel still finds BLAS."""
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-c", _BLAS_SCRIPT], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.split() == ["False", "True", "ensure_blas", "3.0"]


LLVM17 = tuple(llvm_binding.llvm_version_info) >= (17,)


def test_prefer_no_gather_marks_the_loop_and_keeps_its_results():
    """A loop over rows of nine (3×3 matrices), which LLVM vectorises with gathers and
    scatters on AVX-512 targets: marked, its function carries LLVM's tuning flags and
    its machine code has none (on every target); the results are the same."""
    import numba

    def body(m, out):
        for i in range(m.shape[0] // 9):
            if MARK:
                _jit.prefer_no_gather()
            out[4 * i] = m[9 * i] + m[9 * i + 4] + m[9 * i + 8]
            out[4 * i + 1] = m[9 * i + 7] - m[9 * i + 5]
            out[4 * i + 2] = m[9 * i + 2] - m[9 * i + 6]
            out[4 * i + 3] = m[9 * i + 3] - m[9 * i + 1]

    m = np.random.default_rng(0).normal(size=9 * 1001)
    outs = []
    for mark in (True, False):
        k = numba.njit(cache=False)(_jit.specialise(body, f"_{mark}", MARK=mark))
        out = np.empty(4 * 1001)
        k(m, out)
        outs.append(out)
        (llvm,), (asm,) = k.inspect_llvm().values(), k.inspect_asm().values()
        assert (_jit.NO_GATHER_FEATURES in llvm) == (mark and LLVM17)  # LLVM 17's flags: none before
        if mark and LLVM17:
            assert "vgather" not in asm and "vscatter" not in asm
    np.testing.assert_array_equal(outs[0], outs[1])


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_scratch_is_a_new_array_of_zeros_and_compiles_nothing_of_its_own(dtype):
    """``scratch(n, a)``: n zeros of a's dtype, a new array each call (a kernel's work
    array), without numba's ``np.zeros`` overloads to compile; a negative or overflowing
    size raises."""
    import numba

    from compile_events import compiles

    @numba.njit
    def work(n, a):
        s = _jit.scratch(n, a)
        t = _jit.scratch(n, a)
        for i in range(n):
            s[i] += a[i % a.shape[0]]
        return s, t

    a = np.arange(1, 4, dtype=dtype)
    with compiles() as compiled:
        s, t = work(7, a)
    if not numba.config.DISABLE_JIT:
        assert compiled == ["work"]
    assert s.dtype == t.dtype == dtype and s.shape == t.shape == (7,)
    np.testing.assert_array_equal(s, np.resize(a, 7))
    np.testing.assert_array_equal(t, 0)
    assert work(0, a)[0].shape == (0,)
    for bad in (-1, 2**62):
        with pytest.raises((ValueError, MemoryError)):
            work(bad, a)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_fmuladd_is_one_rounding_or_two_and_the_same_in_every_lane(dtype):
    """``fmuladd(a, b, c)``: a·b + c rounded once (an FMA) or twice (no FMA on this
    CPU), the same choice for every element of a loop, SIMD part or remainder."""
    from fractions import Fraction

    import numba

    from quatarray._jit import fmuladd

    @numba.njit
    def loop(a, b, c, out):
        for i in range(a.shape[0]):
            out[i] = fmuladd(a[i], b[i], c[i])

    rng = np.random.default_rng(5)
    a = (1 + rng.integers(1, 2**20, 203) * np.finfo(dtype).eps).astype(dtype)
    b = (1 - rng.integers(1, 2**20, 203) * np.finfo(dtype).eps).astype(dtype)
    c = -np.ones(203, dtype)
    out = np.empty(203, dtype)
    loop(a, b, c, out)
    assert out.dtype == dtype
    if numba.config.DISABLE_JIT:
        assert np.array_equal(out, a * b + c)
        return
    # a·b + c exactly (fractions), rounded once to the float type (float32: a·b − 1
    # is exact in float64, so one rounding)
    exact = [Fraction(float(x)) * Fraction(float(y)) + Fraction(float(z)) for x, y, z in zip(a, b, c)]
    fused = np.array([float(e) for e in exact]).astype(dtype)
    assert np.array_equal(out, fused) or np.array_equal(out, a * b + c)
    one = np.empty(1, dtype)
    for i in (0, 1, 5, 202):  # each alone: the scalar code
        loop(a[i:i + 1], b[i:i + 1], c[i:i + 1], one)
        assert one[0] == out[i]


_COMPILES = """
import json, sys
import numpy as np
from numba.core import event
import quatarray as qa
assert qa.__file__.startswith(sys.argv[1]), qa.__file__
names = []
class Rec(event.Listener):
    def on_start(self, ev):
        names.append(ev.data["dispatcher"].py_func.__qualname__)
    def on_end(self, ev):
        pass
with event.install_listener("numba:compile", Rec()):
    qa.from_rotvec(np.ones((3, 3)))
print(json.dumps(names))
"""


@pytest.mark.needs_cache
@pytest.mark.skipif(__import__("numba").config.DISABLE_JIT, reason="no compiled kernels, no cache")
def test_cached_kernels_compile_again_when_any_source_file_changes(tmp_path):
    """numba stamps a function's cached code with its own file's hash only: a kernel
    of conversions.py must not keep the old code of _trig.py, which it inlines.
    On a copy of the package: warm cache, no compile; _trig.py changed, the
    kernel compiles again; conversions.py's own stamp is unchanged."""
    import shutil
    import subprocess
    import sys

    import quatarray

    pkg = tmp_path / "src"
    shutil.copytree(os.path.dirname(quatarray.__file__), pkg / "quatarray",
                    ignore=shutil.ignore_patterns("__pycache__"))
    env = dict(os.environ, PYTHONPATH=str(pkg), NUMBA_CACHE_DIR=str(tmp_path / "cache"))

    def compiled():
        r = subprocess.run([sys.executable, "-c", _COMPILES, str(pkg)], env=env, capture_output=True, text=True, timeout=300,
                           cwd=tmp_path)  # not the checkout, whose package `-c` would import first
        assert r.returncode == 0, r.stderr[-2000:]
        return json.loads(r.stdout.splitlines()[-1])

    first = compiled()
    assert "_from_rotvec" in " ".join(first)  # cold: the kernel compiled
    assert compiled() == []  # warm: loaded
    trig = pkg / "quatarray" / "_trig.py"
    trig.write_text(trig.read_text() + "\n# changed\n")
    assert "_from_rotvec" in " ".join(compiled())  # the element file changed: compiled again
    assert compiled() == []


def test_package_stamp_follows_sources_and_skips_what_it_cannot_read(tmp_path):
    """The stamp changes with a source's content or name, not with other files,
    and an editor's lock link, a dangling link, a folder named like a source or
    an unreadable file never keep the package from importing."""
    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "b.py").write_text("y = 2\n")
    stamp = _jit.package_stamp(tmp_path)
    (tmp_path / "notes.txt").write_text("not a source")
    (tmp_path / "__pycache__").mkdir()
    (tmp_path / "__pycache__" / "c.py").write_text("z = 3\n")
    os.symlink(tmp_path / "gone.py", tmp_path / ".#a.py")  # emacs' lock link
    os.symlink(tmp_path / "gone.py", tmp_path / "dangling.py")
    (tmp_path / "dir.py").mkdir()
    os.mkfifo(tmp_path / "fifo.py")  # opening it would block
    assert _jit.package_stamp(tmp_path) == stamp
    locked = tmp_path / "locked.py"
    locked.write_text("secret\n")
    locked.chmod(0)
    if os.geteuid() != 0:  # root reads it anyway
        assert _jit.package_stamp(tmp_path) == stamp
    locked.chmod(0o644)
    assert _jit.package_stamp(tmp_path) != stamp
    locked.unlink()
    (tmp_path / "sub" / "b.py").write_text("y = 3\n")
    assert _jit.package_stamp(tmp_path) != stamp
    (tmp_path / "sub" / "b.py").write_text("y = 2\n")
    assert _jit.package_stamp(tmp_path) == stamp
    (tmp_path / "sub" / "b.py").rename(tmp_path / "sub" / "c.py")
    assert _jit.package_stamp(tmp_path) != stamp


def test_package_stamp_follows_linked_folders_and_archives(tmp_path):
    """A linked subfolder's sources count (a loop of links ends); a package imported
    from a zip file (its folder path runs through the archive) is stamped with the
    archive, not with the nothing os.walk finds there."""
    import zipfile

    pkg, real = tmp_path / "pkg", tmp_path / "real"
    pkg.mkdir()
    real.mkdir()
    (pkg / "a.py").write_text("x = 1\n")
    (real / "b.py").write_text("y = 2\n")
    os.symlink(real, pkg / "sub")
    os.symlink(pkg, real / "loop")  # back up: each real folder is stamped once
    stamp = _jit.package_stamp(pkg)
    (real / "b.py").write_text("y = 3\n")
    assert _jit.package_stamp(pkg) != stamp

    archive = tmp_path / "pkg.zip"
    stamps = []
    for text in ("x = 1\n", "x = 2\n"):
        with zipfile.ZipFile(archive, "w") as z:
            z.writestr("quatarray/a.py", text)
        stamps.append(_jit.package_stamp(str(archive / "quatarray")))
    assert stamps[0] != stamps[1] and all(st.startswith("archive:") for st in stamps)
    assert _jit.package_stamp(str(tmp_path / "gone" / "quatarray")) == "archive:unread"  # an ancestor is a folder


_RELOADED = """
import copy, importlib, json, pickle
import numpy as np
from numba.core.caching import CacheImpl
import quatarray as qa
from quatarray import _jit

def ours():
    return [c for c in CacheImpl._locator_classes if getattr(c, "_quatarray_locator", False)]

assert ours() == [_jit._PackageLocator] and CacheImpl._locator_classes[0] is _jit._PackageLocator
fresh = importlib.reload(_jit)
assert ours() == [fresh._PackageLocator] and CacheImpl._locator_classes[0] is fresh._PackageLocator
assert not any(getattr(c, "_quatarray_locator", False) for c in fresh._STANDARD_LOCATORS)
loc = fresh._PackageLocator.from_function(fresh.package_stamp, fresh.__file__)
stamp = loc.get_source_stamp()
assert stamp[1] == fresh.package_stamp(fresh._PACKAGE_DIR)
assert copy.copy(loc).get_source_stamp() == stamp
assert pickle.loads(pickle.dumps(loc)).get_source_stamp() == stamp
assert fresh._PackageLocator.from_function(json.dumps, json.__file__) is None  # not ours
q = qa.normalize(np.array([[2.0, 0, 0, 0]]))  # compiles and saves through the new locator
assert np.array_equal(q, [[1.0, 0, 0, 0]])
print("ok")
"""


def test_the_locator_is_installed_once_and_survives_reload_and_copy(tmp_path):
    """importlib.reload of _jit replaces the locator instead of stacking a second
    one (which recursed through the first); a locator copies and pickles. In a
    subprocess: a reload in the test process would swap _jit's globals under the
    other tests."""
    import subprocess
    import sys

    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    r = subprocess.run([sys.executable, "-c", _RELOADED], env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and r.stdout.split() == ["ok"], r.stderr[-2000:]


# ---- the kernel vocabulary: element, rowloop


def _straight(a, b):
    return _jit.fmuladd(a, b, _jit.like(a, 1.0)) * _jit.select(a < b, a, b)


def _straight_plain(a, b):
    return _jit.fmuladd(a, b, _jit.like(a, 1.0))


def _branchy(a, b):
    if a < b:
        return a * b
    return a - b


def _reads_array(x, i):
    return x[i] * 2.0


def test_element_traces_straight_line_code_and_compiles_the_rest():
    from quatarray import _trace

    traced, branchy, reads = _jit.element(_straight), _jit.element(_branchy), _jit.element(_reads_array)
    assert traced is _straight and _straight in _trace.TRACED  # a builtin of its callers
    assert _jit.ELEMENTS[f"{__name__}._straight"] is None
    assert "POP_JUMP" in _jit.ELEMENTS[f"{__name__}._branchy"] or "JUMP" in _jit.ELEMENTS[f"{__name__}._branchy"]
    assert _jit.ELEMENTS[f"{__name__}._reads_array"] == "an index that is not a constant"
    assert hasattr(branchy, "py_func") and hasattr(reads, "py_func")  # compiled

    @_jit.rowloop(parallel=False)
    def use(x, out):
        for i in range(x.shape[0]):
            out[i] = traced(x[i], 0.5) + branchy(x[i], 0.5) + reads(x, i)

    x = np.linspace(-1, 1, 9)
    out = np.empty_like(x)
    use(x, out)
    assert np.array_equal(out, [_straight(v, 0.5) + _branchy(v, 0.5) + 2 * v for v in x])
    for dtype in (np.float32,):  # a traced element keeps float32 float32
        y = x.astype(dtype)
        o = np.empty_like(y)
        use(y, o)
        assert o.dtype == dtype


def test_element_how_chooses_and_refuses_what_it_does_not_know():
    compiled = _jit.element(how="inline")(_straight_plain)  # traceable, but compiled on its own
    called = _jit.element(how="call")(_branchy)
    assert hasattr(compiled, "py_func") and hasattr(called, "py_func")
    assert compiled(0.25, 0.5) == _straight_plain(0.25, 0.5) and called(0.25, 0.5) == _branchy(0.25, 0.5)
    with pytest.raises(ValueError, match="Expected `how` to be None, 'trace', 'inline' or 'call', got 'fast'"):
        _jit.element(how="fast")(_straight)


def test_no_element_of_the_package_lost_its_trace_to_a_forward_reference():
    # the decorator reads an element's callees when it is defined: one defined below
    # its caller leaves the caller compiled; every such caller must stay untraceable
    # once the module is whole (else its callees belong above it)
    import importlib
    from quatarray import _trace

    for mod in ("algebra", "conversions", "euler", "splines", "transforms", "rigid", "align", "kinematics",
                "trajectory", "skeleton", "davenport", "symmetry", "interpolation", "classes.rotation"):
        importlib.import_module(f"quatarray.{mod}")
    late = {k: v for k, v in _jit.ELEMENTS.items() if v and "not defined yet" in v}
    for name in late:
        module, _, qual = name.rpartition(".")
        fn = getattr(importlib.import_module(module), qual)
        fn = getattr(fn, "py_func", fn)
        assert _trace.untraceable(fn, also=(_jit.like, _jit.fmuladd)), f"{name} could be traced: define its callees above it"
    assert sum(v is None for v in _jit.ELEMENTS.values()) > 50  # the quaternion products, trigonometry, slerp arcs, ...


def test_a_row_loop_calls_another_as_its_serial_variant():
    @_jit.rowloop
    def double(x, out):
        for i in _jit.prange(x.shape[0]):
            out[i] = 2.0 * x[i]

    @_jit.rowloop(parallel=False)
    def twice_then_add(x, out):
        double(x, out)
        for i in range(x.shape[0]):
            out[i] += 1.0

    x = np.arange(5.0)
    out = np.empty_like(x)
    twice_then_add(x, out)
    assert np.array_equal(out, 2 * x + 1)
    assert twice_then_add.parallel is twice_then_add.serial  # parallel=False: the serial variant only
