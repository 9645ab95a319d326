"""quatarray.dask against the in-memory functions, on a real LocalCluster of worker processes.

Element-wise kernels must agree bitwise, scans and splines to 1e-13, whatever
the chunking: chunk borders inside spline segments, on sign flips, chunks of
one row. Results must stay lazy until computed.
"""

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
        "as_mrp": ((q,), {}),
        "from_mrp": ((v,), {}),
        "as_gibbs": ((q,), {}),
        "from_gibbs": ((v,), {}),
        "rotation_between": ((v, v[::-1]), {}),
        "approx_equal": ((p, qa.multiply(p, qa.from_rotvec(v * 1e-3))), {"atol": 2e-3}),
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
    expect = qa.from_su2(m)
    assert same(run(client, qd.from_su2(chunked(m, 7))), expect)
    m32 = m.astype(np.complex64)
    assert qd.from_su2(chunked(m32, 7)).dtype == np.float32


def test_float32_and_weak_scalars(client, q):
    p32 = qa.random(300, rng=6, dtype=np.float32)
    q32 = q[:300].astype(np.float32)
    lazy = qd.slerp(chunked(p32, 64), chunked(q32, 64), 0.25)  # a Python t never upcasts
    assert lazy.dtype == np.float32
    expect = qa.slerp(p32, q32, 0.25)
    assert same(run(client, lazy), expect)
    mixed = qd.multiply(chunked(p32, 64), chunked(q[:300], 50))
    assert mixed.dtype == np.float64
    expect = qa.multiply(p32, q[:300])
    assert same(run(client, mixed), expect)
    assert qd.as_su2(chunked(q32, 64)).dtype == np.complex64


def test_broadcasting_and_numpy_mixing(client, q):
    p = qa.random((5, 1), rng=7)  # numpy (5, 1, 4) against Dask (997, 4) → (5, 997, 4)
    lazy = qd.multiply(p, chunked(q, 300))
    assert lazy.shape == (5, 997, 4)
    expect = qa.multiply(p, q)
    assert same(run(client, lazy), expect)
    one = qd.rotate(q[0], chunked(np.ones((40, 3)), 9))  # a single quaternion against many vectors
    expect = qa.rotate(q[0], np.ones((40, 3)))
    assert same(run(client, one), expect)
    # a scalar t against N pairs, one pair against M t
    t = np.linspace(0, 1, 31)
    lazy = qd.slerp(q[10], q[11], chunked(t, 4))
    expect = qa.slerp(q[10], q[11], t)
    assert same(run(client, lazy), expect)


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
    expect = qa.cumprod(q)
    got = run(client, qd.cumprod(chunked(q, rows)))
    np.testing.assert_allclose(got, expect, rtol=0, atol=1e-13)
    if rows == len(q):
        assert same(got, expect)  # one chunk: the very same sequence of products


def test_cumprod_axes_and_float32(client):
    q = stream(600, seed=9).reshape(20, 30, 4)
    for axis, chunks in ((0, (3, 7, 4)), (1, (20, 4, 4)), (-1, (6, 30, 4))):
        expect = qa.cumprod(q, axis=axis)
        got = run(client, qd.cumprod(da.from_array(q, chunks=chunks), axis=axis))
        np.testing.assert_allclose(got, expect, rtol=0, atol=1e-13)
    q32 = q.astype(np.float32)
    lazy = qd.cumprod(da.from_array(q32, chunks=(3, 30, 4)))
    assert lazy.dtype == np.float32
    np.testing.assert_allclose(lazy.compute(scheduler="sync"), qa.cumprod(q32), rtol=0, atol=1e-5)
    with pytest.raises(ValueError, match="`axis` in"):
        qd.cumprod(da.from_array(q), axis=2)
    with pytest.raises(ValueError, match=r"shape \(N, \.\.\., 4\)"):
        qd.cumprod(da.from_array(q[0, 0]))


@needs("interpolation")
@pytest.mark.parametrize("rows", [1, 2, 13, 500])
def test_unflip_bitwise_any_chunking(client, rows):
    q = stream(120 if rows == 1 else 500, seed=rows)
    expect = qa.unflip(q)
    assert same(run(client, qd.unflip(chunked(q, rows))), expect)


@needs("interpolation")
def test_unflip_flip_exactly_on_borders(client):
    q = stream(64, seed=3, flips=False)
    q[8::8] *= -1  # every chunk of 8 starts with a flip
    q[16:24] *= -1  # a whole chunk flipped
    for rows in (8, 4, 16):
        expect = qa.unflip(q)
        assert same(run(client, qd.unflip(chunked(q, rows))), expect)
    q3 = np.stack([q, -q[::-1]], axis=1)  # (64, 2, 4): two streams side by side
    expect = qa.unflip(q3)
    assert same(run(client, qd.unflip(da.from_array(q3, chunks=(8, 1, 4)))), expect)


def _broken_chain(seed=5):
    """A key stream whose sign chain breaks: a zero row, a nan row and an exact quarter
    turn (dot product 0), each with flips before and after it."""
    q = stream(40, seed=seed)
    q[9] = 0.0
    q[21] = np.nan
    q[30], q[31] = [1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]
    q[[8, 10, 20, 22, 29, 32]] *= -1
    return q


