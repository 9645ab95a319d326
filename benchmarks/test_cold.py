"""First calls from an empty numba cache: what a new user waits for.

Each public function (every entry of the warm-up table, :data:`quatarray._warmup.TABLE`,
called once on contiguous inputs) and float type runs in a fresh process whose ``NUMBA_CACHE_DIR`` is a new empty
folder; the time of its first call (compiling every kernel it needs) is measured
there, as wall time and as the process's CPU time (which the other load of a shared
machine disturbs less); so is each public method of the transform classes alone (their
table entries call every method in one process). ``quatarray demo`` is timed the same
way, as a whole command.

Run ``python -m pytest benchmarks/test_cold.py -s`` for the table; the targets
(issue 13) are asserted with a margin for a shared machine: a public function's
first call within 3 s (the Bézier spline within 4 s) of CPU time, the demo within
20 s of wall time.
"""

import json
import os
import subprocess
import sys
import tempfile
import time

import pytest

from quatarray import _warmup

_FIRST_CALL = """
import json, sys, time, warnings
t0, c0 = time.perf_counter(), time.process_time()
import quatarray as qa
from quatarray import _jit, _warmup
s = _warmup._samples(sys.argv[2])
_jit.PARALLEL_MIN_ROWS = sys.maxsize  # the serial loops, as a first small call uses
# one plain call (contiguous inputs, a new result), not every layout the warm-up covers
_warmup._each = lambda f, *args, out=False, **kw: f(*args, **kw)
_warmup._interp = lambda f, s, *extra, **kw: f(s.p, s.q, *extra, s.t, **kw)
warnings.simplefilter("ignore")
t1, c1 = time.perf_counter(), time.process_time()
_warmup.TABLE[sys.argv[1]](qa, s)
print(json.dumps([time.perf_counter() - t1, time.process_time() - c1, time.perf_counter() - t0]))
"""

# the targets of issue 13, in seconds of the first call's CPU time
TARGET = {name: 4.0 for name in _warmup.TABLE if name.startswith("spline[bezier")}
MARGIN = 1.5  # a shared machine: other processes' load slows compiling too


