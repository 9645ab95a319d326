"""Trajectory evaluation hardened (issue 36, items 7-9 and 15-19): ``quatarray eval`` and its
readers against evo (pairs, interpolation), mpmath (UTM-sized coordinates) and bad inputs."""

import numpy as np
import pytest

import quatarray as qa
from quatarray import trajectory as T

evo = pytest.importorskip("evo", reason="evo (the test extra) is needed to compare with it")
from evo.core import filters, lie_algebra  # noqa: E402

# ---- item 8: RPE pairs by path length, rounded as evo rounds the step lengths ----

# integer steps whose length is a whole number: on a decimal grid the running length lands on delta
_WHOLE = np.array([(a, b, c) for a in range(-6, 7) for b in range(-6, 7) for c in range(-6, 7)
                   if (a, b, c) != (0, 0, 0) and round((a * a + b * b + c * c) ** 0.5) ** 2 == a * a + b * b + c * c])


def _grid_path(rng, n):
    """(positions, delta): a walk on a decimal grid whose steps have lengths k * scale, delta too."""
    if rng.random() < 0.5:
        steps = _WHOLE[rng.integers(len(_WHOLE), size=n - 1)]
        scale = float(rng.choice([0.1, 0.3, 0.7, 0.01]))
        ints = np.concatenate([np.zeros((1, 3), int), np.cumsum(steps, axis=0)]) + rng.integers(-50, 50, size=3)
        return ints * scale, float(rng.integers(1, 8)) * scale
    steps = rng.integers(-2, 3, size=(n - 1, 3)) * rng.choice([0.1, 0.25, 0.3, 1.0, 0.7])
    pos = np.concatenate([np.zeros((1, 3)), np.cumsum(steps, axis=0)]) + rng.choice([0, 3.7, 100.0])
    return pos, float(rng.choice([0.5, 1.0, 1.5, 2.0, 3.0]))


@pytest.mark.parametrize("all_pairs", [False, True])
def test_rpe_pairs_in_metres_equal_evo_on_grid_paths(all_pairs):
    rng = np.random.default_rng(36)
    differ = []
    for k in range(1500):
        pos, delta = _grid_path(rng, 40)
        theirs = filters.filter_pairs_by_path([lie_algebra.se3(np.eye(3), x) for x in pos], delta, 0.1 * delta,
                                              all_pairs)
        try:
            i, j = T.pairs(T.poses(None, pos, qa.identity(len(pos))), delta, "m", all_pairs)
            ours = list(zip(i.tolist(), j.tolist()))
        except ValueError:  # no pair: evo gives an empty list
            ours = []
        if ours != theirs:
            differ.append(k)
    assert differ == []


# ---- item 9: UTM-sized coordinates: errors about the alignment's origins, exact ----

mpmath = pytest.importorskip("mpmath")
UTM = np.array([4.5e6, 1.0e7, 312.0])  # northing-sized offsets (m)


def _utm_case(rng, n=120, offset=UTM):
    """(ref, est): a reference near `offset`, an estimate in its own frame (a similarity of it), noisy."""
    t = np.arange(n) * 0.1
    local = np.c_[300 * np.sin(0.05 * t), 200 * np.cos(0.03 * t), 5 * np.sin(0.2 * t)] + rng.normal(size=(n, 3))
    ref = T.poses(t, local + offset, qa.random(n, rng=rng))
    q = qa.from_rotvec([0.2, -0.4, 1.1])
    pos = 0.8 * qa.rotate(np.tile(q, (n, 1)), local) + [7.0, -3.0, 1.0] + rng.normal(scale=0.02, size=(n, 3))
    pos[::7] += rng.normal(scale=1e-4, size=(pos[::7].shape))  # some errors far smaller than the others
    est = T.poses(t, pos, qa.multiply(np.tile(q, (n, 1)), ref.q))
    return ref, est


