"""Euler angles against scipy's Rotation.as_euler / from_euler (the oracle)."""

import os
import re
import warnings

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation as R

import quatarray as qa
from quatarray import _trig, euler

TAIT_BRYAN = ["xyz", "xzy", "yxz", "yzx", "zxy", "zyx"]
PROPER = ["xyx", "xzx", "yxy", "yzy", "zxz", "zyz"]
EXTRINSIC = TAIT_BRYAN + PROPER
SEQS = EXTRINSIC + [s.upper() for s in EXTRINSIC]


def angdiff(a, b):
    """|a − b| modulo 2π (π and −π are the same angle)."""
    d = np.asarray(a, np.float64) - np.asarray(b, np.float64)
    return np.abs((d + np.pi) % (2 * np.pi) - np.pi)


def scipy_euler(q, seq, degrees=False):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return R.from_quat(np.asarray(q, np.float64), scalar_first=True).as_euler(seq, degrees=degrees)


def scipy_quat(seq, angles, degrees=False):
    return R.from_euler(seq, np.asarray(angles, np.float64), degrees=degrees).as_quat(scalar_first=True)


def is_proper(seq):
    return seq[0].lower() == seq[2].lower()


@pytest.fixture(scope="module")
def quats():
    q = qa.random(2000, rng=7)
    return np.concatenate([q, -q[:200]])  # both signs


# --------------------------------------------------------------------------
# as_euler


@pytest.mark.parametrize("seq", SEQS)
def test_as_euler_matches_scipy_float64(quats, seq):
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)  # random rotations are not at gimbal lock
        got = qa.as_euler(quats, seq)
    ref = scipy_euler(quats, seq)
    assert got.shape == (len(quats), 3) and got.dtype == np.float64
    assert angdiff(got, ref).max() < 1e-13
    # scipy's ranges: first/third in [-π, π], second in [-π/2, π/2] or [0, π]
    assert np.all(np.abs(got) <= np.pi)
    lo, hi = (0, np.pi) if is_proper(seq) else (-np.pi / 2, np.pi / 2)
    assert np.all((got[:, 1] >= lo) & (got[:, 1] <= hi))


@pytest.mark.parametrize("seq", ["xyz", "ZYX", "zxz", "YZY"])
def test_as_euler_float32(quats, seq):
    q32 = quats.astype(np.float32)
    got = qa.as_euler(q32, seq)
    assert got.dtype == np.float32
    ref = scipy_euler(q32, seq)
    # the middle angle is well conditioned; first and third lose ~eps/sin(middle)
    assert angdiff(got[:, 1], ref[:, 1]).max() < 2e-6
    far = np.abs(np.sin(ref[:, 1] + (0 if is_proper(seq) else np.pi / 2))) > 0.05
    assert angdiff(got[far], ref[far]).max() < 5e-5
    # every row still describes the same rotation
    back = qa.from_euler(seq, got.astype(np.float64))
    assert qa.distance(back, q32.astype(np.float64)).max() < 1e-5


@pytest.mark.skipif(os.environ.get("NUMBA_DISABLE_JIT") == "1", reason="inspects compiled signatures")
def test_kernels_stay_float32():
    qa.as_euler(np.ones((3, 4), np.float32), "xyz")
    qa.from_euler("xyz", np.ones((3, 3), np.float32))
    for k in (euler._as_euler.serial, euler._from_euler.serial):
        sigs = [getattr(s.args[0], "types", s.args) for s in k.nopython_signatures]
        sigs = [s for s in sigs if s[0].dtype.name == "float32"]
        assert sigs
        for s in sigs:  # every float array argument (input and output) is float32
            arrays = [a for a in s if hasattr(a, "ndim") and "float" in a.dtype.name]
            assert len(arrays) == 2 and all(a.dtype.name == "float32" for a in arrays)


