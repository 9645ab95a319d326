"""The command line: bad inputs, dropping rows, layouts, several inputs in one call (in-process through ``main([...])``, a few as
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

from cli_common import _tum, cli, read_csv, rot, run, same_rotation, unit  # noqa: E402


def test_convert_axis_angle_and_layout(capsys, tmp_path, rng):
    q = unit(rng, 20)
    np.save(tmp_path / "q.npy", q[:, [1, 2, 3, 0]])
    rc, _, err = cli(capsys, "convert", tmp_path / "q.npy", tmp_path / "o.npy", "--to", "axis-angle",
                     "--layout", "xyzw")
    assert rc == 0, err
    got = np.load(tmp_path / "o.npy")
    np.testing.assert_allclose(got[:, :3] * got[:, 3:], rot(q).as_rotvec(), atol=1e-12)


BAD = {
    "short row": ("t,qw,qx,qy,qz\n0,1,0,0,0\n1,1,0,0\n", "bad.csv:3: expected 5 fields, got 4"),
    "text in number": ("t,qw,qx,qy,qz\n0,1,0,0,0\n1,1,zero,0,0\n", "bad.csv:3: not a number: 'zero' in column qx"),
    "zero quaternion": ("t,qw,qx,qy,qz\n0,1,0,0,0\n1,0,0,0,0\n", "bad.csv:3: zero quaternion"),
    "empty file": ("", "bad.csv: empty file"),
    "missing column": ("t,qw,qx,qy\n0,1,0,0\n", "bad.csv:1: missing column qz"),
    "wrong layout": ("0,0,1\n", "bad.csv:1: expected 4 (quaternion)"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_files(capsys, tmp_path, monkeypatch, case):
    text, msg = BAD[case]
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.csv").write_text(text)
    rc, _, err = cli(capsys, "convert", "bad.csv", "out.npy", "--to", "quat")
    assert rc == 1
    assert err.strip().splitlines() == [msg] or err.startswith(msg)
    assert len(err.strip().splitlines()) == 1
    assert sorted(os.listdir(tmp_path)) == ["bad.csv"]  # no output, no temporary file


def test_bad_npy_layout(capsys, tmp_path):
    np.save(tmp_path / "v.npy", np.zeros((4, 3)))
    rc, _, err = cli(capsys, "unflip", tmp_path / "v.npy", tmp_path / "o.npy")
    assert rc == 1 and "expected quaternions of shape (N, 4)" in err and "got (4, 3)" in err
    assert not (tmp_path / "o.npy").exists()


def test_bad_file_subprocess(tmp_path):
    (tmp_path / "walk.csv").write_text("t,qw,qx,qy,qz\n0,1,0,0,0\n1,1,0,0\n")
    res = run("unflip", tmp_path / "walk.csv", tmp_path / "o.csv")
    assert res.returncode == 1
    assert res.stderr.strip() == f"{tmp_path / 'walk.csv'}:3: expected 5 fields, got 4"
    assert "Traceback" not in res.stderr and not (tmp_path / "o.csv").exists()


def test_drop(capsys, tmp_path):
    (tmp_path / "bad.csv").write_text("t,qw,qx,qy,qz\n0,1,0,0,0\n1,1,0,0\n2,x,0,0,0\n3,0,0,0,0\n4,0,2,0,0\n")
    rc, _, err = cli(capsys, "convert", tmp_path / "bad.csv", tmp_path / "o.csv", "--to", "quat",
                     "--on-invalid", "drop")
    assert rc == 0
    assert "dropped 3 invalid rows" in err and "largest | |q| - 1 | = 1" in err
    got = read_csv(tmp_path / "o.csv")
    np.testing.assert_array_equal(got["t"], [0, 4])
    np.testing.assert_array_equal(got["qx"], [0, 1])
    (tmp_path / "all.csv").write_text("t,qw,qx,qy,qz\n0,0,0,0,0\n")
    rc, _, err = cli(capsys, "convert", tmp_path / "all.csv", tmp_path / "o2.csv", "--to", "quat",
                     "--on-invalid", "drop")
    assert rc == 1 and "no valid rows" in err and not (tmp_path / "o2.csv").exists()


def test_several_inputs_outputs_named_after_inputs(capsys, tmp_path, several):
    src = [tmp_path / "in" / f"{k}.txt" for k in "abc"]
    rc, _, err = cli(capsys, "convert", *src, tmp_path / "new" / "deeper", "--to", "matrix", "--ext", "npy")
    assert rc == 0, err
    assert sorted(os.listdir(tmp_path / "new" / "deeper")) == ["a.npy", "b.npy", "c.npy"]  # folder created
    for k, q in several.items():
        np.testing.assert_allclose(np.load(tmp_path / "new" / "deeper" / f"{k}.npy"), rot(q).as_matrix(), atol=1e-12)
    # default extension: each input's own (TUM in, TUM out); `.csv` via --ext keeps the columns
    rc, _, err = cli(capsys, "unflip", *src, tmp_path / "u")
    assert rc == 0, err
    assert sorted(os.listdir(tmp_path / "u")) == ["a.txt", "b.txt", "c.txt"]
    got, q = np.loadtxt(tmp_path / "u" / "b.txt"), several["b"]
    assert got.shape == (40, 8) and same_rotation(got[:, [7, 4, 5, 6]], q / np.linalg.norm(q, axis=1)[:, None])
    assert (np.sum(got[1:, 4:] * got[:-1, 4:], axis=1) >= 0).all()
    rc, _, err = cli(capsys, "resample", *src, tmp_path / "r", "--rate", "50", "--ext", ".csv")
    assert rc == 0, err
    assert sorted(os.listdir(tmp_path / "r")) == ["a.csv", "b.csv", "c.csv"]
    assert list(read_csv(tmp_path / "r" / "c.csv")) == ["t", "x", "y", "z", "qw", "qx", "qy", "qz"]
    np.save(tmp_path / "times.npy", [1.0, 1.5, 2.0])  # read once, for every input
    rc, _, err = cli(capsys, "resample", *src, tmp_path / "rt", "--times", tmp_path / "times.npy", "--ext", "csv")
    assert rc == 0, err
    assert all(list(read_csv(tmp_path / "rt" / f"{k}.csv")["t"]) == [1.0, 1.5, 2.0] for k in "abc")
    # one input into an existing folder, OUT/ with a slash, or with --ext is the folder form too
    (tmp_path / "one").mkdir()
    assert cli(capsys, "convert", src[0], tmp_path / "one", "--to", "quat", "--ext", "npy")[0] == 0
    assert cli(capsys, "convert", src[1], f"{tmp_path / 'one'}{os.sep}", "--to", "quat", "--ext", "npy")[0] == 0
    assert cli(capsys, "convert", src[2], tmp_path / "one", "--to", "quat")[0] == 0
    assert cli(capsys, "convert", src[0], tmp_path / "two", "--to", "quat", "--ext", "csv")[0] == 0
    assert sorted(os.listdir(tmp_path / "one")) == ["a.npy", "b.npy", "c.txt"]
    assert os.listdir(tmp_path / "two") == ["a.csv"]


def test_several_inputs_one_bad_file(capsys, tmp_path, several):
    bad = tmp_path / "in" / "bad.txt"
    bad.write_text("# timestamp tx ty tz qx qy qz qw\n1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n")
    src = [tmp_path / "in" / "a.txt", bad, tmp_path / "in" / "c.txt", tmp_path / "in" / "none.txt"]
    rc, _, err = cli(capsys, "convert", *src, tmp_path / "o", "--to", "rotvec", "--ext", "npy")
    assert rc == 1
    assert sorted(os.listdir(tmp_path / "o")) == ["a.npy", "c.npy"]  # the others written, no temporary left
    lines = err.splitlines()
    assert f"{bad}:3: expected 8 numbers, got 7" in lines
    assert f"quatarray convert: error: {src[3]}: no such file" in lines
    assert lines[-1] == "quatarray convert: 2 of 4 inputs failed"
    assert "Traceback" not in err
    # info: each good file under its name, the bad one named on stderr
    rc, out, err = cli(capsys, "info", *src[:3])
    assert rc == 1 and f"{bad}:3: expected 8 numbers, got 7" in err
    blocks = out.split("\n\n")
    assert [b.splitlines()[0].split(None, 1)[1] for b in blocks] == [str(src[0]), str(src[2])]
    assert all("rows:         40" in b for b in blocks)


def test_several_inputs_existing_output_and_exit_codes(capsys, tmp_path, several):
    src = [tmp_path / "in" / f"{k}.txt" for k in "abc"]
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "b.npy").write_bytes(b"keep")
    rc, _, err = cli(capsys, "convert", *src, tmp_path / "o", "--to", "quat", "--ext", "npy")
    assert rc == 1 and f"{tmp_path / 'o' / 'b.npy'}: exists; use --force" in err
    assert (tmp_path / "o" / "b.npy").read_bytes() == b"keep"
    assert sorted(os.listdir(tmp_path / "o")) == ["a.npy", "b.npy", "c.npy"]
    rc, _, err = cli(capsys, "convert", *src, tmp_path / "o", "--to", "quat", "--ext", "npy", "--force")
    assert rc == 0 and np.load(tmp_path / "o" / "b.npy").shape == (40, 4)

    def refused(*argv):
        before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
        rc, _, err = cli(capsys, *argv)
        assert rc == 2 and len(err.splitlines()) == 1, err
        assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before  # nothing ran
        return err

    # the folder forgotten: the last input taken for OUT is a file, not a folder
    assert "not a folder" in refused("convert", *src, "--to", "quat")
    # two inputs with the same name, from different folders: no silent overwrite
    (tmp_path / "in2").mkdir()
    _tum(tmp_path / "in2" / "a.txt", np.random.default_rng(3))
    err = refused("convert", src[0], tmp_path / "in2" / "a.txt", tmp_path / "p", "--to", "quat", "--ext", "npy")
    assert "would both be written to" in err and str(tmp_path / "p" / "a.npy") in err
    # OUT holding the inputs, with their own extension: each output would be its input
    err = refused("unflip", *src, tmp_path / "in", "--force")
    assert "the output is the input file" in err
    err = refused("convert", src[0], src[1], src[0], "--to", "quat")  # OUT equal to an input
    assert "not a folder" in err
    assert "cannot tell the output format" in refused("convert", *src, tmp_path / "p", "--to", "quat", "--ext", "xyz")
    assert "SEQ is three axes" in refused("convert", *src, tmp_path / "p", "--to", "euler:XXY")


def test_several_inputs_subprocess(tmp_path, several):
    src = [tmp_path / "in" / f"{k}.txt" for k in "abc"]
    (tmp_path / "in" / "b.txt").write_text("1 2 3\n")
    res = run("convert", *src, tmp_path / "o", "--to", "quat", "--ext", "npy")
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert sorted(os.listdir(tmp_path / "o")) == ["a.npy", "c.npy"]
    assert any(line.startswith(f"{src[1]}:1: ") for line in res.stderr.splitlines())
    assert run("convert", *src, "--to", "quat").returncode == 2


def test_headerless_comma_tum_layout_said_and_chosen(capsys, tmp_path):
    rows = [[0.0, 1, 2, 3, 0, 0, 0, 1], [0.5, 1, 2, 3, 0, 0, 1, 0]]
    (tmp_path / "c.csv").write_text("".join(",".join(map(str, r)) + "\n" for r in rows))
    rc, _, err = cli(capsys, "convert", tmp_path / "c.csv", tmp_path / "o.csv", "--to", "quat")
    assert rc == 0 and err.splitlines() == [
        f"{tmp_path / 'c.csv'}: no column names: read as t x y z qw qx qy qz (scalar first); "
        "choose with --layout xyzw or --format tum"
    ]
    for opt in (["--layout", "xyzw"], ["--format", "tum"]):
        rc, _, err = cli(capsys, "convert", tmp_path / "c.csv", tmp_path / "o.csv", "--to", "quat", "--force", *opt)
        assert rc == 0 and err == ""
        got = read_csv(tmp_path / "o.csv")
        np.testing.assert_array_equal(np.column_stack([got[c] for c in ("qw", "qx", "qy", "qz")]),
                                      [[1, 0, 0, 0], [0, 0, 0, 1]])
    rc, out, _ = cli(capsys, "convert", "--help")
    assert rc == 0 and "--format tum" in " ".join(out.split())


def test_layout_on_named_columns_said(capsys, stream, tmp_path):
    path, t, pos, q = stream
    rc, _, err = cli(capsys, "unflip", path, tmp_path / "o.csv", "--layout", "xyzw")
    assert rc == 0 and f"{path}: --layout xyzw ignored: the file names its columns" in err.splitlines()
    got = read_csv(tmp_path / "o.csv")
    assert same_rotation(np.column_stack([got[c] for c in ("qw", "qx", "qy", "qz")]),
                         q / np.linalg.norm(q, axis=1)[:, None])


def test_float16_npy_is_read_as_float32(capsys, tmp_path):
    q = unit(np.random.default_rng(10), 30)
    np.save(tmp_path / "h.npy", q.astype(np.float16))
    rc, _, err = cli(capsys, "convert", tmp_path / "h.npy", tmp_path / "o.npy", "--to", "matrix")
    assert rc == 0, err
    out = np.load(tmp_path / "o.npy")
    assert out.dtype == np.float32
    np.testing.assert_allclose(out, rot(q.astype(np.float16).astype(np.float64)).as_matrix(), atol=1e-6)
    rc, out, _ = cli(capsys, "info", tmp_path / "h.npy")
    assert rc == 0 and "float32" in out