@needs("interpolation")
def test_unflip_where_the_sign_chain_breaks(client):
    """After a row whose dot product with the row before is 0 or nan, the in-memory
    unflip keeps rows as they are: the sign carried into a chunk stops there."""
    q = _broken_chain()
    expect = qa.unflip(q)
    for rows in (1, 3, 4, 7, 9, 11):
        assert same(run(client, qd.unflip(chunked(q, rows))), expect), rows
    q3 = np.stack([q, -q[::-1]], axis=1)
    assert same(run(client, qd.unflip(da.from_array(q3, chunks=(6, 1, 4)))), qa.unflip(q3))


@needs("interpolation")
@pytest.mark.parametrize("method", ["slerp", "bezier"])
def test_spline_where_the_sign_chain_breaks(client, method):
    q = _broken_chain()
    t = np.arange(40.0)
    nt = np.linspace(0, 39, 400)
    expect = qa.spline(t, q, nt, method=method)
    for rows in (2, 4, 7, 11):
        got = run(client, qd.spline(t, chunked(q, rows), nt, method=method))
        np.testing.assert_allclose(got, expect, rtol=0, atol=1e-13, err_msg=str(rows))  # nan where memory has nan


@needs("interpolation")
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_spline_sign_scan_of_long_blocks(dtype):
    """Blocks longer than the sign summary's tile of 1024 rows, with flips and chain breaks
    on and beside its tile borders: the same signs as the in-memory unflip."""
    q = stream(5000, seed=9, dtype=dtype)
    q[[1023, 1024, 1025, 2047, 2049, 3000, 4500]] *= -1
    q[2048] = 0.0
    q[3071], q[3072] = [1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]
    t = np.arange(5000.0)
    nt = np.linspace(0, 4999, 3000)
    expect = qa.spline(t, q, nt)
    for rows in (1800, 2500, 4000):
        got = qd.spline(t, chunked(q, rows), nt).compute(scheduler="sync")
        np.testing.assert_allclose(got, expect, rtol=0, atol=1e-13 if dtype == np.float64 else 1e-6, err_msg=str(rows))


# --------------------------------------------------------------------------
# neighbours across chunk borders: spline and angular_velocity


def keyed(k=60, seed=0, even=False):
    rng = np.random.default_rng(seed)
    t = np.arange(k, dtype=float) if even else np.cumsum(rng.uniform(0.3, 1.7, k))
    return t, stream(k, seed=seed)


@needs("interpolation")
@pytest.mark.parametrize("method", ["bezier", "slerp", "nlerp", "squad"])
@pytest.mark.parametrize("rows", [1, 3, 10, 60])
def test_spline_any_chunking(client, method, rows):
    t, keys = keyed(60, seed=rows, even=method == "slerp")
    rng = np.random.default_rng(rows)
    nt = np.sort(np.concatenate([rng.uniform(t[0], t[-1], 400), t, [t[0], t[-1]]]))  # on keys and borders
    expect = qa.spline(t, keys, nt, method=method)  # in memory first: workers then load the compiled kernels
    lazy = qd.spline(t, chunked(keys, rows), nt, method=method)
    assert isinstance(lazy, da.Array) and lazy.shape == (len(nt), 4)
    np.testing.assert_allclose(run(client, lazy), expect, rtol=0, atol=1e-13)


@needs("interpolation")
def test_spline_output_chunks_and_order(client):
    t, keys = keyed(40, seed=4)
    rng = np.random.default_rng(4)
    nt = rng.uniform(t[0], t[-1], 300)  # unsorted
    expect = qa.spline(t, keys, nt)
    for new_times, chunks in ((nt, None), (nt, 1), (nt, 37), (da.from_array(nt, chunks=50), None)):
        lazy = qd.spline(t, chunked(keys, 6), new_times, chunks=chunks)
        if chunks == 37:
            assert lazy.chunks[0][0] == 37
        np.testing.assert_allclose(run(client, lazy), expect, rtol=0, atol=1e-13)
    assert qd.spline(t, chunked(keys.astype(np.float32), 7), nt).dtype == np.float32  # as in memory


@needs("interpolation")
def test_spline_integer_stamps_and_errors():
    t = 1_600_000_000_000_000_000 + np.arange(30, dtype=np.int64) * 10_000_000  # ns since the epoch
    keys = stream(30, seed=5)
    nt = t[0] + np.arange(0, 290_000_000, 1_000_000, dtype=np.int64)
    got = qd.spline(t, chunked(keys, 4), nt).compute(scheduler="sync")
    np.testing.assert_allclose(got, qa.spline(t, keys, nt), rtol=0, atol=1e-13)
    x = chunked(keys, 4)
    with pytest.raises(ValueError, match="strictly increasing"):
        qd.spline(t[::-1], x, nt)
    with pytest.raises(ValueError, match="`new_times` within"):
        qd.spline(t, x, np.append(nt, t[-1] + 1))
    with pytest.raises(ValueError, match="method"):
        qd.spline(t, x, nt, method="cubic")
    with pytest.raises(ValueError, match=r"shape \(30,\)"):
        qd.spline(t[:-1], x, nt)


