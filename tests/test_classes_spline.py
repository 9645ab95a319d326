"""quatarray.Slerp, RotationSpline (against scipy 1.17's classes) and BezierSpline (against quatarray.spline)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
import scipy  # noqa: E402

if tuple(int(x) for x in scipy.__version__.split(".")[:2]) != (1, 17):  # the contract is scipy 1.17's API
    pytest.skip(f"the oracle is scipy 1.17's classes (the contract); scipy {scipy.__version__} here",
                allow_module_level=True)

from scipy.spatial.transform import Rotation as SR
from scipy.spatial.transform import RotationSpline as SRotationSpline
from scipy.spatial.transform import Slerp as SSlerp

import quatarray as qa
from quatarray import BezierSpline, Rotation, RotationSpline, Slerp, splines


def keys_and_times(rng, k, flips=True, uneven=True):
    """k random keys (house order) with random signs, strictly increasing uneven times."""
    keys = qa.random(k, rng)
    if flips:
        keys = keys * rng.choice([-1.0, 1.0], k)[:, None]
    times = np.cumsum(rng.uniform(0.1, 2.0, k)) - 3.0 if uneven else np.arange(float(k))
    return keys, times


def both(keys):
    """The same keys as a quatarray Rotation and a scipy Rotation."""
    return Rotation.from_wxyz(np.array(keys)), SR.from_quat(keys, scalar_first=True)


def samples(rng, times, m=300):
    """New times: every key time, both ends, and random ones, shuffled."""
    inside = rng.uniform(times[0], times[-1], m)
    return rng.permutation(np.concatenate([times, inside]))


def quat(r):
    return r.as_quat()  # scalar-last, as stored: signs compared too


# ---------------------------------------------------------------------------
# Slerp


@pytest.mark.parametrize("k", [2, 3, 40])
def test_slerp_matches_scipy(rng, k):
    keys, times = keys_and_times(rng, k)
    mine, ref = both(keys)
    new = samples(rng, times)
    got, want = Slerp(times, mine)(new), SSlerp(times, ref)(new)
    assert isinstance(got, Rotation) and got.shape == (len(new),) and not got.single
    np.testing.assert_allclose(quat(got), quat(want), rtol=0, atol=1e-12)  # signs as scipy's
    s = np.sort(new)
    np.testing.assert_allclose(quat(Slerp(times, mine)(s)), quat(SSlerp(times, ref)(s)), rtol=0, atol=1e-12)


def test_slerp_at_key_times_keeps_scipys_sign(rng):
    """scipy gives a key time t_n (n ≥ 1) as the end of segment n − 1: the key's
    quaternion negated when the step was flipped; t_0 as the first key itself."""
    keys = qa.from_rotvec([[0, 0, 0], [0, 0, 0.5], [0, 0, 1.0], [0, 0.3, 1.0]])
    keys[[1, 3]] *= -1
    mine, ref = both(keys)
    times = [0.0, 1.0, 2.0, 3.0]
    got = quat(Slerp(times, mine)(times))
    np.testing.assert_allclose(got, quat(SSlerp(times, ref)(times)), rtol=0, atol=1e-15)
    # every step here was flipped (keys 1 and 3 negated): each key time n ≥ 1 gives −key n
    np.testing.assert_allclose(got[1:], -mine.as_quat()[1:], rtol=0, atol=1e-15)
    assert np.array_equal(got[0], mine.as_quat()[0])


def test_slerp_scalar_empty_and_single_results(rng):
    keys, times = keys_and_times(rng, 5)
    mine, ref = both(keys)
    sl, ref_sl = Slerp(times, mine), SSlerp(times, ref)
    for t in (times[2], float(times[1] + 0.1), np.float64(times[0]), np.array(times[-1])):
        r = sl(t)
        assert r.single and r.shape == () and r.wxyz.shape == (4,)
        np.testing.assert_allclose(quat(r), quat(ref_sl(t)), rtol=0, atol=1e-12)
    one = sl([times[1]])
    assert not one.single and one.shape == (1,)
    empty = sl(np.array([]))
    assert empty.shape == (0,) and quat(empty).shape == (0, 4)
    assert Slerp(list(times), mine)(list(times[:2])).shape == (2,)  # lists


def test_slerp_integer_times_and_scipy_rotation_input(rng):
    keys, _ = keys_and_times(rng, 4)
    mine, ref = both(keys)
    times = np.array([0, 2, 3, 7])
    new = np.array([0, 1, 2, 5, 7])
    want = quat(SSlerp(times, ref)(new))
    np.testing.assert_allclose(quat(Slerp(times, mine)(new)), want, rtol=0, atol=1e-12)
    np.testing.assert_allclose(quat(Slerp(times, ref)(new)), want, rtol=0, atol=1e-12)  # a scipy Rotation too


def test_slerp_non_unit_keys_and_views(rng):
    keys, times = keys_and_times(rng, 6)
    big = np.zeros((12, 4))
    big[::2] = keys * rng.uniform(0.5, 3.0, 6)[:, None]  # non-unit, strided
    view = big[::2]
    view.flags.writeable = False
    new = samples(rng, times)
    got = Slerp(times, Rotation.from_wxyz(view))(new)
    want = SSlerp(times, SR.from_quat(view, scalar_first=True))(new)
    np.testing.assert_allclose(quat(got), quat(want), rtol=0, atol=1e-12)
    assert np.array_equal(big[::2], view) and not big[1::2].any()  # untouched


def test_slerp_float32(rng):
    keys, times = keys_and_times(rng, 20)
    k32 = keys.astype(np.float32)
    new = samples(rng, times)
    got = Slerp(times, Rotation.from_wxyz(k32))(new)
    assert got.wxyz.dtype == np.float32
    want = SSlerp(times, SR.from_quat(k32.astype(np.float64), scalar_first=True))(new)
    np.testing.assert_allclose(quat(got), quat(want), rtol=0, atol=3e-6)


# ---------------------------------------------------------------------------
# RotationSpline


@pytest.mark.parametrize("order", [0, 1, 2])
@pytest.mark.parametrize("k", [2, 3, 30])
def test_rotation_spline_matches_scipy(rng, k, order):
    keys, times = keys_and_times(rng, k)
    mine, ref = both(keys)
    new = samples(rng, times)
    got, want = RotationSpline(times, mine)(new, order), SRotationSpline(times, ref)(new, order)
    if order == 0:
        got, want = quat(got), quat(want)
    else:
        assert isinstance(got, np.ndarray) and got.shape == (len(new), 3)
    scale = max(1.0, np.abs(want).max())
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-10 * scale)


@pytest.mark.parametrize("order", [0, 1, 2])
def test_rotation_spline_extrapolates_as_scipy(rng, order):
    keys, times = keys_and_times(rng, 6)
    mine, ref = both(keys)
    new = np.array([times[0] - 1.5, times[0] - 1e-9, times[-1] + 1e-9, times[-1] + 0.7, times[-1] + 3.0])
    got, want = RotationSpline(times, mine)(new, order), SRotationSpline(times, ref)(new, order)
    if order == 0:
        got, want = quat(got), quat(want)
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-10)


def test_rotation_spline_scalar_empty_and_reuse(rng):
    keys, times = keys_and_times(rng, 5)
    mine, ref = both(keys)
    spl, ref_spl = RotationSpline(times, mine), SRotationSpline(times, ref)
    t = 0.5 * (times[1] + times[2])
    r = spl(t)
    assert r.single and r.wxyz.shape == (4,)
    np.testing.assert_allclose(quat(r), quat(ref_spl(t)), rtol=0, atol=1e-12)
    for order in (1, 2):
        v = spl(t, order)
        assert v.shape == (3,)
        np.testing.assert_allclose(v, ref_spl(t, order), rtol=0, atol=1e-10)
    assert spl(np.array([])).shape == (0,)
    assert spl([], 1).shape == (0, 3) and spl([], 2).shape == (0, 3)
    new = samples(rng, times)
    first = quat(spl(new))
    assert np.array_equal(first, quat(spl(new)))  # the plan is reused, not changed by a call


def test_rotation_spline_float32(rng):
    keys, times = keys_and_times(rng, 12)
    k32 = keys.astype(np.float32)
    spl = RotationSpline(times, Rotation.from_wxyz(k32))
    ref = SRotationSpline(times, SR.from_quat(k32.astype(np.float64), scalar_first=True))
    new = samples(rng, times)
    assert spl(new).wxyz.dtype == np.float32
    np.testing.assert_allclose(quat(spl(new)), quat(ref(new)), rtol=0, atol=1e-5)
    for order in (1, 2):
        got = spl(new, order)
        assert got.dtype == np.float32
        want = ref(new, order)
        np.testing.assert_allclose(got, want, rtol=0, atol=2e-5 * max(1.0, np.abs(want).max()))


def test_rotation_spline_non_finite_times(rng):
    keys, times = keys_and_times(rng, 4)
    mine, ref = both(keys)
    new = np.array([times[1], np.nan])
    with pytest.raises(ValueError):  # scipy: "Found zero norm quaternions", from the nan rotation
        SRotationSpline(times, ref)(new)
    with pytest.raises(ValueError, match=r"times\[1\] = nan"):
        RotationSpline(times, mine)(new)
    for order in (1, 2):  # rates: nan rows, as scipy's
        got, want = RotationSpline(times, mine)(new, order), SRotationSpline(times, ref)(new, order)
        assert np.isnan(got[1]).all() and np.isnan(want[1]).all()
        np.testing.assert_allclose(got[0], want[0], rtol=0, atol=1e-10)


# ---------------------------------------------------------------------------
# the half-turn tie: keys exactly 180° apart turn the way scipy turns


TIES = {
    "identity, 180 x, identity": [[1, 0, 0, 0], [0, 1, 0, 0], [1, 0, 0, 0]],
    "identity, -(180 x), identity": [[1, 0, 0, 0], [0, -1, 0, 0], [1, 0, 0, 0]],
    "identity, 180 x, -identity": [[1, 0, 0, 0], [0, 1, 0, 0], [-1, 0, 0, 0]],
    "half turns about x, y, z": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, -1], [0, 0, 1, 0], [-1, 0, 0, 0]],
    "tie then ordinary": [[1, 0, 0, 0], [0, 0, -1, 0], [0.5, 0.5, -0.5, 0.5], [0, 0, 0, 1]],
}


@pytest.mark.parametrize("keys", list(TIES.values()), ids=list(TIES))
def test_half_turn_ties_as_scipy(keys):
    keys = np.array(keys, float)
    mine, ref = both(keys)
    times = np.arange(len(keys), dtype=float)
    new = np.linspace(0.0, times[-1], 8 * len(keys) + 1)
    np.testing.assert_allclose(quat(Slerp(times, mine)(new)), quat(SSlerp(times, ref)(new)), rtol=0, atol=1e-12)
    for order in (0, 1, 2):
        got, want = RotationSpline(times, mine)(new, order), SRotationSpline(times, ref)(new, order)
        if order == 0:
            got, want = quat(got), quat(want)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-10)


def test_half_turn_tie_keeps_turning_one_way():
    """Identity → 180° about x → identity: scipy (and these classes) go on turning
    about +x (a full turn), where sign continuity alone would turn back."""
    keys = np.array([[1.0, 0, 0, 0], [0, 1, 0, 0], [1, 0, 0, 0]])
    new = np.linspace(0.0, 2.0, 9)
    for cls in (Slerp, RotationSpline):
        r = cls([0.0, 1.0, 2.0], Rotation.from_wxyz(keys))(new)
        turned = np.unwrap(2 * np.arctan2(r.wxyz[:, 1], r.wxyz[:, 0]))  # angle about x
        assert np.all(np.diff(turned) > 0), cls
        np.testing.assert_allclose(turned[-1], 2 * np.pi, atol=1e-12)
    rate = RotationSpline([0.0, 1.0, 2.0], Rotation.from_wxyz(keys))(new, 1)
    assert np.all(rate[:, 0] > 0)


# ---------------------------------------------------------------------------
# errors: scipy's types, messages that say the same


def _raised(f):
    try:
        f()
    except Exception as exc:  # noqa: BLE001 - compared below
        return exc
    raise AssertionError("no exception")


def _same_error(mine, theirs):
    a, b = _raised(mine), _raised(theirs)
    assert type(a) is type(b), (a, b)
    assert str(a).startswith(str(b)), (str(a), str(b))


BAD_TIMES = {
    "repeated": [0, 1, 1, 2],
    "decreasing": [3, 2, 1, 0],
    "2-D": [[0, 1, 2, 3]],
    "too few": [0, 1, 2],
    "too many": [0, 1, 2, 3, 4],
}


@pytest.mark.parametrize("times", list(BAD_TIMES.values()), ids=list(BAD_TIMES))
@pytest.mark.parametrize("pair", [(Slerp, SSlerp), (RotationSpline, SRotationSpline)], ids=["Slerp", "RotationSpline"])
def test_construction_errors_as_scipy(rng, pair, times):
    keys, _ = keys_and_times(rng, 4)
    mine, ref = both(keys)
    ours, theirs = pair
    _same_error(lambda: ours(times, mine), lambda: theirs(times, ref))


def test_increasing_error_names_the_pair(rng):
    keys, _ = keys_and_times(rng, 4)
    with pytest.raises(ValueError, match=r"Got times\[2\] = 1.0 after times\[1\] = 1.0"):
        Slerp([0, 1, 1, 2], Rotation.from_wxyz(keys))
    with pytest.raises(ValueError, match=r"strictly increasing.*times\[1\] = nan"):
        RotationSpline([0, np.nan, 1, 2], Rotation.from_wxyz(keys))


@pytest.mark.parametrize("pair", [(Slerp, SSlerp), (RotationSpline, SRotationSpline)], ids=["Slerp", "RotationSpline"])
def test_rotation_errors_as_scipy(pair):
    ours, theirs = pair
    q = qa.random(4, 0)
    for lead in [(), (1,), (0,), (2, 2)]:
        a = np.resize(q, lead + (4,))
        mine = Rotation.from_wxyz(a)
        ref = SR.from_quat(a.reshape(-1, 4)[:, [1, 2, 3, 0]].reshape(a.shape)) if a.size else SR.from_quat(
            np.zeros((0, 4)))
        times = np.arange(float(lead[0] if lead else 1))
        if lead == (0,) and ours is RotationSpline:
            with pytest.raises(ValueError, match="at least 2"):  # scipy fails later, on its empty arrays
                ours(times, mine)
            continue
        _same_error(lambda: ours(times, mine), lambda: theirs(times, ref))
    with pytest.raises(TypeError, match="must be a `Rotation` instance"):
        ours([0, 1], q[:2])


def test_call_errors_as_scipy(rng):
    keys, times = keys_and_times(rng, 4)
    mine, ref = both(keys)
    sl, ref_sl = Slerp(times, mine), SSlerp(times, ref)
    for t in ([[times[1]]], times[-1] + 1, times[0] - 1e-9, np.nan, [times[1], np.nan]):
        _same_error(lambda: sl(t), lambda: ref_sl(t))
    spl, ref_spl = RotationSpline(times, mine), SRotationSpline(times, ref)
    _same_error(lambda: spl([[times[1]]]), lambda: ref_spl([[times[1]]]))
    for order in (3, -1, "1"):
        _same_error(lambda: spl(times[1], order), lambda: ref_spl(times[1], order))


# ---------------------------------------------------------------------------
# property tests


@st.composite
def streams(draw):
    k = draw(st.integers(2, 7))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    keys = qa.random(k, rng) * rng.choice([-1.0, 1.0], k)[:, None]
    if draw(st.booleans()):  # a slow stream: small steps between keys
        keys = qa.unflip(qa.from_rotvec(np.cumsum(rng.normal(0, draw(st.floats(1e-6, 0.5)), (k, 3)), 0)))
        keys *= rng.choice([-1.0, 1.0], k)[:, None]
    steps = rng.uniform(draw(st.floats(1e-3, 1.0)), 2.0, k - 1)
    times = np.concatenate([[draw(st.floats(-1e3, 1e3))], steps]).cumsum()
    new = np.concatenate([rng.uniform(times[0], times[-1], draw(st.integers(0, 20))), times[rng.integers(0, k, 3)]])
    return keys, times, new


@settings(max_examples=60, deadline=None)
@given(streams())
def test_property_slerp_and_rotation_spline_are_scipys(stream):
    keys, times, new = stream
    mine, ref = both(keys)
    np.testing.assert_allclose(quat(Slerp(times, mine)(new)), quat(SSlerp(times, ref)(new)), rtol=0, atol=1e-10)
    spl, ref_spl = RotationSpline(times, mine), SRotationSpline(times, ref)
    np.testing.assert_allclose(quat(spl(new)), quat(ref_spl(new)), rtol=0, atol=1e-10)
    for order in (1, 2):
        want = ref_spl(new, order)
        np.testing.assert_allclose(spl(new, order), want, rtol=0, atol=1e-10 * max(1.0, np.abs(want).max()))


# ---------------------------------------------------------------------------
# BezierSpline: quatarray.spline behind RotationSpline's call interface


METHODS = ["bezier", "squad", "slerp", "nlerp", "cubic"]


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_bezier_spline_is_the_functional_spline(rng, method, dtype):
    keys, times = keys_and_times(rng, 9)
    keys = (keys * 1.01).astype(dtype)  # flips and non-unit: normalised and unflipped as spline does
    spl = BezierSpline(times, Rotation.from_wxyz(keys), method=method)
    new = samples(rng, times)
    for t in (new, np.sort(new), new[:12].reshape(3, 4), times[3]):
        for order in (0, 1, 2):
            want = qa.spline(times, keys, t, method=method, order=order)
            got = spl(t, order)
            if order == 0:
                assert isinstance(got, Rotation) and got.shape == np.shape(t) and got.single == (np.ndim(t) == 0)
                got = got.wxyz
            assert got.dtype == dtype and got.shape == want.shape
            np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("method", ["bezier", "slerp"])
def test_bezier_spline_many_keys_sorted(rng, method):
    """Enough keys for the functional spline's piece kernels (sorted new times)."""
    k = splines.PIECES_MIN_KEYS + 5
    keys = qa.unflip(qa.from_rotvec(np.cumsum(rng.normal(0, 0.1, (k, 3)), 0)))
    times = np.cumsum(rng.uniform(0.5, 1.5, k))
    new = np.linspace(times[0], times[-1], 3 * k)
    got = BezierSpline(times, keys, method=method)(new).wxyz
    np.testing.assert_array_equal(got, qa.spline(times, keys, new, method=method))


