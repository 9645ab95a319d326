"""quatarray.dask: scaling from 1 to 2 worker processes, and the overhead against one process.

Run with ``pytest benchmarks/test_dask.py --benchmark-only``. Each group
holds, measured side by side in one run:

- ``inmemory-1thread``: the in-memory path in this process with numba's
  row loops kept on one thread (the single-process baseline);
- ``inmemory-2threads``: the same with numba's parallel row loops (2 cores);
- ``dask-1worker`` / ``dask-2workers``: a ``distributed.LocalCluster`` of 1
  or 2 single-threaded worker processes on 127.0.0.1 (started outside the
  timing).

scaling = time(1 worker) / time(2 workers) (goal ≥ 1.6 on 2 cores);
overhead = time(1 worker) / time(in memory, 1 thread).

Workloads: ``convert`` of a 10⁷-row ``.npy`` file to Euler angles (file to
file, as ``quatarray convert --scheduler``, in blocks of 5·10⁵ or 2.5·10⁶
rows), and a 10⁶-sample Bézier
``spline`` (chunked keys in, the lazy result computed on the workers) through
10⁵ unevenly timed keys (in 4 blocks, Dask's advice being tasks of 100 ms or
so: here ~25 ms each; and in 20 small blocks) or through 10⁶ keys (a stream
resampled at its own rate, 4 blocks), with key times and new times given as
numpy arrays or as Dask arrays persisted on the workers; see ``SPLINE_CASES``.
For scale, ``test_spline_dask_floor`` runs the same spline as 4 independent
tasks on windows placed on the workers beforehand (no sign scan, no
neighbour rows, no graph to build): what Dask itself allows on this machine.
"""

import numpy as np
import pytest

pytest.importorskip("dask")
distributed = pytest.importorskip("distributed")

import dask.array as da  # noqa: E402

import quatarray as qa  # noqa: E402
import quatarray.dask as qd  # noqa: E402
import quatarray.dask.windows as qdw  # noqa: E402
from quatarray import _jit  # noqa: E402

N_CONVERT = 10_000_000
CHUNK_CONVERT = [500_000, 2_500_000]  # rows per block: 20 tasks of ~6 ms, or 4 of ~30 ms
N_SAMPLES = 1_000_000


@pytest.fixture(scope="module", params=[1, 2], ids=["1worker", "2workers"])
def client(request):
    cluster = qd.local_cluster(request.param)
    c = distributed.Client(cluster)
    c.wait_for_workers(request.param)
    yield c
    c.close()
    cluster.close()


@pytest.fixture(scope="module")
def npy(tmp_path_factory):
    folder = tmp_path_factory.mktemp("dask-bench")
    src = folder / "q.npy"
    q = np.lib.format.open_memmap(src, mode="w+", dtype=np.float64, shape=(N_CONVERT, 4))
    for a in range(0, N_CONVERT, 1_000_000):
        q[a : a + 1_000_000] = qa.random(1_000_000, rng=a)
    q.flush()
    del q
    return src, folder / "out.npy"


@pytest.fixture(scope="module", params=[100_000, 1_000_000], ids=["keys1e5", "keys1e6"])
def stream(request):
    n_keys = request.param
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.5, 1.5, n_keys))
    keys = qa.cumprod(qa.from_rotvec(rng.normal(0, 0.1, (n_keys, 3))))
    keys[rng.random(n_keys) < 0.2] *= -1
    nt = np.linspace(t[0], t[-1], N_SAMPLES)
    return t, keys, nt


@pytest.fixture
def one_thread(monkeypatch):
    monkeypatch.setattr(_jit, "PARALLEL_MIN_ROWS", 1 << 62)


@pytest.fixture(params=CHUNK_CONVERT, ids=["blocks5e5", "blocks2.5e6"])
def chunk(request, benchmark):
    benchmark.group = f"dask-convert-1e7-rows-to-euler-blocks-of-{request.param:.1e}"
    return request.param


def _cli_convert(src, dst, chunk):
    from quatarray.app.cli import main

    assert main(["convert", str(src), str(dst), "--to", "euler:ZYX", "--chunk", str(chunk),
                 "--force", "--no-progress"]) == 0


def _fresh(npy, chunk):
    """Setup of every round: no old OUT (unlinking 240 MB of it would be timed with the rename)."""
    if npy[1].exists():
        npy[1].unlink()
    return (*npy, chunk), {}


def test_convert_inmemory_1thread(benchmark, npy, chunk, one_thread):
    benchmark.pedantic(_cli_convert, setup=lambda: _fresh(npy, chunk), rounds=5, warmup_rounds=1)


def test_convert_inmemory_2threads(benchmark, npy, chunk):
    benchmark.pedantic(_cli_convert, setup=lambda: _fresh(npy, chunk), rounds=5, warmup_rounds=1)


