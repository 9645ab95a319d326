"""VQS/VQM transforms against the numpy 4×4 homogeneous-matrix pipeline.

Run with ``pytest benchmarks/test_transforms.py --benchmark-only``.

Claims measured (issue 4):
- one composed transform applied to 2·10⁶ points is at least as fast as
  numpy on the same points, in both fair formulations: ``pts @ R.T + t``
  (3×3 plus translation) and the homogeneous ``(N, 4) @ H.T`` (points
  already stored homogeneous, so no conversion is charged to numpy);
- composing N = 10⁶ pairs of VQS is faster than ``np.matmul`` of the
  equivalent ``(N, 4, 4)`` stacks (the paper: compose first, apply once).
Every competitor is timed on the same arrays in the same run.
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import quatarray as qa
from quatarray import VQS

P = 2_000_000
N = 1_000_000
DTYPES = [np.float64, np.float32]


def _rounds(benchmark, fn, rounds=7):
    fn()  # compile / warm up outside the timing
    return benchmark.pedantic(fn, rounds=rounds, iterations=1, warmup_rounds=1)


@pytest.fixture(scope="module", params=DTYPES, ids=["f64", "f32"])
def points(request):
    dtype = request.param
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(P, 3)).astype(dtype)
    hom = np.concatenate([pts, np.ones((P, 1), dtype)], axis=1)
    a = VQS(rng.normal(size=3), qa.random(rng=2), 2.0).astype(dtype)
    b = VQS(rng.normal(size=3), qa.random(rng=3), 0.5).astype(dtype)
    t = a @ b
    h = t.as_matrix()
    return dict(pts=pts, hom=hom, T=t, a=a, b=b, H=h, R=np.ascontiguousarray(h[:3, :3]), t=h[:3, 3].copy())


@pytest.fixture(scope="module", params=DTYPES, ids=["f64", "f32"])
def pairs(request):
    dtype = request.param
    rng = np.random.default_rng(4)

    def make():
        return VQS(rng.normal(size=(N, 3)), qa.random(N, rng=rng), rng.uniform(0.5, 2, N)).astype(dtype)

    a, b = make(), make()
    return dict(a=a, b=b, Ha=a.as_matrix(), Hb=b.as_matrix(), Ma=a.as_vqm(), Mb=b.as_vqm(), dtype=dtype)


# --------------------------------------------------------------------------
# one transform, 2·10⁶ points


@pytest.mark.benchmark(group="transforms: apply one transform to 2e6 points")
def test_apply_one_quatarray(benchmark, points):
    d = points
    out = _rounds(benchmark, lambda: d["T"].apply(d["pts"]))
    np.testing.assert_allclose(out, d["pts"] @ d["R"].T + d["t"], rtol=1e-4, atol=1e-4)


@pytest.mark.benchmark(group="transforms: apply one transform to 2e6 points")
def test_apply_one_numpy_3x3_plus_t(benchmark, points):
    d = points
    _rounds(benchmark, lambda: d["pts"] @ d["R"].T + d["t"])


@pytest.mark.benchmark(group="transforms: apply one transform to 2e6 points")
def test_apply_one_numpy_homogeneous(benchmark, points):
    d = points
    _rounds(benchmark, lambda: d["hom"] @ d["H"].T)


@pytest.mark.benchmark(group="transforms: apply one transform to 2e6 points")
def test_apply_one_scipy_rotation(benchmark, points):
    # reference: scipy's Rotation.apply for the rotation alone (no scale, no translation)
    d = points
    r = Rotation.from_quat(np.asarray(d["T"].q, np.float64), scalar_first=True)
    _rounds(benchmark, lambda: r.apply(d["pts"]))


# the paper's point: compose first, then apply once, rather than applying twice


@pytest.mark.benchmark(group="transforms: a(b(points)), 2e6 points")
def test_compose_then_apply(benchmark, points):
    d = points
    _rounds(benchmark, lambda: (d["a"] @ d["b"]).apply(d["pts"]))


@pytest.mark.benchmark(group="transforms: a(b(points)), 2e6 points")
def test_apply_twice(benchmark, points):
    d = points
    _rounds(benchmark, lambda: d["a"].apply(d["b"].apply(d["pts"])))


# --------------------------------------------------------------------------
# composing 10⁶ pairs


@pytest.mark.benchmark(group="transforms: compose 1e6 pairs")
def test_compose_vqs_quatarray(benchmark, pairs):
    d = pairs
    c = _rounds(benchmark, lambda: d["a"] @ d["b"])
    tol = 1e-3 if d["dtype"] == np.float32 else 1e-9
    np.testing.assert_allclose(c[:1000].as_matrix(), d["Ha"][:1000] @ d["Hb"][:1000], rtol=tol, atol=tol)


@pytest.mark.benchmark(group="transforms: compose 1e6 pairs")
def test_compose_vqm_quatarray(benchmark, pairs):
    d = pairs
    c = _rounds(benchmark, lambda: d["Ma"] @ d["Mb"])
    tol = 1e-3 if d["dtype"] == np.float32 else 1e-9
    np.testing.assert_allclose(c[:1000].as_matrix(), d["Ha"][:1000] @ d["Hb"][:1000], rtol=tol, atol=tol)


@pytest.mark.benchmark(group="transforms: compose 1e6 pairs")
def test_compose_numpy_4x4_matmul(benchmark, pairs):
    d = pairs
    _rounds(benchmark, lambda: np.matmul(d["Ha"], d["Hb"]))


@pytest.mark.benchmark(group="transforms: compose 1e6 pairs")
def test_compose_scipy_rotation_only(benchmark, pairs):
    # reference: scipy composes the rotations alone
    d = pairs
    ra = Rotation.from_quat(np.asarray(d["a"].q, np.float64), scalar_first=True)
    rb = Rotation.from_quat(np.asarray(d["b"].q, np.float64), scalar_first=True)
    _rounds(benchmark, lambda: ra * rb, rounds=3)


# --------------------------------------------------------------------------
# N transforms to N points


@pytest.mark.benchmark(group="transforms: apply 1e6 transforms to 1e6 points")
def test_apply_many_quatarray(benchmark, pairs):
    d = pairs
    pts = np.asarray(d["a"].v)
    _rounds(benchmark, lambda: d["b"].apply(pts))


@pytest.mark.benchmark(group="transforms: apply 1e6 transforms to 1e6 points")
def test_apply_many_numpy(benchmark, pairs):
    d = pairs
    pts = np.asarray(d["a"].v)
    h = d["Hb"]
    _rounds(benchmark, lambda: np.einsum("nij,nj->ni", h[:, :3, :3], pts) + h[:, :3, 3])


@pytest.mark.benchmark(group="transforms: inverse 1e6")
def test_inverse_vqs_quatarray(benchmark, pairs):
    _rounds(benchmark, lambda: pairs["a"].inverse())


@pytest.mark.benchmark(group="transforms: inverse 1e6")
def test_inverse_vqm_quatarray(benchmark, pairs):
    _rounds(benchmark, lambda: pairs["Ma"].inverse())


@pytest.mark.benchmark(group="transforms: inverse 1e6")
def test_inverse_numpy_4x4(benchmark, pairs):
    _rounds(benchmark, lambda: np.linalg.inv(pairs["Ha"]), rounds=3)
