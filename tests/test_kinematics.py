"""quatarray.integrate_angular_velocity: exact exponential steps, the inverse of angular_velocity."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import quatarray as qa
from quatarray import _jit
from quatarray.interpolation import _interval_rates


def uneven_times(rng, n, scale=0.01):
    return np.cumsum(0.2 + rng.random(n)) * scale


def step_rates(q, times, frame="space"):
    """The rates angular_velocity is built from: each step's rotation vector / h."""
    w = np.empty((len(q) - 1, 3))
    _interval_rates(q, np.diff(times).astype(float), frame == "body", w)
    return w


@pytest.fixture(params=["serial", "blocked"])
def blocked(request, monkeypatch):
    """Both paths of the scan: one block, or one block per thread (threshold 0)."""
    if request.param == "blocked":
        monkeypatch.setattr(_jit, "PARALLEL_MIN_ROWS", 0)
    return request.param


@pytest.mark.parametrize("frame", ["space", "body"])
@pytest.mark.parametrize("hold", ["mean", "start"])
def test_constant_rate_is_from_rotvec(rng, frame, hold, blocked):
    n = 20_000 if blocked == "blocked" else 500
    t = uneven_times(rng, n)
    w = np.array([0.3, -1.2, 2.0])
    q0 = qa.random(rng=rng)
    q = qa.integrate_angular_velocity(np.tile(w, (n, 1)), t, q0=q0, frame=frame, hold=hold)
    turn = qa.from_rotvec(np.outer(t - t[0], w))
    expect = qa.multiply(turn, q0) if frame == "space" else qa.multiply(q0, turn)
    assert np.abs(q - expect).max() < 1e-12
    assert np.array_equal(q[0], q0)


@pytest.mark.parametrize("frame", ["space", "body"])
def test_hold_start_inverts_step_rates(rng, frame, blocked):
    n = 20_000 if blocked == "blocked" else 300
    t = uneven_times(rng, n)
    w = rng.standard_normal((n, 3))
    q = qa.integrate_angular_velocity(w, t, frame=frame, hold="start")
    np.testing.assert_allclose(step_rates(q, t, frame), w[:-1], rtol=0, atol=1e-9)


@pytest.mark.parametrize("frame", ["space", "body"])
def test_round_trip_smooth_rate(rng, frame):
    # a smooth rate: angular_velocity of the integrated stream gives it back to second order
    t = np.sort(rng.uniform(0, 2, 2000))
    w = np.c_[np.sin(3 * t), np.cos(2 * t), 0.5 + 0 * t]
    q = qa.integrate_angular_velocity(w, t, frame=frame)
    back = qa.angular_velocity(q, t, frame=frame)
    assert np.abs(back[5:-5] - w[5:-5]).max() < 1e-4


def test_hold_mean_uses_the_midpoint_rate(rng):
    t = uneven_times(rng, 50)
    w = rng.standard_normal((50, 3))
    q = qa.integrate_angular_velocity(w, t)
    np.testing.assert_allclose(step_rates(q, t), 0.5 * (w[:-1] + w[1:]), atol=1e-10)


def test_body_is_rotated_space(rng):
    t = uneven_times(rng, 400)
    wb = rng.standard_normal((400, 3))
    q_body = qa.integrate_angular_velocity(wb, t, frame="body", hold="start")
    ws = qa.rotate(q_body, wb)  # the same motion's rate in the fixed frame
    q_space = qa.integrate_angular_velocity(ws, t, frame="space", hold="start")
    # hold="start" in both: step k turns by the same rotation exp(w h/2), seen in either frame
    assert np.abs(q_space - q_body).max() < 1e-12


def test_int64_nanoseconds_exact(rng):
    n = 1000
    steps = rng.integers(4_000_000, 6_000_000, n - 1)  # 200 Hz, jittered
    t_ns = np.int64(1_403_636_579_758_555_392) + np.r_[0, np.cumsum(steps)]
    w = rng.standard_normal((n, 3)) * 1e-9  # rad/ns
    q = qa.integrate_angular_velocity(w, t_ns)
    exact = qa.integrate_angular_velocity(w, (t_ns - t_ns[0]).astype(float))
    assert np.array_equal(q, exact)
    # the same times as float64 seconds-since-epoch ns lose the steps' low digits
    rounded = qa.integrate_angular_velocity(w, t_ns.astype(float))
    assert not np.array_equal(q, rounded)
    # seconds and rad/s give the same stream
    np.testing.assert_allclose(qa.integrate_angular_velocity(w * 1e9, (t_ns - t_ns[0]) * 1e-9), q, atol=1e-13)


