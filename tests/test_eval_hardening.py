"""Trajectory evaluation hardened (issue 36, items 7-9 and 15-19): ``quatarray eval`` and its
readers against evo (pairs, interpolation), mpmath (UTM-sized coordinates) and bad inputs."""

import copy

import numpy as np
import pytest

import quatarray as qa
from quatarray import trajectory as T

evo = pytest.importorskip("evo", reason="evo (the test extra) is needed to compare with it")
from evo.core import filters, lie_algebra  # noqa: E402

# ---- item 8: RPE pairs by path length, rounded as evo rounds the step lengths ----

# integer steps whose length is a whole number: on a decimal grid the running length lands on delta
_WHOLE = np.array([(a, b, c) for a in range(-6, 7) for b in range(-6, 7) for c in range(-6, 7)
                   if (a, b, c) != (0, 0, 0) and round((a * a + b * b + c * c) ** 0.5) ** 2 == a * a + b * b + c * c])


def _grid_path(rng, n):
    """(positions, delta): a walk on a decimal grid whose steps have lengths k * scale, delta too."""
    if rng.random() < 0.5:
        steps = _WHOLE[rng.integers(len(_WHOLE), size=n - 1)]
        scale = float(rng.choice([0.1, 0.3, 0.7, 0.01]))
        ints = np.concatenate([np.zeros((1, 3), int), np.cumsum(steps, axis=0)]) + rng.integers(-50, 50, size=3)
        return ints * scale, float(rng.integers(1, 8)) * scale
    steps = rng.integers(-2, 3, size=(n - 1, 3)) * rng.choice([0.1, 0.25, 0.3, 1.0, 0.7])
    pos = np.concatenate([np.zeros((1, 3)), np.cumsum(steps, axis=0)]) + rng.choice([0, 3.7, 100.0])
    return pos, float(rng.choice([0.5, 1.0, 1.5, 2.0, 3.0]))


@pytest.mark.parametrize("all_pairs", [False, True])
def test_rpe_pairs_in_metres_equal_evo_on_grid_paths(all_pairs):
    rng = np.random.default_rng(36)
    differ = []
    for k in range(1500):
        pos, delta = _grid_path(rng, 40)
        theirs = filters.filter_pairs_by_path([lie_algebra.se3(np.eye(3), x) for x in pos], delta, 0.1 * delta,
                                              all_pairs)
        try:
            i, j = T.pairs(T.poses(None, pos, qa.identity(len(pos))), delta, "m", all_pairs)
            ours = list(zip(i.tolist(), j.tolist()))
        except ValueError:  # no pair: evo gives an empty list
            ours = []
        if ours != theirs:
            differ.append(k)
    assert differ == []
