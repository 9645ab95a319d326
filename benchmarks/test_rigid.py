"""quatarray.RigidTransform against scipy's RigidTransform, and ScLERP against pytransform3d.

Run with ``pytest benchmarks/test_rigid.py --benchmark-only -n 0``.

Claims measured (issue 39), on the same 10⁶ poses for every library of a group:
- each operation of ``RigidTransform`` (apply, ``*``, inv, as_matrix,
  from/as_dual_quat, from/as_exp_coords, ``**``) against scipy's;
- ScLERP per pose against a Python loop of pytransform3d's
  ``dual_quaternion_sclerp`` (on 2·10³ poses: the loop takes ~50 µs a pose), the
  rates (poses per second) compared.
The ratio table at the end of the run (benchmarks/conftest.py) gives the
ratios; ``as_matrix`` writes 128 MB and scipy's only copies the matrices it
stores, so there both run at memory speed.
"""

import numpy as np
import pytest
from scipy.spatial.transform import RigidTransform as ST
from scipy.spatial.transform import Rotation as SR

import quatarray as qa
from conftest import run
from quatarray import RigidTransform as QT

N = 1_000_000
LOOP = 2_000
LIBS = ["quatarray", "quatarray-f32", "scipy"]
_DATA = {}


def data():
    if not _DATA:
        rng = np.random.default_rng(39)
        m = ST.from_components(rng.normal(size=(N, 3)), SR.random(N, rng=rng)).as_matrix()
        m2 = ST.from_components(rng.normal(size=(N, 3)), SR.random(N, rng=rng)).as_matrix()
        s = ST.from_matrix(m)
        _DATA.update(
            m=m, s=s, s2=ST.from_matrix(m2), v=rng.normal(size=(N, 3)),
            dq=s.as_dual_quat(), e=s.as_exp_coords(), t=rng.random(N),
        )
        for suffix, dtype in (("", np.float64), ("-f32", np.float32)):
            _DATA["q" + suffix] = QT.from_matrix(m.astype(dtype))
            _DATA["q2" + suffix] = QT.from_matrix(m2.astype(dtype))
    return _DATA


def pick(lib):
    """(module or class, transform, second transform, vectors, dual quaternions,
    exponential coordinates) for `lib`."""
    d = data()
    if lib == "scipy":
        return ST, d["s"], d["s2"], d["v"], d["dq"], d["e"]
    suffix = "-f32" if lib.endswith("f32") else ""
    dtype = np.float32 if suffix else np.float64
    return QT, d["q" + suffix], d["q2" + suffix], d["v"].astype(dtype), d["dq"].astype(dtype), d["e"].astype(dtype)


OPS = {
    "apply": lambda C, a, b, v, dq, e: a.apply(v),
    "mul": lambda C, a, b, v, dq, e: a * b,
    "inv": lambda C, a, b, v, dq, e: a.inv(),
    "as_matrix": lambda C, a, b, v, dq, e: a.as_matrix(),
    "from_dual_quat": lambda C, a, b, v, dq, e: C.from_dual_quat(dq),
    "as_dual_quat": lambda C, a, b, v, dq, e: a.as_dual_quat(),
    "from_exp_coords": lambda C, a, b, v, dq, e: C.from_exp_coords(e),
    "as_exp_coords": lambda C, a, b, v, dq, e: a.as_exp_coords(),
    "pow": lambda C, a, b, v, dq, e: a**0.3,
}


@pytest.mark.parametrize("lib", LIBS)
@pytest.mark.parametrize("op", list(OPS))
def test_rigid_transform(benchmark, op, lib):
    benchmark.group = f"RigidTransform.{op} 1e6"
    args = pick(lib)
    fn = lambda: OPS[op](*args)
    fn()  # compile and warm the memory outside the timing
    run(benchmark, fn, N, slow=lib == "scipy")


@pytest.fixture(scope="module")
def sclerp_data():
    rng = np.random.default_rng(40)
    q0, q1 = qa.random(LOOP, rng=rng), qa.random(LOOP, rng=rng)
    q1 *= np.sign(np.sum(q0 * q1, axis=1))[:, None]  # the short way for both libraries
    t0, t1 = rng.normal(size=(LOOP, 3)), rng.normal(size=(LOOP, 3))
    s = rng.random(LOOP)
    return q0, t0, q1, t1, s


@pytest.mark.parametrize("lib", ["quatarray", "pytransform3d"])
def test_sclerp(benchmark, lib, sclerp_data):
    benchmark.group = f"ScLERP {LOOP} poses"
    q0, t0, q1, t1, s = sclerp_data
    if lib == "quatarray":
        fn = lambda: qa.sclerp(q0, t0, q1, t1, s)
    else:
        pt = pytest.importorskip("pytransform3d.transformations")
        a = [pt.dual_quaternion_from_pq(np.concatenate([t0[i], q0[i]])) for i in range(LOOP)]
        b = [pt.dual_quaternion_from_pq(np.concatenate([t1[i], q1[i]])) for i in range(LOOP)]

        def fn():
            return [pt.dual_quaternion_sclerp(a[i], b[i], s[i]) for i in range(LOOP)]

    fn()
    benchmark.extra_info["items"] = LOOP
    benchmark.pedantic(fn, rounds=5, iterations=1, warmup_rounds=0)


def test_sclerp_1e6(benchmark):
    """The batched rate at 10⁶ poses (compare its Mquat/s with the loop's above)."""
    benchmark.group = "ScLERP 1e6 poses"
    d = data()
    q0, q1 = d["q"].wxyz, d["q2"].wxyz
    t0, t1 = d["q"].xyz, d["q2"].xyz
    fn = lambda: qa.sclerp(q0, t0, q1, t1, d["t"])
    fn()
    run(benchmark, fn, N)