@pytest.mark.parametrize("frame", ["space", "body"])
def test_float32(rng, frame, blocked):
    n = 30_000 if blocked == "blocked" else 1000
    t = uneven_times(rng, n)
    w = rng.standard_normal((n, 3))
    q32 = qa.integrate_angular_velocity(w.astype(np.float32), t, frame=frame)
    assert q32.dtype == np.float32
    q64 = qa.integrate_angular_velocity(w.astype(np.float32).astype(float), t, frame=frame)
    assert qa.distance(q32.astype(float), q64).max() < 1e-5 * np.sqrt(n / 1000)
    # the chain is carried in float64 with unit steps: the norm does not drift
    assert np.abs(np.linalg.norm(q32.astype(float), axis=1) - 1).max() < 1e-6
    # dtype rule: a float64 q0 makes it float64
    assert qa.integrate_angular_velocity(w[:5].astype(np.float32), t[:5], q0=qa.identity()).dtype == np.float64


@pytest.mark.slow
def test_blocked_equals_serial(rng, monkeypatch):
    n = 100_003
    t = uneven_times(rng, n)
    w = rng.standard_normal((n, 3))
    for frame in ("space", "body"):
        serial = qa.integrate_angular_velocity(w, t, frame=frame)
        monkeypatch.setattr(_jit, "PARALLEL_MIN_ROWS", 0)
        blocked = qa.integrate_angular_velocity(w, t, frame=frame)
        monkeypatch.setattr(_jit, "PARALLEL_MIN_ROWS", 10**12)
        assert np.abs(blocked - serial).max() < 1e-12


def test_tiny_and_huge_steps():
    t = np.array([0.0, 1e-12, 1.0, 2.0])
    w = np.array([[1e-9, 0, 0], [1e-9, 0, 0], [3e6, 0, 0], [3e6, 0, 0]])
    q = qa.integrate_angular_velocity(w, t, hold="start")
    assert q[1, 1] == pytest.approx(0.5e-21, rel=1e-15)  # sin(θ/2) of θ = 1e-21, to rounding
    # 3e6 rad in a step: beyond the fast sincos range, libm's sin and cos
    half = 1.5e6
    expect = qa.multiply([np.cos(half), np.sin(half), 0, 0], q[2])
    np.testing.assert_allclose(q[3], expect, atol=1e-12)


def test_shapes_and_errors():
    assert qa.integrate_angular_velocity(np.zeros((0, 3)), []).shape == (0, 4)
    np.testing.assert_array_equal(qa.integrate_angular_velocity([[1.0, 2, 3]], [5.0]), [[1, 0, 0, 0]])
    with pytest.raises(ValueError, match=r"strictly increasing, got times\[3\] = 2.0 after times\[2\] = 2.0"):
        qa.integrate_angular_velocity(np.zeros((5, 3)), [0, 1, 2, 2, 3.0])
    with pytest.raises(ValueError, match=r"Expected `omega` to have shape \(\.\.\., 3\)"):
        qa.integrate_angular_velocity(np.zeros((5, 4)), np.arange(5.0))
    with pytest.raises(ValueError, match=r"Expected `omega` to have shape \(N, 3\)"):
        qa.integrate_angular_velocity(np.zeros((2, 5, 3)), np.arange(5.0))
    with pytest.raises(ValueError, match=r"Expected `times` to have shape \(5,\)"):
        qa.integrate_angular_velocity(np.zeros((5, 3)), np.arange(4.0))
    with pytest.raises(ValueError, match=r"Expected `q0` to have shape \(4,\)"):
        qa.integrate_angular_velocity(np.zeros((5, 3)), np.arange(5.0), q0=np.ones((5, 4)))
    with pytest.raises(ValueError, match="`frame`"):
        qa.integrate_angular_velocity(np.zeros((5, 3)), np.arange(5.0), frame="world")
    with pytest.raises(ValueError, match="`hold`"):
        qa.integrate_angular_velocity(np.zeros((5, 3)), np.arange(5.0), hold="end")
    with pytest.raises(TypeError):
        qa.integrate_angular_velocity(np.zeros((5, 3), complex), np.arange(5.0))


def test_read_only_and_strided_inputs(rng):
    t = uneven_times(rng, 200)
    w = rng.standard_normal((200, 6))[:, ::2]
    w.flags.writeable = False
    q = qa.integrate_angular_velocity(w, t)
    np.testing.assert_array_equal(q, qa.integrate_angular_velocity(np.ascontiguousarray(w), t))


def test_euroc_groundtruth_round_trip(data_dir):
    # the real stream's own step rates integrate back to it (hold="start", int64 ns)
    a = np.loadtxt(data_dir / "euroc_v102_groundtruth.csv", delimiter=",", skiprows=1, max_rows=3000)
    t_ns = a[:, 0].astype(np.int64)
    q = qa.normalize(qa.unflip(a[:, 4:8]))
    w = np.r_[step_rates(q, t_ns), [[0.0, 0, 0]]]
    back = qa.integrate_angular_velocity(w, t_ns, q0=q[0], hold="start")
    assert qa.distance(back, q).max() < 1e-9