def _exact_ape(ref, est, with_scale):
    """Umeyama's fit and the APE (translation) in 40-digit arithmetic (mpmath) of the float inputs."""
    mp = mpmath.mp
    with mpmath.workdps(40):
        x = [[mp.mpf(float(v)) for v in row] for row in est.pos]
        y = [[mp.mpf(float(v)) for v in row] for row in ref.pos]
        n = len(x)
        mx = [mp.fsum(r[k] for r in x) / n for k in range(3)]
        my = [mp.fsum(r[k] for r in y) / n for k in range(3)]
        xc = [[r[k] - mx[k] for k in range(3)] for r in x]
        yc = [[r[k] - my[k] for k in range(3)] for r in y]
        cov = mp.matrix(3, 3)
        for i in range(3):
            for j in range(3):
                cov[i, j] = mp.fsum(a[i] * b[j] for a, b in zip(yc, xc)) / n
        u, d, vt = mp.svd_r(cov)
        sign = mp.matrix([[1, 0, 0], [0, 1, 0], [0, 0, 1 if mp.det(u) * mp.det(vt) > 0 else -1]])
        r = u * sign * vt
        sx = mp.fsum(v * v for a in xc for v in a) / n
        s = (d[0] + d[1] + sign[2, 2] * d[2]) / sx if with_scale else mp.mpf(1)
        out = []
        for a, b in zip(xc, yc):
            e = [s * mp.fsum(r[i, k] * a[k] for k in range(3)) - b[i] for i in range(3)]
            out.append(float(mp.sqrt(mp.fsum(v * v for v in e))))
        return np.array(out), float(s)


@pytest.mark.parametrize("align", ["se3", "sim3"])
def test_utm_offsets_ape_is_exact(rng, align, tmp_path):
    ref, est = _utm_case(rng)
    exact, s = _exact_ape(ref, est, align == "sim3")
    r = T.evaluate(ref, est, "ape", align=align, relation="trans")
    assert r.alignment.s == pytest.approx(s, rel=1e-12)
    np.testing.assert_allclose(r.errors, exact, rtol=1e-10, atol=0)
    for k, v in (("min", exact.min()), ("max", exact.max()), ("rmse", np.sqrt(np.mean(exact ** 2)))):
        assert r.stats[k] == pytest.approx(v, rel=1e-10), k
    # the chunked pass over pose arrays gives the same numbers
    from quatarray.app.eval_verb import PoseFile, run_chunked

    for name, p in (("ref", ref), ("est", est)):
        np.save(tmp_path / f"{name}.npy", np.c_[p.t, p.pos, p.q])
    c = run_chunked(PoseFile.open(str(tmp_path / "ref.npy")), PoseFile.open(str(tmp_path / "est.npy")), "ape",
                    align, "trans", 1, False, None, 0.01, 0.0, 17)
    np.testing.assert_allclose(np.sort(c.errors), np.sort(exact), rtol=1e-10, atol=0)
    # the aligned estimate lies on the reference as well as float positions there can
    moved = T.align(ref, est, align)[0]
    np.testing.assert_allclose(np.linalg.norm(moved.pos - ref.pos, axis=1), exact, rtol=0, atol=4e-9)


@pytest.mark.parametrize("align", ["se3", "sim3"])
def test_near_origin_equals_evo_and_exact(rng, align):
    """Where evo is exact (coordinates near the origin), quatarray equals it and the exact numbers."""
    from evo.core import metrics
    from evo.core.trajectory import PoseTrajectory3D

    ref, est = _utm_case(rng, offset=np.zeros(3))
    exact, _ = _exact_ape(ref, est, align == "sim3")
    r = T.evaluate(ref, est, "ape", align=align, relation="trans")
    np.testing.assert_allclose(r.errors, exact, rtol=1e-10)
    er = PoseTrajectory3D(ref.pos, ref.q, ref.t)
    ee = PoseTrajectory3D(est.pos, est.q, est.t)
    ee.align(er, correct_scale=align == "sim3")
    m = metrics.APE(metrics.PoseRelation.translation_part)
    m.process_data((er, ee))
    np.testing.assert_allclose(r.errors, m.error, rtol=1e-9)
    for k, v in m.get_all_statistics().items():
        assert r.stats[k] == pytest.approx(v, rel=1e-9), k


