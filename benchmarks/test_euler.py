"""Euler angles: quatarray against scipy, numpy-quaternion and quaternionic.

Same arrays, same run; N = 1 (per-call overhead), 10³, 10⁶, 2·10⁶ (the size
of the performance targets) and, with ``QUATARRAY_BENCH_LARGE=1``, 10⁷;
float64 for every library and float32 for quatarray. Two sequences: ``"xyz"``
(extrinsic Tait–Bryan; scipy and quatarray only) and ``"ZYZ"`` (intrinsic
proper Euler: the only convention numpy-quaternion's
``as_euler_angles``/``from_euler_angles`` and quaternionic's
``to_euler_angles``/``from_euler_angles`` offer, R = e^{αz/2} e^{βy/2} e^{γz/2}).
For scipy the ``Rotation`` of an ``as_euler`` call is built outside the
timing, and ``from_euler`` times the construction only (no ``as_quat``):
both favour scipy.

Run: ``pytest benchmarks/test_euler.py --benchmark-only`` (add ``-k 2000000``
for the target size only). Targets (issue 2), float64 at N = 2·10⁶, versus
scipy: as_euler ≥ 5×, from_euler ≥ 20×.
"""

import numpy as np
import pytest
from conftest import LIBS, SIZES, arrays, need, npq, qn, run

import quatarray as qa

Rotation = pytest.importorskip("scipy.spatial.transform").Rotation

SEQS = ["xyz", "ZYZ"]

_ANGLES = {}


def _data(lib, n, seq):
    """Unit quaternions and their Euler angles (the same for every library)."""
    dtype = np.float32 if lib.endswith("f32") else np.float64
    key = (n, seq)
    if key not in _ANGLES:
        _ANGLES[key] = qa.as_euler(arrays(n)["q"], seq, suppress_warnings=True)
    return arrays(n, dtype)["q"], _ANGLES[key].astype(dtype)


def _as_euler(lib, seq, q, a):
    if lib.startswith("quatarray"):
        return lambda: qa.as_euler(q, seq)
    if lib == "scipy":
        r = Rotation.from_quat(q, scalar_first=True)  # built outside the timing
        return lambda: r.as_euler(seq)
    if lib == "numpy-quaternion":
        Q = npq.as_quat_array(q)
        return lambda: npq.as_euler_angles(Q)
    Q = qn.array(q)
    return lambda: Q.to_euler_angles  # a property


def _from_euler(lib, seq, q, a):
    if lib.startswith("quatarray"):
        return lambda: qa.from_euler(seq, a)
    if lib == "scipy":
        return lambda: Rotation.from_euler(seq, a)
    if lib == "numpy-quaternion":
        return lambda: npq.from_euler_angles(a)
    return lambda: qn.array.from_euler_angles(a)


@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
@pytest.mark.parametrize("seq", SEQS)
@pytest.mark.parametrize("lib", LIBS)
@pytest.mark.parametrize("op", [_as_euler, _from_euler], ids=["as_euler", "from_euler"])
def test_euler(benchmark, op, lib, seq, n):
    need(lib)
    if lib in ("numpy-quaternion", "quaternionic") and seq != "ZYZ":
        pytest.skip(f"{lib} has only the ZYZ convention")
    name = op.__name__.strip("_")
    benchmark.group = f"{name} {seq} N={n}"
    fn = op(lib, seq, *_data(lib, n, seq))
    run(benchmark, fn, n, slow=lib == "scipy" and name == "from_euler")