def test_convert_dask(benchmark, npy, chunk, client):
    src, dst = npy

    def run(src, dst, chunk):
        qd.convert_file(src, dst, "euler:ZYX", chunk=chunk, scheduler=client, force=True)

    benchmark.pedantic(run, setup=lambda: _fresh(npy, chunk), rounds=5, warmup_rounds=1)
    np.testing.assert_array_equal(np.load(dst, mmap_mode="r")[:1000], qa.as_euler(np.load(src)[:1000], "ZYX"))


def _spline_group(benchmark, keys):
    benchmark.group = f"dask-spline-1e6-samples-from-{len(keys):.0e}-keys"


def test_spline_inmemory_1thread(benchmark, stream, one_thread):
    t, keys, nt = stream
    _spline_group(benchmark, keys)
    benchmark.pedantic(qa.spline, args=(t, keys, nt), rounds=5, iterations=1, warmup_rounds=1)


def test_spline_inmemory_2threads(benchmark, stream):
    t, keys, nt = stream
    _spline_group(benchmark, keys)
    benchmark.pedantic(qa.spline, args=(t, keys, nt), rounds=5, iterations=1, warmup_rounds=1)


SPLINE_CASES = [  # (key blocks, key times, new times, result)
    (4, "numpy", "dask", "persisted"),
    (4, "dask", "dask", "persisted"),
    (4, "numpy", "numpy", "persisted"),
    (4, "numpy", "dask", "gathered"),
    (20, "numpy", "dask", "persisted"),
]


@pytest.mark.parametrize("blocks,key_times,new_times,result", SPLINE_CASES,
                         ids=[f"{b}blocks-t_{t}-nt_{n}-{r}" for b, t, n, r in SPLINE_CASES])
def test_spline_dask(benchmark, stream, client, blocks, key_times, new_times, result):
    """Keys persisted on the workers in `blocks` blocks. Key times ``numpy``: an
    in-memory array (its windows travel in the graph); ``dask``: persisted on the
    workers like the keys. New times ``dask``: also persisted on the workers, in as
    many blocks as the keys; ``numpy``: an in-memory array whose slices travel in the
    graph. Result ``persisted``: kept in the workers' memory (``persist``), as a
    cluster keeps what it stores or processes further; ``gathered``: the 32 MB result
    comes back to this process (``compute``)."""
    t, keys, _ = stream
    _spline_group(benchmark, keys)
    if blocks == 20 and len(keys) > 100_000:
        pytest.skip("small blocks: measured on the 10⁵ keys")
    chunk = -(-len(keys) // blocks)
    keys_d = client.persist(da.from_array(keys, chunks=(chunk, 4)))
    distributed.wait(keys_d)
    times = t
    if key_times == "dask":
        times = client.persist(da.from_array(t, chunks=chunk))
        distributed.wait(times)
    nt = stream[2]
    new = nt
    if new_times == "dask":
        new = client.persist(da.from_array(nt, chunks=-(-N_SAMPLES // blocks)))
        distributed.wait(new)

    def run():
        lazy = qd.spline(times, keys_d, new)  # a fresh graph (and fresh names) every round
        if result == "gathered":
            return client.compute(lazy, sync=True)
        kept = client.persist(lazy)
        distributed.wait(kept)
        return kept

    got = benchmark.pedantic(run, rounds=10, warmup_rounds=1)  # short jobs on a shared machine: more rounds
    got = got if result == "gathered" else got.compute()
    np.testing.assert_allclose(got, qa.spline(t, keys, nt), rtol=0, atol=1e-13)


def test_spline_dask_floor(benchmark, stream, client):
    """The floor under ``test_spline_dask``: the in-memory spline of each quarter of the
    new times, on its window of keys (one before, two after) placed beforehand on the
    worker that runs it (half of them on each of 2 workers), as 4 independent tasks. Each
    window keeps its first key's sign (no scan), so a quarter may come out negated."""
    t, keys, nt = stream
    _spline_group(benchmark, keys)
    workers = sorted(client.scheduler_info()["workers"])
    placed = []
    for j in range(4):
        a, b = j * N_SAMPLES // 4, (j + 1) * N_SAMPLES // 4
        w0 = max(0, int(np.searchsorted(t, nt[a], "right")) - 2)
        w1 = min(len(t), int(np.searchsorted(t, nt[b - 1], "right")) + 2)
        where = [workers[j * len(workers) // 4]]
        placed.append((where, client.scatter([t[w0:w1], keys[w0:w1], nt[a:b]], workers=where)))

    def run():
        tasks = [client.submit(qdw._spline_task, wt, [wk], False, wn, "bezier", None, workers=where, pure=False)
                 for where, (wt, wk, wn) in placed]
        distributed.wait(tasks)
        return tasks

    tasks = benchmark.pedantic(run, rounds=10, warmup_rounds=1)
    expect = np.array_split(qa.spline(t, keys, nt), 4)
    for got, want in zip(client.gather(tasks), expect):
        np.testing.assert_allclose(got if got[0] @ want[0] > 0 else -got, want, rtol=0, atol=1e-13)