@needs("interpolation")
@pytest.mark.parametrize("lazy_times", [False, True])
def test_spline_integer_stamps_far_from_the_first(lazy_times):
    """Integer times more than 2**53 units after the first key: every window counts them
    from the stream's first key time, as in memory (from its own first key they round
    differently to float64)."""
    t = np.r_[0, 2**54 + 1001 * np.arange(12)].astype(np.int64)
    keys = keyed(13, seed=3)[1]
    nt = t[5] + np.array([1, 500, 1700])
    times = da.from_array(t, chunks=5) if lazy_times else t
    for method in ("slerp", "bezier"):
        got = qd.spline(times, chunked(keys, 4), nt, method).compute(scheduler="sync")
        np.testing.assert_allclose(got, qa.spline(t, keys, nt, method), rtol=0, atol=1e-13)


@needs("interpolation")
def test_spline_argument_errors():
    t, keys = keyed(20, seed=4)
    x, nt = chunked(keys, 6), np.linspace(t[0], t[-1], 50)
    for bad in (0, -3, 2.5, True):
        with pytest.raises(ValueError, match=r"Expected `chunks` to be a positive integer"):
            qd.spline(t, x, nt, chunks=bad)
    assert qd.spline(t, x, nt, chunks=np.int64(7)).chunks[0][0] == 7
    with pytest.raises(ValueError, match=r"Expected `times` to have shape \(20,\)"):
        qd.spline(t[:, None], x, nt)


@needs("interpolation")
def test_spline_lazy_new_times(client):
    """New times as a Dask array stay on the workers: one output block per block of them,
    equal to in memory; the first block with a time outside the keys' span is named."""
    t, keys = keyed(50, seed=6)
    rng = np.random.default_rng(6)
    nt = np.sort(rng.uniform(t[0], t[-1], 700))
    expect = qa.spline(t, keys, nt)
    for chunks in ((100,) * 7, (0, 350, 0, 349, 1)):  # empty blocks too
        nt_d = da.from_array(nt, chunks=(chunks,))
        lazy = qd.spline(t, chunked(keys, 9), nt_d)
        assert lazy.chunks[0] == chunks
        np.testing.assert_allclose(run(client, lazy), expect, rtol=0, atol=1e-13)
    np.testing.assert_allclose(run(client, qd.spline(t, keys, da.from_array(nt[::-1], chunks=90))), expect[::-1],
                               rtol=0, atol=1e-13)  # unsorted, numpy keys
    bad = nt.copy()
    bad[[250, 610]] = t[-1] + 1, np.nan
    with pytest.raises(ValueError) as memory:
        qa.spline(t, keys, bad)
    with pytest.raises(ValueError) as lazy_error:
        qd.spline(t, chunked(keys, 9), da.from_array(bad, chunks=100))
    assert str(lazy_error.value) == str(memory.value) and "flat index 250" in str(memory.value)
    ti = 1_600_000_000_000_000_000 + np.arange(30, dtype=np.int64) * 10_000_000  # ns since the epoch
    nti = ti[0] + np.arange(0, 290_000_000, 1_000_000, dtype=np.int64)
    got = run(client, qd.spline(ti, chunked(keyed(30, seed=7)[1], 4), da.from_array(nti, chunks=50)))
    np.testing.assert_allclose(got, qa.spline(ti, keyed(30, seed=7)[1], nti), rtol=0, atol=1e-13)


@needs("interpolation")
@pytest.mark.parametrize("t_chunks", [1, 7, (0, 100, 0, 100), 200])
def test_spline_lazy_key_times(client, t_chunks):
    """Key times as a Dask array, chunked unlike the keys: the same results as in memory,
    the key times of each window read from their blocks (no key time travels in the
    graph), and the in-memory messages for times out of order and new times outside."""
    t, keys = keyed(200, seed=9)
    rng = np.random.default_rng(9)
    nt = np.sort(np.concatenate([rng.uniform(t[0], t[-1], 900), t]))
    expect = qa.spline(t, keys, nt)
    t_d = da.from_array(t, chunks=(t_chunks,) if isinstance(t_chunks, tuple) else t_chunks)
    for rows in (1, 13, 200):
        for new_times, chunks in ((nt, None), (nt, 31), (da.from_array(nt, chunks=77), None)):
            lazy = qd.spline(t_d, chunked(keys, rows), new_times, chunks=chunks)
            np.testing.assert_allclose(run(client, lazy), expect, rtol=0, atol=1e-13)
    graph = dict(lazy.__dask_graph__())
    literals = [a for task in graph.values() if isinstance(task, tuple) for a in task if isinstance(a, np.ndarray)]
    assert not [a for a in literals if a.size > 1], "key times travelled in the graph"
    x = chunked(keys, 13)
    for bad_t in (np.r_[t[:120], t[119], t[121:]], np.r_[t[:99], t[100], t[99], t[101:]], np.r_[t[:50], np.nan, t[51:]]):
        with pytest.raises(ValueError) as memory:
            qa.spline(bad_t, keys, nt)
        with pytest.raises(ValueError) as lazy_error:
            qd.spline(da.from_array(bad_t, chunks=t_d.chunks), x, nt)
        assert str(lazy_error.value) == str(memory.value)
    bad = nt.copy()
    bad[[250, 610]] = t[-1] + 1, np.nan
    with pytest.raises(ValueError) as memory:
        qa.spline(t, keys, bad)
    for new_times in (bad, da.from_array(bad, chunks=100)):
        with pytest.raises(ValueError) as lazy_error:
            qd.spline(t_d, x, new_times)
        assert str(lazy_error.value) == str(memory.value) and "flat index 250" in str(memory.value)


