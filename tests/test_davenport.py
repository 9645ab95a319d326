"""quatarray.from_davenport / as_davenport against scipy's Rotation (the oracle)."""

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import quatarray as qa


def axes_set(rng, symmetric=False):
    a = rng.standard_normal(3)
    b = np.cross(a, rng.standard_normal(3))
    c = a.copy() if symmetric else np.cross(b, rng.standard_normal(3))
    return np.array([a, b, c]) * rng.uniform(0.5, 3, (3, 1))  # any lengths: normalised


def xyzw(q):
    return qa.as_xyzw(q)


@pytest.mark.parametrize("order", ["e", "i", "extrinsic", "intrinsic"])
def test_from_davenport_matches_scipy(order):
    rng = np.random.default_rng(0)
    for sym in (False, True):
        axes = axes_set(rng, sym)
        ang = rng.uniform(-7, 7, (40, 3))
        want = Rotation.from_davenport(axes, order, ang).as_quat()
        assert np.allclose(xyzw(qa.from_davenport(axes, order, ang)), want, rtol=0, atol=1e-13)
        deg = np.rad2deg(ang)
        got = qa.from_davenport(axes, order, deg, degrees=True)
        assert np.allclose(xyzw(got), Rotation.from_davenport(axes, order, deg, degrees=True).as_quat(), atol=1e-13)


@pytest.mark.parametrize("order", ["e", "i"])
def test_as_davenport_matches_scipy(order):
    rng = np.random.default_rng(1)
    for _ in range(10):
        axes = axes_set(rng)
        q = qa.random(50, rng=rng)
        want = Rotation.from_quat(xyzw(q)).as_davenport(axes, order)
        assert np.allclose(qa.as_davenport(q, axes, order), want, rtol=0, atol=1e-12)
        assert np.allclose(qa.as_davenport(3 * q, axes, order, degrees=True), np.rad2deg(want), atol=1e-10)


def test_symmetric_axes_give_the_euler_set():
    # first axis = third: the set with the middle angle in [0, π] (that of as_euler)
    q = qa.random(30, rng=2)
    got = qa.as_davenport(q, np.eye(3)[[2, 0, 2]], "e")
    assert np.allclose(got, qa.as_euler(q, "zxz"), atol=1e-12)
    rng = np.random.default_rng(3)
    axes = axes_set(rng, True)
    ang = qa.as_davenport(q, axes, "i")
    assert np.all(ang[:, 1] >= 0)
    assert np.all(qa.distance(qa.from_davenport(axes, "i", ang), q) < 1e-12)


def test_fewer_axes_and_shapes():
    axes = np.eye(3)[[2, 0]]
    for k in (1, 2):
        ang = np.full((4, k), 0.3)
        got = qa.from_davenport(axes[:k], "i", ang)
        assert got.shape == (4, 4)
        assert np.allclose(xyzw(got), Rotation.from_davenport(axes[:k], "i", ang).as_quat(), atol=1e-15)
    assert qa.from_davenport([0, 0, 1], "e", 0.5).shape == (4,)
    # axes per row broadcast against the angles
    rng = np.random.default_rng(4)
    many = np.stack([axes_set(rng) for _ in range(5)])
    ang = rng.uniform(-3, 3, (5, 3))
    got = qa.from_davenport(many, "e", ang)
    for i in range(5):
        assert np.allclose(got[i], qa.from_davenport(many[i], "e", ang[i]), atol=1e-15)
    back = qa.as_davenport(got, many, "e")  # the angles in as_davenport's ranges: the same rotations
    assert np.all(qa.distance(qa.from_davenport(many, "e", back), got) < 1e-12)
    assert qa.from_davenport(np.eye(3), "e", np.zeros((0, 3))).shape == (0, 4)
    assert qa.as_davenport(np.zeros((0, 4)), np.eye(3), "e").shape == (0, 3)


def test_float32_stays_float32():
    ax = np.eye(3, dtype=np.float32)[[0, 1, 2]]
    ang = np.float32([[0.1, 0.2, 0.3]])
    q = qa.from_davenport(ax, "e", ang)
    assert q.dtype == np.float32
    back = qa.as_davenport(q, ax, "e")
    assert back.dtype == np.float32 and np.allclose(back, ang, atol=1e-6)


def test_gimbal_lock_warns_once_and_sets_third_angle_zero():
    ax = np.eye(3)[[2, 1, 2]]
    q = qa.from_davenport(ax, "e", [[0.3, 0.0, 0.2], [0.1, np.pi, 0.4], [0.1, 0.2, 0.3]])
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        got = qa.as_davenport(q, ax, "e")
    assert len(w) == 1 and "2 of 3" in str(w[0].message)
    assert got[0, 2] == 0 and got[1, 2] == 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        want = Rotation.from_quat(xyzw(q)).as_davenport(ax, "e")
    # a middle angle of π lands on either end of [-π, π] by rounding: compare modulo 2π
    assert np.allclose(np.angle(np.exp(1j * (got - want))), 0, atol=1e-12)
    assert np.all(qa.distance(qa.from_davenport(ax, "e", got), q) < 1e-7)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        qa.as_davenport(q, ax, "e", suppress_warnings=True)


@pytest.mark.parametrize("call, match", [
    (lambda: qa.from_davenport(np.eye(3), "x", [1, 2, 3]), "order"),
    (lambda: qa.from_davenport([[1, 0, 0], [1, 1, 0], [0, 0, 1]], "e", [1, 2, 3]), "orthogonal"),
    (lambda: qa.from_davenport(np.ones((4, 3)), "e", [1, 2, 3, 4]), "1 to 3 axes"),
    (lambda: qa.from_davenport([[1, 0], [0, 1]], "e", [1, 2]), "length 3"),
    (lambda: qa.from_davenport(np.eye(3), "e", [1, 2]), "angles"),
    (lambda: qa.as_davenport([1, 0, 0, 0], np.eye(3)[:2], "e"), "3 axes"),
    (lambda: qa.as_davenport([1, 0, 0, 0], [[1, 0, 0], [1, 1, 0], [0, 0, 1]], "e"), "orthogonal"),
])
def test_errors(call, match):
    with pytest.raises(ValueError, match=match):
        call()


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), order=st.sampled_from(["e", "i"]))
def test_round_trip_property(seed, order):
    rng = np.random.default_rng(seed)
    axes = axes_set(rng)
    q = qa.random(8, rng=rng)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ang = qa.as_davenport(q, axes, order)
    assert np.all(np.abs(ang) <= np.pi + 1e-12)
    assert np.all(qa.distance(qa.from_davenport(axes, order, ang), q) < 1e-9)
