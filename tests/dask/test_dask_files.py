"""quatarray.dask's file jobs (quatarray.dask.files: convert_file, resample_file, the
command line's --scheduler path) against the command line in one process, on a
real LocalCluster of worker processes and on threads: npy and zarr in and out,
--on-invalid drop, errors naming the file's row, no output left by a failed run.
"""

import numpy as np
import pytest

da = pytest.importorskip("dask.array")
dask = pytest.importorskip("dask")
distributed = pytest.importorskip("distributed")

import quatarray as qa  # noqa: E402
import quatarray.dask as qd  # noqa: E402
import quatarray.dask.files as qdf  # noqa: E402
import quatarray.io.targets as targets  # noqa: E402
from dask_common import chunked, client, needs, run, same, stream  # noqa: E402,F401


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
    from quatarray.app.cli import main

    src, dst, ref = npy_stream / "q.npy", npy_stream / f"d-{to}.npy", npy_stream / f"m-{to}.npy"
    extra = ["--degrees"] if to in ("rotvec", "euler:ZXY") else []
    assert main(["convert", str(src), str(ref), "--to", to, "--chunk", "700", *extra]) == 0
    assert qd.convert_file(src, dst, to, degrees=bool(extra), chunk=700, scheduler=client) == str(dst)
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
    from quatarray.app.cli import main

    src = npy_stream / "q.npy"
    dst, ref = npy_stream / f"r-{method}.npy", npy_stream / f"rm-{method}.npy"
    assert main(["resample", str(src), str(ref), "--rate", "7", "--in-rate", "2", "--method", method,
                 "--chunk", "800", "--force"]) == 0
    assert qd.resample_file(src, dst, rate=7, in_rate=2, method=method, chunk=800, scheduler=client) == str(dst)
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
    from quatarray.app.cli import main

    if out == "zarr":
        pytest.importorskip("zarr")
    q, nbad = _bad_stream()
    np.save(npy_stream / "holes.npy", q)
    src, ref = npy_stream / "holes.npy", npy_stream / "holes-ref.npy"
    assert main(["convert", str(src), str(ref), "--to", "euler:ZYX", "--on-invalid", "drop", "--force"]) == 0
    expect_err = capsys.readouterr().err
    assert f"dropped {nbad} invalid rows" in expect_err
    dst = npy_stream / f"holes-d.{out}"
    assert qd.convert_file(src, dst, "euler:ZYX", chunk=700, scheduler=client, on_invalid="drop") == str(dst)
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
    from quatarray.app.cli import main
    from quatarray.jobs import ROWS_PER_PIECE

    n = 3 * ROWS_PER_PIECE + 123
    q = stream(n, seed=13)
    if on_invalid == "drop":
        q[[5, ROWS_PER_PIECE - 1, 2 * ROWS_PER_PIECE + 11, 3 * ROWS_PER_PIECE + 7]] = np.nan  # piece and block borders
        q[ROWS_PER_PIECE : 2 * ROWS_PER_PIECE + 10] = 0  # the first block's second and third pieces all bad
    np.save(tmp_path / "long.npy", q)
    src, ref, dst = tmp_path / "long.npy", tmp_path / "ref.npy", tmp_path / "out.npy"
    assert main(["convert", str(src), str(ref), "--to", "euler:ZYX", "--on-invalid", on_invalid]) == 0
    capsys.readouterr()
    chunk = 2 * ROWS_PER_PIECE + 5
    assert qd.convert_file(src, dst, "euler:ZYX", chunk=chunk, scheduler=client, on_invalid=on_invalid) == str(dst)
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
    from quatarray.app.cli import main

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
    from quatarray.dask.files import lazy_key_times, plan_sizes

    rows, bad = 10, np.array(bad, np.int64)
    cuts = [0, 4, 7, rows]
    kept = [int(b - a - np.count_nonzero((bad >= a) & (bad < b))) for a, b in zip(cuts[:-1], cuts[1:])]
    plan = [(a, b, o) for a, b, o in zip(cuts[:-1], cuts[1:], np.cumsum([0] + kept[:-1]).tolist())]
    t, ends = lazy_key_times(plan, bad, rows, 100.0)
    expect = np.delete(np.arange(rows, dtype=np.float64), bad) / 100.0
    assert t.chunks[0] == tuple(plan_sizes(plan, rows - bad.size))
    assert np.array_equal(t.compute(scheduler="sync"), expect) and np.array_equal(ends, expect[[0, -1]])


def test_resample_file_drop_zarr_equals_cli(client, npy_stream, capsys):
    from quatarray.app.cli import main

    q, nbad = _bad_stream(seed=13)
    np.save(npy_stream / "kholes.npy", q)
    src = _zarr_store(npy_stream / "kholes.zarr", q, rows=640)
    ref = npy_stream / "kholes-ref.npy"
    assert main(["resample", str(npy_stream / "kholes.npy"), str(ref), "--rate", "7", "--in-rate", "2",
                 "--on-invalid", "drop", "--chunk", "900", "--force"]) == 0
    assert f"dropped {nbad} invalid rows" in capsys.readouterr().err
    dst = npy_stream / "kholes-r.zarr"
    assert qd.resample_file(src, dst, rate=7, in_rate=2, chunk=800, scheduler=client, on_invalid="drop") == str(dst)
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
    target = targets.ZarrTarget if out == "zarr" else targets.NpyTarget
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
    read = qdf.read_keys_task

    def slow_first(reader, a, b, drop):
        if a == 0:
            time.sleep(0.5)
        return read(reader, a, b, drop)

    if scheduler == "threads":
        monkeypatch.setattr(qdf, "read_keys_task", slow_first)
    with pytest.raises(DataError, match=r"two-bad\.npy: row 990: quaternion is not finite"):
        qd.resample_file(src, npy_stream / "never.npy", rate=5, in_rate=2, chunk=1000,
                         scheduler=None if scheduler == "threads" else client)
    assert not (npy_stream / "never.npy").exists()


def test_command_line_local_cluster(npy_stream, capsys):
    """``--scheduler local``: the command line starts (and stops) its own cluster, whose
    client is not the default one."""
    pytest.importorskip("zarr")
    from quatarray.app.cli import main

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
    from quatarray.app.cli import main

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
    from quatarray.app.cli import main

    src = npy_stream / "q.npy"  # slightly non-unit keys
    assert qd.resample_file(src, tmp_path / "r.npy", rate=3, in_rate=2, chunk=900) == str(tmp_path / "r.npy")
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