@needs("interpolation")
def test_spline_lazy_integer_stamps():
    ti = 1_600_000_000_000_000_000 + np.arange(30, dtype=np.int64) * 10_000_000  # ns since the epoch
    nti = ti[0] + np.arange(0, 290_000_000, 1_000_000, dtype=np.int64)
    keys = keyed(30, seed=7)[1]
    for new_times in (nti, da.from_array(nti, chunks=50)):
        got = qd.spline(da.from_array(ti, chunks=7), chunked(keys, 4), new_times).compute(scheduler="sync")
        np.testing.assert_allclose(got, qa.spline(ti, keys, nti), rtol=0, atol=1e-13)
    with pytest.raises(TypeError, match="real dtype"):
        qd.spline(da.from_array(ti.astype(str), chunks=7), chunked(keys, 4), nti)
    with pytest.raises(ValueError, match=r"shape \(30,\)"):
        qd.spline(da.from_array(ti[:-1], chunks=7), chunked(keys, 4), nti)


@needs("interpolation")
def test_spline_stays_lazy_in_the_keys():
    t = np.arange(100.0)
    for times in (t, da.from_array(t, chunks=30)):  # lazy key times: a pass over them only
        lazy = qd.spline(times, exploding((100, 4), 10), np.linspace(0, 99, 1000))
        assert isinstance(lazy, da.Array) and lazy.numblocks == (10, 1)
        with pytest.raises(RuntimeError, match="was computed"):
            lazy.compute(scheduler="sync")


def _whole_blocks_and_small_inputs(lazy, x, small_name):
    """Per output block of `lazy`: the blocks of `x` it takes whole, and its inputs named
    like `small_name`, each made from one block of `x` (where that block is kept)."""
    deps = lazy.__dask_graph__().get_all_dependencies()
    out = []
    for key in lazy.__dask_keys__():
        key = key[0]
        whole = sorted(d[1] for d in deps[key] if d[0] == x.name)
        small = [d for d in deps[key] if d[0].startswith(small_name)]
        assert all(deps[d] == {(x.name, d[1], 0)} for d in small)
        out.append((whole, small))
    return out


@needs("interpolation")
def test_neighbour_rows_travel_without_their_blocks():
    """A task needing a few rows of a neighbouring block depends on a small task that cuts
    them (run where the block is), not on the whole block: a worker receives those rows only.
    angular_velocity: a task that cuts them; spline: the block's sign summary, which holds them."""
    t, keys = keyed(100, seed=8)
    x = chunked(keys, 25)
    lazy = qd.angular_velocity(x, t)
    found = _whole_blocks_and_small_inputs(lazy, x, f"rows-{x.name}")
    assert [w for w, _ in found] == [[0], [1], [2], [3]]
    assert [sum(d[3] - d[2] for d in small) for _, small in found] == [2, 4, 4, 2]
    lazy = qd.spline(t, x, np.linspace(t[0], t[-1], 1000))
    found = _whole_blocks_and_small_inputs(lazy, x, "spline-summary")
    assert [w for w, _ in found] == [[0], [1], [2], [3]]
    # the summaries of the blocks a window cuts rows from, and of those up to its first
    # row's block (for the sign carried into it)
    assert [sorted(d[1] for d in small) for _, small in found] == [[0, 1], [0, 2], [0, 1, 3], [0, 1, 2]]
    # a summary carries _EDGE_ROWS rows from each end of its block, whatever the block's size
    t, keys = keyed(1000, seed=9)
    x = chunked(keys, 250)
    nt = np.linspace(t[0], t[-1], 3000)
    lazy = qd.spline(t, x, nt)  # output blocks start where key blocks do
    assert not any(small for _, small in _whole_blocks_and_small_inputs(lazy, x, f"rows-{x.name}"))
    found = _whole_blocks_and_small_inputs(lazy, x, "spline-summary")
    summaries = dask.get(lazy.__dask_graph__(), sorted({d for _, small in found for d in small}))
    assert [len(e) for s in summaries for e in s[5]] == [qd._EDGE_ROWS] * 2 * len(summaries)
    # output blocks starting inside key blocks: rows from a block's middle are cut by a task
    lazy = qd.spline(t, x, nt, chunks=700)
    found = _whole_blocks_and_small_inputs(lazy, x, f"rows-{x.name}")
    assert any(small for _, small in found)
    assert np.abs(lazy.compute(scheduler="sync") - qa.spline(t, keys, nt)).max() <= 1e-13


@needs("interpolation")
@pytest.mark.parametrize("rows", [1, 9, 200])
@pytest.mark.parametrize("frame", ["space", "body"])
def test_angular_velocity_bitwise_any_chunking(client, rows, frame):
    t, q = keyed(60 if rows == 1 else 200, seed=rows)
    expect = qa.angular_velocity(q, t, frame=frame)
    lazy = qd.angular_velocity(chunked(q, rows), da.from_array(t, chunks=13), frame=frame)
    assert lazy.chunks[0] == chunked(q, rows).chunks[0]
    assert same(run(client, lazy), expect)


# --------------------------------------------------------------------------
# files: the command line's --scheduler path


@pytest.fixture(scope="module")
def npy_stream(tmp_path_factory):
    folder = tmp_path_factory.mktemp("dask-files")
    q = stream(5000, seed=11)
    np.save(folder / "q.npy", q)
    np.save(folder / "xyzw32.npy", q[:, [1, 2, 3, 0]].astype(np.float32))
    return folder


