"""Trajectory evaluation (quatarray.trajectory, ``quatarray eval``) against evo itself.

Estimates are made from the real ground truths (slices of them): a known
similarity transform, noise on positions and rotations, dropped poses and
jittered times; evo reads the same files with its own readers.
"""

import copy
import json
import os
import subprocess
import sys

import numpy as np
import pytest

import quatarray as qa
from quatarray import trajectory as T
from quatarray.app.cli import main
from quatarray.app.eval_verb import PoseFile, read_poses, run_chunked

evo = pytest.importorskip("evo", reason="evo (the test extra) is needed to compare with it")
from evo.core import metrics, sync  # noqa: E402
from evo.core.metrics import PoseRelation, Unit  # noqa: E402
from evo.tools import file_interface  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ROWS = 1500  # rows of each ground truth used
RTOL = 1e-9
RELATIONS = {"trans": PoseRelation.translation_part, "rot": PoseRelation.rotation_angle_deg,
             "full": PoseRelation.full_transformation}
SIM = (1.7, qa.from_rotvec([0.3, -0.2, 0.9]), np.array([2.0, -1.0, 0.5]))  # est = s R ref + t


def _head(src, dst, rows):
    """The comment lines and the first `rows` data lines of a text file."""
    with open(src) as f, open(dst, "w") as g:
        n = 0
        for line in f:
            g.write(line)
            n += not line.startswith("#")
            if n >= rows:
                break


def _make_estimate(ref, rng, timed):
    """The known similarity applied, noise, and (timed) 10 % of the poses dropped, times jittered."""
    s, q, t = SIM
    qq = np.tile(q, (len(ref), 1))
    pos = s * qa.rotate(qq, ref.pos) + t + rng.normal(scale=0.01, size=ref.pos.shape)
    rot = qa.multiply(qa.multiply(qq, ref.q), qa.from_rotvec(rng.normal(scale=0.01, size=(len(ref), 3))))
    if not timed:
        return T.Poses(None, pos, rot)
    keep = np.sort(rng.choice(len(ref), int(0.9 * len(ref)), replace=False))
    times = ref.t[keep] + rng.uniform(-0.003, 0.003, keep.size)
    return T.Poses(times, pos[keep], rot[keep])


def _write_tum(path, p):
    np.savetxt(path, np.c_[p.t, p.pos, p.q[:, 1:], p.q[:, :1]], fmt="%.17g")


def _write_kitti(path, p):
    m = np.concatenate([qa.as_matrix(p.q), p.pos[:, :, None]], axis=2)
    np.savetxt(path, m.reshape(-1, 12), fmt="%.17g")


DATASETS = {
    "tum": ("tum_freiburg2_desk_groundtruth.txt", file_interface.read_tum_trajectory_file),
    "euroc": ("euroc_v102_groundtruth.csv", file_interface.read_euroc_csv_trajectory),
    "kitti": ("kitti_00_poses.txt", file_interface.read_kitti_poses_file),
}
_CASES = {}


@pytest.fixture(params=sorted(DATASETS))
def case(request, data_dir, tmp_path_factory):
    """(name, ref path, est path, evo ref, evo est) for one ground truth."""
    name = request.param
    if name not in _CASES:
        folder = tmp_path_factory.mktemp(name)
        src, evo_read = DATASETS[name]
        ref_path = str(folder / os.path.basename(src))
        _head(data_dir / src, ref_path, ROWS)
        ref = read_poses(ref_path)
        est = _make_estimate(ref, np.random.default_rng(18), timed=ref.t is not None)
        est_path = str(folder / "est.txt")
        (_write_tum if ref.t is not None else _write_kitti)(est_path, est)
        est_read = file_interface.read_tum_trajectory_file if ref.t is not None else file_interface.read_kitti_poses_file
        evo_ref_path = ref_path
        if name == "kitti":  # see test_kitti_raw_matrices_against_evo
            evo_ref_path = str(folder / "ref_orthonormal.txt")
            _write_kitti(evo_ref_path, ref)
        _CASES[name] = (name, ref_path, est_path, evo_read(evo_ref_path), est_read(est_path))
    return _CASES[name]