@pytest.mark.parametrize("metric", ["ape", "rpe"])
@pytest.mark.parametrize("relation", ["trans", "full"])
def test_utm_offsets_do_not_change_the_errors(rng, metric, relation):
    """Moving the reference by 10⁷ m (exactly: the offset is subtracted without rounding)
    changes no error beyond rounding of the motion's own size."""
    ref, est = _utm_case(rng)
    near = ref.replace(pos=ref.pos - UTM)
    assert np.array_equal(near.pos + UTM, ref.pos)
    a = T.evaluate(ref, est, metric, align="sim3", relation=relation)
    b = T.evaluate(near, est, metric, align="sim3", relation=relation)
    np.testing.assert_allclose(a.errors, b.errors, rtol=1e-10)


# ---- item 16: tiny motions are aligned (a relative test), degenerate ones named ----


@pytest.mark.parametrize("span", [1e-6, 1e-8, 1e-12, 1e-30, 1e30])
def test_tiny_and_huge_motions_are_aligned(rng, span):
    x = rng.normal(size=(50, 3)) * span
    q = qa.from_rotvec([0.1, 0.2, 0.3])
    y = 2.0 * qa.rotate(np.tile(q, (50, 1)), x) + 3.0 * span
    a = T.umeyama(x, y)
    assert a.s == pytest.approx(2.0, rel=1e-12)
    np.testing.assert_allclose(a.r, qa.as_matrix(q), atol=1e-12)
    ref, est = T.poses(None, y, qa.identity(50)), T.poses(None, x, qa.identity(50))
    r = T.evaluate(ref, est, align="sim3")
    assert r.stats["max"] <= 1e-12 * span


@pytest.mark.parametrize("what, pos, message", [
    ("line", lambda rng: np.outer(rng.normal(size=30), [1.0, 2.0, 3.0]) * 1e-9,
     r"the positions lie on a line \(the covariance's second singular value is .* of its first, at most 1e-12\)"),
    ("equal est", lambda rng: np.full((30, 3), 1e-9), r"all positions are equal in the estimate"),
])
def test_degenerate_motions_say_what_is_wrong(rng, what, pos, message):
    x = pos(rng)
    y = x + rng.normal(size=x.shape) * 1e-12 if what != "line" else 2 * x
    with pytest.raises(ValueError, match=message):
        T.umeyama(x, y)
    with pytest.raises(ValueError, match=r"all positions are equal in the reference"):
        T.umeyama(rng.normal(size=(30, 3)), np.ones((30, 3)))


# ---- item 15: --interpolate is evo's --sync_method interpolation (the spline rule by name) ----


def _smooth(t, rng, shift=0.0):
    w = np.c_[np.sin(0.7 * t), np.cos(0.5 * t), 0.3 * t] + shift
    pos = np.c_[t, np.sin(t) * 3, 0.2 * np.abs(t) ** 1.5] + rng.normal(scale=0.01, size=(t.size, 3))
    return pos, qa.multiply(qa.from_rotvec(w), qa.from_rotvec(rng.normal(scale=0.01, size=(t.size, 3))))


def _sync_case(rng, kind):
    """(ref, est, t_offset): streams at different rates, jittered, the estimate offset in time."""
    tr = np.arange(0.0, 30.0, 1 / 30) + rng.uniform(-0.002, 0.002, 900)
    rates = {"denser est": 1 / 100, "sparser est": 1 / 20, "equal": 1 / 30}
    te = np.arange(0.3, 29.0, rates[kind]) + rng.uniform(-0.003, 0.003, np.arange(0.3, 29.0, rates[kind]).size)
    if kind == "equal":
        te = te[:tr.size] if te.size >= tr.size else np.r_[te, te[-1] + 0.03 * np.arange(1, tr.size - te.size + 1)]
    off = 0.0137
    pr, qr = _smooth(tr, rng)
    pe, qe = _smooth(te + off, rng, 0.01)
    return T.poses(tr, pr, qr), T.poses(te, 1.3 * pe + [1.0, 2.0, 3.0], qe), off


def _evo_traj(p):
    from evo.core.trajectory import PoseTrajectory3D

    return PoseTrajectory3D(p.pos.copy(), p.q.copy(), p.t.copy())


