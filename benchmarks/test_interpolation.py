"""Interpolation benchmarks: quatarray vs numpy-quaternion, quaternionic and scipy, same arrays, same run.

Run: pytest benchmarks/test_interpolation.py --benchmark-only
Groups: slerp (10⁶ pairs), spline-bezier (10⁴ keys → 10⁶ samples, against
scipy RotationSpline and numpy-quaternion squad), spline-slerp (against scipy Slerp),
spline-cubic-order{0,1,2} (``method="cubic"``, scipy's C² curve, against scipy
RotationSpline built and evaluated in the call, as quatarray's call does, and
evaluated only), spline-rates (``order`` 0, 1, 2 of bezier and cubic side by side:
the targets are cubic ≥ 10× scipy and order 1 within 2× of order 0),
spline-bezier-order{1,2} (the Bézier curve's angular velocity and acceleration
against scipy RotationSpline's ``(t, order)`` built in the call, on the stream of
``quatarray bench``'s rows: 1.25·10⁵ keys at 30 Hz with sign flips → 5·10⁵
samples; target ≥ 20× each).
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, RotationSpline, Slerp

import quatarray as qa

N = 10**6
K = 10**4


@pytest.fixture(scope="module")
def pairs():
    rng = np.random.default_rng(1)
    return qa.random(N, rng), qa.random(N, rng), rng.random(N)


@pytest.fixture(scope="module")
def stream():
    rng = np.random.default_rng(2)
    times = np.cumsum(rng.uniform(0.5, 1.5, K))
    times -= times[0]
    keys = qa.unflip(qa.from_rotvec(np.cumsum(rng.standard_normal((K, 3)) * 0.05, axis=0)))
    new = np.linspace(times[0], times[-1], N)
    return times, keys, new


def run(benchmark, f):
    f()  # compile / warm up outside the timing
    benchmark.pedantic(f, rounds=5, iterations=1, warmup_rounds=1)


# ---- slerp ----


@pytest.mark.benchmark(group="slerp")
def test_slerp_quatarray(benchmark, pairs):
    p, q, t = pairs
    out = np.empty_like(p)
    run(benchmark, lambda: qa.slerp(p, q, t, out=out))


@pytest.mark.benchmark(group="slerp")
def test_slerp_numpy_quaternion(benchmark, pairs):
    quaternion = pytest.importorskip("quaternion")
    p, q, t = pairs
    a, b = quaternion.as_quat_array(p), quaternion.as_quat_array(q)
    # `slerp_vectorized` is registered on numpy by numpy-quaternion (the C ufunc)
    run(benchmark, lambda: np.slerp_vectorized(a, b, t))


@pytest.mark.benchmark(group="slerp")
def test_slerp_quaternionic(benchmark, pairs):
    quaternionic = pytest.importorskip("quaternionic")
    from quatarray.app.bench import peer_crashes

    if peer_crashes("quaternionic.slerp"):
        pytest.skip("quaternionic's slerp crashes the interpreter on this set-up")
    p, q, t = pairs
    a, b = quaternionic.array(p), quaternionic.array(q)
    run(benchmark, lambda: quaternionic.slerp(a, b, t))


# ---- spline, Bézier ----


@pytest.mark.benchmark(group="spline-bezier")
def test_spline_bezier_quatarray(benchmark, stream):
    times, keys, new = stream
    run(benchmark, lambda: qa.spline(times, keys, new, method="bezier"))


@pytest.mark.benchmark(group="spline-bezier")
def test_spline_squad_quatarray(benchmark, stream):
    times, keys, new = stream
    run(benchmark, lambda: qa.spline(times, keys, new, method="squad"))


@pytest.mark.benchmark(group="spline-bezier")
def test_spline_scipy_rotationspline(benchmark, stream):
    times, keys, new = stream
    spl = RotationSpline(times, Rotation.from_quat(keys, scalar_first=True))
    run(benchmark, lambda: spl(new))


@pytest.mark.benchmark(group="spline-bezier")
def test_spline_numpy_quaternion_squad(benchmark, stream):
    quaternion = pytest.importorskip("quaternion")
    times, keys, new = stream
    k = quaternion.as_quat_array(keys)
    run(benchmark, lambda: quaternion.squad(k, times, new))


# ---- spline, slerp ----


@pytest.mark.benchmark(group="spline-slerp")
def test_spline_slerp_quatarray(benchmark, stream):
    times, keys, new = stream
    run(benchmark, lambda: qa.spline(times, keys, new, method="slerp"))


@pytest.mark.benchmark(group="spline-slerp")
def test_spline_slerp_scipy(benchmark, stream):
    times, keys, new = stream
    sl = Slerp(times, Rotation.from_quat(keys, scalar_first=True))
    run(benchmark, lambda: sl(new))


# ---- spline, cubic (scipy's RotationSpline) and the rates ----


@pytest.mark.parametrize("order", [0, 1, 2])
def test_spline_cubic_quatarray(benchmark, stream, order):
    times, keys, new = stream
    benchmark.group = f"spline-cubic-order{order}"
    run(benchmark, lambda: qa.spline(times, keys, new, method="cubic", order=order))


@pytest.mark.parametrize("order", [0, 1, 2])
def test_spline_cubic_scipy_built_in_the_call(benchmark, stream, order):
    times, keys, new = stream
    benchmark.group = f"spline-cubic-order{order}"
    r = Rotation.from_quat(keys, scalar_first=True)
    run(benchmark, lambda: RotationSpline(times, r)(new, order))


@pytest.mark.parametrize("order", [0, 1, 2])
def test_spline_cubic_scipy_evaluated(benchmark, stream, order):
    times, keys, new = stream
    benchmark.group = f"spline-cubic-order{order}"
    spl = RotationSpline(times, Rotation.from_quat(keys, scalar_first=True))
    run(benchmark, lambda: spl(new, order))


@pytest.mark.benchmark(group="spline-rates")
@pytest.mark.parametrize("method", ["bezier", "cubic", "squad", "slerp", "nlerp"])
@pytest.mark.parametrize("order", [0, 1, 2])
def test_spline_rates_quatarray(benchmark, stream, method, order):
    times, keys, new = stream
    run(benchmark, lambda: qa.spline(times, keys, new, method=method, order=order))


# ---- the Bézier curve's rates against scipy's (quatarray bench's rows)


@pytest.fixture(scope="module")
def bench_stream():
    """``quatarray bench``'s spline stream: K = 125 000 keys at 30 Hz, every third negated,
    four samples per segment."""
    rng = np.random.default_rng(0)
    k = 125_000
    times = np.arange(k) / 30.0
    keys = qa.from_rotvec(np.cumsum(rng.normal(0, 0.05, (k, 3)), axis=0))
    keys[1::3] *= -1
    return times, keys, np.linspace(times[0], times[-1], 4 * (k - 1) + 1)


@pytest.mark.parametrize("order", [1, 2])
def test_spline_bezier_rates_quatarray(benchmark, bench_stream, order):
    times, keys, new = bench_stream
    benchmark.group = f"spline-bezier-order{order}"
    run(benchmark, lambda: qa.spline(times, keys, new, method="bezier", order=order))


@pytest.mark.parametrize("order", [1, 2])
def test_spline_bezier_rates_scipy_rotationspline(benchmark, bench_stream, order):
    times, keys, new = bench_stream
    benchmark.group = f"spline-bezier-order{order}"
    r = Rotation.from_quat(keys, scalar_first=True)
    run(benchmark, lambda: RotationSpline(times, r)(new, order))
