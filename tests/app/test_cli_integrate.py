"""``quatarray integrate``: angular-velocity streams (csv, parquet, EuRoC IMU) to orientation streams."""

import numpy as np
import pytest

import quatarray as qa
from cli_common import cli, run

IMU_HEADER = ("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
              "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]")
T0_NS = 1_403_715_271_262_142_976


def imu_file(path, t_ns, w):
    lines = [IMU_HEADER] + [f"{t},{a!r},{b!r},{c!r},9.81,0.1,-0.2" for t, (a, b, c) in zip(t_ns, w.tolist())]
    path.write_text("\n".join(lines) + "\n")
    return path


def read_out(path):
    a = np.loadtxt(path, delimiter=",", skiprows=1)
    return a[:, 0], a[:, 1:]


@pytest.fixture
def imu(tmp_path, rng):
    n = 400
    t_ns = T0_NS + np.r_[0, np.cumsum(rng.integers(4_900_000, 5_100_000, n - 1))]
    w = np.c_[np.sin(np.arange(n) / 30), np.cos(np.arange(n) / 50), 0.3 + 0 * np.arange(n)]
    return imu_file(tmp_path / "imu0.csv", t_ns, w), t_ns, w


@pytest.mark.parametrize("frame", ["space", "body"])
@pytest.mark.parametrize("hold", ["mean", "start"])
def test_euroc_imu_any_chunk(capsys, tmp_path, imu, frame, hold):
    path, t_ns, w = imu
    expect = qa.integrate_angular_velocity(w * 1e-9, t_ns, frame=frame, hold=hold)  # exact ns steps
    outs = []
    for chunk in (7, 100_000):
        out = tmp_path / f"q{chunk}.csv"
        rc, _, err = cli(capsys, "integrate", path, out, "--frame", frame, "--hold", hold, "--chunk", chunk)
        assert rc == 0, err
        t, q = read_out(out)
        np.testing.assert_allclose(t, t_ns * 1e-9, rtol=1e-15)
        assert np.abs(q - expect).max() < 1e-14
        outs.append(out.read_bytes())
    assert outs[0] == outs[1]  # the orientation is carried across chunks exactly


def test_csv_constant_rate_degrees_and_npy(capsys, tmp_path, rng):
    t = np.cumsum(0.5 + rng.random(300)) * 0.01
    w_deg = np.array([10.0, -20.0, 45.0])
    src = tmp_path / "rate.csv"
    src.write_text("t,wx,wy,wz\n" + "".join(f"{ti!r},10,-20,45\n" for ti in t.tolist()))
    out = tmp_path / "q.npy"
    rc, _, err = cli(capsys, "integrate", src, out, "--degrees")
    assert rc == 0, err
    q = np.load(out)
    assert q.shape == (300, 4)
    assert np.abs(q - qa.from_rotvec(np.outer(t - t[0], np.radians(w_deg)))).max() < 1e-12


def test_parquet_in_and_out(capsys, tmp_path, rng):
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    t = np.cumsum(0.5 + rng.random(100)) * 0.01
    w = rng.standard_normal((100, 3))
    src = tmp_path / "rate.parquet"
    pq.write_table(pa.table({"t": t, "wx": w[:, 0], "wy": w[:, 1], "wz": w[:, 2]}), src)
    out = tmp_path / "q.parquet"
    rc, _, err = cli(capsys, "integrate", src, out, "--frame", "body")
    assert rc == 0, err
    tab = pq.read_table(out)
    assert tab.column_names == ["t", "qw", "qx", "qy", "qz"]
    q = np.column_stack([tab.column(c).to_numpy() for c in ("qw", "qx", "qy", "qz")])
    np.testing.assert_array_equal(q, qa.integrate_angular_velocity(w, t, frame="body"))


def test_bad_data_and_usage(capsys, tmp_path):
    src = tmp_path / "rate.csv"
    src.write_text("t,wx,wy,wz\n0,1,2,3\n1,1,2,3\n1,1,2,3\n")
    rc, _, err = cli(capsys, "integrate", src, tmp_path / "q.csv")
    assert rc == 1
    assert err.strip() == (f"{src}:4: repeated time 1.0 (previous 1.0); times must increase")
    src.write_text("t,x,y,z\n0,1,2,3\n")
    rc, _, err = cli(capsys, "integrate", src, tmp_path / "q.csv")
    assert rc == 1 and "missing column wx, wy, wz" in err and err.count("\n") == 1
    src.write_text("t,wx,wy,wz\n0,1,2,3\n1,nan,2,3\n")
    rc, _, err = cli(capsys, "integrate", src, tmp_path / "q.csv")
    assert rc == 1 and f"{src}:3: angular velocity is not finite" in err
    rc, _, err = cli(capsys, "integrate", src, tmp_path / "q.csv", "--on-invalid", "drop")
    assert rc == 0 and "dropped 1 invalid row" in err
    np.save(tmp_path / "w.npy", np.zeros((5, 3)))
    rc, _, err = cli(capsys, "integrate", tmp_path / "w.npy", tmp_path / "q2.csv")
    assert rc == 2 and "has no time column" in err
    rc, _, err = cli(capsys, "integrate", src, tmp_path / "q3.csv", "--frame", "world")
    assert rc == 2


def test_subprocess_euroc(tmp_path, imu):
    path, t_ns, w = imu
    res = run("integrate", path, tmp_path / "q.csv")
    assert res.returncode == 0, res.stderr
    _, q = read_out(tmp_path / "q.csv")
    assert np.abs(q - qa.integrate_angular_velocity(w * 1e-9, t_ns)).max() < 1e-14
    res = run("integrate", tmp_path / "missing.csv", tmp_path / "q2.csv")
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and "missing.csv: no such file" in res.stderr