def _cold(*argv):
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        r = subprocess.run([sys.executable, *argv], env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    return r


@pytest.mark.parametrize("dtype", ["float64", "float32"])
@pytest.mark.parametrize("name", sorted(_warmup.TABLE))
def test_first_call(name, dtype):
    wall, cpu, process = json.loads(_cold("-c", _FIRST_CALL, name, dtype).stdout.splitlines()[-1])
    print(f"\n{name:24s} {dtype}: first call {wall:5.2f} s wall, {cpu:5.2f} s CPU ({process:5.2f} s with the import)")
    assert cpu <= MARGIN * TARGET.get(name, 3.0)


# The transform classes' entries of the table call every method in one process;
# here each public method's first call alone, as a user meets it (the class made
# beforehand, except for the constructor's own line).
_METHOD_CALL = """
import json, sys, time, warnings
import quatarray as qa
from quatarray import _jit, _warmup
s = _warmup._samples(sys.argv[3])
_jit.PARALLEL_MIN_ROWS = sys.maxsize
warnings.simplefilter("ignore")
make = {"VQS": _warmup._vqs, "VQM": _warmup._vqm}[sys.argv[1]]
t = None if sys.argv[2] == "constructor" else make(qa, s)
m = t.as_matrix() if sys.argv[2] == "from_matrix" else None
calls = {
    "constructor": lambda: make(qa, s),
    "apply": lambda: t.apply(s.v),
    "compose (@)": lambda: t @ t,
    "inverse": lambda: t.inverse(),
    "as_matrix": lambda: t.as_matrix(),
    "from_matrix": lambda: type(t).from_matrix(m),
    "identity": lambda: getattr(qa, sys.argv[1]).identity(3, dtype=s.dtype),
    "interpolate": lambda: qa.interpolate(t, t, s.t),
}
c = time.process_time()
calls[sys.argv[2]]()
print(json.dumps(time.process_time() - c))
"""
METHODS = ["constructor", "apply", "compose (@)", "inverse", "as_matrix", "from_matrix", "identity", "interpolate"]


@pytest.mark.parametrize("dtype", ["float64", "float32"])
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("cls", ["VQS", "VQM"])
def test_first_call_of_a_transform_method(cls, method, dtype):
    cpu = json.loads(_cold("-c", _METHOD_CALL, cls, method, dtype).stdout.splitlines()[-1])
    print(f"\n{cls}.{method:12s} {dtype}: first call {cpu:5.2f} s CPU")
    assert cpu <= MARGIN * 3.0


# The 16 common first calls of issue 13, one after another in one process (kernels
# that several of them share compile once): target 15 s CPU together.
_SIXTEEN = """
import json, time, warnings
import numpy as np
c0 = time.process_time()
import quatarray as qa
rng = np.random.default_rng(0)
p = qa.random(1000, rng=1)
q = qa.random(1000, rng=2)
v = rng.normal(size=(1000, 3))
t = np.arange(1000.0)
nt = np.linspace(0.0, 999.0, 4000)
c1 = time.process_time()
calls = {
    "multiply": lambda: qa.multiply(p, q),
    "rotate": lambda: qa.rotate(p, v),
    "normalize": lambda: qa.normalize(p),
    "as_matrix": lambda: qa.as_matrix(p),
    "from_matrix": lambda: qa.from_matrix(qa.as_matrix(p)),
    "as_rotvec": lambda: qa.as_rotvec(p),
    "from_rotvec": lambda: qa.from_rotvec(v),
    "as_euler": lambda: qa.as_euler(p, "xyz"),
    "from_euler": lambda: qa.from_euler("xyz", v),
    "slerp": lambda: qa.slerp(p, q, 0.3),
    "unflip": lambda: qa.unflip(p),
    "spline bezier": lambda: qa.spline(t, p, nt),
    "spline slerp": lambda: qa.spline(t, p, nt, method="slerp"),
    "angular_velocity": lambda: qa.angular_velocity(p, t),
    "mean": lambda: qa.mean(p),
    "multiply float32": lambda: qa.multiply(p.astype(np.float32), q.astype(np.float32)),
}
each = {}
for name, call in calls.items():
    c = time.process_time()
    call()
    each[name] = time.process_time() - c
print(json.dumps([time.process_time() - c1, c1 - c0, each]))
"""


def test_sixteen_first_calls_together():
    total, start, each = json.loads(_cold("-c", _SIXTEEN).stdout.splitlines()[-1])
    print(f"\n16 common first calls in one process: {total:.1f} s CPU (import {start:.2f} s)")
    for name, cpu in each.items():
        print(f"  {name:18s} {cpu:5.2f} s")
    assert total <= MARGIN * 15.0


def test_demo_from_an_empty_cache(tmp_path):
    t0 = time.perf_counter()
    _cold("-m", "quatarray", "demo", "--out", str(tmp_path / "demo"))
    wall = time.perf_counter() - t0
    print(f"\nquatarray demo from an empty cache: {wall:.1f} s wall")
    assert wall <= MARGIN * 20.0


# A yardstick of the machine's speed at compiling, measured in the same run: the
# issue quotes quaternionic (numba-based too) at about 10 s to compile everything
# from an empty cache, on the machine where the targets above were set. On a
# shared host that compiles slower, every first call above is slower by about the
# same factor; this figure says by how much. It is a measurement, not a check.
QUATERNIONIC_REFERENCE = 10.0  # s, the figure
_QUATERNIONIC = """
import json, time
c = time.process_time()
import numpy as np, quaternionic
a = quaternionic.array(np.random.default_rng(0).normal(size=(10, 4))).normalized
b = a * a
quaternionic.array.from_rotation_matrix(b.to_rotation_matrix)
np.log(b), np.exp(b)
print(json.dumps(time.process_time() - c))
"""


def test_yardstick_quaternionic_from_an_empty_cache():
    pytest.importorskip("quaternionic")
    cpu = json.loads(_cold("-c", _QUATERNIONIC).stdout.splitlines()[-1])
    print(f"\nyardstick: quaternionic's import and first calls from an empty cache {cpu:.1f} s CPU "
          f"(about {QUATERNIONIC_REFERENCE:.0f} s where issue 13's targets were set: "
          f"this machine compiles {cpu / QUATERNIONIC_REFERENCE:.1f}x as slowly)")