@pytest.mark.needs_simd
@pytest.mark.skipif(os.environ.get("NUMBA_DISABLE_JIT") == "1", reason="inspects compiled code")
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_as_euler_loop_vectorises(dtype):
    """The angles go through a block of planes, not straight into the rows of the
    result: with those stride-3 stores in the loop, LLVM judged it not worth
    vectorising on AVX2 CPUs (Zen 3: 11 against 45 Mq/s in float64)."""
    import numba

    qa.as_euler(np.ones((3, 4), dtype), "xyz")
    sig = next(s for s in euler._as_euler.serial.signatures if s[0].dtype.name == dtype)
    fresh = numba.njit(cache=False, error_model="numpy")(euler._as_euler.py_func)  # cached code has no IR to see
    fresh.compile(sig)
    llvm = fresh.inspect_llvm(sig)
    ftype = "double" if dtype == "float64" else "float"
    assert re.search(rf"= fmul (?:\w+ )*<\d+ x {ftype}>", llvm), "the as_euler loop did not vectorise"


def gimbal_angles(seq, n, rng):
    """Rotations whose middle angle is singular: ±90° (Tait–Bryan), 0/180° (proper)."""
    a = rng.uniform(-np.pi, np.pi, (n, 3))
    choice = rng.random(n) < 0.5
    if is_proper(seq):
        a[:, 1] = np.where(choice, 0.0, np.pi)
    else:
        a[:, 1] = np.where(choice, np.pi / 2, -np.pi / 2)
    return a


@pytest.mark.parametrize("seq", SEQS)
def test_gimbal_lock_matches_scipy(seq):
    rng = np.random.default_rng(SEQS.index(seq))  # deterministic (str hashes are salted)
    q = scipy_quat(seq, gimbal_angles(seq, 50, rng))
    q = np.concatenate([q, qa.random(5, rng=1)])  # some regular rows too
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        got = qa.as_euler(q, seq)
    gimbal = [x for x in w if issubclass(x.category, UserWarning)]
    assert len(gimbal) == 1 and "Gimbal lock" in str(gimbal[0].message)
    assert "50 of 55" in str(gimbal[0].message)
    assert gimbal[0].filename == __file__  # stacklevel points at the caller
    ref = scipy_euler(q, seq)
    assert angdiff(got, ref).max() < 1e-12
    assert np.all(got[:50, 2] == 0)  # scipy's rule: the third angle of `seq` set to zero
    assert qa.distance(qa.from_euler(seq, got), q).max() < 1e-12


@pytest.mark.parametrize("seq", ["zxz", "XYZ"])
def test_gimbal_threshold_is_scipys(seq):
    # the second angle within 1e-7 of its singular value locks, 1e-6 away does not
    base = 0.0 if is_proper(seq) else np.pi / 2
    a = np.array([[0.3, base + 0.4e-7, -0.7], [0.3, base + 1e-6, -0.7], [0.3, base - 0.4e-7, -0.7]])
    q = scipy_quat(seq, a)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        got = qa.as_euler(q, seq)
    w = [x for x in w if issubclass(x.category, UserWarning)]
    assert len(w) == 1 and "2 of 3" in str(w[0].message)
    assert angdiff(got, scipy_euler(q, seq)).max() < 1e-9


def test_suppress_warnings_and_no_warning_when_regular():
    q = scipy_quat("zxz", [[0.1, 0.0, 0.2], [0.3, np.pi, 0.1]])
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        got = qa.as_euler(q, "zxz", suppress_warnings=True)
        qa.as_euler(qa.random(100, rng=3), "xyz")
    assert np.allclose(got, scipy_euler(q, "zxz"))
    with pytest.warns(UserWarning, match="Gimbal lock"):
        qa.as_euler(q, "zxz")


def test_float32_gimbal_exact_quaternions():
    # (c, 0, 0, s) is a pure z rotation: zxz with middle angle 0, exactly in float32
    t = np.linspace(-3, 3, 7)
    q = np.stack([np.cos(t / 2), 0 * t, 0 * t, np.sin(t / 2)], axis=1).astype(np.float32)
    with pytest.warns(UserWarning, match="7 of 7"):
        got = qa.as_euler(q, "zxz")
    assert got.dtype == np.float32
    assert angdiff(got, scipy_euler(q, "zxz")).max() < 1e-6
    assert np.all(got[:, 1:] == 0)


