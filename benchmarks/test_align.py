"""Rotation tools: quatarray against scipy (same arrays, same run).

- ``align_vectors`` on 10⁵ problems of 8 pairs against a Python loop of
  scipy's ``Rotation.align_vectors`` (scipy has no batch form): the loop is
  timed on the first 1000 problems and its time scaled by 100 (the entry's
  ``extra_info["scaled_by"]``); target ≥ 30×. Compare the rates in the
  summary (problems/s, printed as Mquat/s); its "ratio" is of raw times, so
  for this group multiply it by 100.
- ``align_vectors`` on one problem of 10⁶ pairs; target ≥ 2× scipy.

(``as_mrp`` and ``from_mrp`` are timed with the other conversions, in
``benchmarks/test_conversions.py``.)

Run: ``pytest benchmarks/test_align.py --benchmark-only``.
"""

import warnings

import numpy as np
import pytest
from conftest import run

import quatarray as qa

Rotation = pytest.importorskip("scipy.spatial.transform").Rotation

PROBLEMS, PAIRS, LOOP = 100_000, 8, 1_000
LIBS = ["quatarray", "quatarray-f32", "scipy"]


def _problems(n, m):
    rng = np.random.default_rng(99)
    b = rng.standard_normal((n, m, 3))
    a = qa.rotate(qa.random(n, rng=rng)[:, None], b) + 0.05 * rng.standard_normal((n, m, 3))
    return a, b, rng.random((n, m)) + 0.5


@pytest.mark.benchmark(group=f"align_vectors {PROBLEMS} problems x {PAIRS} pairs")
@pytest.mark.parametrize("lib", LIBS)
def test_align_batch(benchmark, lib):
    a, b, w = _problems(PROBLEMS, PAIRS)
    if lib == "quatarray-f32":
        a, b, w = a.astype(np.float32), b.astype(np.float32), w.astype(np.float32)
    if lib.startswith("quatarray"):
        fn = lambda: qa.align_vectors(a, b, w)  # noqa: E731
        run(benchmark, fn, PROBLEMS)
        return

    def loop():
        for i in range(LOOP):
            Rotation.align_vectors(a[i], b[i], w[i])

    benchmark.extra_info["scaled_by"] = PROBLEMS / LOOP
    benchmark.extra_info["items"] = LOOP  # Mquat/s of the loop: the rate per problem
    benchmark.pedantic(loop, rounds=3, iterations=1, warmup_rounds=1)


@pytest.mark.benchmark(group="align_vectors one problem of 10^6 pairs")
@pytest.mark.parametrize("lib", LIBS)
def test_align_one_large(benchmark, lib):
    a, b, w = (x[0] for x in _problems(1, 1_000_000))
    if lib == "quatarray-f32":
        a, b, w = a.astype(np.float32), b.astype(np.float32), w.astype(np.float32)
    if lib.startswith("quatarray"):
        fn = lambda: qa.align_vectors(a, b, w)  # noqa: E731
    else:
        fn = lambda: Rotation.align_vectors(a, b, w)  # noqa: E731
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run(benchmark, fn, len(a))
