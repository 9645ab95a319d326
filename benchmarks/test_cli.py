"""The command line's start-up: several inputs in one process against one process each.

Run with ``pytest benchmarks/test_cli.py -s`` (not part of the default test
run). ``quatarray convert`` of 50 small TUM files (100 poses each) as 50
calls and as one call ``quatarray convert *.txt OUT --to quat --ext npy``,
then the same for ``unflip`` (a verb that loads numba and a cached kernel),
best of three rounds each, side by side; the goal is one call ≥ 8× faster
than 50 (asserted ≥ 3×: a shared machine can stall either side).
"""

import os
import subprocess
import sys
import time

import numpy as np
import pytest

FILES, ROWS, ROUNDS = 50, 100, 3


@pytest.fixture(scope="module")
def tum_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("tum")
    rng = np.random.default_rng(5)
    paths = []
    for k in range(FILES):
        t = 1305031098.0 + 0.01 * np.arange(ROWS)
        q = rng.standard_normal((ROWS, 4))
        pos = rng.standard_normal((ROWS, 3))
        path = folder / f"s{k:02d}.txt"
        np.savetxt(path, np.column_stack([t, pos, q[:, [1, 2, 3, 0]]]), fmt="%.6f",
                   header="timestamp tx ty tz qx qy qz qw")
        paths.append(str(path))
    return paths


def _quatarray(*argv):
    subprocess.run([sys.executable, "-m", "quatarray", *map(str, argv)], check=True, capture_output=True)


@pytest.mark.parametrize("verb, extra", [("convert", ["--to", "quat"]), ("unflip", [])], ids=["convert", "unflip"])
def test_several_inputs_in_one_process(tmp_path, tum_files, verb, extra):
    _quatarray(verb, tum_files[0], tmp_path / "warm.npy", *extra)  # kernels into the cache
    many, one = [], []
    for r in range(ROUNDS):
        out = tmp_path / f"many{r}"
        out.mkdir()
        t = time.perf_counter()
        for f in tum_files:
            _quatarray(verb, f, out / (os.path.basename(f)[:-4] + ".npy"), *extra)
        many.append(time.perf_counter() - t)
        t = time.perf_counter()
        _quatarray(verb, *tum_files, tmp_path / f"one{r}", "--ext", "npy", *extra)
        one.append(time.perf_counter() - t)
    for f in os.listdir(tmp_path / "many0"):
        np.testing.assert_array_equal(np.load(tmp_path / "many0" / f), np.load(tmp_path / "one0" / f))
    ratio = min(many) / min(one)
    print(f"\n{verb}: {FILES} calls {min(many):.2f} s, one call {min(one):.3f} s: {ratio:.1f}x")
    assert ratio >= 3
