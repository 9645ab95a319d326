"""``quatarray demo``, ``plot`` and ``bench`` run end to end at small sizes.

The outputs must exist and hold sane numbers: the resampled CSV matches
:func:`quatarray.spline` on the packaged sample, Bézier passes through the
keys and beats slerp on the hold-out test of a smooth walk, the PNGs are
PNGs, and the benchmark reports positive rates and consistent ratios.
"""

import csv
import io as _io
import json
import os

import numpy as np
import pytest

import quatarray as qa
from quatarray.app import bench, demo, plot

PNG = b"\x89PNG\r\n\x1a\n"


def test_sample_ships_inside_the_package():
    path = demo.sample_path()
    assert os.path.isfile(path)
    assert os.path.dirname(path).endswith(os.path.join("quatarray", "data"))
    readme = os.path.join(os.path.dirname(path), "README.md")
    assert "Mocapbank" in open(readme, encoding="utf-8").read()


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    text = _io.StringIO()
    assert demo.run(out_dir=str(out), long_keys=2_000, stream=text) == 0
    return out, text.getvalue(), json.loads((out / "summary.json").read_text())


def test_demo_outputs_and_summary(demo_run):
    out, text, s = demo_run
    assert s["frames"] == 455 and s["joints"] > 10
    assert s["fps"] == pytest.approx(30, rel=1e-3)
    assert s["samples_per_joint"] == pytest.approx((455 - 1) * 4 + 1, abs=1)
    assert s["sign_flips_after_unflip"] == 0
    assert s["bezier_at_keys_max_deg"] < 1e-6
    hold = s["holdout_all_joints_deg"]
    assert 0 < hold["bezier"]["rms"] < hold["slerp"]["rms"]  # a smooth walk: the C¹ curve predicts better
    assert 0 < s["bezier_vs_slerp_deg"]["max"] < 10
    assert s["long_stream"]["bezier"]["Msamples_per_s"] > 0
    for f in s["files"]:
        assert os.path.isfile(f), f
    for word in ("Bézier", "slerp", "hold-out", "Msamples/s", "wrote"):
        assert word in text


def test_demo_csv_is_the_bezier_resampling(demo_run):
    out, _, s = demo_run
    path = next(f for f in s["files"] if f.endswith("bezier_120fps.csv") and "all_joints" not in f)
    with open(path) as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["t", "x", "y", "z", "qw", "qx", "qy", "qz"]
    data = np.array(rows[1:], dtype=float)
    assert len(data) == s["samples_per_joint"]
    t, _, _, _ = demo.read_joints(demo.sample_path())
    keys = qa.unflip(qa.normalize(demo.read_joints(demo.sample_path())[1]["Hips"]))
    expect = qa.spline(t, keys, data[:, 0], method="bezier")
    np.testing.assert_allclose(qa.distance(data[:, 4:], expect), 0, atol=1e-9)
    np.testing.assert_allclose(np.diff(data[:, 0]), 1 / 120, rtol=1e-6)


def test_demo_png(demo_run):
    pytest.importorskip("matplotlib")
    out, _, s = demo_run
    pngs = [f for f in s["files"] if f.endswith(".png")]
    assert pngs
    for f in pngs:
        with open(f, "rb") as fh:
            assert fh.read(8) == PNG
        assert os.path.getsize(f) > 20_000


def test_demo_default_folder_is_new(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "quatarray-demo").mkdir()  # taken: the demo picks the next name
    assert demo.run(long_keys=0, stream=_io.StringIO()) == 0
    assert (tmp_path / "quatarray-demo-2" / "summary.json").is_file()
    assert not any((tmp_path / "quatarray-demo").iterdir())


def test_demo_compiles_its_long_stream_kernels_ahead(tmp_path, monkeypatch):
    """With a long stream of many keys, the demo starts a worker on the table entries
    of the kernels that section takes (serial loops: 16 385 samples) and waits for it
    before timing."""
    from quatarray import _warmup
    from quatarray.splines import PIECES_MIN_KEYS

    asked = []

    class Worker:
        def wait(self):
            asked.append("wait")
            return 0

    monkeypatch.setattr(_warmup, "in_background", lambda names, **kw: asked.append((names, kw)) or Worker())
    assert demo.run(out_dir=str(tmp_path), long_keys=PIECES_MIN_KEYS, stream=_io.StringIO()) == 0
    names = ["spline[bezier, many keys]", "spline[slerp, many keys]"]
    assert asked == [(names, {"variants": ("serial",)}), "wait"]
    assert all(n in _warmup.TABLE for n in names)
    asked.clear()
    demo.run(out_dir=str(tmp_path), long_keys=PIECES_MIN_KEYS - 1, stream=_io.StringIO())
    assert asked == []  # the whole-table kernels of steps 1-5: nothing to compile ahead


def _stream_csv(path, n=200):
    t = np.arange(n) / 50.0
    q = qa.from_rotvec(np.column_stack([np.sin(t), 0.5 * t, np.cos(2 * t)]))
    q[1::7] *= -1
    with open(path, "w") as f:
        f.write("t,qw,qx,qy,qz\n")
        for ti, qi in zip(t, q):
            f.write(",".join(repr(float(x)) for x in (ti, *qi)) + "\n")
    return t, q


