"""quatarray.dask's lazy arrays (quatarray.dask.arrays, quatarray.dask.windows) against
the in-memory functions, on a real LocalCluster of worker processes.

Element-wise kernels must agree bitwise, scans and splines to 1e-13, whatever
the chunking: chunk borders inside spline segments, on sign flips, chunks of
one row. Results must stay lazy until computed.
"""

import numpy as np
import pytest

da = pytest.importorskip("dask.array")
dask = pytest.importorskip("dask")
distributed = pytest.importorskip("distributed")

import quatarray as qa  # noqa: E402
import quatarray.dask as qd  # noqa: E402
import quatarray.dask.arrays as qda  # noqa: E402
import quatarray.dask.windows as qdw  # noqa: E402
from dask_common import CHUNKS, MODULE_OF, _cases, chunked, client, has, needs, q, run, same, stream  # noqa: E402,F401


# --------------------------------------------------------------------------
# element-wise functions: bitwise on the cluster


@pytest.mark.parametrize("rows", [100, 1])
@pytest.mark.parametrize("name", sorted(set(qda.ELEMENTWISE) - {"from_su2"}))  # from_su2: below
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


@pytest.mark.parametrize("seq", ["z", "X", "xy", "ZX", "zyx"])
def test_from_euler_short_sequences_bitwise(client, seq):
    ang = np.random.default_rng(5).uniform(-4, 4, (300, len(seq)))
    for kw in ({}, {"degrees": True}):
        lazy = qd.from_euler(seq, chunked(ang, 64), **kw)
        expect = qa.from_euler(seq, ang, **kw)
        assert lazy.shape == expect.shape and same(run(client, lazy), expect)
    if len(seq) == 1:  # one angle about one axis, as in memory
        assert same(qd.from_euler(seq, 0.5).compute(), qa.from_euler(seq, 0.5))
    with pytest.raises(ValueError, match=rf"\(\.\.\., {len(seq)}\)"):
        qd.from_euler(seq, chunked(np.zeros((10, len(seq) % 3 + 1)), 5))
    with pytest.raises(ValueError, match="Expected `seq`"):
        qd.from_euler(seq + seq[-1] * 3, chunked(ang, 64))


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
    """A key stream whose sign chain breaks: a zero row and a nan row, and an exact
    half turn (dot product 0: the tie rule, which carries the sign on), each with flips
    before and after it."""
    q = stream(40, seed=seed)
    q[9] = 0.0
    q[21] = np.nan
    q[30], q[31] = [1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]
    q[14:17] = [[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, -1.0, 0.0], [0.0, 0.6, 0.0, -0.8]]  # half turns
    q[[8, 10, 15, 20, 22, 29, 32]] *= -1
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
@pytest.mark.parametrize("method", ["bezier", "slerp", "nlerp", "squad"])
def test_spline_rates_any_chunking(method):
    """order=1, 2 from the same key windows as the values: the in-memory rates."""
    t, keys = keyed(50, seed=9)
    rng = np.random.default_rng(9)
    nt = np.concatenate([rng.uniform(t[0], t[-1], 300), t])
    for order in (1, 2):
        expect = qa.spline(t, keys, nt, method=method, order=order)
        for rows in (1, 7):
            lazy = qd.spline(t, chunked(keys, rows), nt, method=method, order=order)
            assert lazy.shape == (len(nt), 3)
            np.testing.assert_allclose(lazy.compute(scheduler="sync"), expect, rtol=0,
                                       atol=1e-12 * (1 + np.abs(expect).max()))


