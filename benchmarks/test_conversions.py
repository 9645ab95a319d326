"""Conversions: quatarray against scipy, numpy-quaternion and quaternionic.

Same arrays, same run; N = 1 (per-call overhead), 10³, 10⁶, 2·10⁶ (the size
of the performance targets) and, with ``QUATARRAY_BENCH_LARGE=1``, 10⁷;
float64 for every library and float32 for quatarray. Every entry returns a
new array (no ``out=``), as the other libraries do. For scipy, the
``Rotation`` object of an ``as_*`` call is built outside the timing (only the
conversion is timed); a ``from_*`` call times the construction only, not a
further ``as_quat``. Both choices favour scipy.

Run: ``pytest benchmarks/test_conversions.py --benchmark-only`` (add
``-k 2000000`` for the target size only). The targets (issue 2), float64 at
N = 2·10⁶, versus scipy: as_matrix ≥ 3×, from_matrix ≥ 5× (and with
``assume_valid=True`` ≥ 3× scipy's ``assume_valid=True``), as_rotvec ≥ 5×,
from_rotvec ≥ 2×; as_mrp ≥ 3× and from_mrp ≥ 10× (at N = 2·10⁶ only).

numpy-quaternion's and quaternionic's ``from_rotation_matrix`` with their
default ``nonorthogonal=True`` run a Python loop of eigen-decompositions
(about 50 µs a matrix), so they are measured up to N = 10³ only; their
``nonorthogonal=False`` variant appears in the ``assume_valid`` group.
"""

import numpy as np
import pytest
from conftest import LIBS, SIZES, arrays, need, npq, qn, run

import quatarray as qa

Rotation = pytest.importorskip("scipy.spatial.transform").Rotation

SLOW_LOOP_MAX = 1_000  # largest N for the competitors' Python-loop paths

_DERIVED = {}


def _derived(n, dtype):
    """q and, from it, matrices, noisy matrices and rotation vectors (same for every library)."""
    key = (n, np.dtype(dtype).str)
    if key not in _DERIVED:
        q = arrays(n, np.float64)["q"]
        rng = np.random.default_rng(777)
        m = qa.as_matrix(q)
        d = dict(
            q=q,
            m=m,
            noisy=m + 1e-4 * rng.standard_normal(m.shape),  # not orthogonal: projected
            r=qa.as_rotvec(q),
            axis=qa.as_axis_angle(q)[0],
            angle=qa.as_axis_angle(q)[1],
            xyzw=qa.as_xyzw(q),
        )
        d["su2"] = qa.as_su2(q)
        _DERIVED[key] = {k: a.astype(dtype) if a.dtype.kind == "f" else a for k, a in d.items()}
        if np.dtype(dtype) == np.float32:
            _DERIVED[key]["su2"] = d["su2"].astype(np.complex64)
    return _DERIVED[key]


def _data(lib, n):
    return _derived(n, np.float32 if lib.endswith("f32") else np.float64)


def _rot(q):
    return Rotation.from_quat(q, scalar_first=True)


def _unsupported(lib):
    pytest.skip(f"{lib} has no equivalent")


# --------------------------------------------------------------------------
# rotation matrices


@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
@pytest.mark.parametrize("lib", LIBS)
def test_as_matrix(benchmark, lib, n):
    need(lib)
    q = _data(lib, n)["q"]
    benchmark.group = f"as_matrix N={n}"
    if lib.startswith("quatarray"):
        fn = lambda: qa.as_matrix(q)  # noqa: E731
    elif lib == "scipy":
        r = _rot(q)
        fn = r.as_matrix
    elif lib == "numpy-quaternion":
        Q = npq.as_quat_array(q)
        fn = lambda: npq.as_rotation_matrix(Q)  # noqa: E731
    else:
        Q = qn.array(q)
        fn = lambda: Q.to_rotation_matrix  # noqa: E731  (a property)
    run(benchmark, fn, n)


@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
@pytest.mark.parametrize("lib", LIBS)
def test_from_matrix(benchmark, lib, n):
    """Default path: checks and the nearest rotation of non-orthogonal input (here all orthogonal)."""
    need(lib)
    m = _data(lib, n)["m"]
    benchmark.group = f"from_matrix N={n}"
    if lib.startswith("quatarray"):
        fn = lambda: qa.from_matrix(m)  # noqa: E731
    elif lib == "scipy":
        fn = lambda: Rotation.from_matrix(m)  # noqa: E731
    else:
        if n > SLOW_LOOP_MAX:
            pytest.skip(f"{lib}'s nonorthogonal=True loops in Python (~50 µs a matrix)")
        if lib == "numpy-quaternion":
            fn = lambda: npq.from_rotation_matrix(m)  # noqa: E731
        else:
            fn = lambda: qn.array.from_rotation_matrix(m)  # noqa: E731
    run(benchmark, fn, n)


