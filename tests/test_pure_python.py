"""Run the kernel test modules once more with NUMBA_DISABLE_JIT=1.

The kernels then run as plain Python, so their bodies are executed (and
covered) line by line, and any difference between the compiled and the
interpreted semantics shows up as a failing test.
"""

import os
import pathlib
import subprocess
import sys

import pytest

HERE = pathlib.Path(__file__).parent
MODULES = [
    "test_access.py",
    "test_trace.py",
    "test_algebra.py",
    "test_vectors.py",
    "test_conversions.py",
    "test_layouts.py",
    "test_euler.py",
    "test_trig.py",
    "test_interpolation.py",
    "test_splines.py",
    "test_cubic.py",
    "test_rates.py",
    "test_transforms.py",
    "test_align.py",
    "test_kinematics.py",
    "test_davenport.py",
    "test_symmetry.py",
    "test_classes_rotation.py",
    "test_rigid.py",
    "test_rigid_transform.py",
]


@pytest.mark.skipif(os.environ.get("NUMBA_DISABLE_JIT") == "1", reason="already running without the JIT")
def test_kernels_as_plain_python():
    files = [str(HERE / m) for m in MODULES if (HERE / m).exists()]
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    # `not slow` keeps large inputs out of the interpreted pass
    cmd = [sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", "-m", "not slow", *files]
    res = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-2000:]