def _evo_run(ref, est, metric, align, relation, t_max_diff, t_offset, **rpe):
    from evo.core import metrics, sync
    from evo.core.sync_method import SyncMethod

    r, e = sync.associate_trajectories(_evo_traj(ref), _evo_traj(est), sync_method=SyncMethod.interpolation,
                                       max_diff=t_max_diff, offset_2=t_offset)
    if align != "none":
        e.align(r, correct_scale=align == "sim3")
    rel = {"trans": metrics.PoseRelation.translation_part, "rot": metrics.PoseRelation.rotation_angle_deg,
           "full": metrics.PoseRelation.full_transformation}[relation]
    m = metrics.APE(rel) if metric == "ape" else metrics.RPE(rel, **rpe)
    m.process_data((r, e))
    return r, e, m


@pytest.mark.parametrize("kind", ["denser est", "sparser est", "equal"])
@pytest.mark.parametrize("metric, align, relation", [
    ("ape", "none", "trans"), ("ape", "sim3", "rot"), ("ape", "se3", "full"), ("rpe", "sim3", "trans"),
    ("rpe", "none", "rot"), ("rpe", "se3", "full")])
def test_interpolate_equals_evo(rng, kind, metric, align, relation):
    ref, est, off = _sync_case(rng, kind)
    er, ee, m = _evo_run(ref, est, metric, align, relation, 0.02, off)
    r = T.evaluate(ref, est, metric, align=align, relation=relation, t_max_diff=0.02, t_offset=off,
                   interpolate=True)
    assert len(r.ref) == er.num_poses and r.errors.size == m.error.size
    np.testing.assert_array_equal(r.ref.t, er.timestamps)
    np.testing.assert_array_equal(r.est.t, ee.timestamps)
    np.testing.assert_allclose(r.errors, m.error, rtol=1e-9, atol=1e-12)
    for k, v in m.get_all_statistics().items():
        assert r.stats[k] == pytest.approx(v, rel=1e-9), k
    assert T.evaluate(ref, est, metric, align=align, relation=relation, t_max_diff=0.02, t_offset=off,
                      interpolate="evo").stats == r.stats


def test_interpolate_evo_edge_cases_equal_evo(rng):
    """Repeated times in the stream resampled, times outside its span (clamped), keys nearer than
    evo's slerp threshold, keys a quarter turn apart on the 4-sphere (p·q = 0) and q vs −q."""
    n = 200
    tr = np.arange(n) * 0.1
    pos, q = _smooth(tr, rng)
    q[50] = q[49]  # identical keys
    q[51] = -q[50]  # q vs -q
    q[80] = qa.multiply(q[79], [np.cos(1e-9), np.sin(1e-9), 0, 0])  # nearer than 4 eps on S³
    q[120] = qa.multiply(q[119], [0.0, 1.0, 0.0, 0.0])  # a half turn: p·q = 0
    tr[30] = tr[29]  # a repeated reference time
    ref = T.poses(tr, pos, q)
    te = np.r_[-0.004, np.sort(rng.uniform(0, tr[-1], 60)), tr[-1] + 0.004, tr[29] + 1e-4, 5.0, 12.0 + 0.003]
    te.sort()
    pe, qe = _smooth(te, rng)
    est = T.poses(te, pe, qe)
    er, _, m = _evo_run(ref, est, "ape", "none", "full", 0.01, 0.0)
    r = T.evaluate(ref, est, "ape", relation="full", interpolate=True)
    assert r.errors.size == m.error.size
    np.testing.assert_allclose(r.ref.pos, er.positions_xyz, rtol=0, atol=0)
    dots = np.abs(np.sum(r.ref.q * er.orientations_quat_wxyz, axis=1))
    assert np.all(dots > 1 - 1e-15)
    np.testing.assert_allclose(r.errors, m.error, rtol=1e-9, atol=1e-13)


def test_interpolate_spline_rule_by_name(rng):
    ref, est, off = _sync_case(rng, "sparser est")
    r = T.evaluate(ref, est, "ape", relation="rot", t_offset=off, interpolate="spline")
    inside = (ref.t >= est.t[0] + off) & (ref.t <= est.t[-1] + off)
    assert r.errors.size == np.count_nonzero(inside)  # every reference time inside the estimate's span
    np.testing.assert_array_equal(r.est.t, r.ref.t - off)
    with pytest.raises(ValueError, match="unknown interpolation 'cubic'"):
        T.evaluate(ref, est, interpolate="cubic")


