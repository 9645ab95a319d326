"""quatarray.create_group and quatarray.reduce against scipy's Rotation (the oracle)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import quatarray as qa

GROUPS = ["I", "O", "T", "C1", "C2", "C3", "C6", "D1", "D2", "D3", "D7", "D10"]


@pytest.mark.parametrize("group", GROUPS)
@pytest.mark.parametrize("axis", ["x", "Y", "z"])
def test_create_group_matches_scipy(group, axis):
    got = qa.create_group(group, axis)
    assert np.allclose(qa.as_xyzw(got), Rotation.create_group(group, axis).as_quat(), rtol=0, atol=1e-15)


@pytest.mark.parametrize("group, size", [("I", 60), ("O", 24), ("T", 12), ("C5", 5), ("D5", 10)])
def test_groups_are_closed(group, size):
    g = qa.create_group(group)
    assert g.shape == (size, 4)
    prod = qa.multiply(g[:, None], g[None, :]).reshape(-1, 4)
    d = qa.distance(prod[:, None], g[None, :])
    assert np.all(np.min(d, axis=1) < 1e-12)  # every product is a member
    assert np.all(np.sort(d, axis=1)[:, 1] > 0.1)  # and members are distinct
    assert qa.create_group(group, dtype=np.float32).dtype == np.float32


@pytest.mark.parametrize("bad, match", [(1, "string"), ("Q", "one of"), ("C0", "positive"), ("Cx", "one of")])
def test_create_group_errors(bad, match):
    with pytest.raises(ValueError, match=match):
        qa.create_group(bad)
    with pytest.raises(ValueError, match="axis"):
        qa.create_group("C2", axis="w")


def test_reduce_matches_scipy_without_ties():
    p = qa.random(40, rng=0)
    g = qa.create_group("O")
    red, i, j = qa.reduce(p, g)
    want, wi, _ = Rotation.from_quat(qa.as_xyzw(p)).reduce(Rotation.from_quat(qa.as_xyzw(g)), return_indices=True)
    assert np.array_equal(i, wi) and np.all(j == 0)
    assert np.allclose(qa.as_xyzw(red), want.as_quat(), atol=1e-15)
    red, i, j = qa.reduce(p, None, g)
    want, _, wj = Rotation.from_quat(qa.as_xyzw(p)).reduce(right=Rotation.from_quat(qa.as_xyzw(g)), return_indices=True)
    assert np.array_equal(j, wj)
    assert np.allclose(qa.as_xyzw(red), want.as_quat(), atol=1e-15)


def test_reduce_picks_the_smallest_angle_and_first_of_ties():
    p = qa.random((3, 5), rng=1)
    left, right = qa.create_group("T"), qa.create_group("D3")
    red, i, j = qa.reduce(p, left, right)
    assert red.shape == (3, 5, 4) and i.shape == j.shape == (3, 5)
    assert np.allclose(red, qa.multiply(left[i], qa.multiply(p, right[j])), atol=1e-15)
    every = qa.multiply(qa.multiply(left[:, None, None, None], p), right[None, :, None, None])
    best = np.abs(every[..., 0]).max(axis=(0, 1))
    assert np.allclose(np.abs(red[..., 0]), best, atol=1e-15)
    # the identity: reduced to itself, by the first pair (in the order of left, then
    # right) with l r = ±1
    r, i, j = qa.reduce(qa.identity(), left, right)
    w = np.abs(qa.multiply(left[:, None], right[None, :])[..., 0])
    first = np.argwhere(w > 1 - 1e-15)[0]
    assert np.allclose(np.abs(r[0]), 1) and (int(i), int(j)) == tuple(first)


def test_reduce_edge_cases():
    r, i, j = qa.reduce(np.zeros((0, 4)), qa.create_group("O"))
    assert r.shape == (0, 4) and i.shape == (0,)
    q = qa.random(4, rng=2)
    r, i, j = qa.reduce(q)
    assert np.array_equal(r, q) and not i.any() and not j.any()
    assert qa.reduce(q.astype(np.float32), qa.create_group("C4", dtype=np.float32))[0].dtype == np.float32
    with pytest.raises(ValueError, match="left"):
        qa.reduce(q, np.zeros((0, 4)))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), group=st.sampled_from(["O", "T", "C4", "D3"]))
def test_reduce_is_invariant_under_the_group(seed, group):
    # the reduced angle of p and of g p (g in the group) is the same
    rng = np.random.default_rng(seed)
    g = qa.create_group(group)
    p = qa.random(6, rng=rng)
    k = rng.integers(len(g))
    a = qa.angle(qa.reduce(p, g)[0])
    b = qa.angle(qa.reduce(qa.multiply(g[k], p), g)[0])
    assert np.allclose(a, b, atol=1e-12)
    assert np.all(a <= qa.angle(p) + 1e-12)
