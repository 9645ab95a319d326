"""Euler angles: quatarray against scipy, numpy-quaternion and quaternionic.

Same arrays, same run; N = 1 (per-call overhead), 10³, 10⁶, 2·10⁶ (the size
of the performance targets) and, with ``QUATARRAY_BENCH_LARGE=1``, 10⁷;
float64 for every library and float32 for quatarray. Two sequences: ``"xyz"``
(extrinsic Tait–Bryan; scipy and quatarray only) and ``"ZYZ"`` (intrinsic
proper Euler: the only convention numpy-quaternion's
``as_euler_angles``/``from_euler_angles`` and quaternionic's
``to_euler_angles``/``from_euler_angles`` offer, R = e^{αz/2} e^{βy/2} e^{γz/2}).
For scipy the ``Rotation`` of an ``as_euler`` call is built outside the
timing, and ``from_euler`` times the construction only (no ``as_quat``):
both favour scipy.

Run: ``pytest benchmarks/test_euler.py --benchmark-only`` (add ``-k 2000000``
for the target size only). Targets (issue 2), float64 at N = 2·10⁶, versus
scipy: as_euler ≥ 5×, from_euler ≥ 20×.
"""

import numpy as np
import pytest
from conftest import SIZES, arrays, run

import quatarray as qa

Rotation = pytest.importorskip("scipy.spatial.transform").Rotation

try:
    import quaternion as npq
except ImportError:  # pragma: no cover - optional competitor
    npq = None
try:
    import quaternionic as qn
except ImportError:  # pragma: no cover - optional competitor
    qn = None

LIBS = ["quatarray", "quatarray-f32", "scipy", "numpy-quaternion", "quaternionic"]
SEQS = ["xyz", "ZYZ"]

_ANGLES = {}


def _need(lib, seq):
    if lib == "numpy-quaternion" and npq is None:
        pytest.skip("numpy-quaternion is not installed")
    if lib == "quaternionic" and qn is None:
        pytest.skip("quaternionic is not installed")
    if lib in ("numpy-quaternion", "quaternionic") and seq != "ZYZ":
        pytest.skip(f"{lib} has only the ZYZ convention")


def _data(lib, n, seq):
    """Unit quaternions and their Euler angles (the same for every library)."""
    dtype = np.float32 if lib.endswith("f32") else np.float64
    key = (n, seq)
    if key not in _ANGLES:
        q = arrays(n)["q"]
        _ANGLES[key] = qa.as_euler(q, seq, suppress_warnings=True)
    return arrays(n, dtype)["q"], _ANGLES[key].astype(dtype)


def _slow(benchmark, fn, n):
    """Few rounds for a slow competitor at large N (scipy's from_euler takes seconds)."""
    benchmark.extra_info["items"] = n
    if n <= 10_000:
        return benchmark(fn)
    return benchmark.pedantic(fn, rounds=3, iterations=1, warmup_rounds=1)


@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
@pytest.mark.parametrize("seq", SEQS)
@pytest.mark.parametrize("lib", LIBS)
def test_as_euler(benchmark, lib, seq, n):
    _need(lib, seq)
    q, _ = _data(lib, n, seq)
    benchmark.group = f"as_euler {seq} N={n}"
    if lib.startswith("quatarray"):
        run(benchmark, lambda: qa.as_euler(q, seq), n)
    elif lib == "scipy":
        r = Rotation.from_quat(q, scalar_first=True)
        run(benchmark, lambda: r.as_euler(seq), n)
    elif lib == "numpy-quaternion":
        Q = npq.as_quat_array(q)
        run(benchmark, lambda: npq.as_euler_angles(Q), n)
    else:
        Q = qn.array(q)
        run(benchmark, lambda: Q.to_euler_angles, n)  # a property


@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
@pytest.mark.parametrize("seq", SEQS)
@pytest.mark.parametrize("lib", LIBS)
def test_from_euler(benchmark, lib, seq, n):
    _need(lib, seq)
    _, a = _data(lib, n, seq)
    benchmark.group = f"from_euler {seq} N={n}"
    if lib.startswith("quatarray"):
        run(benchmark, lambda: qa.from_euler(seq, a), n)
    elif lib == "scipy":
        _slow(benchmark, lambda: Rotation.from_euler(seq, a), n)
    elif lib == "numpy-quaternion":
        run(benchmark, lambda: npq.from_euler_angles(a), n)
    else:
        run(benchmark, lambda: qn.array.from_euler_angles(a), n)