@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
@pytest.mark.parametrize("lib", LIBS)
def test_from_matrix_assume_valid(benchmark, lib, n):
    need(lib)
    m = _data(lib, n)["m"]
    benchmark.group = f"from_matrix assume_valid N={n}"
    if lib.startswith("quatarray"):
        fn = lambda: qa.from_matrix(m, assume_valid=True)  # noqa: E731
    elif lib == "scipy":
        fn = lambda: Rotation.from_matrix(m, assume_valid=True)  # noqa: E731
    elif lib == "numpy-quaternion":
        fn = lambda: npq.from_rotation_matrix(m, nonorthogonal=False)  # noqa: E731
    else:
        fn = lambda: qn.array.from_rotation_matrix(m, nonorthogonal=False)  # noqa: E731
    run(benchmark, fn, n)


@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
@pytest.mark.parametrize("lib", ["quatarray", "quatarray-f32", "scipy"])
def test_from_matrix_non_orthogonal(benchmark, lib, n):
    """Every matrix off by ~1e-4: projected to the nearest rotation (scipy: an SVD each)."""
    m = _data(lib, n)["noisy"]
    benchmark.group = f"from_matrix non-orthogonal N={n}"
    if lib.startswith("quatarray"):
        run(benchmark, lambda: qa.from_matrix(m), n)
    else:
        run(benchmark, lambda: Rotation.from_matrix(m), n, slow=True)


# --------------------------------------------------------------------------
# rotation vectors and axis-angle


@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
@pytest.mark.parametrize("lib", LIBS)
def test_as_rotvec(benchmark, lib, n):
    need(lib)
    q = _data(lib, n)["q"]
    benchmark.group = f"as_rotvec N={n}"
    if lib.startswith("quatarray"):
        fn = lambda: qa.as_rotvec(q)  # noqa: E731
    elif lib == "scipy":
        r = _rot(q)
        fn = r.as_rotvec
    elif lib == "numpy-quaternion":
        Q = npq.as_quat_array(q)
        fn = lambda: npq.as_rotation_vector(Q)  # noqa: E731
    else:
        Q = qn.array(q)
        fn = lambda: Q.to_axis_angle  # noqa: E731  (its rotation vector, a property)
    run(benchmark, fn, n)


@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
@pytest.mark.parametrize("lib", LIBS)
def test_from_rotvec(benchmark, lib, n):
    need(lib)
    r = _data(lib, n)["r"]
    benchmark.group = f"from_rotvec N={n}"
    if lib.startswith("quatarray"):
        fn = lambda: qa.from_rotvec(r)  # noqa: E731
    elif lib == "scipy":
        fn = lambda: Rotation.from_rotvec(r)  # noqa: E731
    elif lib == "numpy-quaternion":
        fn = lambda: npq.from_rotation_vector(r)  # noqa: E731
    else:
        fn = lambda: qn.array.from_axis_angle(r)  # noqa: E731  (takes a rotation vector)
    run(benchmark, fn, n)


@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
@pytest.mark.parametrize("lib", ["quatarray", "quatarray-f32", "scipy"])
def test_as_axis_angle(benchmark, lib, n):
    q = _data(lib, n)["q"]
    benchmark.group = f"as_axis_angle N={n}"
    if lib.startswith("quatarray"):
        fn = lambda: qa.as_axis_angle(q)  # noqa: E731
    else:
        r = _rot(q)
        fn = lambda: (r.as_rotvec(), r.magnitude())  # noqa: E731  (closest scipy has)
    run(benchmark, fn, n)


@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
@pytest.mark.parametrize("lib", ["quatarray", "quatarray-f32", "scipy"])
def test_from_axis_angle(benchmark, lib, n):
    d = _data(lib, n)
    axis, angle = d["axis"], d["angle"]
    benchmark.group = f"from_axis_angle N={n}"
    if lib.startswith("quatarray"):
        fn = lambda: qa.from_axis_angle(axis, angle)  # noqa: E731
    else:
        fn = lambda: Rotation.from_rotvec(axis * angle[:, None])  # noqa: E731  (closest scipy has)
    run(benchmark, fn, n)