# ---- the command line: items 7, 15, 17, 18, 19 ----


def _cli(capsys, *argv):
    from quatarray.app.cli import main

    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def _tum(path, p):
    np.savetxt(path, np.c_[p.t, p.pos, p.q[:, 1:], p.q[:, :1]], fmt="%.17g")
    return path


def test_cli_interpolate_equals_evo_on_files(rng, tmp_path, capsys):
    """``eval --interpolate`` on TUM files: evo's pairs and statistics; ``--interpolate spline``
    the spline rule (other pairs)."""
    import json

    from evo.tools import file_interface

    ref, est, off = _sync_case(rng, "denser est")
    rp, ep = _tum(tmp_path / "ref.txt", ref), _tum(tmp_path / "est.txt", est)
    from evo.core import metrics, sync
    from evo.core.sync_method import SyncMethod

    r, e = sync.associate_trajectories(file_interface.read_tum_trajectory_file(str(rp)),
                                       file_interface.read_tum_trajectory_file(str(ep)),
                                       sync_method=SyncMethod.interpolation, max_diff=0.01, offset_2=off)
    e.align(r, correct_scale=True)
    m = metrics.APE(metrics.PoseRelation.rotation_angle_deg)
    m.process_data((r, e))
    for rule in (["--interpolate"], ["--interpolate-rule", "evo"], ["--interpolate", "--interpolate-rule", "evo"]):
        rc, _, err = _cli(capsys, "eval", rp, ep, "--align", "sim3", "--pose-relation", "rot", "--t-offset", off,
                          *rule, "--json", tmp_path / "s.json", "--force")
        assert rc == 0 and err == "", err
        got = json.loads((tmp_path / "s.json").read_text())
        assert got["pairs"] == m.error.size and got["options"]["interpolate"] == "evo"
        for k, v in m.get_all_statistics().items():
            assert got["stats"][k] == pytest.approx(v, rel=1e-9), k
    rc, _, err = _cli(capsys, "eval", rp, ep, "--t-offset", off, "--interpolate-rule", "spline", "--json",
                        tmp_path / "s.json", "--force")
    got = json.loads((tmp_path / "s.json").read_text())
    assert rc == 0 and got["options"]["interpolate"] == "spline"
    assert got["pairs"] == np.count_nonzero((ref.t >= est.t[0] + off) & (ref.t <= est.t[-1] + off))
    rc, _, err = _cli(capsys, "eval", rp, ep, "--interpolate-rule", "cubic")
    assert rc == 2 and "invalid choice: 'cubic'" in err


@pytest.mark.parametrize("ext, magic", [(".pdf", b"%PDF"), (".svg", b"<?xml"), (".png", b"\x89PNG")])
def test_cli_eval_plot_writes_the_format_its_extension_names(rng, tmp_path, capsys, ext, magic):
    pytest.importorskip("matplotlib")
    ref, est, _ = _sync_case(rng, "equal")
    rp, ep = _tum(tmp_path / "ref.txt", ref), _tum(tmp_path / "est.txt", est)
    out = tmp_path / f"p{ext}"
    rc, _, err = _cli(capsys, "eval", rp, ep, "--t-max-diff", "0.02", "--plot", out)
    assert rc == 0, err
    assert out.read_bytes().startswith(magic)
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temporary left
    rc, _, err = _cli(capsys, "eval", rp, ep, "--plot", tmp_path / "p.xyz")
    assert rc == 2 and "cannot tell the image format from the extension '.xyz'" in err
    assert not (tmp_path / "p.xyz").exists()


@pytest.mark.parametrize("align, legend", [("none", "est.txt"), ("se3", "est.txt (aligned)")])
def test_eval_plot_legend_says_aligned_only_when_aligned(rng, tmp_path, align, legend):
    pytest.importorskip("matplotlib")
    from unittest import mock

    from matplotlib.axes import Axes

    from quatarray import evaluate

    ref, est, _ = _sync_case(rng, "equal")
    r = T.evaluate(ref, est, align=align, t_max_diff=0.02)
    labels = []
    real = Axes.plot

    def spy(self, *a, **kw):
        labels.append(kw.get("label"))
        return real(self, *a, **kw)

    with mock.patch.object(Axes, "plot", spy):
        evaluate.plot(str(tmp_path / "p.svg"), r, "ref.txt", str(tmp_path / "est.txt"), aligned=align != "none")
    assert labels[-1] == legend
    with mock.patch.object(Axes, "plot", spy):
        evaluate.plot(str(tmp_path / "q.svg"), r, "ref.txt", str(tmp_path / "est.txt"))  # told by the alignment
    assert labels[-1] == legend


