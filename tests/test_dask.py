"""quatarray.dask against the in-memory functions, on a real LocalCluster of worker processes.

Element-wise kernels must agree bitwise, scans and splines to 1e-13, whatever
the chunking: chunk borders inside spline segments, on sign flips, chunks of
one row. Results must stay lazy until computed.
"""

import importlib
import operator

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


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, host="127.0.0.1", dashboard_address=None
    )
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


# --------------------------------------------------------------------------
# element-wise functions: bitwise on the cluster


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
    }
    return cases


MODULE_OF = {name: mod for mod, names in qa._MODULES.items() for name in names}


@pytest.mark.parametrize("rows", [100, 1])
@pytest.mark.parametrize("name", sorted(set(qd._ELEMENTWISE) - {"from_su2"}))  # from_su2: below
def test_elementwise_bitwise(client, q, name, rows):
    if not has(MODULE_OF[name]):
        pytest.skip(f"quatarray.{MODULE_OF[name]} is not there yet")
    n = 997 if rows > 1 else 23
    args, kwargs = _cases(q[:n])[name]
    lazy = qd.__dict__[name](*[chunked(a, rows) if isinstance(a, np.ndarray) else a for a in args], **kwargs)
    expect = getattr(qa, name)(*args, **kwargs)
    if isinstance(expect, tuple):
        assert isinstance(lazy, tuple) and all(isinstance(x, da.Array) for x in lazy)
        got = run(client, lazy)
        assert all(same(g, e) for g, e in zip(got, expect))
        assert all(x.dtype == e.dtype and x.shape == e.shape for x, e in zip(lazy, expect))
    else:
        assert isinstance(lazy, da.Array)
        assert lazy.dtype == expect.dtype and lazy.shape == expect.shape  # meta before computing
        assert lazy.chunks[0][0] == rows
        assert same(run(client, lazy), expect)


def test_from_su2_bitwise(client):
    m = qa.as_su2(qa.random(50, rng=4))
    got = run(client, qd.from_su2(chunked(m, 7)))
    assert same(got, qa.from_su2(m))
    m32 = m.astype(np.complex64)
    assert qd.from_su2(chunked(m32, 7)).dtype == np.float32


def test_float32_and_weak_scalars(client, q):
    p32 = qa.random(300, rng=6, dtype=np.float32)
    q32 = q[:300].astype(np.float32)
    lazy = qd.slerp(chunked(p32, 64), chunked(q32, 64), 0.25)  # a Python t never upcasts
    assert lazy.dtype == np.float32
    assert same(run(client, lazy), qa.slerp(p32, q32, 0.25))
    mixed = qd.multiply(chunked(p32, 64), chunked(q[:300], 50))
    assert mixed.dtype == np.float64
    assert same(run(client, mixed), qa.multiply(p32, q[:300]))
    assert qd.as_su2(chunked(q32, 64)).dtype == np.complex64


def test_broadcasting_and_numpy_mixing(client, q):
    p = qa.random((5, 1), rng=7)  # numpy (5, 1, 4) against Dask (997, 4) → (5, 997, 4)
    lazy = qd.multiply(p, chunked(q, 300))
    assert lazy.shape == (5, 997, 4)
    assert same(run(client, lazy), qa.multiply(p, q))
    one = qd.rotate(q[0], chunked(np.ones((40, 3)), 9))  # a single quaternion against many vectors
    assert same(run(client, one), qa.rotate(q[0], np.ones((40, 3))))
    # a scalar t against N pairs, one pair against M t
    t = np.linspace(0, 1, 31)
    lazy = qd.slerp(q[10], q[11], chunked(t, 4))
    assert same(run(client, lazy), qa.slerp(q[10], q[11], t))


def test_core_axis_chunks_are_rechunked(q):
    x = da.from_array(q, chunks=(100, 2))
    lazy = qd.normalize(x)
    assert lazy.chunks[1] == (4,)
    assert same(lazy.compute(scheduler="sync"), qa.normalize(q))
    m = da.from_array(qa.as_matrix(q[:20]), chunks=(5, 1, 2))
    assert qd.from_matrix(m).chunks == ((5, 5, 5, 5), (4,))


def test_bad_inputs_named_like_in_memory(q):
    x = chunked(q, 100)
    with pytest.raises(ValueError, match=r"Expected `q` to have shape \(\.\.\., 4\), got \(997, 3\)"):
        qd.normalize(chunked(q[:, :3], 100))
    with pytest.raises(ValueError, match="`p` .* and `q` .* to broadcast"):
        qd.multiply(x, np.ones((7, 4)))
    with pytest.raises(TypeError, match="`q` to have a real"):
        qd.conjugate(x.astype(complex))
    with pytest.raises(TypeError, match="no `out=`"):
        qd.normalize(x, out=np.empty_like(q))
    with pytest.raises(TypeError):
        qd.multiply(x)  # missing argument, as in memory


