"""What the command-line tests share: running the verbs, streams to feed them."""

import os
import subprocess
import sys
import types

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

import quatarray as qa
from quatarray.app.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def cli(capsys, *argv):
    rc = main([str(a) for a in argv] + (["--no-progress"] if _takes_io(argv) else []))
    out, err = capsys.readouterr()
    return rc, out, err


def _takes_io(argv):
    return argv and argv[0] not in ("demo", "bench") and "--progress" not in argv and "--help" not in argv


def run(*argv, **kw):
    """``python -m quatarray ...`` in a subprocess."""
    return subprocess.run(
        [sys.executable, "-m", "quatarray", *map(str, argv)], capture_output=True, text=True, cwd=ROOT, **kw
    )


def rot(q):
    return Rotation.from_quat(np.asarray(q, float), scalar_first=True)


def same_rotation(a, b, atol=1e-9):
    d = np.abs(np.sum(np.asarray(a) * np.asarray(b), axis=-1))
    return np.allclose(d, 1, atol=atol)


def unit(rng, n):
    q = rng.standard_normal((n, 4))
    return q / np.linalg.norm(q, axis=1)[:, None]


def smooth_stream(rng, n=60):
    """A smooth pose stream with uneven times, sign flips and slightly non-unit quaternions."""
    t = np.cumsum(rng.uniform(0.05, 0.15, n))
    q = rot(qa.identity()).as_quat(scalar_first=True)
    rv = np.cumsum(rng.normal(0, 0.15, (n, 3)), axis=0)
    q = Rotation.from_rotvec(rv).as_quat(scalar_first=True)
    q[rng.random(n) < 0.3] *= -1
    q *= rng.uniform(0.9999, 1.0001, (n, 1))
    pos = np.cumsum(rng.normal(0, 0.1, (n, 3)), axis=0)
    return t, pos, q


def write_csv(path, t=None, pos=None, q=None, header=True):
    cols, names = [], []
    if t is not None:
        cols.append(t[:, None])
        names.append("t")
    if pos is not None:
        cols.append(pos)
        names += ["x", "y", "z"]
    cols.append(q)
    names += ["qw", "qx", "qy", "qz"] if q.shape[1] == 4 else ["x", "y", "z"]
    data = np.concatenate(cols, axis=1)
    lines = ([",".join(names)] if header else []) + [",".join(repr(float(v)) for v in row) for row in data]
    path.write_text("\n".join(lines) + "\n")
    return path


def read_csv(path):
    import pyarrow.csv as pcsv

    table = pcsv.read_csv(path)
    return {n: table.column(n).to_numpy() for n in table.column_names}


def _tum(path, rng, n=40):
    t, pos, q = smooth_stream(rng, n)
    np.savetxt(path, np.column_stack([t, pos, q[:, [1, 2, 3, 0]]]), header="timestamp tx ty tz qx qy qz qw")
    return q


RSS = (
    "import resource, subprocess, sys\n"
    "subprocess.run(sys.argv[1:], check=True)\n"
    "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n"
)


def _peak_kib(*argv):
    res = subprocess.run([sys.executable, "-c", RSS, sys.executable, "-m", "quatarray", *map(str, argv)],
                         capture_output=True, text=True, cwd=ROOT)
    assert res.returncode == 0, res.stderr
    return int(res.stdout.split()[-1])


def _leftovers(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))