def _evo(ref, est, metric, align, relation, n_to_align=-1, **rpe):
    ref, est = copy.deepcopy(ref), copy.deepcopy(est)
    if hasattr(ref, "timestamps"):
        ref, est = sync.associate_trajectories(ref, est, max_diff=0.01)
    if align != "none":
        est.align(ref, correct_scale=align in ("sim3", "scale"), correct_only_scale=align == "scale", n=n_to_align)
    if metric == "ape":
        m = metrics.APE(RELATIONS[relation])
    else:
        unit = {"frames": Unit.frames, "m": Unit.meters}[rpe.pop("delta_unit", "frames")]
        m = metrics.RPE(RELATIONS[relation], delta_unit=unit, **rpe)
    m.process_data((ref, est))
    return m.get_all_statistics(), m.error


_READ = {}


def _read(path):
    if path not in _READ:
        _READ[path] = read_poses(path)
    return _READ[path]


def _ours(case, metric, align, relation, **kw):
    ref, est = _read(case[1]), _read(case[2])
    return T.evaluate(ref, est, metric, align=align, relation=relation, **kw)


def _same(ours, theirs, rtol=RTOL, atol=0):
    for k in T.STATISTICS:
        assert ours[k] == pytest.approx(theirs[k], rel=rtol, abs=atol), k


@pytest.mark.parametrize("metric", ["ape", "rpe"])
@pytest.mark.parametrize("align", T.ALIGNMENTS)
@pytest.mark.parametrize("relation", T.RELATIONS)
def test_equals_evo(case, metric, align, relation):
    name, _, _, evo_ref, evo_est = case
    theirs, evo_errors = _evo(evo_ref, evo_est, metric, align, relation)
    r = _ours(case, metric, align, relation)
    assert r.errors.size == evo_errors.size
    np.testing.assert_allclose(r.errors, evo_errors, rtol=1e-7)
    _same(r.stats, theirs)


@pytest.mark.parametrize("metric", ["ape", "rpe"])
@pytest.mark.parametrize("relation", T.RELATIONS)
def test_kitti_raw_matrices_against_evo(case, metric, relation):
    """KITTI prints its rotation matrices to 7 digits: they are orthonormal to ~1e-7 only.
    quatarray reads the nearest rotation; evo keeps the matrix and inverts it by its
    transpose, so its RPE and full APE carry that ~1e-7. The other tests give evo the
    reference re-written from the rotations read (1e-9 there); against the raw file the
    APE translation is still exact (1e-9) and the rest agrees within 1e-6 (m, degrees)."""
    name, ref_path, est_path, _, evo_est = case
    if name != "kitti":
        pytest.skip("KITTI only")
    raw, _ = _evo(file_interface.read_kitti_poses_file(ref_path), evo_est, metric, "sim3", relation)
    exact = metric == "ape" and relation == "trans"
    _same(_ours(case, metric, "sim3", relation).stats, raw, rtol=RTOL if exact else 1e-5, atol=0 if exact else 1e-6)


@pytest.mark.parametrize("rpe", [
    dict(delta=10), dict(delta=7, all_pairs=True), dict(delta=0.5, delta_unit="m"),
    dict(delta=0.3, delta_unit="m", all_pairs=True),
])
@pytest.mark.parametrize("relation", ["trans", "rot"])
def test_rpe_deltas_equal_evo(case, rpe, relation):
    theirs, evo_errors = _evo(case[3], case[4], "rpe", "sim3", relation, **dict(rpe))
    r = _ours(case, "rpe", "sim3", relation, **rpe)
    assert r.errors.size == evo_errors.size
    _same(r.stats, theirs)


@pytest.mark.parametrize("align", ["se3", "sim3", "scale"])
def test_n_to_align_equals_evo(case, align):
    theirs, _ = _evo(case[3], case[4], "ape", align, "trans", n_to_align=300)
    _same(_ours(case, "ape", align, "trans", n_to_align=300).stats, theirs)


# ---- association ----