def test_det_error_raised_at_compute(client):
    m = qa.as_matrix(qa.random(20, rng=8))
    m[13] = -m[13]
    lazy = qd.from_matrix(chunked(m, 6))  # no data is looked at yet
    with pytest.raises(ValueError, match="positive determinant"):
        run(client, lazy)


# --------------------------------------------------------------------------
# laziness


def _explode():
    raise RuntimeError("an input block was computed")


def exploding(shape, chunks, dtype=np.float64):
    """A Dask array whose every block raises when computed."""
    blocks = []
    for start in range(0, shape[0], chunks):
        n = min(chunks, shape[0] - start)
        blocks.append(da.from_delayed(dask.delayed(_explode)(), (n,) + shape[1:], dtype=dtype))
    return da.concatenate(blocks)


def test_results_stay_lazy():
    x = exploding((1000, 4), 100)
    inputs = len(dict(x.__dask_graph__()))
    lazy = qd.as_matrix(x)
    assert isinstance(lazy, da.Array)
    assert lazy.numblocks == (10, 1, 1)
    # one task per block on top of the input graph: nothing was computed, nothing duplicated
    assert len(dict(lazy.__dask_graph__())) == inputs + 10
    for fn in (qd.cumprod, qd.unflip):
        if fn is qd.unflip and not has("interpolation"):
            continue
        scan = fn(x)
        assert isinstance(scan, da.Array)
        # local pass, summary and final pass per block, one carry task per line of blocks
        assert len(dict(scan.__dask_graph__())) == inputs + 3 * 10 + 1
    with pytest.raises(RuntimeError, match="was computed"):
        lazy.compute(scheduler="sync")


# --------------------------------------------------------------------------
# scans


@pytest.mark.parametrize("rows", [1, 7, 128, 1000])
def test_cumprod_any_chunking(client, rows):
    q = stream(120 if rows == 1 else 1000, seed=rows)  # chunks of one row: fewer rows, same logic
    got = run(client, qd.cumprod(chunked(q, rows)))
    expect = qa.cumprod(q)
    np.testing.assert_allclose(got, expect, rtol=0, atol=1e-13)
    if rows == len(q):
        assert same(got, expect)  # one chunk: the very same sequence of products


def test_cumprod_axes_and_float32(client):
    q = stream(600, seed=9).reshape(20, 30, 4)
    for axis, chunks in ((0, (3, 7, 4)), (1, (20, 4, 4)), (-1, (6, 30, 4))):
        got = run(client, qd.cumprod(da.from_array(q, chunks=chunks), axis=axis))
        np.testing.assert_allclose(got, qa.cumprod(q, axis=axis), rtol=0, atol=1e-13)
    q32 = q.astype(np.float32)
    lazy = qd.cumprod(da.from_array(q32, chunks=(3, 30, 4)))
    assert lazy.dtype == np.float32
    np.testing.assert_allclose(run(client, lazy), qa.cumprod(q32), rtol=0, atol=1e-5)
    with pytest.raises(ValueError, match="`axis` in"):
        qd.cumprod(da.from_array(q), axis=2)
    with pytest.raises(ValueError, match=r"shape \(N, \.\.\., 4\)"):
        qd.cumprod(da.from_array(q[0, 0]))


@needs("interpolation")
@pytest.mark.parametrize("rows", [1, 2, 13, 500])
def test_unflip_bitwise_any_chunking(client, rows):
    q = stream(500, seed=rows)
    got = run(client, qd.unflip(chunked(q, rows)))
    assert same(got, qa.unflip(q))


@needs("interpolation")
def test_unflip_flip_exactly_on_borders(client):
    q = stream(64, seed=3, flips=False)
    q[8::8] *= -1  # every chunk of 8 starts with a flip
    q[16:24] *= -1  # a whole chunk flipped
    for rows in (8, 4, 16):
        assert same(run(client, qd.unflip(chunked(q, rows))), qa.unflip(q))
    q3 = np.stack([q, -q[::-1]], axis=1)  # (64, 2, 4): two streams side by side
    got = run(client, qd.unflip(da.from_array(q3, chunks=(8, 1, 4))))
    assert same(got, qa.unflip(q3))