def test_plot_file(tmp_path):
    pytest.importorskip("matplotlib")
    src = tmp_path / "s.csv"
    _stream_csv(src)
    out = tmp_path / "s.png"
    assert plot.plot_file(str(src), str(out)) == 0
    assert out.read_bytes()[:8] == PNG
    # with a resampled version drawn over it
    out2 = tmp_path / "s2.png"
    assert plot.plot_file(str(src), str(out2), after=str(src)) == 0
    assert out2.read_bytes()[:8] == PNG
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp") or p.startswith(".")]


def test_plot_curves_are_right():
    t = np.arange(50) / 10.0
    q = qa.from_rotvec(np.column_stack([np.zeros(50), np.zeros(50), 0.3 * t]))  # 0.3 rad/s about z
    q[::3] *= -1
    _, eul, ang, speed = plot._curves(t, q, "ZYX")
    np.testing.assert_allclose(eul[:, 0], np.degrees(0.3 * t), atol=1e-9)
    np.testing.assert_allclose(ang, np.degrees(0.3 * t), atol=1e-9)
    np.testing.assert_allclose(speed[1:], np.degrees(0.3), rtol=1e-9)


def test_plot_without_matplotlib(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(plot, "have_matplotlib", lambda: False)
    src = tmp_path / "s.csv"
    _stream_csv(src, 10)
    assert plot.plot_file(str(src), str(tmp_path / "x.png")) == 2
    err = capsys.readouterr().err
    assert "matplotlib" in err and "pip install" in err
    assert not (tmp_path / "x.png").exists()


def test_plot_real_stream(data_dir, tmp_path):
    pytest.importorskip("matplotlib")
    out = tmp_path / "tum.png"
    assert plot.plot_file(str(data_dir / "tum_freiburg1_xyz_groundtruth.txt"), str(out)) == 0
    assert out.read_bytes()[:8] == PNG


def test_bench_run_small(tmp_path):
    text = _io.StringIO()
    path = tmp_path / "b.json"
    assert bench.run(n=2_000, json_path=str(path), budget=0.02, stream=text) == 0
    doc = json.loads(path.read_text())
    assert doc["n"] == 2_000
    assert doc["ceiling"]["GBps"] > 0 and doc["ceiling"]["Mquat_s_product"] > 0
    rows = {r["op"]: r for r in doc["results"]}
    mul = rows["multiply (out=)"]
    assert mul["rates_Mquat_s"]["quatarray"] > 0
    for lib, ratio in mul["ratios"].items():
        assert ratio == pytest.approx(mul["rates_Mquat_s"]["quatarray"] / mul["rates_Mquat_s"][lib])
    assert "scipy" in mul["ratios"]
    assert "float64" in rows["multiply float32 (out=)"]["ratios"]
    out = text.getvalue()
    assert "memory-stream ceiling" in out and "multiply (out=)" in out and "as_matrix" in out
    # a new array's row is timed against the plainest kernel making a new array of its size
    assert rows["as_matrix"]["fresh_fraction"] > 0 and "fresh_fraction" not in mul
    assert "as_matrix: " in out and "of the fresh-array ceiling" in out
    assert all(r["rates_Mquat_s"] or "status" in r for r in doc["results"])


def test_bench_measure_leaves_out_the_call_after_another_librarys():
    """A slow call (fresh pages) right after another candidate's is untimed where a
    batch is a few calls; the best round is the steady call."""
    import time

    state = {"after_other": False}

    def ours():
        time.sleep(0.05 if state["after_other"] else 0.01)
        state["after_other"] = False

    def other():
        state["after_other"] = True
        time.sleep(0.01)

    best = bench.measure({"ours": ours, "other": other}, budget=0, min_rounds=3)
    assert best["ours"] < 0.03


def test_bench_fresh_fill_makes_a_new_array_of_the_shape():
    p = np.arange(12.0).reshape(3, 4)
    a, b = bench.fresh_fill(p, 9), bench.fresh_fill(p, 9)
    np.testing.assert_array_equal(a, np.repeat(p[:, :1], 9, axis=1))
    assert a.shape == (3, 9) and not np.shares_memory(a, b)
    np.testing.assert_array_equal(bench.fresh_fill(p, 3), np.repeat(p[:, :1], 3, axis=1))


def test_bench_rejects_bad_n():
    with pytest.raises(ValueError, match="`n`"):
        bench.run(n=0)


def test_demo_clip_outputs(demo_run):
    """Hold-out test as world joint positions, the 120 fps BVH, the trajectory plot."""
    from quatarray import io

    out, text, s = demo_run
    pos = s["holdout_world_positions_cm"]
    assert 0 < pos["bezier"]["rms"] < pos["slerp"]["rms"] and pos["bezier"]["max"] < 5
    assert "cm" in text
    clip = io.read_bvh(out / "walk_120fps.bvh")
    ref = io.read_bvh(demo.sample_path()).resample(rate=120)
    assert clip.frames == s["samples_per_joint"] and clip.joints == ref.joints
    assert qa.distance(clip.rotations, ref.rotations).max() < 1e-9
    if plot.have_matplotlib():
        assert (out / "walk_trajectories.png").read_bytes()[:8] == PNG


def test_bench_leaves_out_a_peer_call_that_crashes(monkeypatch, capsys):
    from quatarray import bench as B

    monkeypatch.setattr(B, "PROBES", {"peer.dies": "import os; os.abort()", "peer.works": "pass"})
    monkeypatch.setattr(B, "_PROBED", {})
    assert B.peer_crashes("peer.dies") is True
    assert "peer.dies crashed" in capsys.readouterr().err
    assert B.peer_crashes("peer.works") is False