@pytest.mark.parametrize("sort", [True, False])
def test_match_times_equals_evo(rng, sort):
    s1 = np.round(rng.uniform(0, 10, 400), 2)
    s2 = np.round(rng.uniform(0, 10, 300), 2)  # many repeated and tied times
    s1, s2 = (np.sort(s1), np.sort(s2)) if sort else (s1, s2)
    for offset in (0.0, 0.013, -0.02):
        i1, i2 = T.match_times(s1, s2, 0.01, offset)
        e1, e2 = sync.matching_time_indices(s1, s2, 0.01, offset)
        np.testing.assert_array_equal(i1, e1)
        np.testing.assert_array_equal(i2, e2)


def test_association_equals_evo_with_offset(case):
    name, ref_path, est_path, evo_ref, evo_est = case
    if name == "kitti":
        pytest.skip("no times")
    ref, est = read_poses(ref_path), read_poses(est_path)
    est = est.replace(t=est.t - 0.5)
    r, e = T.associate(ref, est, 0.01, 0.5)
    er, ee = sync.associate_trajectories(evo_ref, file_interface.read_tum_trajectory_file(est_path),
                                         max_diff=0.01, offset_2=0.0)
    np.testing.assert_array_equal(r.t, er.timestamps)
    np.testing.assert_array_equal(e.t + 0.5, ee.timestamps)


def test_kitti_lengths_must_match(case):
    if case[0] != "kitti":
        pytest.skip("KITTI only")
    ref, est = read_poses(case[1]), read_poses(case[2])
    with pytest.raises(ValueError, match="pose by pose"):
        T.associate(ref, est.take(slice(0, 10)))


def test_interpolate_spline_resamples_the_estimate(rng):
    t = np.linspace(0, 10, 1001)
    w = np.c_[np.sin(t), np.cos(0.5 * t), 0.3 * t]
    ref = T.poses(t, np.c_[t, t ** 2, np.sin(t)], qa.from_rotvec(w))
    te = np.linspace(-0.05, 9.5, 300)  # sparser, its own span, offset
    est = T.poses(te - 0.2, np.c_[te, te ** 2, np.sin(te)], qa.from_rotvec(np.c_[np.sin(te), np.cos(0.5 * te), 0.3 * te]))
    r, e = T.associate(ref, est, t_offset=0.2, interpolate="spline")
    assert r.t[0] >= te[0] and r.t[-1] <= te[-1] and len(r) == np.count_nonzero((t >= te[0]) & (t <= te[-1]))
    np.testing.assert_array_equal(e.t, r.t - 0.2)
    assert np.max(T.ape(r, e, "rot")) < 0.01  # degrees: the Bézier spline follows the smooth rotation
    assert np.max(T.ape(r, e, "trans")) < 0.01


# ---- alignment ----


def _umeyama_numpy(x, y, with_scale):
    """Textbook Umeyama (1991) with numpy's SVD: y ≈ c R x + t."""
    mx, my = x.mean(0), y.mean(0)
    cov = (y - my).T @ (x - mx) / len(x)
    u, d, vt = np.linalg.svd(cov)
    s = np.diag([1.0, 1.0, np.sign(np.linalg.det(u) * np.linalg.det(vt))])
    r = u @ s @ vt
    c = np.trace(np.diag(d) @ s) / np.mean(np.sum((x - mx) ** 2, 1)) if with_scale else 1.0
    return r, my - c * r @ mx, c


@pytest.mark.parametrize("with_scale", [True, False])
def test_umeyama_equals_numpy_svd(case, with_scale):
    ref, est = T.associate(read_poses(case[1]), read_poses(case[2]))
    r, t, c = _umeyama_numpy(est.pos, ref.pos, with_scale)
    a = T.umeyama(est.pos, ref.pos, with_scale)
    np.testing.assert_allclose(a.r, r, atol=1e-12)
    np.testing.assert_allclose(a.t, t, rtol=1e-12, atol=1e-12)
    assert a.s == pytest.approx(c, rel=1e-12)
    np.testing.assert_allclose(qa.as_matrix(a.q), a.r, atol=1e-14)


