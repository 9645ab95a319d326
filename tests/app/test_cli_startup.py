"""The command line: parsing, help, start-up imports and the wiring of optional verbs (in-process through ``main([...])``, a few as
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

from cli_common import ROOT, run, smooth_stream, unit  # noqa: E402


def test_help_and_usage(capsys):
    assert main(["--help"]) == 0
    assert "resample" in capsys.readouterr().out
    assert main([]) == 2
    assert main(["convert", "a.npy"]) == 2
    assert "required" in capsys.readouterr().err
    assert main(["resample", "a.npy", "b.npy"]) == 2  # --rate or --times
    assert main(["convert", "a.npy", "b.npy", "--to", "quat", "--chunk", "0"]) == 2
    assert main(["nope"]) == 2


def test_python_m_help_subprocess():
    res = run("--help")
    assert res.returncode == 0 and "convert" in res.stdout
    res = run("convert", "missing.npy", "o.npy", "--to", "quat")
    assert res.returncode == 2
    assert res.stderr.strip() == "quatarray convert: error: missing.npy: no such file"


IMPORTS = (
    "import sys\n"
    "from quatarray.app.cli import main\n"
    "rc = main(sys.argv[1:])\n"
    "heavy = ('numba', 'scipy', 'pandas', 'pyarrow', 'pyarrow.compute', 'dask', 'distributed', 'matplotlib',\n"
    "         'tqdm', 'zarr')\n"
    "print(rc, *[m for m in heavy if m in sys.modules])\n"
)


def _loaded(*argv):
    """The exit status and the heavy modules loaded by ``main(argv)`` in a fresh process."""
    res = subprocess.run([sys.executable, "-c", IMPORTS, *map(str, argv)], capture_output=True, text=True, cwd=ROOT)
    assert res.returncode == 0, res.stderr
    rc, *mods = res.stdout.splitlines()[-1].split()  # after what the verb prints
    assert rc == "0", res.stderr
    return int(rc), set(mods)


def test_startup_imports_only_what_the_verb_needs(tmp_path, rng):
    t, pos, q = smooth_stream(rng, 50)
    tum = tmp_path / "x.txt"
    np.savetxt(tum, np.column_stack([t, pos, q[:, [1, 2, 3, 0]]]), header="timestamp tx ty tz qx qy qz qw")
    np.save(tmp_path / "q.npy", unit(rng, 50))
    # text is parsed by pyarrow.csv; checking and writing the quaternions needs no kernel
    assert _loaded("convert", tum, tmp_path / "y.npy", "--to", "quat") == (0, {"pyarrow"})
    assert _loaded("info", tum) == (0, {"pyarrow"})
    assert _loaded("convert", tmp_path / "q.npy", tmp_path / "y2.npy", "--to", "quat") == (0, set())
    assert _loaded("convert", tmp_path / "q.npy", tmp_path / "y3.npy", "--to", "xyzw") == (0, set())
    # a conversion runs a kernel: numba (which imports scipy itself), nothing else
    assert _loaded("convert", tmp_path / "q.npy", tmp_path / "m.npy", "--to", "matrix") == (0, {"numba", "scipy"})
    # a csv output: pyarrow writes it (and pandas, which pyarrow's conversions import, stays out)
    assert _loaded("unflip", tum, tmp_path / "u.csv") == (0, {"numba", "scipy", "pyarrow"})
    assert np.load(tmp_path / "y.npy").shape == (50, 4)


def test_optional_verbs_wiring(capsys, monkeypatch, tmp_path):
    calls = {}
    fake = types.ModuleType("quatarray.app.demo")
    fake.run = lambda out_dir=None: calls.setdefault("demo", out_dir) and 0
    monkeypatch.setitem(sys.modules, "quatarray.app.demo", fake)
    fake_b = types.ModuleType("quatarray.app.bench")
    fake_b.run = lambda n=None, json_path=None: calls.setdefault("bench", (n, json_path)) and 3
    monkeypatch.setitem(sys.modules, "quatarray.app.bench", fake_b)
    fake_p = types.ModuleType("quatarray.app.plot")
    fake_p.plot_file = lambda i, o, **kw: calls.setdefault("plot", (i, o, kw)) and 0
    monkeypatch.setitem(sys.modules, "quatarray.app.plot", fake_p)
    assert main(["demo", "--out", "d"]) == 0 and calls["demo"] == "d"
    assert main(["bench", "--n", "1000", "--json", "b.json"]) == 3 and calls["bench"] == (1000, "b.json")
    (tmp_path / "s.csv").write_text("qw,qx,qy,qz\n1,0,0,0\n")
    assert main(["plot", str(tmp_path / "s.csv"), str(tmp_path / "p.png"), "--joint", "Hips"]) == 0
    assert calls["plot"][2]["joint"] == "Hips" and calls["plot"][2]["fmt"] == "auto"
    monkeypatch.setitem(sys.modules, "quatarray.app.demo", None)  # not installed
    assert main(["demo"]) == 2
    assert "demo is not available" in capsys.readouterr().err


def test_scheduler_wiring(capsys, monkeypatch):
    pytest.importorskip("dask")
    import quatarray.dask as qd

    seen = {}
    monkeypatch.setattr(qd, "convert_file", lambda src, dst, **kw: seen.setdefault("c", (src, dst, kw)) and 0,
                        raising=False)
    monkeypatch.setattr(qd, "resample_file", lambda src, dst, **kw: seen.setdefault("r", (src, dst, kw)) and 0,
                        raising=False)
    assert main(["convert", "a.npy", "b.npy", "--to", "matrix", "--scheduler", "local", "--chunk", "10"]) == 0
    assert seen["c"] == ("a.npy", "b.npy", dict(to="matrix", degrees=False, layout="wxyz", chunk=10,
                                                  scheduler="local", on_invalid="error", force=False))
    assert main(["resample", "a.npy", "b.npy", "--rate", "50", "--scheduler", "tcp://h:8786"]) == 0
    assert seen["r"][2]["rate"] == 50 and seen["r"][2]["scheduler"] == "tcp://h:8786"