@pytest.mark.parametrize("array, what", [
    (lambda p: p.astype(np.int64), r"holds int64 of shape \(20, 8\)"),
    (lambda p: np.c_[p, p[:, :1]], r"holds float64 of shape \(20, 9\)"),
    (lambda p: p[:, 4:], r"holds float64 of shape \(20, 4\)"),
])
def test_cli_eval_names_its_pose_array_layouts(rng, tmp_path, capsys, array, what):
    t = np.arange(20.0)
    good = np.c_[t, rng.normal(size=(20, 3)), qa.random(20, rng=rng)]
    np.save(tmp_path / "ref.npy", good)
    np.save(tmp_path / "est.npy", array(good))
    rc, _, err = _cli(capsys, "eval", tmp_path / "ref.npy", tmp_path / "est.npy")
    assert rc == 1
    assert err.strip().startswith(f"{tmp_path / 'est.npy'}: eval reads a pose array as floats of shape (N, 8), "
                                  "t x y z qw qx qy qz a row, or (N, 7), x y z qw qx qy qz; this one holds"), err
    import re
    assert re.search(what, err) and "expected quaternions" not in err


def test_cli_eval_interpolate_needs_times(rng, tmp_path, capsys):
    good = np.c_[rng.normal(size=(20, 3)), qa.random(20, rng=rng)]
    np.save(tmp_path / "a.npy", good)
    for rule in (["--interpolate"], ["--interpolate-rule", "spline"]):
        rc, _, err = _cli(capsys, "eval", tmp_path / "a.npy", tmp_path / "a.npy", *rule)
        assert rc == 1 and "interpolation needs times; the reference and the estimate have none" in err, err
    with pytest.raises(ValueError, match="the estimate has none"):
        T.associate(T.poses(np.arange(20.0), good[:, :3], good[:, 3:]), T.poses(None, good[:, :3], good[:, 3:]),
                    interpolate=True)


@pytest.mark.parametrize("rule", ["evo", "spline"])
def test_cli_eval_unsorted_estimate_is_named_by_its_line(rng, tmp_path, capsys, rule):
    ref, est, _ = _sync_case(rng, "denser est")
    t = est.t.copy()
    t[[40, 41]] = t[[41, 40]]
    rp = _tum(tmp_path / "ref.txt", ref)
    with open(tmp_path / "est.txt", "w") as f:
        f.write("# timestamp tx ty tz qx qy qz qw\n")
        np.savetxt(f, np.c_[t, est.pos, est.q[:, 1:], est.q[:, :1]], fmt="%.17g")
    rc, _, err = _cli(capsys, "eval", rp, tmp_path / "est.txt", "--interpolate-rule", rule)
    assert rc == 1
    assert err.strip() == (f"{tmp_path / 'est.txt'}:43: time {float(t[41])!r} is before the previous one "
                           f"({float(t[40])!r}); "
                           "--interpolate needs the times of the stream it resamples in order"), err
    # with a dropped row before it, the line is still the file's
    with open(tmp_path / "est2.txt", "w") as f:
        f.write("# timestamp tx ty tz qx qy qz qw\n0 nan 0 0 0 0 0 1\n")
        np.savetxt(f, np.c_[t, est.pos, est.q[:, 1:], est.q[:, :1]], fmt="%.17g")
    rc, _, err = _cli(capsys, "eval", rp, tmp_path / "est2.txt", "--interpolate-rule", rule, "--on-invalid", "drop")
    assert rc == 1 and f"{tmp_path / 'est2.txt'}:44: time {float(t[41])!r}" in err, err
    # a pose array: its row
    np.save(tmp_path / "ref.npy", np.c_[ref.t, ref.pos, ref.q])
    np.save(tmp_path / "est.npy", np.c_[t, est.pos, est.q])
    rc, _, err = _cli(capsys, "eval", tmp_path / "ref.npy", tmp_path / "est.npy", "--interpolate-rule", rule)
    assert rc == 1 and err.startswith(f"{tmp_path / 'est.npy'}: row 41: time {float(t[41])!r} is before"), err
    rc, _, err = _cli(capsys, "eval", tmp_path / "ref.npy", tmp_path / "est.npy", "--json", tmp_path / "s.json")
    assert rc == 0  # nearest pairs: unsorted times are accepted, as evo accepts them
    import json
    assert json.loads((tmp_path / "s.json").read_text())["options"]["interpolate"] is False