@pytest.mark.parametrize("to", ["quat", "xyzw", "matrix", "rotvec", "axis-angle", "euler:ZXY"])
def test_convert_file_equals_cli(client, npy_stream, to, capsys):
    from quatarray.cli import main

    src, dst, ref = npy_stream / "q.npy", npy_stream / f"d-{to}.npy", npy_stream / f"m-{to}.npy"
    extra = ["--degrees"] if to in ("rotvec", "euler:ZXY") else []
    assert main(["convert", str(src), str(ref), "--to", to, "--chunk", "700", *extra]) == 0
    assert qd.convert_file(src, dst, to, degrees=bool(extra), chunk=700, scheduler=client) == 0
    assert same(np.load(dst), np.load(ref))
    assert "normalised 5000 non-unit quaternions" in capsys.readouterr().err


def test_convert_file_layout_float32_threads(npy_stream):
    src, dst = npy_stream / "xyzw32.npy", npy_stream / "t.npy"
    qd.convert_file(src, dst, "quat", layout="xyzw", chunk=999, scheduler=None)
    out = np.load(dst)
    assert out.dtype == np.float32
    np.testing.assert_allclose(out, qa.normalize(np.load(npy_stream / "q.npy")), atol=1e-6)


def test_convert_file_errors_leave_no_output(client, npy_stream):
    from quatarray.io.errors import DataError, UsageError

    q = np.load(npy_stream / "q.npy")
    q[3210] = np.nan
    np.save(npy_stream / "bad.npy", q)
    dst = npy_stream / "never.npy"
    with pytest.raises(DataError, match=r"bad\.npy: row 3210: quaternion is not finite"):
        qd.convert_file(npy_stream / "bad.npy", dst, "matrix", chunk=1000, scheduler=client)
    assert not dst.exists() and not [p for p in npy_stream.iterdir() if p.name.startswith(".never")]
    with pytest.raises(UsageError, match="the output is the input"):
        qd.convert_file(npy_stream / "q.npy", npy_stream / "q.npy", "quat")
    with pytest.raises(UsageError, match="exists"):
        qd.convert_file(npy_stream / "q.npy", npy_stream / "bad.npy", "quat")
    with pytest.raises(UsageError, match="--to"):
        qd.convert_file(npy_stream / "q.npy", dst, "euler:XXY")


@needs("interpolation")
@pytest.mark.parametrize("method", ["bezier", "slerp"])
def test_resample_file_equals_cli(client, npy_stream, method):
    from quatarray.cli import main

    src = npy_stream / "q.npy"
    dst, ref = npy_stream / f"r-{method}.npy", npy_stream / f"rm-{method}.npy"
    assert main(["resample", str(src), str(ref), "--rate", "7", "--in-rate", "2", "--method", method,
                 "--chunk", "800", "--force"]) == 0
    assert qd.resample_file(src, dst, rate=7, in_rate=2, method=method, chunk=800, scheduler=client) == 0
    got, expect = np.load(dst), np.load(ref)
    assert got.shape == expect.shape == (17497, 4)  # 0 … 2499.5 s at 7 Hz
    np.testing.assert_allclose(got, expect, rtol=0, atol=1e-13)


@needs("interpolation")
def test_resample_file_times_and_text_input(npy_stream, data_dir):
    t = np.linspace(0.0, 2000.0, 333)
    np.save(npy_stream / "nt.npy", t)
    dst = npy_stream / "rt.npy"
    qd.resample_file(npy_stream / "q.npy", dst, times=npy_stream / "nt.npy", in_rate=2, chunk=100)
    q = np.load(npy_stream / "q.npy")
    np.testing.assert_allclose(np.load(dst), qa.spline(np.arange(5000) / 2, q, t), rtol=0, atol=1e-13)
    # a real recording with a time column is read on the client and resampled on the workers
    src = data_dir / "tum_freiburg1_xyz_groundtruth.txt"
    qd.resample_file(src, dst, rate=200, chunk=5000, force=True, scheduler=None)
    assert np.load(dst).shape[1] == 4 and np.isfinite(np.load(dst)).all()


# --------------------------------------------------------------------------
# files: zarr stores in and out, --on-invalid drop, errors naming their row


def _bad_stream(n=5000, seed=12):
    """A stream with bad rows: the first row, rows on block borders (chunk 700), a whole
    block of bad rows, nan, inf and zero quaternions."""
    q = stream(n, seed=seed)
    bad = [0, 699, 700, 701, 1399, 2345, n - 1] + list(range(2800, 3500))
    for k, i in enumerate(bad):
        q[i] = (np.nan, 1, 0, 0) if k % 3 == 0 else (0, 0, 0, 0) if k % 3 == 1 else (np.inf, 0, 0, 1)
    return q, len(bad)


def _zarr_store(path, a, rows):
    zarr = pytest.importorskip("zarr")
    zarr.create_array(store=str(path), data=a, chunks=(rows,) + a.shape[1:])
    return path


def _read_zarr(path):
    import zarr

    arr = zarr.open_array(str(path), mode="r")
    return arr[:], arr.chunks