def test_bezier_spline_inputs_and_errors(rng):
    keys, _ = keys_and_times(rng, 4)
    ns = np.array([0, 10**9, 3 * 10**9, 4 * 10**9], np.int64) + 1_700_000_000 * 10**9  # ns stamps, exact
    new = ns[:1] + np.array([5 * 10**8, 2 * 10**9], np.int64)
    want = qa.spline(ns, keys, new)
    np.testing.assert_array_equal(BezierSpline(ns, keys)(new).wxyz, want)
    np.testing.assert_array_equal(BezierSpline(ns, SR.from_quat(keys, scalar_first=True))(new).wxyz, want)
    np.testing.assert_allclose(BezierSpline([0, 1, 3, 4], keys, method="cubic")([0.5, 2.0]).wxyz,
                               qa.spline([0, 1, 3, 4], keys, [0.5, 2.0], method="cubic"), rtol=0, atol=0)
    spl = BezierSpline([0, 1, 3, 4], keys)
    with pytest.raises(ValueError, match=r"Expected `new_times` within \[0, 4\].*got 4.5 at flat index 1"):
        spl([1.0, 4.5])
    with pytest.raises(ValueError, match="order"):
        spl(1.0, order=3)
    with pytest.raises(ValueError, match="method"):
        BezierSpline([0, 1, 3, 4], keys, method="hermite")
    with pytest.raises(ValueError, match="strictly increasing"):
        BezierSpline([0, 1, 1, 4], keys)
    with pytest.raises(ValueError, match="at least 2"):
        BezierSpline([0], keys[:1])
    with pytest.raises(ValueError, match="sequence of rotations"):
        BezierSpline([0], Rotation.from_wxyz(keys[0]))
    with pytest.raises(ValueError, match=r"shape \(\.\.\., 4\)"):
        BezierSpline([0, 1], keys[:2, :3])


