"""The debug mode of the row accessors (QUATARRAY_CHECK_BOUNDS=1): an access past an
array raises IndexError in every layout, and the public functions give the same
numbers with the checks on."""

import os
import pathlib
import subprocess
import sys
import textwrap

ROOT = pathlib.Path(__file__).resolve().parents[1]

SCRIPT = textwrap.dedent("""
    import numpy as np
    import quatarray as qa
    from quatarray import _elements as E
    from quatarray._jit import CACHE, CHECK_BOUNDS, rowloop

    assert CHECK_BOUNDS and not CACHE

    @rowloop(parallel=False)
    def one_row_too_many(q, out):
        for i in range(q.shape[0] + 1):
            E.store4(out, i, E.load4(q, i))

    @rowloop(parallel=False)
    def store_past(out):
        E.store3(out, out.shape[0], (1.0, 2.0, 3.0))

    @rowloop(parallel=False)
    def stream_past(out):
        E.stream4(out, out.shape[0], (1.0, 2.0, 3.0, 4.0))
        E.stream_end()

    cases = {
        "C": (np.zeros((3, 4)), np.zeros((3, 4))),
        "strided": (np.zeros((3, 8))[:, ::2], np.zeros((3, 4))),
        "flat": (np.zeros(12), np.zeros(12)),
        "float32": (np.zeros((3, 4), np.float32), np.zeros((3, 4), np.float32)),
    }
    for name, (q, out) in cases.items():
        try:
            one_row_too_many(q, out)
        except IndexError:
            print(name, "IndexError")
    try:
        store_past(np.zeros((2, 3)))
    except IndexError:
        print("store3 IndexError")
    try:
        stream_past(np.zeros((2, 4)))
    except IndexError:
        print("stream4 IndexError")

    rng = np.random.default_rng(0)
    p, q = qa.random(50, rng=rng), qa.random(50, rng=rng)
    print("multiply", np.abs(qa.multiply(p, q) - qa.multiply(p, q)).max() == 0)
    t = np.arange(50.0)
    s = qa.spline(t, qa.unflip(q), np.linspace(0, 49, 200))
    print("spline", s.shape)
""")


def test_debug_mode_raises_past_the_array_and_computes_the_same():
    env = dict(os.environ, QUATARRAY_CHECK_BOUNDS="1", PYTHONPATH=str(ROOT))
    res = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env, cwd=ROOT,
                         timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    lines = res.stdout.splitlines()
    for name in ("C", "strided", "flat", "float32", "store3", "stream4"):
        assert f"{name} IndexError" in lines, res.stdout
    assert "multiply True" in lines and "spline (200, 4)" in lines