@pytest.mark.parametrize("out", ["npy", "zarr"])
def test_convert_file_drop_equals_cli(client, npy_stream, out, capsys):
    from quatarray.cli import main

    if out == "zarr":
        pytest.importorskip("zarr")
    q, nbad = _bad_stream()
    np.save(npy_stream / "holes.npy", q)
    src, ref = npy_stream / "holes.npy", npy_stream / "holes-ref.npy"
    assert main(["convert", str(src), str(ref), "--to", "euler:ZYX", "--on-invalid", "drop", "--force"]) == 0
    expect_err = capsys.readouterr().err
    assert f"dropped {nbad} invalid rows" in expect_err
    dst = npy_stream / f"holes-d.{out}"
    assert qd.convert_file(src, dst, "euler:ZYX", chunk=700, scheduler=client, on_invalid="drop") == 0
    got, chunks = _read_zarr(dst) if out == "zarr" else (np.load(dst), None)
    assert got.shape == (5000 - nbad, 3)
    assert same(got, np.load(ref))
    assert capsys.readouterr().err == expect_err  # the same notes: rows dropped, normalised
    if out == "zarr":
        assert chunks == (700, 3)  # every task wrote whole chunks
    assert not [p for p in npy_stream.iterdir() if p.name.startswith(".holes-d")]


@pytest.mark.parametrize("on_invalid", ["error", "drop"])
def test_convert_file_blocks_of_many_pieces(client, tmp_path, on_invalid, capsys):
    """Blocks longer than the command line's pieces: an npy target takes them piece by
    piece (the last one short; with drop, pieces shortened by their bad rows, one
    piece all bad), each at its place in the file."""
    from quatarray.cli import main
    from quatarray.jobs import ROWS_PER_PIECE as _PIECE

    n = 3 * _PIECE + 123
    q = stream(n, seed=13)
    if on_invalid == "drop":
        q[[5, _PIECE - 1, 2 * _PIECE + 11, 3 * _PIECE + 7]] = np.nan  # on piece and block borders too
        q[_PIECE : 2 * _PIECE + 10] = 0  # the first block's second and third pieces all bad
    np.save(tmp_path / "long.npy", q)
    src, ref, dst = tmp_path / "long.npy", tmp_path / "ref.npy", tmp_path / "out.npy"
    assert main(["convert", str(src), str(ref), "--to", "euler:ZYX", "--on-invalid", on_invalid]) == 0
    capsys.readouterr()
    chunk = 2 * _PIECE + 5
    assert qd.convert_file(src, dst, "euler:ZYX", chunk=chunk, scheduler=client, on_invalid=on_invalid) == 0
    assert same(np.load(dst), np.load(ref))


def test_convert_file_zarr_in_and_out(client, npy_stream):
    q = np.load(npy_stream / "q.npy")
    src = _zarr_store(npy_stream / "q.zarr", q[:, [1, 2, 3, 0]], rows=333)  # stored x, y, z, w
    dst = npy_stream / "m.zarr"
    for force in (False, True):  # a second run replaces the store
        qd.convert_file(src, dst, "matrix", layout="xyzw", chunk=1000, scheduler=client, force=force)
        got, chunks = _read_zarr(dst)
        assert chunks == (1000, 3, 3)
        # the file job normalises as the command line does (plain numpy, no kernel):
        # to rounding, not bit for bit, what qa.normalize gives
        np.testing.assert_allclose(got, qa.as_matrix(qa.normalize(q)), rtol=0, atol=1e-15)
    assert sorted(p.name for p in npy_stream.iterdir() if "m.zarr" in p.name) == ["m.zarr"]
    # the command line's in-memory path reads a zarr store too
    from quatarray.cli import main

    assert main(["convert", str(src), str(npy_stream / "m1.npy"), "--to", "matrix", "--layout", "xyzw"]) == 0
    assert same(np.load(npy_stream / "m1.npy"), got)


def test_convert_file_bad_row_named_in_a_later_block(client, npy_stream):
    from quatarray.io.errors import DataError

    q = np.load(npy_stream / "q.npy")
    q[4321] = 0
    src = _zarr_store(npy_stream / "zero.zarr", q, rows=500)
    with pytest.raises(DataError, match=r"zero\.zarr: row 4321: zero quaternion"):
        qd.convert_file(src, npy_stream / "never.zarr", "quat", chunk=1000, scheduler=client)
    q[2500] = np.inf  # two bad rows: the first is named, whichever task fails first
    src = _zarr_store(npy_stream / "two.zarr", q, rows=500)
    for scheduler in (client, None):
        with pytest.raises(DataError, match=r"two\.zarr: row 2500: quaternion is not finite"):
            qd.convert_file(src, npy_stream / "never.npy", "quat", chunk=1000, scheduler=scheduler)
    assert not [p for p in npy_stream.iterdir() if "never" in p.name]
    every = _zarr_store(npy_stream / "nan.zarr", np.full((10, 4), np.nan), rows=3)
    with pytest.raises(DataError, match=r"nan\.zarr: no valid rows \(all 10 dropped\)"):
        qd.convert_file(every, npy_stream / "never.npy", "quat", chunk=4, scheduler=client, on_invalid="drop")