# ---------------------------------------------------------------------------
# quatarray.dask: a blocked scan equal to the in-memory result


@pytest.mark.parametrize("frame", ["space", "body"])
@pytest.mark.parametrize("hold", ["mean", "start"])
@pytest.mark.parametrize("chunks", [1, 7, 64, 1000])
def test_dask_equals_in_memory(rng, frame, hold, chunks):
    da = pytest.importorskip("dask.array")
    import quatarray.dask as qd

    n = 500
    t = uneven_times(rng, n)
    w = rng.standard_normal((n, 3))
    q0 = qa.random(rng=rng)
    expect = qa.integrate_angular_velocity(w, t, q0=q0, frame=frame, hold=hold)
    lazy = qd.integrate_angular_velocity(da.from_array(w, chunks=(chunks, 3)), da.from_array(t, chunks=13),
                                         q0=q0, frame=frame, hold=hold)
    assert lazy.chunks[0] == da.from_array(w, chunks=(chunks, 3)).chunks[0]
    assert np.abs(lazy.compute(scheduler="sync") - expect).max() < 1e-13


def test_dask_nanoseconds_float32_and_errors(rng):
    da = pytest.importorskip("dask.array")
    import quatarray.dask as qd

    n = 300
    t_ns = np.int64(1_403_636_579_758_555_392) + np.r_[0, np.cumsum(rng.integers(4_000_000, 6_000_000, n - 1))]
    w = rng.standard_normal((n, 3)) * 1e-9
    got = qd.integrate_angular_velocity(da.from_array(w, chunks=(40, 3)), t_ns).compute(scheduler="sync")
    assert np.abs(got - qa.integrate_angular_velocity(w, t_ns)).max() < 1e-13
    w32 = (w * 1e9).astype(np.float32)
    t = (t_ns - t_ns[0]) * 1e-9
    got = qd.integrate_angular_velocity(da.from_array(w32, chunks=(40, 3)), t).compute(scheduler="sync")
    assert got.dtype == np.float32
    assert np.abs(got - qa.integrate_angular_velocity(w32, t)).max() < 1e-6
    bad = t.copy()
    bad[123] = bad[122]
    with pytest.raises(ValueError, match=r"times\[123\] = .* after times\[122\]"):
        qd.integrate_angular_velocity(da.from_array(w, chunks=(40, 3)), bad).compute(scheduler="sync")
    with pytest.raises(ValueError, match="`hold`"):
        qd.integrate_angular_velocity(da.from_array(w, chunks=(40, 3)), t, hold="end")


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("n", [2, 15, 16, 17, 18, 19, 64, 67, 1000])
def test_scan_chains_equal_one_chain(rng, n, dtype):
    """The scan's interleaved chains (then carried) give the one serial chain of
    products to rounding, at every length around the cut into parts."""
    from quatarray.kinematics import _scan

    e = qa.random(n, rng=rng).astype(dtype)
    q0 = qa.random(rng=rng)
    for body in (False, True):
        acc = q0.astype(np.float64)
        ref = np.empty((n, 4))
        for k in range(n):
            x = e[k].astype(np.float64)
            x = x / np.linalg.norm(x) if dtype == np.float32 else x
            acc = qa.multiply(acc, x) if body else qa.multiply(x, acc)
            ref[k] = acc
        out = e.copy()
        _scan(out, q0, body, dtype == np.float32)
        tol = 1e-14 if dtype == np.float64 else 2e-7
        assert out.dtype == dtype and np.abs(out - ref).max() < tol, (n, body)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(2, 300), scale=st.floats(1e-3, 30),
       frame=st.sampled_from(["space", "body"]), f32=st.booleans())
def test_integrate_then_step_rates_round_trip(seed, n, scale, frame, f32):
    # integrate (hold="start": each step the exponential of its start rate) and the step rates
    # of the result give the rates back, for any steps and rate sizes (turns up to ~π a step)
    rng = np.random.default_rng(seed)
    t = uneven_times(rng, n, 0.05)
    w = rng.standard_normal((n, 3)) * scale
    w *= np.minimum(1.0, 3.0 / (np.linalg.norm(w, axis=1, keepdims=True) * np.r_[np.diff(t), 1.0][:, None]))
    dt = np.float32 if f32 else np.float64
    q = qa.integrate_angular_velocity(w.astype(dt), t, frame=frame, hold="start")
    assert q.dtype == dt
    tol = 2e-3 if f32 else 1e-8
    np.testing.assert_allclose(step_rates(q.astype(float), t, frame), w[:-1].astype(dt), atol=tol * (1 + scale), rtol=0)
    assert np.abs(np.linalg.norm(q.astype(float), axis=1) - 1).max() < (1e-5 if f32 else 1e-12)
