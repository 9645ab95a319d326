"""quatarray.Rotation against scipy's Rotation, side by side in one process.

Run: ``python benchmarks/rotation_vs_scipy.py [--n 1000000] [--rounds 5]``.
Prints, per method, the best-of-rounds time of each (interleaved rounds) and
the ratio scipy / quatarray (above 1: quatarray is faster), at N = n and at
N = 1 (a single rotation, per call), and at N = 1 the bare functional call
that the method wraps.
"""

import argparse
import timeit
import warnings

import numpy as np
from scipy.spatial.transform import Rotation as S

import quatarray as qa
from quatarray import Rotation as Q


def cases_big(n, rng):
    quat = rng.standard_normal((n, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    v = rng.standard_normal((n, 3))
    ang = rng.uniform(-3, 3, (n, 3))
    rv = rng.uniform(-2, 2, (n, 3))
    a = rng.standard_normal((n, 3))
    s1, s2, q1, q2 = S.from_quat(quat), S.from_quat(quat[::-1].copy()), Q.from_quat(quat), Q.from_quat(quat[::-1].copy())
    return {
        "from_quat + as_matrix": (lambda: S.from_quat(quat).as_matrix(), lambda: Q.from_quat(quat).as_matrix()),
        "from_quat": (lambda: S.from_quat(quat), lambda: Q.from_quat(quat)),
        "as_quat": (lambda: s1.as_quat(), lambda: q1.as_quat()),
        "as_matrix": (lambda: s1.as_matrix(), lambda: q1.as_matrix()),
        "apply": (lambda: s1.apply(v), lambda: q1.apply(v)),
        "apply inverse": (lambda: s1.apply(v, inverse=True), lambda: q1.apply(v, inverse=True)),
        "r1 * r2": (lambda: s1 * s2, lambda: q1 * q2),
        "inv": (lambda: s1.inv(), lambda: q1.inv()),
        "magnitude": (lambda: s1.magnitude(), lambda: q1.magnitude()),
        "as_euler": (lambda: s1.as_euler("xyz"), lambda: q1.as_euler("xyz")),
        "from_euler": (lambda: S.from_euler("xyz", ang), lambda: Q.from_euler("xyz", ang)),
        "as_rotvec": (lambda: s1.as_rotvec(), lambda: q1.as_rotvec()),
        "from_rotvec": (lambda: S.from_rotvec(rv), lambda: Q.from_rotvec(rv)),
        "as_mrp": (lambda: s1.as_mrp(), lambda: q1.as_mrp()),
        "from_matrix": (lambda: S.from_matrix(m), lambda: Q.from_matrix(m)) if (m := s1.as_matrix()) is not None else None,
        "mean": (lambda: s1.mean(), lambda: q1.mean()),
        "align_vectors": (lambda: S.align_vectors(a, v), lambda: Q.align_vectors(a, v)),
        "approx_equal": (lambda: s1.approx_equal(s2), lambda: q1.approx_equal(q2)),
        "r ** 0.5": (lambda: s1 ** 0.5, lambda: q1 ** 0.5),
    }


def cases_one(rng):
    quat = rng.standard_normal(4)
    quat /= np.linalg.norm(quat)
    v = rng.standard_normal(3)
    s1, s2 = S.from_quat(quat), S.from_quat(quat[::-1].copy())
    q1, q2 = Q.from_quat(quat), Q.from_quat(quat[::-1].copy())
    w1, w2 = q1.wxyz, q2.wxyz
    return {
        "from_quat(q).apply(v)": (lambda: S.from_quat(quat).apply(v), lambda: Q.from_quat(quat).apply(v),
                                  lambda: qa.rotate(qa.normalize(qa.from_xyzw(quat)), v)),
        "from_quat(q)": (lambda: S.from_quat(quat), lambda: Q.from_quat(quat), lambda: qa.normalize(qa.from_xyzw(quat))),
        "r.apply(v)": (lambda: s1.apply(v), lambda: q1.apply(v), lambda: qa.rotate(w1, v)),
        "r1 * r2": (lambda: s1 * s2, lambda: q1 * q2, lambda: qa.multiply(w1, w2)),
        "r.as_euler('xyz')": (lambda: s1.as_euler("xyz"), lambda: q1.as_euler("xyz"), lambda: qa.as_euler(w1, "xyz")),
        "r.inv()": (lambda: s1.inv(), lambda: q1.inv(), lambda: qa.conjugate(w1)),
        "r.as_quat()": (lambda: s1.as_quat(), lambda: q1.as_quat(), lambda: qa.as_xyzw(w1)),
        "r.as_matrix()": (lambda: s1.as_matrix(), lambda: q1.as_matrix(), lambda: qa.as_matrix(w1)),
        "r.magnitude()": (lambda: s1.magnitude(), lambda: q1.magnitude(), lambda: qa.angle(w1)),
        "r.as_rotvec()": (lambda: s1.as_rotvec(), lambda: q1.as_rotvec(), lambda: qa.as_rotvec(w1)),
        "from_euler('xyz', a)": (lambda: S.from_euler("xyz", v), lambda: Q.from_euler("xyz", v), lambda: qa.from_euler("xyz", v)),
        "from_rotvec(v)": (lambda: S.from_rotvec(v), lambda: Q.from_rotvec(v), lambda: qa.from_rotvec(v)),
    }


def best(f, number, rounds):
    return min(timeit.repeat(f, number=number, repeat=rounds)) / number


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=1_000_000)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--only", default="")
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    warnings.simplefilter("ignore")
    if args.only != "one":
        print(f"N = {args.n}: best of {args.rounds} interleaved rounds (ms), ratio scipy/quatarray")
        for name, pair in cases_big(args.n, rng).items():
            for f in pair:
                f()  # warm: compile, page in
            ts, tq = [], []
            for _ in range(args.rounds):
                ts.append(best(pair[0], 1, 1))
                tq.append(best(pair[1], 1, 1))
            print(f"  {name:24s} scipy {min(ts) * 1e3:9.2f}  quatarray {min(tq) * 1e3:9.2f}  ratio {min(ts) / min(tq):6.2f}")
    if args.only != "big":
        print("N = 1 (per call, µs): scipy, quatarray.Rotation, bare functional call; ratio scipy/Rotation, Rotation - functional")
        for name, (fs, fq, ff) in cases_one(rng).items():
            for f in (fs, fq, ff):
                f()
            t = [[], [], []]
            for _ in range(args.rounds):
                for k, f in enumerate((fs, fq, ff)):
                    t[k].append(best(f, 20000, 1))
            s, q, fn = (min(x) * 1e6 for x in t)
            print(f"  {name:24s} scipy {s:6.2f}  Rotation {q:6.2f}  functional {fn:6.2f}  ratio {s / q:5.2f}  overhead {q - fn:+5.2f}")


if __name__ == "__main__":
    main()