def test_known_transform_is_recovered(case):
    ref = read_poses(case[1])
    s, q, t = SIM
    qq = np.tile(q, (len(ref), 1))
    est = T.Poses(ref.t, s * qa.rotate(qq, ref.pos) + t, qa.multiply(qq, ref.q))
    moved, a = T.align(ref, est, "sim3")
    # est = s R ref + t, so the alignment of est onto ref is the inverse
    assert a.s == pytest.approx(1 / s, rel=1e-12)
    np.testing.assert_allclose(a.r, qa.as_matrix(q).T, atol=1e-12)
    np.testing.assert_allclose(a.t, -qa.as_matrix(q).T @ t / s, atol=1e-12)
    assert T.ape(ref, moved, "trans").max() < 1e-9 * np.abs(ref.pos).max()
    assert T.ape(ref, moved, "rot").max() < 1e-9


def test_moments_merge_equals_whole(case):
    ref, est = T.associate(read_poses(case[1]), read_poses(case[2]))
    whole = T.umeyama(est.pos, ref.pos)
    m = T.Moments()
    for a in range(0, len(ref), 333):
        m = m.merge(T.Moments.of(est.pos[a:a + 333], ref.pos[a:a + 333]))
    parts = T.umeyama(m)
    np.testing.assert_allclose(parts.r, whole.r, atol=1e-12)
    assert parts.s == pytest.approx(whole.s, rel=1e-12)


@pytest.mark.parametrize("pos, what", [
    (np.zeros((2, 3)), "at least 3"),
    (np.ones((10, 3)), "all positions are equal"),
    (np.outer(np.arange(10.0), [1, 2, 3]) + 5, "on a line"),
])
def test_degenerate_alignment_is_a_value_error(pos, what):
    p = T.poses(None, pos, qa.identity(len(pos)))
    for method in ("se3", "sim3", "scale"):
        with pytest.raises(ValueError, match=what):
            T.align(p, p, method)


# ---- command line ----


def _cli(capsys, *argv):
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def test_cli_eval_prints_writes_and_plots(case, capsys, tmp_path):
    name, ref_path, est_path, evo_ref, evo_est = case
    pytest.importorskip("matplotlib")
    out, js, png = tmp_path / "e.csv", tmp_path / "s.json", tmp_path / "p.png"
    rc, text, err = _cli(capsys, "eval", ref_path, est_path, "--align", "sim3", "--pose-relation", "rot",
                         "--out", out, "--json", js, "--plot", png)
    assert rc == 0, err
    theirs, evo_errors = _evo(evo_ref, evo_est, "ape", "sim3", "rot")
    assert "rmse" in text and "Sim(3)" in text
    _same(json.loads(js.read_text())["stats"], theirs)
    table = np.genfromtxt(out, delimiter=",", names=True)
    np.testing.assert_allclose(table["error"], evo_errors, rtol=1e-7)
    assert ("t" in table.dtype.names) == (name != "kitti")
    assert png.stat().st_size > 1000