def test_cli_eval_out_npy_is_one_dimensional(rng, tmp_path, capsys):
    ref, est, _ = _sync_case(rng, "equal")
    for name, p in (("ref", ref), ("est", est)):
        np.save(tmp_path / f"{name}.npy", np.c_[p.t, p.pos, p.q])
        _tum(tmp_path / f"{name}.txt", p)
    for ext in ("npy", "txt"):  # the chunked pass over pose arrays, and the in-memory one
        for metric in ("ape", "rpe"):
            out = tmp_path / f"{metric}_{ext}.npy"
            rc, _, err = _cli(capsys, "eval", tmp_path / f"ref.{ext}", tmp_path / f"est.{ext}", "--metric", metric,
                              "--t-max-diff", "0.02", "--out", out)
            assert rc == 0, err
            e = np.load(out)
            want = T.evaluate(ref, est, metric, t_max_diff=0.02).errors
            assert e.shape == want.shape and e.ndim == 1
            np.testing.assert_allclose(e, want, rtol=1e-12)


def test_plain_tum_files_say_nothing(rng, tmp_path, capsys):
    ref, est, _ = _sync_case(rng, "equal")
    rp, ep = _tum(tmp_path / "ref.txt", ref), _tum(tmp_path / "est.txt", est)
    rc, out, err = _cli(capsys, "eval", rp, ep, "--t-max-diff", "0.02")
    assert rc == 0 and err == "" and "APE w.r.t. translation part" in out
    # a guess is still said: headerless comma-separated numbers
    (tmp_path / "c.csv").write_text("".join(",".join(repr(float(v)) for v in row) + "\n"
                                            for row in np.c_[ref.t, ref.pos, ref.q]))
    rc, _, err = _cli(capsys, "eval", tmp_path / "c.csv", ep, "--t-max-diff", "0.02")
    assert rc == 0 and err.splitlines() == [
        (f"{tmp_path / 'c.csv'}: no column names: read as t x y z qw qx qy qz (scalar first); "
         "choose with --layout xyzw or --format tum")]


@pytest.mark.parametrize("text, line, shown", [
    ("a\nb\nc\n", 1, "a"),
    ("# times\n\none\n", 3, "one"),
    ("t\n0.5\nx1\n", 3, "x1"),
    ("time\nseconds\n0.5\n", 2, "seconds"),
    ("0.5\n0.6\n\n0,7\n", 4, "0,7"),
])
def test_times_file_names_its_first_bad_line(tmp_path, capsys, text, line, shown):
    from quatarray import io

    p = tmp_path / "times.txt"
    p.write_text(text)
    with pytest.raises(io.DataError, match=rf"^times\.txt:{line}: not a number: '{shown}'"):
        io.read_times(p, name="times.txt")
    q = tmp_path / "q.csv"
    q.write_text("t,qw,qx,qy,qz\n0,1,0,0,0\n1,0,1,0,0\n")
    rc, _, err = _cli(capsys, "resample", q, tmp_path / "o.csv", "--times", p)
    assert rc == 1 and err.startswith(f"{p}:{line}: not a number: '{shown}'"), err
    assert "empty file" not in err
    np.save(tmp_path / "k.npy", qa.identity(2))
    rc, _, err = _cli(capsys, "resample", tmp_path / "k.npy", tmp_path / "o2.csv", "--rate", "4", "--in-times", p)
    assert rc == 1 and err.startswith(f"{p}:{line}: not a number: '{shown}'"), err