def test_identity():
    q = qa.identity(3)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        for seq in TAIT_BRYAN + ["ZYX"]:
            assert np.array_equal(qa.as_euler(q, seq), np.zeros((3, 3)))
    # a proper Euler sequence is at gimbal lock at the identity (middle angle 0), as in scipy
    with pytest.warns(UserWarning):
        assert np.array_equal(qa.as_euler(q, "zxz"), np.zeros((3, 3)))
    for seq in ["xyz", "ZXZ"]:
        assert np.array_equal(qa.from_euler(seq, np.zeros(3)), [1, 0, 0, 0])


def test_sign_and_scale_invariance(quats):
    q = quats[:500]
    for seq in ["xyz", "ZYZ", "yxy", "ZXY"]:
        a = qa.as_euler(q, seq)
        assert angdiff(qa.as_euler(-q, seq), a).max() < 1e-13
        assert angdiff(qa.as_euler(3.7 * q, seq), a).max() < 1e-13
        assert angdiff(qa.as_euler(1e-100 * q, seq), a).max() < 1e-13


def test_degrees(quats):
    for seq in ["zyx", "XZX"]:
        rad = qa.as_euler(quats, seq)
        deg = qa.as_euler(quats, seq, degrees=True)
        assert np.array_equal(deg, np.rad2deg(rad))
        assert np.abs(deg - scipy_euler(quats, seq, degrees=True)).max() < 1e-10
        back = qa.from_euler(seq, deg, degrees=True)
        assert qa.distance(back, quats).max() < 1e-12
        assert np.abs(back - scipy_quat(seq, deg, degrees=True)).max() < 1e-15


def test_nan_zero_and_inf():
    q = np.array([[1, 0, 0, 0], [np.nan, 0, 0, 0], [0, 0, 0, 0], [0.5, np.inf, 0, 0], [0, 0, 0, 1]])
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)  # degenerate rows are not "gimbal lock"
        got = qa.as_euler(q, "xyz")
    assert np.all(np.isnan(got[1:4]))
    assert np.array_equal(got[0], [0, 0, 0])
    assert np.allclose(got[4], scipy_euler(q[4], "xyz"))
    a = np.array([[0.1, np.nan, 0.2], [0.1, 0.2, 0.3], [np.inf, 0, 0]])
    out = qa.from_euler("XYZ", a)
    assert np.all(np.isnan(out[[0, 2]]))
    assert np.allclose(out[1], scipy_quat("XYZ", a[1]))


def test_shapes_and_broadcasting():
    q = qa.random((2, 3), rng=1)
    got = qa.as_euler(q, "xyz")
    assert got.shape == (2, 3, 3)
    assert np.allclose(got.reshape(-1, 3), qa.as_euler(q.reshape(-1, 4), "xyz"))
    assert qa.as_euler(q[0, 0], "xyz").shape == (3,)
    assert qa.as_euler(np.empty((0, 4)), "xyz").shape == (0, 3)
    assert qa.from_euler("xyz", [0.1, 0.2, 0.3]).shape == (4,)
    a = np.random.default_rng(0).uniform(-3, 3, (2, 5, 3))
    out = qa.from_euler("ZXZ", a)
    assert out.shape == (2, 5, 4)
    assert np.allclose(out.reshape(-1, 4), scipy_quat("ZXZ", a.reshape(-1, 3)))
    assert qa.from_euler("xyz", np.empty((0, 3))).shape == (0, 4)
    # lists and integers become float64
    assert qa.from_euler("xyz", [[0, 0, 1]]).dtype == np.float64
    assert qa.as_euler([[1, 0, 0, 0]], "xyz").dtype == np.float64


def test_strided_and_read_only_inputs():
    q = qa.random(200, rng=2)
    view = np.asfortranarray(q)[::2]
    view.flags.writeable = False
    before = view.copy()
    assert np.allclose(qa.as_euler(view, "yzx"), scipy_euler(before, "yzx"))
    assert np.array_equal(view, before)
    ro = q.copy()
    ro.flags.writeable = False  # contiguous and read-only: used in place
    assert np.array_equal(qa.as_euler(ro, "XYX"), qa.as_euler(q, "XYX"))
    a = np.random.default_rng(1).uniform(-3, 3, (3, 400)).T[::3]
    a.flags.writeable = False
    assert np.allclose(qa.from_euler("yzx", a), scipy_quat("yzx", a))
    c = np.ascontiguousarray(a)
    c.flags.writeable = False
    assert np.array_equal(qa.from_euler("yzx", c), qa.from_euler("yzx", a))


