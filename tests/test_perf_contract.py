"""The performance contract that can be checked without timing anything.

- ``import quatarray`` is cheap: ≤ 0.5 s in a fresh process, and it imports no numba;
- the ``out=`` path allocates no array of the batch's size (tracemalloc sees
  numpy's buffers), serial and multi-threaded;
- the contiguous fast path (rows addressed at a literal stride so the loops
  vectorise) gives bit for bit what the strided path gives, for every
  remainder length of the SIMD loop and with ``out`` aliasing an input.

Speed itself is measured side by side in ``benchmarks/`` (not in tests).
"""

import subprocess
import sys
import tracemalloc

import numpy as np
import pytest

import quatarray as qa
from quatarray import _jit

N = 10_000


def test_import_is_cheap_and_loads_no_numba():
    code = (
        "import sys, time; t = time.perf_counter(); import quatarray; "
        "print(time.perf_counter() - t, 'numba' in sys.modules, 'scipy' in sys.modules)"
    )
    # best of three: a shared machine can stall one start
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
            for _ in range(3)]
    times = [float(r.stdout.split()[0]) for r in runs]
    assert all(r.stdout.split()[1] == "False" for r in runs), "import quatarray imported numba"
    assert min(times) <= 0.5, f"import quatarray took {min(times):.2f} s"


def _calls(dtype):
    rng = np.random.default_rng(1)
    p = qa.random(N, rng=rng, dtype=dtype)
    q = qa.random(N, rng=rng, dtype=dtype)
    v = rng.standard_normal((N, 3)).astype(dtype)
    o4, o3 = np.empty_like(p), np.empty_like(v)
    return {
        "multiply": lambda: qa.multiply(p, q, out=o4),
        "multiply out=p": lambda: qa.multiply(p, q, out=p),
        "multiply strided": lambda: qa.multiply(p[::2], q[::2], out=o4[::2]),
        "multiply broadcast": lambda: qa.multiply(p, q[0], out=o4),
        "rotate": lambda: qa.rotate(p, v, out=o3),
        "rotate out=v": lambda: qa.rotate(p, v, out=v),
        "normalize": lambda: qa.normalize(p, out=o4),
        "inverse": lambda: qa.inverse(p, out=o4),
        "conjugate": lambda: qa.conjugate(p, out=o4),
    }


def _peak(fn):
    fn()  # compile / load from the cache first
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_out_path_allocates_nothing(dtype):
    size = N * 3 * np.dtype(dtype).itemsize  # the smallest N-row array involved
    for name, fn in _calls(dtype).items():
        peak = _peak(fn)
        assert peak < size / 4, f"{name}: {peak} bytes allocated (an (N, 3) array is {size})"


def test_out_path_allocates_nothing_multithreaded(monkeypatch):
    monkeypatch.setattr(_jit, "PARALLEL_MIN_ROWS", 0)
    calls = _calls(np.float64)
    for name in ("multiply", "rotate"):
        peak = _peak(calls[name])
        assert peak < N * 24 / 4, f"{name} (parallel): {peak} bytes allocated"


def test_tracemalloc_sees_numpy_buffers():
    """The check above can fail: a call without out= is seen allocating its result."""
    p = qa.random(N, rng=2)
    assert _peak(lambda: qa.multiply(p, p)) >= p.nbytes


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_contiguous_fast_path_equals_strided_path(dtype):
    rng = np.random.default_rng(7)
    for n in list(range(0, 20)) + [257, 1001]:
        p = (rng.standard_normal((n, 4)) * 2).astype(dtype)
        q = rng.standard_normal((n, 4)).astype(dtype)
        v = rng.standard_normal((n, 3)).astype(dtype)
        # a Fortran-ordered copy holds the same numbers but takes the strided path
        pf, qf, vf = np.asfortranarray(p), np.asfortranarray(q), np.asfortranarray(v)
        for fn, a, b in ((qa.multiply, (p, q), (pf, qf)), (qa.rotate, (p, v), (pf, vf))):
            np.testing.assert_array_equal(fn(*a), fn(*b))
        for fn in (qa.normalize, qa.inverse, qa.conjugate):
            np.testing.assert_array_equal(fn(p), fn(pf))
        ref = qa.multiply(pf, qf)
        a = p.copy()
        np.testing.assert_array_equal(qa.multiply(a, q, out=a), ref)
        b = q.copy()
        np.testing.assert_array_equal(qa.multiply(p, b, out=b), ref)
        w = v.copy()
        np.testing.assert_array_equal(qa.rotate(p, w, out=w), qa.rotate(pf, vf))


def test_contiguous_fast_path_multithreaded(monkeypatch):
    monkeypatch.setattr(_jit, "PARALLEL_MIN_ROWS", 0)
    rng = np.random.default_rng(8)
    p, q = qa.random(1001, rng=rng), qa.random(1001, rng=rng)
    a = p.copy()
    qa.multiply(a, q, out=a)
    np.testing.assert_array_equal(a, qa.multiply(np.asfortranarray(p), np.asfortranarray(q)))