# --------------------------------------------------------------------------
# modified Rodrigues parameters


@pytest.mark.benchmark(group="as_mrp N=2000000")
@pytest.mark.parametrize("lib", ["quatarray", "quatarray-f32", "scipy"])
def test_as_mrp(benchmark, lib):
    q = arrays(2_000_000, np.float32 if lib.endswith("f32") else np.float64)["q"]
    if lib.startswith("quatarray"):
        fn = lambda: qa.as_mrp(q)  # noqa: E731
    else:
        fn = Rotation.from_quat(q, scalar_first=True).as_mrp
    run(benchmark, fn, len(q))


@pytest.mark.benchmark(group="from_mrp N=2000000")
@pytest.mark.parametrize("lib", ["quatarray", "quatarray-f32", "scipy"])
def test_from_mrp(benchmark, lib):
    p = qa.as_mrp(arrays(2_000_000)["q"]).astype(np.float32 if lib.endswith("f32") else np.float64)
    if lib.startswith("quatarray"):
        fn = lambda: qa.from_mrp(p)  # noqa: E731
    else:
        fn = lambda: Rotation.from_mrp(p)  # noqa: E731
    run(benchmark, fn, len(p))


# --------------------------------------------------------------------------
# layouts (quatarray.layouts): xyzw, scipy objects, the 4×4 and SU(2) matrices


@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
@pytest.mark.parametrize("lib", ["quatarray", "quatarray-f32", "scipy", "numpy"])
def test_as_xyzw(benchmark, lib, n):
    q = _data(lib, n)["q"]
    benchmark.group = f"as_xyzw N={n}"
    if lib.startswith("quatarray"):
        fn = lambda: qa.as_xyzw(q)  # noqa: E731
    elif lib == "scipy":
        r = _rot(q)
        fn = r.as_quat
    else:
        fn = lambda: np.roll(q, -1, axis=-1)  # noqa: E731
    run(benchmark, fn, n)


@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
@pytest.mark.parametrize("lib", ["quatarray", "quatarray-f32", "numpy"])
def test_from_xyzw(benchmark, lib, n):
    a = _data(lib, n)["xyzw"]
    benchmark.group = f"from_xyzw N={n}"
    if lib.startswith("quatarray"):
        fn = lambda: qa.from_xyzw(a)  # noqa: E731
    else:
        fn = lambda: np.roll(a, 1, axis=-1)  # noqa: E731
    run(benchmark, fn, n)


@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
@pytest.mark.parametrize("lib", ["quatarray", "scipy-from_quat"])
def test_to_scipy(benchmark, lib, n):
    q = _data(lib, n)["q"]
    benchmark.group = f"to_scipy N={n}"
    if lib == "quatarray":
        fn = lambda: qa.to_scipy(q)  # noqa: E731
    else:
        fn = lambda: Rotation.from_quat(q, scalar_first=True)  # noqa: E731
    run(benchmark, fn, n)


@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
def test_from_scipy(benchmark, n):
    r = _rot(_data("quatarray", n)["q"])
    benchmark.group = f"from_scipy N={n}"
    run(benchmark, lambda: qa.from_scipy(r), n)


@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
@pytest.mark.parametrize("lib", ["quatarray", "quatarray-f32", "quatarray-right"])
def test_as_left_right_matrix(benchmark, lib, n):
    q = _data(lib, n)["q"]
    benchmark.group = f"as_left_matrix N={n}"
    fn = (lambda: qa.as_right_matrix(q)) if lib.endswith("right") else (lambda: qa.as_left_matrix(q))
    run(benchmark, fn, n)


@pytest.mark.parametrize("n", SIZES, ids=lambda n: f"N={n}")
@pytest.mark.parametrize("lib", ["quatarray", "quatarray-f32", "quatarray-from_su2", "numpy"])
def test_su2(benchmark, lib, n):
    d = _data(lib, n)
    q, u = d["q"], d["su2"]
    benchmark.group = f"as_su2 N={n}"
    if lib == "quatarray-from_su2":
        fn = lambda: qa.from_su2(u)  # noqa: E731
    elif lib.startswith("quatarray"):
        fn = lambda: qa.as_su2(q)  # noqa: E731
    else:
        # the same matrices from numpy expressions
        def fn():
            w, x, y, z = q.T
            a, b = w + 1j * x, y + 1j * z
            return np.stack([np.stack([a, b], -1), np.stack([-b.conj(), a.conj()], -1)], -2)

    run(benchmark, fn, n)