@needs("interpolation")
@pytest.mark.parametrize("bad", [[], [0, 1, 5, 9], [3], [0, 8, 9], [9], [1, 2, 3, 4, 5, 6, 7]])
def test_resample_key_times_made_by_the_workers(bad):
    """--in-rate key times of an npy or zarr stream (row k at k / rate, dropped rows left
    out) come from the workers, blocked like the keys: those of the whole array."""
    from quatarray.dask import _lazy_key_times, _plan_sizes

    rows, bad = 10, np.array(bad, np.int64)
    cuts = [0, 4, 7, rows]
    kept = [int(b - a - np.count_nonzero((bad >= a) & (bad < b))) for a, b in zip(cuts[:-1], cuts[1:])]
    plan = [(a, b, o) for a, b, o in zip(cuts[:-1], cuts[1:], np.cumsum([0] + kept[:-1]).tolist())]
    t, ends = _lazy_key_times(plan, bad, rows, 100.0)
    expect = np.delete(np.arange(rows, dtype=np.float64), bad) / 100.0
    assert t.chunks[0] == tuple(_plan_sizes(plan, rows - bad.size))
    assert np.array_equal(t.compute(scheduler="sync"), expect) and np.array_equal(ends, expect[[0, -1]])


def test_resample_file_drop_zarr_equals_cli(client, npy_stream, capsys):
    from quatarray.cli import main

    q, nbad = _bad_stream(seed=13)
    np.save(npy_stream / "kholes.npy", q)
    src = _zarr_store(npy_stream / "kholes.zarr", q, rows=640)
    ref = npy_stream / "kholes-ref.npy"
    assert main(["resample", str(npy_stream / "kholes.npy"), str(ref), "--rate", "7", "--in-rate", "2",
                 "--on-invalid", "drop", "--chunk", "900", "--force"]) == 0
    assert f"dropped {nbad} invalid rows" in capsys.readouterr().err
    dst = npy_stream / "kholes-r.zarr"
    assert qd.resample_file(src, dst, rate=7, in_rate=2, chunk=800, scheduler=client, on_invalid="drop") == 0
    assert f"dropped {nbad} invalid rows" in capsys.readouterr().err
    got, chunks = _read_zarr(dst)
    assert chunks == (800, 4)
    np.testing.assert_allclose(got, np.load(ref), rtol=0, atol=1e-13)


def test_errors_name_the_row_of_the_whole_array(client):
    """A block's error names the row (or index) in the whole array, as in memory."""
    m = qa.as_matrix(qa.random(1000, rng=0))
    m[777] *= -1
    for shape, chunks in (((1000, 3, 3), (100, 3, 3)), ((10, 100, 3, 3), (3, 40, 3, 3))):
        with pytest.raises(ValueError) as memory:
            qa.from_matrix(m.reshape(shape))
        with pytest.raises(ValueError) as lazy:
            run(client, qd.from_matrix(da.from_array(m.reshape(shape), chunks=chunks)))
        assert str(lazy.value) == str(memory.value)
        assert ("row 777" if len(shape) == 3 else "index (7, 77)") in str(lazy.value)
    axis = np.ones((50, 3))
    axis[33] = 0
    with pytest.raises(ValueError, match=r"row 33 is \(0, 0, 0\)"):
        run(client, qd.from_axis_angle(chunked(axis, 10), 0.5))


@pytest.mark.parametrize("out", ["npy", "zarr"])
def test_failed_run_waits_for_every_task(npy_stream, out, monkeypatch):
    """The first error is raised only after every other task has finished, so none of them
    writes into the temporary output after it was removed (threads: the writes are slowed
    down in this process)."""
    import threading
    import time

    from quatarray.io.errors import DataError

    if out == "zarr":
        pytest.importorskip("zarr")
    q = np.load(npy_stream / "q.npy")
    q[150] = np.nan
    np.save(npy_stream / "early.npy", q)
    target = qd._ZarrTarget if out == "zarr" else qd._NpyTarget
    events, lock = [], threading.Lock()
    write, leave = target.write, target.__exit__

    def slow_write(self, row0, data):
        time.sleep(0.05)
        with lock:
            events.append("write")
        return write(self, row0, data)

    def logged_exit(self, *exc):
        with lock:
            events.append("cleanup")
        return leave(self, *exc)

    monkeypatch.setattr(target, "write", slow_write)
    monkeypatch.setattr(target, "__exit__", logged_exit)
    with pytest.raises(DataError, match="row 150"):
        qd.convert_file(npy_stream / "early.npy", npy_stream / f"gone.{out}", "matrix", chunk=500, scheduler=None)
    time.sleep(0.3)  # a task still running would write now
    assert events[-1] == "cleanup" and "write" in events  # tasks finished (or were never started) first
    assert not [p.name for p in npy_stream.iterdir() if "gone" in p.name]


@needs("interpolation")
@pytest.mark.parametrize("scheduler", ["threads", "cluster"])
def test_resample_file_names_the_first_bad_row(npy_stream, scheduler, client, monkeypatch):
    """Block 1's bad row is found first (block 0 is read slowly), yet the error names
    block 0's: the first bad row of the file, as in memory."""
    import time

    from quatarray.io.errors import DataError

    q = np.load(npy_stream / "q.npy")
    q[[990, 1005, 2500]] = np.nan
    src = npy_stream / "two-bad.npy"
    np.save(src, q)
    read = qd._read_keys_task

    def slow_first(reader, a, b, drop):
        if a == 0:
            time.sleep(0.5)
        return read(reader, a, b, drop)

    if scheduler == "threads":
        monkeypatch.setattr(qd, "_read_keys_task", slow_first)
    with pytest.raises(DataError, match=r"two-bad\.npy: row 990: quaternion is not finite"):
        qd.resample_file(src, npy_stream / "never.npy", rate=5, in_rate=2, chunk=1000,
                         scheduler=None if scheduler == "threads" else client)
    assert not (npy_stream / "never.npy").exists()


