"""Trajectory evaluation benchmarks: quatarray.trajectory against evo, and against reading the poses.

Run: pytest benchmarks/test_trajectory.py --benchmark-only
Groups:
- ``ape-sim3-<n>``: association + Sim(3) alignment + APE (translation) of n poses,
  quatarray against evo's own pipeline (``associate_trajectories``, ``align``, ``APE``)
  on the same arrays (evo only up to 10⁵ poses: it loops over poses in Python).
- ``eval-vs-read-<n>``: APE (sim3, full) plus RPE (full) of n poses in memory, against
  reading the same poses from an ``(n, 8)`` npy pose array (the contract: within 3×).
QUATARRAY_BENCH_LARGE=1 adds n = 10⁷.
"""

import copy
import os

import numpy as np
import pytest

import quatarray as qa
from quatarray import trajectory as T

SIZES = [10**5, 10**6] + ([10**7] if os.environ.get("QUATARRAY_BENCH_LARGE", "0") not in ("", "0") else [])
_CACHE = {}


def streams(n):
    """A random walk reference and a noisy, scaled, time-jittered estimate of it."""
    if n not in _CACHE:
        rng = np.random.default_rng(18)
        t = 1e9 + np.arange(n) * 0.01
        pos = np.cumsum(rng.normal(scale=0.01, size=(n, 3)), axis=0)
        q = qa.cumprod(qa.from_rotvec(rng.normal(scale=0.01, size=(n, 3))))
        ref = T.poses(t, pos, q)
        est = T.poses(t + rng.uniform(-0.002, 0.002, n), 1.3 * pos + 1 + rng.normal(scale=0.01, size=(n, 3)),
                      qa.multiply(q, qa.from_rotvec(rng.normal(scale=0.005, size=(n, 3)))))
        _CACHE[n] = ref, est
    return _CACHE[n]


def run(benchmark, f, rounds=3):
    f()  # compile / warm up outside the timing
    benchmark.pedantic(f, rounds=rounds, iterations=1)


@pytest.mark.parametrize("n", [10**5, 10**6])
@pytest.mark.parametrize("lib", ["quatarray", "evo"])
def test_ape_sim3(benchmark, lib, n):
    benchmark.group = f"ape-sim3-{n:.0e}"
    benchmark.extra_info["items"] = n
    ref, est = streams(n)
    if lib == "quatarray":
        run(benchmark, lambda: T.evaluate(ref, est, "ape", align="sim3"))
        return
    if n > 10**5:
        pytest.skip("evo loops over poses in Python: minutes at this size")
    evo_traj = pytest.importorskip("evo.core.trajectory")
    from evo.core import metrics, sync

    a = evo_traj.PoseTrajectory3D(ref.pos, ref.q, ref.t)
    b = evo_traj.PoseTrajectory3D(est.pos, est.q, est.t)

    def job():
        r, e = sync.associate_trajectories(copy.deepcopy(a), copy.deepcopy(b), max_diff=0.01)
        e.align(r, correct_scale=True)
        m = metrics.APE(metrics.PoseRelation.translation_part)
        m.process_data((r, e))
        return m.get_all_statistics()

    run(benchmark, job, rounds=1)


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("what", ["quatarray-ape+rpe", "read-npy"])
def test_eval_vs_read(benchmark, tmp_path_factory, what, n):
    from quatarray.app.eval_verb import read_poses

    benchmark.group = f"eval-vs-read-{n:.0e}"
    benchmark.extra_info["items"] = n
    ref, est = streams(n)
    if what == "read-npy":
        path = str(tmp_path_factory.mktemp("poses") / "ref.npy")
        np.save(path, np.c_[ref.t, ref.pos, ref.q])
        run(benchmark, lambda: read_poses(path))
        os.unlink(path)
        return

    def job():
        T.evaluate(ref, est, "ape", align="sim3", relation="full")
        T.evaluate(ref, est, "rpe", align="sim3", relation="full")

    run(benchmark, job)
