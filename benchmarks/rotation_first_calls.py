"""First call of each ``quatarray.Rotation`` method from an empty numba cache.

``python benchmarks/rotation_first_calls.py [names...]``: one fresh process per
method with ``NUMBA_CACHE_DIR`` a new empty folder; prints the seconds of the
call alone (the import and the objects it needs are made before the clock starts).
"""
import os, subprocess, sys, tempfile, json
CALLS = {
 "from_quat (N)": "R.from_quat(q)",
 "from_quat (1)": "R.from_quat(q[0])",
 "as_quat": "r.as_quat()",
 "apply (N)": "r.apply(v)",
 "apply (1)": "r1.apply(v[0])",
 "apply inverse": "r.apply(v, inverse=True)",
 "r1 * r2": "r * r",
 "inv": "r.inv()",
 "magnitude": "r.magnitude()",
 "as_matrix": "r.as_matrix()",
 "from_matrix": "R.from_matrix(m)",
 "as_rotvec": "r.as_rotvec()",
 "from_rotvec": "R.from_rotvec(v)",
 "as_mrp": "r.as_mrp()",
 "from_mrp": "R.from_mrp(v)",
 "as_euler (N)": "r.as_euler('xyz')",
 "as_euler (1)": "r1.as_euler('xyz')",
 "from_euler": "R.from_euler('xyz', v)",
 "mean": "r.mean()",
 "approx_equal": "r.approx_equal(r)",
 "pow": "r ** 0.5",
 "align_vectors": "R.align_vectors(v, v[::-1])",
 "from_davenport": "R.from_davenport(np.eye(3), 'e', v)",
 "as_davenport": "r.as_davenport(np.eye(3)[[2,0,1]], 'e')",
 "reduce": "r.reduce(R.create_group('O'))",
 "create_group": "R.create_group('I')",
 "as_davenport (1)": "r1.as_davenport(np.eye(3)[[2,0,1]], 'e')",
 "approx_equal (1)": "r1.approx_equal(r1)",
 "pow (1)": "r1 ** 0.5",
 "mean (1)": "r1.mean()",
}
SETUP = """
import time, numpy as np, quatarray as qa
from quatarray.classes.rotation import Rotation as R
import numba
rng = np.random.default_rng(0); q = rng.standard_normal((5, 4)); v = rng.standard_normal((5, 3))
m = np.eye(3)[None].repeat(5, 0)
"""
only = sys.argv[1:] or list(CALLS)
for name in only:
    expr = CALLS[name]
    with tempfile.TemporaryDirectory() as d:
        code = SETUP
        # objects needing kernels are built first and their compile time excluded
        if "r." in expr or "r *" in expr or "r **" in expr or "r1" in expr:
            code += "r = R.from_wxyz(qa.random(5, rng=1)); r1 = R.from_wxyz(qa.random(None, rng=1))\n"
        code += f"t = time.perf_counter(); {expr}; print(time.perf_counter() - t)\n"
        env = dict(os.environ, NUMBA_CACHE_DIR=d, PYTHONPATH=os.getcwd())
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
        print(f"{name:16s} {out.stdout.strip() or out.stderr[-300:]}", flush=True)
