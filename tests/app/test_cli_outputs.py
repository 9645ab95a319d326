"""The command line: output files: overwrite rules, modes, signals, full disks, memory (in-process through ``main([...])``, a few as
``python -m quatarray`` subprocesses)."""

import os
import subprocess
import sys
import types

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

import quatarray as qa
from quatarray.app.cli import main

from cli_common import ROOT, _leftovers, cli, run, smooth_stream, unit  # noqa: E402


def test_overwrite_rules(capsys, tmp_path, rng):
    np.save(tmp_path / "q.npy", unit(rng, 5))
    (tmp_path / "o.npy").write_bytes(b"keep")
    rc, _, err = cli(capsys, "convert", tmp_path / "q.npy", tmp_path / "o.npy", "--to", "matrix")
    assert rc == 2 and "exists; use --force" in err
    assert (tmp_path / "o.npy").read_bytes() == b"keep"
    rc, _, err = cli(capsys, "convert", tmp_path / "q.npy", tmp_path / "o.npy", "--to", "matrix", "--force")
    assert rc == 0 and np.load(tmp_path / "o.npy").shape == (5, 3, 3)
    rc, _, err = cli(capsys, "unflip", tmp_path / "q.npy", tmp_path / "q.npy", "--force")
    assert rc == 2 and "the output is the input" in err
    assert sorted(os.listdir(tmp_path)) == ["o.npy", "q.npy"]


def test_failure_keeps_existing_output(capsys, tmp_path):
    (tmp_path / "bad.csv").write_text("t,qw,qx,qy,qz\n0,1,0,0,0\n1,0,0,0,0\n")
    (tmp_path / "o.csv").write_text("old")
    rc, _, _ = cli(capsys, "convert", tmp_path / "bad.csv", tmp_path / "o.csv", "--to", "quat", "--force")
    assert rc == 1 and (tmp_path / "o.csv").read_text() == "old"
    assert sorted(os.listdir(tmp_path)) == ["bad.csv", "o.csv"]


def test_progress_bar_on_stderr(capsys, tmp_path, rng):
    np.save(tmp_path / "q.npy", unit(rng, 100))
    rc = main(["convert", str(tmp_path / "q.npy"), str(tmp_path / "o.npy"), "--to", "quat", "--progress"])
    err = capsys.readouterr().err
    assert rc == 0 and "convert:" in err and "/100 " in err
    rc, _, err = cli(capsys, "convert", tmp_path / "q.npy", tmp_path / "o2.npy", "--to", "quat")
    assert rc == 0 and err == ""


@pytest.mark.parametrize("ext", ["npy", "csv", "parquet", "txt"])
def test_output_mode_is_0666_less_umask(capsys, tmp_path, ext):
    t, pos, q = smooth_stream(np.random.default_rng(1), 20)
    np.savetxt(tmp_path / "s.csv", np.column_stack([t, pos, q]), delimiter=",",
               header="t,x,y,z,qw,qx,qy,qz", comments="")
    out = tmp_path / f"o.{ext}"
    old = os.umask(0o027)
    try:
        assert cli(capsys, "unflip", tmp_path / "s.csv", out)[0] == 0
    finally:
        os.umask(old)
    assert out.stat().st_mode & 0o777 == 0o640


def test_force_keeps_the_mode_of_the_file_it_replaces(capsys, tmp_path):
    np.save(tmp_path / "q.npy", unit(np.random.default_rng(2), 10))
    out = tmp_path / "o.csv"
    out.write_text("old\n")
    out.chmod(0o604)
    assert cli(capsys, "convert", tmp_path / "q.npy", out, "--to", "quat", "--force")[0] == 0
    assert out.stat().st_mode & 0o777 == 0o604 and out.read_text().startswith("qw,")


def test_force_refuses_a_fifo(capsys, tmp_path):
    np.save(tmp_path / "q.npy", unit(np.random.default_rng(3), 10))
    os.mkfifo(tmp_path / "o.csv")
    rc, _, err = cli(capsys, "convert", tmp_path / "q.npy", tmp_path / "o.csv", "--to", "quat", "--force")
    assert rc == 2 and "not a regular file" in err and len(err.strip().splitlines()) == 1
    assert (tmp_path / "o.csv").is_fifo()


def test_parent_that_is_a_file(capsys, tmp_path):
    np.save(tmp_path / "q.npy", unit(np.random.default_rng(4), 10))
    rc, _, err = cli(capsys, "convert", tmp_path / "q.npy", tmp_path / "q.npy" / "o.csv", "--to", "quat")
    assert rc == 2 and "is not a folder" in err and "does not exist" not in err