def test_bad_seq():
    for bad in ["xyzx", "xy", "xxy", "xyy", "xYz", "abc", "", "XxZ"]:
        with pytest.raises(ValueError, match="Expected `seq`.*'xyz'.*'zxz'"):
            qa.as_euler([1, 0, 0, 0], bad)
        if bad != "xy":  # a valid two-axis sequence for from_euler (scipy)
            with pytest.raises(ValueError, match="Expected `seq`"):
                qa.from_euler(bad, [0, 0, 0])
    with pytest.raises(TypeError, match="Expected `seq`"):
        qa.from_euler(None, [0, 0, 0])


def test_bad_shapes_and_dtypes():
    with pytest.raises(ValueError, match=r"Expected `q` to have shape \(\.\.\., 4\), got \(10, 3\)\."):
        qa.as_euler(np.zeros((10, 3)), "xyz")
    with pytest.raises(ValueError, match=r"Expected `angles` to have shape \(\.\.\., 3\), got \(10, 2\)\."):
        qa.from_euler("xyz", np.zeros((10, 2)))
    with pytest.raises(ValueError, match=r"Expected `angles` to have shape \(\.\.\., 3\), got \(\)\."):
        qa.from_euler("xyz", 0.5)
    with pytest.raises(TypeError, match="`q`"):
        qa.as_euler(np.zeros((2, 4), complex), "xyz")
    with pytest.raises(TypeError, match="`angles`"):
        qa.from_euler("xyz", np.zeros(3, complex))


# --------------------------------------------------------------------------
# from_euler


@pytest.mark.parametrize("seq", SEQS)
def test_from_euler_matches_scipy(seq):
    rng = np.random.default_rng(len(seq) + sum(map(ord, seq)))
    a = rng.uniform(-2 * np.pi, 2 * np.pi, (1000, 3))
    a[:10] *= 100  # larger angles still in the fast range
    ref = scipy_quat(seq, a)
    got = qa.from_euler(seq, a)
    assert got.dtype == np.float64
    assert np.abs(got - ref).max() < 1e-14  # same formula, same sign as scipy
    got32 = qa.from_euler(seq, a.astype(np.float32))
    assert got32.dtype == np.float32
    assert np.abs(got32 - scipy_quat(seq, a.astype(np.float32))).max() < 2e-6


def test_from_euler_huge_angles_use_libm():
    a = np.array([[1e7, 0.5, -3e8], [1e5, -2e5, 7e5], [0.1, 0.2, 1e300]])
    assert np.abs(qa.from_euler("zyx", a) - scipy_quat("zyx", a)).max() < 1e-9
    a32 = np.array([[3e4, 0.5, -1e5], [0.1, 0.2, 0.3]], np.float32)
    assert np.abs(qa.from_euler("ZYX", a32) - scipy_quat("ZYX", a32)).max() < 1e-6


def test_from_euler_float32_around_the_fast_range():
    # float32 half angles beyond _trig.SINCOS_LIMIT_32 are redone with libm
    lim = 2 * _trig.SINCOS_LIMIT_32
    a = (np.linspace(-8 * lim, 8 * lim, 401)[:, None] * [1.0, 0.5, -0.7]).astype(np.float32)
    a[::7] = np.float32(lim) * np.array([1, -1, 1], np.float32)  # exactly at the limit
    got = qa.from_euler("zyx", a)
    assert got.dtype == np.float32
    assert np.abs(got - scipy_quat("zyx", a)).max() < 3e-7


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda v: np.linalg.norm(v) > 1e-3),
    st.sampled_from(SEQS),
)
@example([-2.5050760253406863e-08, 0.0, 0.75, 0.0], "XYX")  # 6.7e-8 rad short of β = π: error 1.34e-7
def test_round_trip(v, seq):
    q = np.array(v)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        a = qa.as_euler(q, seq)
    # at gimbal lock (middle angle within δ <= 1e-7 of singular) setting the third
    # angle to 0 moves the rotation by up to 2δ (test_lock_error_bound)
    tol = 2.05e-7 if any(issubclass(x.category, UserWarning) for x in w) else 1e-12
    assert float(qa.distance(qa.from_euler(seq, a), q)) < tol
    # and from_euler → as_euler reproduces the rotation of the angles
    back = qa.from_euler(seq, qa.as_euler(qa.from_euler(seq, a), seq, suppress_warnings=True))
    assert float(qa.distance(back, q)) < 2 * tol


