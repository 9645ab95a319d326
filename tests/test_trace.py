"""quatarray._trace: straight-line element functions, builtins of the kernels that call them."""

import math
import os

import numba
import numpy as np
import pytest
from numba.core.errors import TypingError

from compile_events import compiles
from quatarray._jit import fmuladd, like
from quatarray._trace import float_bits, select, traced

JIT = os.environ.get("NUMBA_DISABLE_JIT", "0") in ("", "0")


def _every_op_with(pick, bits):
    """Every operation a traced function may use, on a scalar x and a 3-tuple v; `pick`
    and `bits` are select and float_bits, or numba-compilable stand-ins for them."""

    def every_op(x, v):
        one = like(x, 1.0)
        a = (x + v[0]) * (v[1] - x) / (abs(v[2]) + one)
        b = fmuladd(x, v[1], -v[2]) + np.sqrt(abs(x)) - np.rint(x * like(x, 3.7)) + np.floor(v[0])
        c = np.copysign(a, v[1]) - like(x, 2.0) * (x < v[0])  # a comparison's result as 0 or 1
        flag = ((x <= v[1]) & ~(v[2] > x)) | (x == v[0]) | ((x >= one) != (v[1] != one))
        k = like(x, 1e-300 if bits(x) == 64 else 1e-30)  # a compile-time choice by type
        return pick(flag, (a, b), (b, c)), pick(flag, a, like(x, 0.5)) + k, -c

    return every_op


traced_every_op = traced(_every_op_with(select, float_bits))


def _rows_of(op):
    @numba.njit
    def rows(xs, vs):
        out = np.empty((xs.shape[0], 4), xs.dtype)
        for i in range(xs.shape[0]):
            (p, q), r, s = op(xs[i], (vs[i, 0], vs[i, 1], vs[i, 2]))
            out[i, 0], out[i, 1], out[i, 2], out[i, 3] = p, q, r, s
        return out

    return rows


# numba's own compile of the same code, as the oracle (select as a conditional
# expression; the float width fixed for each type)
_pick = numba.njit(lambda c, a, b: a if c else b)
ORACLE = {np.dtype(t): _rows_of(numba.njit(_every_op_with(_pick, numba.njit(lambda x, w=w: w))))
          for t, w in ((np.float64, 64), (np.float32, 32))}
TRACED = _rows_of(traced_every_op)


def _inputs(dtype):
    rng = np.random.default_rng(5)
    xs = rng.normal(size=400) * 10.0 ** rng.integers(-3, 4, 400)
    xs[:8] = [0.0, -0.0, 1.0, np.nan, np.inf, -np.inf, 2.5, -2.5]
    vs = rng.normal(size=(400, 3))
    vs[:8] = [[0.0, 1.0, 0.0], [1.0, 1.0, 1.0], [1.0, np.nan, 0.0], [0.0, 0.0, np.nan], [np.inf, 1.0, 1.0],
              [2.0, -1.0, 0.0], [2.5, 1.0, -1.0], [-2.5, 2.0, 1.0]]
    return xs.astype(dtype), vs.astype(dtype)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_the_same_bits_as_numba_compiling_the_function(dtype):
    xs, vs = _inputs(dtype)
    with np.errstate(all="ignore"):
        got, want = TRACED(xs, vs), ORACLE[np.dtype(dtype)](xs, vs)
    assert got.dtype == dtype
    np.testing.assert_array_equal(got.view(np.uint8), want.view(np.uint8))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_in_plain_python_it_runs_as_written(dtype):
    xs, vs = _inputs(dtype)
    with np.errstate(all="ignore"):
        for x, v in zip(xs[:50], vs[:50], strict=True):
            got = traced_every_op(x, tuple(v))
            want = _every_op_with(lambda c, a, b: a if c else b, float_bits)(x, tuple(v))
            np.testing.assert_array_equal(np.array(got[0] + got[1:], dtype), np.array(want[0] + want[1:], dtype))


@traced
def _mixed(a, b, i):
    return a * b, a * like(a, 0.1), a + i, b * 2.0


@numba.njit
def _types_of(a, b, i):
    return _mixed(a, b, i)