@needs("interpolation")
def test_spline_refuses_cubic_and_bad_order():
    t, keys = keyed(20, seed=4)
    x, nt = chunked(keys, 6), np.linspace(t[0], t[-1], 50)
    for order in (0, 1):
        with pytest.raises(ValueError, match=r"got 'cubic': its C² spline is global \(one tridiagonal system"):
            qd.spline(t, x, nt, method="cubic", order=order)
    for bad in (3, -1, 1.5, True):
        with pytest.raises(ValueError, match=r"Expected `order` to be 0, 1 or 2"):
            qd.spline(t, x, nt, order=bad)


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
    # a summary carries EDGE_ROWS rows from each end of its block, whatever the block's size
    t, keys = keyed(1000, seed=9)
    x = chunked(keys, 250)
    nt = np.linspace(t[0], t[-1], 3000)
    lazy = qd.spline(t, x, nt)  # output blocks start where key blocks do
    assert not any(small for _, small in _whole_blocks_and_small_inputs(lazy, x, f"rows-{x.name}"))
    found = _whole_blocks_and_small_inputs(lazy, x, "spline-summary")
    summaries = dask.get(lazy.__dask_graph__(), sorted({d for _, small in found for d in small}))
    assert [len(e) for s in summaries for e in s[5]] == [qdw.EDGE_ROWS] * 2 * len(summaries)
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
# align_vectors and mean (issue 36.20)


def _problems(p, n, seed=11, dtype=np.float64):
    rng = np.random.default_rng(seed)
    b = rng.standard_normal((p, n, 3))
    a = qa.rotate(qa.random((p, 1), rng=rng), b) + 0.02 * rng.standard_normal((p, n, 3))
    return a.astype(dtype), b.astype(dtype), rng.uniform(0.5, 2, (p, n))


@pytest.mark.parametrize("rows", [1, 7, 40])
def test_align_vectors_bitwise_any_chunking(client, rows):
    a, b, w = _problems(40, 6)
    for args, kw in (((a, b), {}), ((a, b, w), {}), ((a, b[0], w[0]), {}), ((a, b, w), {"return_sensitivity": True})):
        expect = qa.align_vectors(*args, **kw)
        lazy = qd.align_vectors(*[chunked(x, rows) if x.ndim == a.ndim else x for x in args], **kw)
        assert isinstance(lazy, tuple) and len(lazy) == len(expect) and all(isinstance(x, da.Array) for x in lazy)
        assert all(x.shape == e.shape and x.dtype == e.dtype for x, e in zip(lazy, expect))
        assert lazy[0].chunks[0][0] == rows
        got = run(client, lazy)
        assert all(same(g, e) for g, e in zip(got, expect))
    # Dask weights chunked otherwise, b chunked along its pairs (rechunked whole), float32
    a32, b32, _ = _problems(40, 6, dtype=np.float32)
    lazy = qd.align_vectors(chunked(a32, rows), da.from_array(b32, chunks=(13, 2, 3)), da.from_array(w, chunks=(9, 6)))
    expect = qa.align_vectors(a32, b32, w)
    assert lazy[0].dtype == np.float32 and all(same(g, e) for g, e in zip(run(client, lazy), expect))
    # one pair per problem (the shortest arc) and a single vector
    assert all(same(g, e) for g, e in zip(run(client, qd.align_vectors(chunked(a[:, :1], rows), b[:, :1])),
                                          qa.align_vectors(a[:, :1], b[:, :1])))
    assert all(same(g, e) for g, e in zip(dask.compute(*qd.align_vectors(a[0, 0], b[0, 0])),
                                          qa.align_vectors(a[0, 0], b[0, 0])))


def test_align_vectors_errors():
    a, b, w = _problems(20, 4)
    with pytest.raises(ValueError, match="same number of vectors"):
        qd.align_vectors(chunked(a, 5), b[:, :3])
    with pytest.raises(ValueError, match=r"`weights` to have shape \(\.\.\., 4\)"):
        qd.align_vectors(chunked(a, 5), b, np.ones(3))
    with pytest.raises(ValueError, match="`a` to have shape"):
        qd.align_vectors(chunked(a[..., :2], 5), b)
    w[13, 1:3] = np.inf  # several infinite weights: raised at compute, naming the problem in the whole batch
    lazy = qd.align_vectors(chunked(a, 5), b, chunked(w, 5))
    with pytest.raises(ValueError, match="row 13 has several"):
        dask.compute(*lazy, scheduler="sync")


