"""Shared fixtures and the ratio summary for the benchmarks.

Run with ``pytest benchmarks/<file> --benchmark-only`` (benchmarks are not
part of the default test run). Conventions every benchmark file may follow:

- one ``@pytest.mark.benchmark(group=...)`` group per operation and size;
- a ``lib`` parameter whose id starts with ``quatarray`` for the entry the
  others are compared with (``quatarray`` = float64; ``quatarray-f32`` etc.
  are further quatarray variants);
- the same arrays for every library of a group (use :func:`arrays`).

At the end of the session a table prints, for each group, every entry's rate
relative to the plain ``quatarray`` entry of that group (best round against
best round, measured in the same run), plus Mquat/s where the test stored
``benchmark.extra_info["items"]``. The "stream" groups of
``test_algebra.py`` give the machine's memory ceiling in the same unit (a
STREAM triad moving 96 bytes per item, like a float64 product).

Environment
-----------
QUATARRAY_BENCH_LARGE=1
    Add N = 10⁷ (about 1 GB of arrays per operation and a much longer run).
"""

import os

import numpy as np
import pytest

try:
    import quaternion as npq
except ImportError:  # pragma: no cover - optional competitor
    npq = None
try:
    import quaternionic as qn
except ImportError:  # pragma: no cover - optional competitor
    qn = None

# the usual `lib` parameter values: quatarray float64 (the reference), quatarray float32, the others
LIBS = ["quatarray", "quatarray-f32", "scipy", "numpy-quaternion", "quaternionic"]

SIZES = [1, 1_000, 1_000_000, 2_000_000]
if os.environ.get("QUATARRAY_BENCH_LARGE", "0") not in ("", "0"):
    SIZES.append(10_000_000)

_CACHE = {}


def arrays(n, dtype=np.float64):
    """The same random data for every library: p, q (unit, (n, 4)), v ((n, 3)), t ((n,)), all C-contiguous."""
    key = (n, np.dtype(dtype).str)
    if key not in _CACHE:
        base = (n, "<f8")
        if base not in _CACHE:
            rng = np.random.default_rng(12345)
            p = rng.standard_normal((n, 4))
            p /= np.linalg.norm(p, axis=1, keepdims=True)
            q = rng.standard_normal((n, 4))
            q /= np.linalg.norm(q, axis=1, keepdims=True)
            _CACHE[base] = dict(p=p, q=q, v=rng.standard_normal((n, 3)), t=rng.random(n))
        _CACHE[key] = {k: a.astype(dtype) for k, a in _CACHE[base].items()}
    return _CACHE[key]


def need(lib):
    """Skip unless the competitor ``lib`` is installed."""
    if lib == "numpy-quaternion" and npq is None:
        pytest.skip("numpy-quaternion is not installed")
    if lib == "quaternionic" and qn is None:
        pytest.skip("quaternionic is not installed")


def data_for(lib, n):
    """:func:`arrays` in the dtype of ``lib`` (float32 for ``...-f32`` entries)."""
    return arrays(n, np.float32 if lib.endswith("f32") else np.float64)


def run(benchmark, fn, n, slow=False):
    """Time ``fn``: auto-calibrated for small n, fixed rounds of one call for large n.

    ``slow=True`` is for competitors that take seconds at large n (scipy's
    from_euler, its SVD per matrix): 3 rounds and no warm-up round there.
    """
    benchmark.extra_info["items"] = n
    if n <= 10_000:
        return benchmark(fn)
    if slow:
        return benchmark.pedantic(fn, rounds=3, iterations=1, warmup_rounds=0)
    rounds = 15 if n <= 2_000_000 else 5
    return benchmark.pedantic(fn, rounds=rounds, iterations=1, warmup_rounds=1)


def pytest_terminal_summary(terminalreporter, config):
    session = getattr(config, "_benchmarksession", None)
    if session is None or not getattr(session, "benchmarks", None):
        return
    groups = {}
    for b in session.benchmarks:
        if getattr(b, "has_error", False) or not b.stats:
            continue
        groups.setdefault(b.group, []).append(b)
    tw = terminalreporter
    tw.write_sep("=", "quatarray ratios (same run; ratio = quatarray rate / other rate, best rounds)")
    for group, items in groups.items():
        ref = [b for b in items if _lib(b) == "quatarray"]
        ref_t = ref[0].stats.min if ref else None
        parts = []
        for b in sorted(items, key=lambda b: b.stats.min):
            n = b.extra_info.get("items")
            rate = f"{n / b.stats.min / 1e6:.3g} Mquat/s" if n else f"{b.stats.min * 1e3:.3g} ms"
            if ref_t and b is not ref[0]:
                parts.append(f"{_lib(b)} {rate} (ratio {b.stats.min / ref_t:.2f}×)")
            else:
                parts.append(f"{_lib(b)} {rate}")
        tw.write_line(f"{group}: " + "; ".join(parts))


def _lib(b):
    params = getattr(b, "params", None) or {}
    if "lib" in params:
        return str(params["lib"])
    return b.name