@pytest.mark.parametrize("seq", ["XYX", "zyz", "xyz", "ZYX"])
def test_lock_error_bound(seq, rng):
    # X(α) Y(π - δ) X(γ) read back with γ = 0 differs from the input by the
    # commutator of Y(δ) and X(γ): 2δ·|sin(γ/2)|, up to 2δ at γ = ±π
    n = 10000
    a = rng.uniform(-np.pi, np.pi, (n, 3))
    proper = seq[0].lower() == seq[2].lower()
    sing = rng.choice([0.0, np.pi] if proper else [-np.pi / 2, np.pi / 2], n)
    delta = rng.uniform(-1e-7, 1e-7, n)
    a[:, 1] = sing + delta
    q = qa.from_euler(seq, a)
    b = qa.as_euler(q, seq, suppress_warnings=True)
    err = qa.distance(qa.from_euler(seq, b), q)
    locked = b[:, 2] == 0
    assert locked.mean() > 0.9
    assert err.max() < 2.05e-7
    assert err.max() > 1.9e-7  # the bound is sharp: the docstring's 2e-7 is not loose


# --------------------------------------------------------------------------
# the vectorisable elementary functions


def ulps(got, ref):
    return np.abs(got - ref) / np.spacing(np.maximum(np.abs(ref), np.finfo(np.float64).tiny))


@pytest.fixture(scope="module")
def loops():
    """Loops over quatarray._trig's atan2 and sincos (the ones the euler kernels use),
    compiled as the kernels are (numpy's error model: 0/0 is nan, not an exception)."""
    from numba import njit

    @njit(error_model="numpy")
    def atan2_loop(y, x, out):
        for i in range(y.shape[0]):
            out[i] = _trig.atan2(y[i], x[i])

    @njit(error_model="numpy")
    def sincos_loop(x, s, c):
        for i in range(x.shape[0]):
            s[i], c[i] = _trig.sincos(x[i])

    return atan2_loop, sincos_loop


def test_atan2_within_2_ulp(loops):
    rng = np.random.default_rng(3)
    n = 20000
    y = rng.standard_normal(n) * np.exp(rng.uniform(-40, 40, n))
    x = rng.standard_normal(n) * np.exp(rng.uniform(-40, 40, n))
    out = np.empty(n)
    loops[0](y, x, out)
    assert ulps(out, np.arctan2(y, x)).max() <= 2
    s = np.array([0.0, -0.0, 1.0, -1.0, np.inf, -np.inf, np.nan])
    yy, xx = np.meshgrid(s, s)
    out = np.empty(yy.size)
    loops[0](yy.ravel(), xx.ravel(), out)
    ref = np.arctan2(yy.ravel(), xx.ravel())
    both_inf = np.isinf(yy.ravel()) & np.isinf(xx.ravel())
    ok = ~both_inf
    np.testing.assert_array_equal(out[ok], ref[ok])  # also the signs of zeros and ±π
    num = ok & ~np.isnan(ref)
    assert np.array_equal(np.signbit(out[num]), np.signbit(ref[num]))
    assert np.all(np.isnan(out[both_inf]))  # documented: atan2(±inf, ±inf) is nan
    out32 = np.empty(n, np.float32)
    loops[0](y.astype(np.float32), x.astype(np.float32), out32)
    assert np.abs(out32 - np.arctan2(y.astype(np.float32), x.astype(np.float32))).max() < 5e-7