@pytest.mark.skipif(not JIT, reason="numba's typing")
def test_types_follow_numbas_rules():
    # float32 with float32 stays float32, also with a Python constant (it takes the
    # symbol's type, as like() would); with float64 or an integer it gives float64
    _types_of(np.float32(1.5), np.float64(2.0), 3)
    (sig,) = _types_of.nopython_signatures
    assert [str(t) for t in sig.return_type] == ["float64", "float32", "float64", "float64"]
    _types_of(np.float32(1.5), np.float32(2.0), np.int32(3))
    ret = [str(t) for t in _types_of.nopython_signatures[1].return_type]
    assert ret == ["float32", "float32", "float64", "float32"]


@traced
def _branches(x):
    if x > like(x, 0.0):
        return x
    return -x


@traced
def _returns_a_python_number(x):
    return 1.0


@pytest.mark.skipif(not JIT, reason="numba's typing")
@pytest.mark.parametrize(("fn", "message"), [(_branches, "use select"), (_returns_a_python_number, "use like")])
def test_what_cannot_be_traced_is_a_clear_typing_error(fn, message):
    kernel = numba.njit(lambda x: fn(x))
    with pytest.raises(TypingError, match=message):
        kernel(1.0)


@traced
def _rot(q, v):
    """A nested traced call: the vector part of q ⊗ (0, v)."""
    w, x, y, z = q
    return _cross((x, y, z), v)[0] + w * v[0], _cross((x, y, z), v)[1] + w * v[1], _cross((x, y, z), v)[2] + w * v[2]


@traced
def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@numba.njit
def _rot_rows(q, v, out):
    for i in range(q.shape[0]):
        r = _rot((q[i, 0], q[i, 1], q[i, 2], q[i, 3]), (v[i, 0], v[i, 1], v[i, 2]))
        out[i, 0], out[i, 1], out[i, 2] = r


@pytest.mark.skipif(not JIT, reason="counts numba compiles")
def test_a_kernel_calling_traced_functions_compiles_nothing_else():
    q = np.random.default_rng(0).normal(size=(5, 4))
    v = np.random.default_rng(1).normal(size=(5, 3))
    out = np.empty((5, 3))
    with compiles() as names:
        _rot_rows(q, v, out)
    assert names == ["_rot_rows"]
    u = q[:, 1:]
    np.testing.assert_allclose(out, np.cross(u, v) + q[:, :1] * v, rtol=1e-15)


@traced
def _pick_by_number(c, a, b):
    return select(c, a, b)


@numba.njit
def _picks(cs, a, b):
    return [_pick_by_number(c, a, b) for c in cs]


@pytest.mark.parametrize("cs", [[0, 1, -3], [0.0, np.nan, -0.0, 2.5], [np.int32(0), np.int32(7)]])
def test_select_on_a_number_takes_its_truth(cs):
    assert _picks(np.array(cs), 1.0, 2.0) == [1.0 if c else 2.0 for c in cs]


def test_select_picks_component_by_component():
    assert select(True, (1.0, 2.0), (3.0, 4.0)) == (1.0, 2.0)
    assert select(False, (1.0, (2.0, 5.0)), (3.0, (4.0, 6.0))) == (3.0, (4.0, 6.0))
    assert select(np.bool_(False), 1.0, 2.0) == 2.0
    assert float_bits(np.float32(1.0)) == 32
    assert float_bits(1.0) == float_bits(np.float64(1.0)) == 64
    assert math.isnan(select(True, math.nan, 0.0))


def test_select_in_compiled_code_equals_traced_and_python():
    import numba

    @numba.njit(cache=False)
    def pick(c, a, b, x):
        for _ in range(1):  # a loop: numba compiles this, select included
            r = select(c, a, b)
        return r, select(x, 1.0, 2.0), select(x < 0.0, (1.0, 2.0), (3.0, 4.0))

    for c, x in ((True, 0.0), (False, np.nan), (True, -1.0)):
        assert pick(c, 1.5, 2.5, x) == (select(c, 1.5, 2.5), 2.0 if x == 0 else 1.0, select(x < 0.0, (1.0, 2.0), (3.0, 4.0)))
    f32 = pick(True, np.float32(1.5), np.float32(2.5), 0.0)[0]
    assert f32 == np.float32(1.5)