def test_unwritable_destination_names_out(capsys, tmp_path, monkeypatch):
    import tempfile

    np.save(tmp_path / "q.npy", unit(np.random.default_rng(5), 10))

    def refused(prefix, suffix, dir):
        path = os.path.join(dir, prefix + "abc123" + suffix)
        raise PermissionError(13, "Permission denied", path)

    monkeypatch.setattr(tempfile, "mkstemp", refused)
    out = tmp_path / "o.npy"
    rc, _, err = cli(capsys, "convert", tmp_path / "q.npy", out, "--to", "quat")
    assert rc == 2 and err.strip() == f"quatarray convert: error: {out}: cannot write the output: Permission denied"


FSIZE = (
    "import resource, signal, sys\n"
    "signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
    "lim = int(sys.argv[1])\n"
    "resource.setrlimit(resource.RLIMIT_FSIZE, (lim, lim))\n"
    "from quatarray.app.cli import main\n"
    "sys.exit(main(sys.argv[2:]))\n"
)


@pytest.mark.parametrize("ext", ["csv", "npy"])
def test_write_error_at_the_end_leaves_nothing(tmp_path, ext):
    """A file-size limit one byte short of the output: the last write (the final flush) fails."""
    np.save(tmp_path / "q.npy", unit(np.random.default_rng(6), 5000))
    args = ["convert", tmp_path / "q.npy", tmp_path / f"full.{ext}", "--to", "quat", "--no-progress"]
    assert run(*args).returncode == 0
    size = (tmp_path / f"full.{ext}").stat().st_size
    out = tmp_path / f"o.{ext}"
    args[2] = out
    res = subprocess.run([sys.executable, "-c", FSIZE, str(size - 1), *map(str, args)], capture_output=True,
                         text=True, cwd=ROOT)
    assert res.returncode == 2, res.stderr
    assert res.stderr.strip().startswith(f"quatarray convert: error: {out}: cannot write the output: ")
    assert len(res.stderr.strip().splitlines()) == 1
    assert not out.exists() and _leftovers(tmp_path) == []


@pytest.mark.parametrize("sig, code", [("SIGTERM", 143), ("SIGHUP", 129), ("SIGINT", 130)])
def test_signals_leave_nothing_behind(tmp_path, sig, code):
    import signal
    import time

    np.save(tmp_path / "k.npy", unit(np.random.default_rng(9), 20))
    out = tmp_path / "o.npy"
    # SIGINT's default (KeyboardInterrupt) only where it is not ignored, as it is under `cmd &`;
    # SIGHUP's likewise (ignored under nohup, which the program honours)
    proc = subprocess.Popen(
        [sys.executable, "-m", "quatarray", "resample", str(tmp_path / "k.npy"), str(out), "--in-rate", "1",
         "--rate", "1e7", "--chunk", "10000", "--no-progress"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
        preexec_fn=lambda: [signal.signal(s, signal.SIG_DFL) for s in (signal.SIGINT, signal.SIGHUP)],
    )
    try:
        deadline = time.monotonic() + 120
        while not any(p.stat().st_size > 1 << 20 for p in tmp_path.glob(".o.npy.*")):
            assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read()
            time.sleep(0.02)
        proc.send_signal(getattr(signal, sig))
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == code, err
    assert err.strip() == f"quatarray: interrupted ({sig})"
    assert not out.exists() and _leftovers(tmp_path) == []


def test_resample_beyond_the_disk_is_one_line(capsys, tmp_path):
    np.save(tmp_path / "q.npy", unit(np.random.default_rng(12), 20))
    rc, _, err = cli(capsys, "resample", tmp_path / "q.npy", tmp_path / "r.npy", "--in-rate", 1, "--rate", 1e12)
    assert rc == 2 and "free on its disk" in err and len(err.strip().splitlines()) == 1
    assert _leftovers(tmp_path) == [] and not (tmp_path / "r.npy").exists()


def test_memory_error_is_one_line(capsys, tmp_path, monkeypatch):
    np.save(tmp_path / "q.npy", unit(np.random.default_rng(13), 20))

    def no_memory(*a, **kw):
        raise MemoryError("Unable to allocate 267. GiB for an array with shape (35800000000000,)")

    import quatarray.conversions

    monkeypatch.setattr(quatarray.conversions, "as_matrix", no_memory)  # what convert --to matrix calls
    rc, _, err = cli(capsys, "convert", tmp_path / "q.npy", tmp_path / "o.npy", "--to", "matrix")
    assert rc == 2 and err.strip() == "quatarray convert: error: out of memory; try a smaller --chunk"
    assert _leftovers(tmp_path) == []
