"""integrate_angular_velocity against the plain composition of the peers.

The peer pipeline is the fastest plain one: scipy's vectorised
``Rotation.from_rotvec`` of every step's rotation vector (the held rate times
the step), then numpy-quaternion's C ufunc ``np.multiply.accumulate`` over
``quaternion.as_quat_array`` of the steps (the body frame's order; for the
space frame the conjugates are accumulated and conjugated back). Target
(issue 16): at N = 10⁶, quatarray ≥ 5× the peers. ``quatarray-serial`` is the
one-block scan (the parallel threshold raised), to show what the blocked scan
on all threads gives. ``cold first call``: the CPU time of a fresh process's
first call with an empty numba cache, less that of the same process with a
filled cache (target ≲ 1-2 s).

Run: ``pytest benchmarks/test_kinematics.py --benchmark-only``.
"""

import os
import subprocess
import sys
import tempfile

import numpy as np
import pytest
from conftest import need, npq, run

import quatarray as qa
from quatarray import _jit

Rotation = pytest.importorskip("scipy.spatial.transform").Rotation
SIZES = [1_000, 1_000_000]
LIBS = ["quatarray", "quatarray-f32", "quatarray-serial", "scipy+numpy-quaternion"]
_DATA = {}


def rates(n, dtype=np.float64):
    """An IMU-like stream: 200 Hz with jitter, rates of a few rad/s."""
    if n not in _DATA:
        rng = np.random.default_rng(16)
        t = np.cumsum(0.005 + 0.0002 * rng.standard_normal(n))
        _DATA[n] = t, rng.standard_normal((n, 3))
    t, w = _DATA[n]
    return t, w.astype(dtype)


def peers(w, t, frame):
    h = np.diff(t)
    steps = Rotation.from_rotvec(0.5 * (w[:-1] + w[1:]) * h[:, None]).as_quat(scalar_first=True)
    e = npq.as_quat_array(np.concatenate([[[1.0, 0, 0, 0]], steps]))
    if frame == "body":
        return np.multiply.accumulate(e)
    return np.multiply.accumulate(e.conjugate()).conjugate()


@pytest.mark.parametrize("frame", ["space", "body"])
@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
@pytest.mark.parametrize("lib", LIBS)
def test_integrate(benchmark, monkeypatch, lib, n, frame):
    benchmark.group = f"integrate {frame} N={n}"
    t, w = rates(n, np.float32 if lib.endswith("f32") else np.float64)
    if lib.startswith("quatarray"):
        if lib == "quatarray-serial":
            monkeypatch.setattr(_jit, "PARALLEL_MIN_ROWS", 1 << 62)
        fn = lambda: qa.integrate_angular_velocity(w, t, frame=frame)  # noqa: E731
    else:
        need("numpy-quaternion")
        ref = npq.as_float_array(peers(w, t, frame))
        assert np.abs(ref - qa.integrate_angular_velocity(w, t, frame=frame)).max() < 1e-10  # the same job
        fn = lambda: peers(w, t, frame)  # noqa: E731
    fn()
    run(benchmark, fn, n)


CODE = """
import resource, time, numpy as np, quatarray as qa
t = np.cumsum(np.full(1000, 0.005)); w = np.ones((1000, 3))
import quatarray.kinematics  # imports numba and the kernel modules (nothing compiled yet)
u = resource.getrusage(resource.RUSAGE_SELF)
c0 = u.ru_utime + u.ru_stime
for frame in ("space", "body"):
    for hold in ("mean", "start"):
        qa.integrate_angular_velocity(w, t, frame=frame, hold=hold)
u = resource.getrusage(resource.RUSAGE_SELF)
print(u.ru_utime + u.ru_stime - c0)
"""


def _cpu(env):
    res = subprocess.run([sys.executable, "-c", CODE], env=env, capture_output=True, text=True, check=True)
    return float(res.stdout.split()[-1])


def test_cold_first_call(benchmark):
    """CPU seconds of the first float64 calls (both frames and holds) in a fresh process,
    compiling into an empty cache, against the same with the cache filled."""
    benchmark.group = "integrate cold first call (CPU s, fresh process)"
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        cold = _cpu(env)
        warm = _cpu(env)
    benchmark.extra_info.update(cold_cpu_s=cold, cached_cpu_s=warm)
    print(f"\nintegrate first call: {cold:.2f} s CPU compiling, {warm:.3f} s from the cache")
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)