def test_cli_eval_rpe_parquet(case, capsys, tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    out = tmp_path / "e.parquet"
    rc, _, err = _cli(capsys, "eval", case[1], case[2], "--metric", "rpe", "--delta", "5", "--align", "se3",
                      "--out", out)
    assert rc == 0, err
    tab = pq.read_table(out)
    _, evo_errors = _evo(case[3], case[4], "rpe", "se3", "trans", delta=5)
    np.testing.assert_allclose(tab["error"].to_numpy(), evo_errors, rtol=1e-7)
    assert np.all(tab["pose"].to_numpy() - tab["pose0"].to_numpy() == 5)


def test_cli_eval_exit_codes(data_dir, tmp_path):
    tum = tmp_path / "a.txt"
    _head(data_dir / "tum_freiburg1_xyz_groundtruth.txt", tum, 100)
    later = tmp_path / "b.txt"
    rows = np.loadtxt(tum)
    rows[:, 0] += 1000
    np.savetxt(later, rows, fmt="%.17g")
    line = [tmp_path / "c.txt"]
    np.savetxt(line[0], np.c_[rows[:, 0] - 1000, np.outer(np.arange(100.0), [1, 1, 0]), rows[:, 4:]], fmt="%.17g")

    def run(*argv):
        p = subprocess.run([sys.executable, "-m", "quatarray", "eval", *map(str, argv)], capture_output=True,
                           text=True, cwd=ROOT)
        return p.returncode, p.stderr.strip().splitlines()[-1]

    rc, err = run(tum, later)
    assert rc == 1 and "no matching times" in err
    rc, err = run(tum, line[0], "--align", "se3")
    assert rc == 1 and "on a line" in err
    rc, err = run(tum, tmp_path / "missing.txt")
    assert rc == 2 and "no such file" in err
    rc, err = run(tum, tum, "--metric", "rpe", "--delta", "1.5")
    assert rc == 2 and "whole number" in err
    rc, err = run(tum, tum, "--align", "rigid")
    assert rc == 2


# --------------------------------------------------------------------------
# pose arrays evaluated in chunks


def _npy(path, p):
    np.save(path, np.c_[p.pos, p.q] if p.t is None else np.c_[p.t, p.pos, p.q])
    return PoseFile.open(str(path))


@pytest.mark.parametrize("metric, delta, all_pairs", [("ape", 1, False), ("rpe", 1, False), ("rpe", 7, False),
                                                      ("rpe", 5, True)])
@pytest.mark.parametrize("align, n_to_align", [("none", None), ("sim3", None), ("se3", 300), ("scale", None)])
def test_chunked_equals_in_memory(case, tmp_path, metric, delta, all_pairs, align, n_to_align):
    """Chunked evaluation of npy pose arrays gives the in-memory numbers bit for bit (the alignment's
    moments are summed over the same blocks), whichever stream is the longer, and equals evo."""
    files = _npy(tmp_path / "r.npy", _read(case[1])), _npy(tmp_path / "e.npy", _read(case[2]))
    ref, est = read_poses(files[0].path), read_poses(files[1].path)  # the in-memory path on the same files
    for a, b, off in ((files, (ref, est), 0.0), (files[::-1], (est, ref), 0.002)):
        mem = T.evaluate(*b, metric, align, "full", delta, "frames", all_pairs, n_to_align, t_offset=off)
        for chunk in (97, 4096):
            got = run_chunked(*a, metric, align, "full", delta, all_pairs, n_to_align, 0.01, off, chunk)
            assert got.stats == mem.stats
            np.testing.assert_array_equal(got.errors, mem.errors)
    theirs, _ = _evo(case[3], case[4], metric, align, "full", -1 if n_to_align is None else n_to_align,
                     **({} if metric == "ape" else {"delta": delta, "all_pairs": all_pairs}))
    _same(run_chunked(*files, metric, align, "full", delta, all_pairs, n_to_align, 0.01, 0.0, 97).stats, theirs)


def test_chunked_cli_writes_as_in_memory(case, capsys, tmp_path):
    """`eval` of npy pose arrays (chunked) prints, and writes --out, as on the text files (to the
    last digits: the npy holds rotations normalised once more)."""
    ref, est = _read(case[1]), _read(case[2])
    _npy(tmp_path / "r.npy", ref), _npy(tmp_path / "e.npy", est)
    for metric in ("ape", "rpe"):
        argv = ["--metric", metric, "--delta", "3", "--align", "sim3", "--pose-relation", "rot"]
        rc, text_npy, err = _cli(capsys, "eval", tmp_path / "r.npy", tmp_path / "e.npy", *argv, "--chunk", 101,
                                 "--out", tmp_path / f"{metric}.csv")
        assert rc == 0, err
        rc, text, err = _cli(capsys, "eval", case[1], case[2], *argv, "--out", tmp_path / f"{metric}_txt.csv")
        assert rc == 0, err
        assert text_npy == text
        a = np.genfromtxt(tmp_path / f"{metric}.csv", delimiter=",", names=True)
        b = np.genfromtxt(tmp_path / f"{metric}_txt.csv", delimiter=",", names=True)
        assert a.dtype.names == b.dtype.names
        for k in a.dtype.names:  # the npy holds the rotations once more normalised: last digits
            np.testing.assert_allclose(a[k], b[k], rtol=1e-12 if k == "error" else 0)


def test_chunked_unsorted_times_read_whole(tmp_path, capsys):
    """Times that go back in the stream searched: the streams are read whole, with the same result."""
    rng = np.random.default_rng(4)
    n = 400
    t = np.arange(n) * 0.1
    ref = T.poses(t, np.cumsum(rng.normal(size=(n, 3)), axis=0), qa.random(n, rng=rng))
    est = ref.take(np.r_[0:200, 250:300, 200:250, 300:n]).replace(t=t[np.r_[0:200, 250:300, 200:250, 300:n]])
    files = _npy(tmp_path / "r.npy", ref), _npy(tmp_path / "e.npy", est)
    assert run_chunked(*files[::-1], "ape", "sim3", "trans", 1, False, None, 0.01, 0.0, 64) is None
    rc, text, err = _cli(capsys, "eval", tmp_path / "e.npy", tmp_path / "r.npy", "--align", "sim3")
    assert rc == 0, err
    stats = T.evaluate(est, ref, "ape", "sim3").stats
    assert f"{stats['rmse']:.9g}" in text


@pytest.mark.slow
def test_chunked_memory_is_bounded(tmp_path):
    """A 5·10⁶-pose npy pair (610 MiB) is evaluated (sim3 APE, errors to an npy) with peak RSS a few
    MiB above the interpreter's own plus the errors themselves (8 bytes a pose: 38 MiB)."""
    n = 5_000_000
    rng = np.random.default_rng(5)
    for name, jitter in (("r", 0.0), ("e", 0.002)):
        mm = np.lib.format.open_memmap(tmp_path / f"{name}.npy", "w+", np.float64, (n, 8))
        for a in range(0, n, 1 << 20):
            k = np.arange(a, min(a + (1 << 20), n))
            mm[k[0]:k[-1] + 1, 0] = 1e9 + k * 0.01 + rng.uniform(-jitter, jitter, k.size)
            mm[k[0]:k[-1] + 1, 1:4] = np.c_[np.sin(k * 1e-4), np.cos(k * 1.3e-4), k * 1e-6]
            mm[k[0]:k[-1] + 1, 4:] = [1.0, 0, 0, 0]
            mm[k[0]:k[-1] + 1, 5] = rng.normal(scale=0.01, size=k.size)
        del mm
        np.save(tmp_path / f"{name}_small.npy", np.load(tmp_path / f"{name}.npy", mmap_mode="r")[:1000])
    rss = ("import resource, subprocess, sys\nsubprocess.run(sys.argv[1:], check=True)\n"
           "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n")

    def peak_kib(r, e, out, *argv):
        res = subprocess.run([sys.executable, "-c", rss, sys.executable, "-m", "quatarray", "eval", tmp_path / r,
                              tmp_path / e, "--align", "sim3", "--out", tmp_path / out, *map(str, argv)],
                             capture_output=True, text=True, cwd=ROOT)
        assert res.returncode == 0, res.stderr
        return int(res.stdout.split()[-1])

    base = peak_kib("r_small.npy", "e_small.npy", "o_small.npy")
    grown = (peak_kib("r.npy", "e.npy", "o.npy", "--chunk", 8192) - base) / 1024
    assert grown < 38 + 25, f"peak RSS grew by {grown:.0f} MiB over the {base / 1024:.0f} MiB baseline"
    assert np.load(tmp_path / "o.npy", mmap_mode="r").shape == (n,)  # the errors alone (issue 36)


def test_chunked_zarr_equals_npy(case, capsys, tmp_path):
    """Zarr pose stores (chunked unlike the evaluation's blocks) are evaluated in chunks as npy files are."""
    zarr = pytest.importorskip("zarr")
    ref, est = _read(case[1]), _read(case[2])
    for name, p in (("r", ref), ("e", est)):
        a = np.c_[p.pos, p.q] if p.t is None else np.c_[p.t, p.pos, p.q]
        np.save(tmp_path / f"{name}.npy", a)
        zarr.create_array(store=str(tmp_path / f"{name}.zarr"), data=a, chunks=(333, a.shape[1]))
    argv = ["--metric", "rpe", "--delta", "2", "--align", "sim3", "--chunk", "101"]
    rc, via_npy, err = _cli(capsys, "eval", tmp_path / "r.npy", tmp_path / "e.npy", *argv)
    assert rc == 0, err
    rc, via_zarr, err = _cli(capsys, "eval", tmp_path / "r.zarr", tmp_path / "e.zarr", *argv)
    assert rc == 0, err
    assert via_zarr == via_npy
