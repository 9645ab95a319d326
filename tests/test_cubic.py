"""spline(method="cubic"): scipy's RotationSpline, values, rates and accelerations."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, RotationSpline

import quatarray as qa
from quatarray import _cubic


def smooth_keys(rng, k, step=0.3):
    return qa.from_rotvec(np.cumsum(rng.standard_normal((k, 3)) * step, axis=0))


def flipped(rng, keys):
    """The keys with random signs and a small non-unit scale (scipy is sign-blind)."""
    return keys * rng.choice([-1.0, 1.0], len(keys))[:, None] * 1.001


def scipy_spline(times, keys):
    return RotationSpline(np.asarray(times, float), Rotation.from_quat(np.asarray(keys, float), scalar_first=True))


def sign_blind(a, b):
    """Largest component difference of a and b, each row compared with ±b."""
    return np.minimum(np.abs(a - b).max(-1), np.abs(a + b).max(-1)).max()


def new_times(rng, times, m=400):
    nt = rng.uniform(times[0], times[-1], m)
    return np.concatenate([nt, times, times[[0, -1]]])  # the key times, both ends


@pytest.mark.parametrize("k", [2, 3, 4, 7, 40])
@pytest.mark.parametrize("spacing", ["even", "uneven"])
def test_cubic_equals_scipy(rng, k, spacing):
    times = 0.5 * np.arange(k) if spacing == "even" else np.cumsum(rng.choice([0.05, 0.4, 1.0, 3.0], k))
    keys = flipped(rng, smooth_keys(rng, k, 0.5))
    ref = scipy_spline(times, keys)
    nt = new_times(rng, times)
    for shuffled in (np.sort(nt), nt):
        got = qa.spline(times, keys, shuffled, method="cubic")
        assert got.shape == (len(nt), 4)
        assert sign_blind(got, ref(shuffled).as_quat(scalar_first=True)) <= 1e-10
        np.testing.assert_allclose(qa.spline(times, keys, shuffled, method="cubic", order=1), ref(shuffled, 1),
                                   rtol=0, atol=1e-10)
        np.testing.assert_allclose(qa.spline(times, keys, shuffled, method="cubic", order=2), ref(shuffled, 2),
                                   rtol=0, atol=1e-10 * (1 + np.abs(ref(shuffled, 2)).max()))


def test_cubic_large_turns_and_random_keys(rng):
    """Keys far apart (random rotations: the rate iteration runs its 10 passes) still equal scipy."""
    times = np.cumsum(rng.uniform(0.3, 2.0, 25))
    keys = qa.random(25, rng=5)
    ref = scipy_spline(times, keys)
    nt = new_times(rng, times)
    assert sign_blind(qa.spline(times, keys, nt, method="cubic"), ref(nt).as_quat(scalar_first=True)) <= 1e-10
    for order in (1, 2):
        want = ref(nt, order)
        got = qa.spline(times, keys, nt, method="cubic", order=order)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-10 * (1 + np.abs(want).max()))


def test_cubic_converged_iteration_and_two_keys(rng):
    q = qa.unflip(qa.normalize(smooth_keys(rng, 30, 0.05)))
    t = np.cumsum(rng.uniform(0.5, 1.0, 30))
    assert 1 <= _cubic.coefficients(t, q)[1] < _cubic.MAX_ITER  # smooth keys: converges early
    assert _cubic.coefficients(t[:2], q[:2])[1] == 0  # two keys: no system
    # two keys: the great arc at constant rate, as slerp
    nt = np.linspace(t[0], t[1], 11)
    np.testing.assert_allclose(qa.spline(t[:2], q[:2], nt, method="cubic"),
                               qa.spline(t[:2], q[:2], nt, method="slerp"), rtol=0, atol=1e-14)


def test_cubic_tiny_and_zero_steps(rng):
    """Identical keys (zero rotation vectors) and nearly identical ones: the series branches."""
    base = smooth_keys(rng, 6, 0.4)
    keys = np.repeat(base, 2, axis=0)
    keys[1::2] = qa.multiply(keys[1::2], qa.from_rotvec(rng.standard_normal((6, 3)) * 1e-6))
    keys[4] = keys[3]
    times = np.cumsum(rng.uniform(0.5, 1.5, 12))
    ref = scipy_spline(times, keys)
    nt = new_times(rng, times)
    assert sign_blind(qa.spline(times, keys, nt, method="cubic"), ref(nt).as_quat(scalar_first=True)) <= 1e-10
    for order in (1, 2):
        want = ref(nt, order)
        np.testing.assert_allclose(qa.spline(times, keys, nt, method="cubic", order=order), want, rtol=0,
                                   atol=1e-10 * (1 + np.abs(want).max()))


def test_cubic_float32_and_integer_stamps(rng):
    keys = flipped(rng, smooth_keys(rng, 20, 0.3))
    times = np.cumsum(rng.uniform(0.5, 1.5, 20))
    nt = new_times(rng, times)
    ref = scipy_spline(times, keys)
    got = qa.spline(times, keys.astype(np.float32), nt, method="cubic")
    assert got.dtype == np.float32
    assert sign_blind(got.astype(float), ref(nt).as_quat(scalar_first=True)) <= 2e-6
    for order in (1, 2):
        g = qa.spline(times, keys.astype(np.float32), nt, method="cubic", order=order)
        assert g.dtype == np.float32 and g.shape == (len(nt), 3)
        want = ref(nt, order)
        np.testing.assert_allclose(g, want, rtol=0, atol=2e-5 * (1 + np.abs(want).max()))
    # int64 nanosecond stamps: taken from the first key exactly, rates per nanosecond
    # (scipy's convergence test 1e-9·(1 + |ω|) is then loose: compare with scipy on the
    # same times, not with the spline in seconds)
    stamps = 1403715524907143168 + np.cumsum(rng.integers(4_000_000, 6_000_000, 20))
    new = stamps[:-1] + 2_500_000
    ref = scipy_spline((stamps - stamps[0]).astype(float), keys)
    rel = (new - stamps[0]).astype(float)
    assert sign_blind(qa.spline(stamps, keys, new, method="cubic"), ref(rel).as_quat(scalar_first=True)) <= 1e-10
    np.testing.assert_allclose(qa.spline(stamps, keys, new, method="cubic", order=1), ref(rel, 1), rtol=1e-10,
                               atol=0)


def test_cubic_shapes_and_empty(rng):
    keys = smooth_keys(rng, 5)
    t = np.arange(5.0)
    nt = rng.uniform(0, 4, (3, 7))
    assert qa.spline(t, keys, nt, method="cubic").shape == (3, 7, 4)
    assert qa.spline(t, keys, nt, method="cubic", order=2).shape == (3, 7, 3)
    np.testing.assert_array_equal(qa.spline(t, keys, nt, method="cubic", order=1).reshape(-1, 3),
                                  qa.spline(t, keys, nt.reshape(-1), method="cubic", order=1))
    assert qa.spline(t, keys, np.empty(0), method="cubic").shape == (0, 4)
    assert qa.spline(t, keys, np.empty(0), method="cubic", order=1).shape == (0, 3)


TIE_KEYS = [
    # identity -> 180° about x -> identity: scipy keeps turning one way (a full spin)
    ([0, 1, 2], [[1, 0, 0, 0], [0, 1, 0, 0], [1, 0, 0, 0]]),
    ([0, 1, 2, 3.5, 4], [[1, 0, 0, 0], [0, 0, 1, 0], [1, 0, 0, 0], [0, 0, 1, 0], [0.5, 0.5, 0.5, 0.5]]),
    ([0, 0.5, 2, 3], [[1, 0, 0, 0], [0, 0, 0, -1], [-1, 0, 0, 0], [0, 0, 0.6, 0.8]]),
    ([0, 1, 2, 3], [[0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1], [1, 0, 0, 0]]),  # every step a half turn
    ([0, 1, 3], [[0.5, 0.5, 0.5, 0.5], [-0.5, 0.5, -0.5, 0.5], [0.5, 0.5, 0.5, 0.5]]),
]


@pytest.mark.parametrize("times, keys", TIE_KEYS)
def test_cubic_and_slerp_equal_scipy_at_half_turns(times, keys):
    """Keys a half turn apart (p·q = 0) follow scipy's tie rule (the relative rotation's
    canonical axis): issue 36 item 3, where "cubic" and "slerp" turned back."""
    from scipy.spatial.transform import Slerp

    keys = np.array(keys, float)
    nt = np.linspace(times[0], times[-1], 97)
    ref = scipy_spline(times, keys)
    got = qa.spline(times, keys, nt, method="cubic")
    assert np.abs(qa.distance(got, ref(nt).as_quat(scalar_first=True))).max() < 1e-10
    for order in (1, 2):
        np.testing.assert_allclose(qa.spline(times, keys, nt, method="cubic", order=order), ref(nt, order),
                                   rtol=0, atol=1e-10)
    slerp = Slerp(np.asarray(times, float), Rotation.from_quat(keys, scalar_first=True))(nt)
    got = qa.spline(times, keys, nt, method="slerp")
    assert np.abs(qa.distance(got, slerp.as_quat(scalar_first=True))).max() < 1e-10


@pytest.mark.parametrize("k", [2, 3, 4, 9, 300])
def test_cubic_fused_setup_equals_numpy_setup(rng, k, monkeypatch):
    """The set-up in kernels (many keys) and in numpy (fewer keys, no compiling) give the
    same coefficients and passes (within rounding), ties and tiny steps included."""
    keys = smooth_keys(rng, k, 0.4)
    if k > 4:
        keys[3] = qa.multiply(keys[2], [0.0, 0.0, 1.0, 0.0])  # a half turn
        keys[5] = keys[4]  # no turn
    keys = qa.unflip(keys)
    t = np.cumsum(rng.uniform(0.2, 2.0, k))
    coef = {}
    for name, keys_from in (("fused", 0), ("numpy", 10**9)):
        monkeypatch.setattr(_cubic, "FUSED_MIN_KEYS", keys_from)
        coef[name] = _cubic.coefficients(t, keys)
    assert coef["fused"][1] == coef["numpy"][1]
    np.testing.assert_allclose(coef["fused"][0], coef["numpy"][0], rtol=1e-13, atol=1e-13)
