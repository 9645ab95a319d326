"""What the Dask test modules share: the cluster fixture (kernels warmed up in this
process first), the element-wise cases, streams and comparisons."""

import importlib

import numpy as np
import pytest

da = pytest.importorskip("dask.array")
dask = pytest.importorskip("dask")
distributed = pytest.importorskip("distributed")

import quatarray as qa  # noqa: E402
import quatarray.dask as qd  # noqa: E402


def has(module):
    try:
        importlib.import_module(f"quatarray.{module}")
    except ImportError:
        return False
    return True


def needs(module):
    return pytest.mark.skipif(not has(module), reason=f"quatarray.{module} is not there yet")


def _warm_up():
    """Compile (or load) every kernel the workers will run in this process first: numba's
    on-disk cache then hands the machine code to the worker processes instead of each
    compiling it again."""
    q = qa.random(8, rng=0)
    for name, (args, kwargs) in _cases(q).items():
        if has(MODULE_OF[name]):
            getattr(qa, name)(*args, **kwargs)
    qa.cumprod(q)
    qa.norm(q)
    qa.dot(q, q)
    qa.from_su2(qa.as_su2(q))
    if has("interpolation"):
        qa.unflip(q)
        for method in ("bezier", "slerp", "nlerp", "squad"):
            qa.spline(np.arange(8.0), q, [0.5, 6.5], method=method)
        qa.angular_velocity(q, np.arange(8.0), frame="space")
        qa.angular_velocity(q, np.arange(8.0), frame="body")


@pytest.fixture(scope="module")
def client():
    _warm_up()
    cluster = qd.local_cluster(2)
    c = distributed.Client(cluster)
    try:
        yield c
    finally:
        c.close()
        cluster.close()


def run(client, x):
    """Compute on the cluster's worker processes."""
    if isinstance(x, tuple):
        return tuple(client.compute(list(x), sync=True))
    return client.compute(x, sync=True)


def same(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b, equal_nan=True)


def stream(n, seed=0, flips=True, dtype=np.float64):
    """A smooth, slightly non-unit stream with sign flips (like real data)."""
    rng = np.random.default_rng(seed)
    steps = qa.from_rotvec(rng.normal(0, 0.2, (n, 3)))
    q = qa.cumprod(steps) * rng.uniform(0.99, 1.01, (n, 1))
    if flips:
        q[rng.random(n) < 0.3] *= -1
    return q.astype(dtype)


@pytest.fixture(scope="module")
def q():
    q = qa.random(997, rng=5)
    q[3] = 0.0  # zero quaternion → nan, as in memory
    q[4] = [np.nan, 0, 0, 0]
    q[5] = [1, 0, 0, 0]
    q[6] = [0, 1, 0, 0]  # 180°
    q[7] = [1, 1e-9, 0, 0]  # tiny angle
    q[8] *= 3.0  # non-unit
    return q


CHUNKS = [(100, 4), (997, 4), (1, 4)]


def chunked(a, rows):
    return da.from_array(a, chunks=(rows,) + a.shape[1:])


def _cases(q):
    rng = np.random.default_rng(1)
    n = len(q)
    p = qa.random(n, rng=2)
    v = rng.normal(size=(n, 3))
    t = rng.uniform(-0.2, 1.2, n)
    unit = qa.normalize(q)
    cases = {
        "multiply": ((p, q), {}),
        "conjugate": ((q,), {}),
        "inverse": ((q,), {}),
        "normalize": ((q,), {}),
        "norm": ((q,), {}),
        "dot": ((p, q), {}),
        "exp": ((q,), {}),
        "log": ((q,), {}),
        "power": ((q, t), {}),
        "canonical": ((q,), {}),
        "angle": ((q,), {}),
        "distance": ((p, q), {}),
        "rotate": ((q, v), {}),
        "as_matrix": ((q,), {}),
        "from_matrix": ((qa.as_matrix(p) * 1.001,), {}),  # projected to the nearest rotation
        "as_rotvec": ((q,), {"degrees": True}),
        "from_rotvec": ((v,), {}),
        "as_axis_angle": ((q,), {}),
        "from_axis_angle": ((v, t), {"degrees": True}),
        "as_xyzw": ((q,), {}),
        "from_xyzw": ((q,), {}),
        "as_left_matrix": ((q,), {}),
        "as_right_matrix": ((q,), {}),
        "as_su2": ((q,), {}),
        "as_euler": ((unit, "ZYX"), {"suppress_warnings": True}),
        "from_euler": (("xyz", v), {}),
        "lerp": ((p, q, t), {}),
        "nlerp": ((p, q, t), {"shortest": False}),
        "slerp": ((p, unit, t), {}),
        "double": ((p, q), {}),
        "bisect": ((p, q), {}),
        "bezier": ((p, unit, qa.random(n, rng=3), p[::-1], t), {}),
        "as_mrp": ((q,), {}),
        "from_mrp": ((v,), {}),
        "as_gibbs": ((q,), {}),
        "from_gibbs": ((v,), {}),
        "rotation_between": ((v, v[::-1]), {}),
        "approx_equal": ((p, qa.multiply(p, qa.from_rotvec(v * 1e-3))), {"atol": 2e-3}),
    }
    return cases


MODULE_OF = {name: mod for mod, names in qa._MODULES.items() for name in names}