def test_command_line_local_cluster(npy_stream, capsys):
    """``--scheduler local``: the command line starts (and stops) its own cluster, whose
    client is not the default one."""
    pytest.importorskip("zarr")
    from quatarray.cli import main

    q, nbad = _bad_stream(seed=14)
    np.save(npy_stream / "cli.npy", q)
    ref = npy_stream / "cli-ref.npy"
    assert main(["convert", str(npy_stream / "cli.npy"), str(ref), "--to", "euler:ZYX", "--on-invalid", "drop"]) == 0
    dst = npy_stream / "cli.zarr"
    assert main(["convert", str(npy_stream / "cli.npy"), str(dst), "--to", "euler:ZYX", "--on-invalid", "drop",
                 "--scheduler", "local", "--chunk", "1000"]) == 0
    assert same(_read_zarr(dst)[0], np.load(ref))
    assert main(["resample", str(dst), str(npy_stream / "cli-r.npy"), "--rate", "3", "--in-rate", "2",
                 "--scheduler", "local"]) == 1  # angles are no quaternions: a one-line data error
    assert "expected quaternions of shape (N, 4)" in capsys.readouterr().err


def test_empty_and_unknown_chunks(client):
    """Empty chunks pass through every scan; unknown chunk sizes are a clear error."""
    q = stream(20, seed=15)
    t, nt = np.arange(20.0), np.linspace(0, 19, 77)
    for rows in ((5, 0, 15), (0, 20), (20, 0), (3, 0, 0, 7, 0, 10)):
        x = da.from_array(q, chunks=(rows, 4))
        assert same(run(client, qd.unflip(x)), qa.unflip(q))
        np.testing.assert_allclose(run(client, qd.cumprod(x)), qa.cumprod(q), rtol=0, atol=1e-13)
        np.testing.assert_allclose(run(client, qd.spline(t, x, nt, chunks=10)), qa.spline(t, q, nt), atol=1e-13)
        np.testing.assert_allclose(run(client, qd.spline(t, x, nt)), qa.spline(t, q, nt), atol=1e-13)  # blocks per key block
    x = chunked(q, 6)
    with pytest.raises(ValueError, match=r"known chunk sizes.*q\.compute_chunk_sizes\(\)"):
        qd.normalize(x[x[:, 0] > 0])
    times = da.from_array(nt, chunks=30)
    with pytest.raises(ValueError, match="`new_times` with known chunk sizes"):
        qd.spline(t, x, times[times > 3])


def test_gimbal_lock_counted_in_rows(npy_stream, capsys):
    """The note counts rows at gimbal lock, the same on threads, a cluster and in memory."""
    from quatarray.cli import main

    q = stream(3000, seed=16)
    q[::100] = qa.from_euler("ZYX", [0.3, np.pi / 2, 0.2])  # 30 rows at gimbal lock
    np.save(npy_stream / "lock.npy", q)
    assert main(["convert", str(npy_stream / "lock.npy"), str(npy_stream / "lock-m.npy"), "--to", "euler:ZYX",
                 "--chunk", "700", "--force"]) == 0
    assert "gimbal lock in 30 rows" in capsys.readouterr().err
    for i in range(2):  # threads, then the local cluster of the command line
        qd.convert_file(npy_stream / "lock.npy", npy_stream / "lock-d.npy", "euler:ZYX", chunk=200,
                        scheduler=[None, "local"][i], force=True)
        assert "gimbal lock in 30 rows" in capsys.readouterr().err
        assert same(np.load(npy_stream / "lock-d.npy"), np.load(npy_stream / "lock-m.npy"))


@needs("interpolation")
def test_resample_file_notes_and_text_drop(npy_stream, tmp_path, capsys):
    """Resample on the workers reports normalised keys like the command line, and a text
    file without times keeps each row's own time when bad rows are dropped."""
    from quatarray.cli import main

    src = npy_stream / "q.npy"  # slightly non-unit keys
    assert qd.resample_file(src, tmp_path / "r.npy", rate=3, in_rate=2, chunk=900) == 0
    assert "normalised 5000 non-unit quaternions" in capsys.readouterr().err
    q = stream(20, seed=17)
    lines = ["qw,qx,qy,qz"] + [",".join(str(float(v)) for v in row) for row in q]
    lines[8] = "nan,0,0,1"
    (tmp_path / "k.csv").write_text("\n".join(lines) + "\n")
    args = [str(tmp_path / "k.csv"), "--rate", "2", "--in-rate", "1", "--on-invalid", "drop"]
    assert main(["resample", args[0], str(tmp_path / "cli.csv"), *args[1:]]) == 0
    expect = np.loadtxt(tmp_path / "cli.csv", delimiter=",", skiprows=1)[:, 1:]
    qd.resample_file(tmp_path / "k.csv", tmp_path / "d.npy", rate=2, in_rate=1, on_invalid="drop")
    got = np.load(tmp_path / "d.npy")
    assert got.shape == expect.shape == (39, 4)  # 0 … 19 s at 2 Hz: row 7's gap keeps the times
    np.testing.assert_allclose(got, expect, rtol=0, atol=1e-12)