def test_bezier_spline_cubic_is_rotation_spline_on_continuous_keys(rng):
    """On keys without sign flips or half-turn steps the "cubic" curve is scipy's."""
    k = 12
    keys = qa.unflip(qa.from_rotvec(np.cumsum(rng.normal(0, 0.4, (k, 3)), 0)))
    times = np.cumsum(rng.uniform(0.2, 1.0, k))
    new = samples(rng, times)
    for order in (0, 1, 2):
        got = BezierSpline(times, Rotation.from_wxyz(keys), method="cubic")(new, order)
        want = RotationSpline(times, Rotation.from_wxyz(keys))(new, order)
        if order == 0:
            got, want = got.wxyz, want.wxyz
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * max(1.0, np.abs(want).max()))


@pytest.mark.parametrize("cls", [Slerp, RotationSpline, BezierSpline])
def test_pickle_and_copy(rng, cls):
    import copy
    import pickle

    keys, times = keys_and_times(rng, 5)
    spl = cls(times, Rotation.from_wxyz(keys))
    new = samples(rng, times)
    for other in (pickle.loads(pickle.dumps(spl)), copy.deepcopy(spl), copy.copy(spl)):
        assert np.array_equal(other(new).wxyz, spl(new).wxyz)


@pytest.mark.parametrize("method", ["bezier", "cubic"])
def test_parallel_loops(rng, method):
    """The parallel variants of the evaluation loops (long calls take them) give the same numbers."""
    from quatarray import _jit

    keys, times = keys_and_times(rng, 200)
    mine, ref = both(keys)
    new = samples(rng, times, 20000)
    with _jit.variant("parallel"):
        sl, spl, bz = Slerp(times, mine)(new), RotationSpline(times, mine), BezierSpline(times, mine, method=method)
        np.testing.assert_allclose(quat(sl), quat(SSlerp(times, ref)(new)), rtol=0, atol=1e-12)
        for order in (0, 1, 2):
            got, want = spl(new, order), SRotationSpline(times, ref)(new, order)
            if order == 0:
                got, want = quat(got), quat(want)
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-10 * max(1.0, np.abs(want).max()))
            got = bz(new, order)
            np.testing.assert_array_equal(got.wxyz if order == 0 else got,
                                          qa.spline(times, keys, new, method=method, order=order))