def test_sincos_accuracy(loops):
    rng = np.random.default_rng(4)
    x = np.concatenate([rng.uniform(-10, 10, 10000), rng.uniform(-1e6, 1e6, 10000), [0.0, -0.0, 1e-300]])
    x = np.concatenate([x, np.arange(-20, 21) * (np.pi / 2)])
    s, c = np.empty_like(x), np.empty_like(x)
    loops[1](x, s, c)
    assert np.abs(s - np.sin(x)).max() < 3e-16
    assert np.abs(c - np.cos(x)).max() < 3e-16
    small = np.abs(x) < 1
    assert ulps(s[small], np.sin(x[small])).max() <= 2
    assert np.array_equal(np.signbit(s[:10002][x[:10002] == 0]), np.signbit(x[:10002][x[:10002] == 0]))
    # float32 within the range where the kernels trust it (beyond it they use libm)
    lim = _trig.SINCOS_LIMIT_32
    x32 = rng.uniform(-lim, lim, 10000).astype(np.float32)
    s32, c32 = np.empty_like(x32), np.empty_like(x32)
    loops[1](x32, s32, c32)
    assert np.abs(s32 - np.sin(x32.astype(np.float64))).max() < 2e-7
    assert np.abs(c32 - np.cos(x32.astype(np.float64))).max() < 2e-7


@pytest.mark.parametrize("seq", ["x", "Y", "z", "xy", "XZ", "yx", "ZY", "zx", "YX"])
def test_from_euler_one_two_axes_vs_scipy(seq):
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(len(seq) + ord(seq[0]))
    ang = rng.uniform(-4, 4, (50, len(seq)))
    want = Rotation.from_euler(seq, ang).as_quat(scalar_first=True)
    np.testing.assert_allclose(qa.from_euler(seq, ang), want, atol=1e-15)
    np.testing.assert_allclose(qa.from_euler(seq, np.rad2deg(ang), degrees=True), want, atol=1e-14)
    got32 = qa.from_euler(seq, ang.astype(np.float32))
    assert got32.dtype == np.float32 and np.allclose(got32, want, atol=1e-6)
    assert qa.from_euler(seq, ang.reshape(5, 10, -1)).shape == (5, 10, 4)
    np.testing.assert_allclose(qa.from_euler(seq, ang[0]), want[0], atol=1e-15)
    with pytest.raises(ValueError, match=rf"\(\.\.\., {len(seq)}\)"):
        qa.from_euler(seq, np.zeros((2, len(seq) + 1)))


def test_euler_short_sequences_rules():
    from scipy.spatial.transform import Rotation

    np.testing.assert_allclose(qa.from_euler("x", 0.3), Rotation.from_euler("x", 0.3).as_quat(scalar_first=True))
    for bad in ["xx", "xY", "", "xyzx", "w"]:
        with pytest.raises(ValueError):
            qa.from_euler(bad, np.zeros(max(len(bad), 1)))
    with pytest.raises(ValueError):
        qa.from_euler("xy", 0.3)  # two axes need two angles, as scipy
    for seq in ["x", "xy", "ZX"]:
        with pytest.raises(ValueError, match="three axes"):  # scipy's as_euler: three axes only
            qa.as_euler([1, 0, 0, 0], seq)


@settings(max_examples=200, deadline=None)
@given(st.sampled_from([s[:k] for s in SEQS for k in (1, 2)]),
       st.lists(st.floats(-10, 10, allow_nan=False), min_size=2, max_size=2))
def test_one_two_axes_are_products_of_elementary_turns(seq, angles):
    # extrinsic: the later turns act on the left; intrinsic: on the right (as scipy)
    turns = [qa.from_rotvec(np.eye(3)["xyz".index(c.lower())] * t) for c, t in zip(seq, angles)]
    want = turns[0]
    for t in turns[1:]:
        want = qa.multiply(want, t) if seq.isupper() else qa.multiply(t, want)
    got = qa.from_euler(seq, angles[: len(seq)])
    assert qa.distance(got, want) < 1e-12
    want = R.from_euler(seq, angles[: len(seq)]).as_quat(scalar_first=True)
    if len(seq) == 1 and want.shape == (1, 4):
        want = want[0]  # an older scipy (1.14, 1.15): one axis, its angle in a list, give a stack of one
    np.testing.assert_allclose(got, want, atol=1e-14)