@pytest.mark.parametrize("chunks", [(1, 50), (7, 11), (30, 50)])
def test_mean_across_chunks(client, chunks):
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(12)
    # random rotations (their mean is ill-conditioned: the worst case for the order of the sums)
    # and a cluster around one rotation
    for qs in (qa.random((30, 50), rng=rng), qa.multiply(qa.from_rotvec([0.3, -1, 2]), qa.from_rotvec(
            0.3 * rng.standard_normal((30, 50, 3))))):
        qs[::3] *= -2.5  # sign- and scale-blind
        w = rng.random((30, 50))
        x = da.from_array(qs, chunks=chunks + (4,))
        r = Rotation.from_quat(qs, scalar_first=True)
        for axis in (None, 0, 1, -1, (0, 1), ()):
            for weights in (None, w, w[:1], da.from_array(w, chunks=(4, 17))):
                ww = weights.compute() if isinstance(weights, da.Array) else weights
                lazy = qd.mean(x, weights, axis=axis)
                expect = qa.mean(qs, ww, axis=axis)
                assert isinstance(lazy, da.Array) and lazy.shape == expect.shape and lazy.dtype == expect.dtype
                got = lazy.compute(scheduler="sync")
                assert np.all(qa.distance(got, expect) < 1e-12)
                assert np.all(qa.distance(got, r.mean(weights=ww, axis=axis).as_quat(scalar_first=True)) < 1e-12)
                whole = axis == () or (axis in (1, -1) and chunks[1] == 50) or chunks == (30, 50)
                if whole:  # the averaged axes in one chunk: the in-memory sums, bitwise
                    assert same(got, expect)
    # on the cluster's worker processes; float32 stays float32
    q32 = qs.astype(np.float32)
    got = run(client, qd.mean(da.from_array(q32, chunks=chunks + (4,)), axis=1))
    assert same(got, qa.mean(q32, axis=1)) if chunks[1] == 50 else np.all(qa.distance(got, qa.mean(q32, axis=1)) < 1e-6)
    got = run(client, qd.mean(da.from_array(q32, chunks=chunks + (4,))))
    assert got.dtype == np.float32 and qa.distance(got, qa.mean(q32)) < 1e-6


def test_mean_edges_and_errors():
    qs = qa.random(100, rng=13)
    x = chunked(qs, 30)
    # a single quaternion; all weights zero: the identity, as scipy
    assert same(qd.mean(qs[5]).compute(), qa.mean(qs[5]))
    assert same(qd.mean(qs[5], axis=0).compute(), qa.mean(qs[5], axis=0))
    assert same(qd.mean(x, np.zeros(100)).compute(), qa.mean(qs, np.zeros(100)))
    for bad in (3, (0, 1), 1.0):
        with pytest.raises(ValueError, match="axis"):
            qd.mean(x, axis=bad)
    with pytest.raises(ValueError, match="broadcast"):
        qd.mean(x, np.ones(7))
    with pytest.raises(ValueError, match="at least one"):
        qd.mean(chunked(np.ones((0, 4)), 5))
    with pytest.raises(TypeError, match="weights"):
        qd.mean(x, np.ones(100, complex))
    # a bad row is named by its index in the whole array, at compute
    b = qs.copy()
    b[67] = 0.0
    lazy = qd.mean(chunked(b, 30))
    with pytest.raises(ValueError, match=r"`q` to be finite and non-zero; row 67 is zero"):
        lazy.compute(scheduler="sync")
    w = np.ones(100)
    w[71] = -1
    with pytest.raises(ValueError, match=r"`weights` to be non-negative; row 71"):
        qd.mean(x, chunked(w, 30)).compute(scheduler="sync")
    with pytest.raises(ValueError, match=r"index \(6, 7\) is zero"):
        qd.mean(da.from_array(b.reshape(10, 10, 4), chunks=(3, 4, 4)), axis=0).compute(scheduler="sync")
    # the blocks' sums are finite, their total is not
    big = np.full(100, 1e307)
    with pytest.raises(ValueError, match="overflows"), np.errstate(over="ignore"):  # (numpy's sum of the blocks)
        qd.mean(x, chunked(big, 30)).compute(scheduler="sync")


def test_mean_and_align_stay_lazy():
    x = exploding((100, 4), 10)
    for lazy in (qd.mean(x), qd.mean(x, np.ones(100)), qd.align_vectors(exploding((100, 3), 10)[:, None], [[1.0, 0, 0]])[0]):
        assert isinstance(lazy, da.Array)
        with pytest.raises(RuntimeError, match="was computed"):
            lazy.compute(scheduler="sync")
