"""Many streams on one time plan: the spline engine in lane layout.

:func:`resample_streams` samples J key streams that share their K key times (a
clip's joints) at the same new times with one segment search for all of them,
and the math of each sample runs as SIMD over the streams; each stream's result
equals :func:`quatarray.spline` on it alone, bit for bit. Used by
:meth:`quatarray.skeleton.Clip.resample`.
"""

import numpy as np

from . import _elements as E
from ._jit import element, like, prange, rowloop, specialise
from ._slerp import arc_slerp, bezier_seg, bisect4, controls4, double4, fixed_arc, nlerp4, slerp4, squad_inner4, unflip_sign
from .interpolation import tangent_scales
from .splines import BLOCK, TABLED, next_run, resample_unit, unit_keys

KIND = 1  # rebound in each method's copy of _lane_arcs and _lane_eval (see _LANE_SPLINE)

# ---- many streams on one time plan (lane layout)
#
# The keys of J streams at the same K times (a clip's joints) are held in lane
# layout: groups of LANES streams, each group a (K, 4, LANES) block of a flat
# array (element ((g K + n) 4 + c) LANES + l is component c of key n of stream
# g LANES + l; spare lanes hold the identity). Every loop over a group's lanes
# reads and writes contiguous memory at constant strides (which LLVM vectorises:
# a run-time stride made it give up), so one segment search serves all streams
# and the math of a sample runs as SIMD over the streams: _lane_spline finds each
# run of samples in one segment (next_run), copies the segment's keys of a lane
# group into a small table, finds its fixed arcs once (_lane_arcs) and evaluates
# the run's samples (_lane_eval), in kernels that touch only the small tables.
# Each lane computes exactly what spline computes for its stream alone (the
# same element functions on the same numbers): equal bit for bit.

LANES = 32  # streams per group: the constant stride of the lane loops (as TILE for the Bézier tiles)
G4 = 4 * LANES  # floats per key of a group


def lane_groups(j):
    """Lane groups for j streams."""
    return max(1, -(-j // LANES))


@element
def load_lane(a, b, l):
    """The quaternion of lane l at offset b (a key's start) of a lane-layout array."""
    return E.load1(a, b + l), E.load1(a, b + LANES + l), E.load1(a, b + 2 * LANES + l), E.load1(a, b + 3 * LANES + l)


@element
def store_lane(a, b, l, q):
    E.store1(a, b + l, q[0])
    E.store1(a, b + LANES + l, q[1])
    E.store1(a, b + 2 * LANES + l, q[2])
    E.store1(a, b + 3 * LANES + l, q[3])


@rowloop(parallel=False)
def _gather_unit(p, cols, out):
    """Lane layout `out` of the streams ``p[:, cols[s]]`` (p of shape (K, J, 4)), each
    normalised and unflipped along K as :func:`quatarray.spline` does (the
    ``_unit_unflip`` rule); spare lanes hold the identity."""
    nk = p.shape[0]
    ng = out.shape[0] // (nk * G4)
    zero = like(out, 0.0)
    one = like(out, 1.0)
    for g in range(ng):
        for k in range(nk):
            b = (g * nk + k) * G4
            for l in range(LANES):
                s = g * LANES + l
                if s < cols.shape[0]:
                    j = cols[s]
                    r = E.qnormalize((p[k, j, 0], p[k, j, 1], p[k, j, 2], p[k, j, 3]))
                    if k > 0 and unflip_sign(load_lane(out, b - G4, l), r) < zero:
                        r = E.qneg(r)
                else:
                    r = (one, zero, zero, zero)
                store_lane(out, b, l, r)


@element
def lane_neighbours(q, c, cp, cx, first, last, l):
    """(q_{n−1}, q_n, q_{n+1}) of lane l for the controls of key n, with the phantom end
    keys of ``_bezier_controls``: q_{−1} = double(q_1, q_0), q_K = double(q_{K−2}, q_{K−1})."""
    qn = load_lane(q, c, l)
    qp = load_lane(q, cp, l)
    qx = load_lane(q, cx, l)
    if first:
        qp = double4(qp, qn)
    if last:
        qx = double4(qx, qn)
    return qp, qn, qx


@rowloop(rows=0)
def _lane_bezier_controls(q, f_out, f_in, a, b):
    """:func:`quatarray.bezier_controls` of every lane (the ``_bezier_controls`` rule).

    A key whose tangent factors are both exactly 1 (evenly spaced times) skips the
    two scaling slerps of :func:`controls4`: a slerp at t = 1 returns its end
    exactly, so a_n = a₀ and b_n = double(a₀, q_n) bit for bit."""
    nk = f_out.shape[0]
    ng = q.shape[0] // (nk * G4)
    one = like(q, 1.0)
    third = one / like(q, 3.0)
    zero = like(q, 0.0)
    for i in prange(ng * nk):
        g = i // nk
        n = i - g * nk
        c = (g * nk + n) * G4
        first = n == 0
        last = n == nk - 1
        cp = c + G4 if first else c - G4  # key n − 1, or q_1 for the phantom q_{−1}
        cx = c - G4 if last else c + G4  # key n + 1, or q_{K−2} for the phantom q_K
        fo = f_out[n]
        fi = f_in[n]
        if fo == one and fi == one:
            for l in range(LANES):
                qp, qn, qx = lane_neighbours(q, c, cp, cx, first, last, l)
                a0 = slerp4(qn, bisect4(double4(qp, qn), qx), third, zero)
                store_lane(a, c, l, a0)
                store_lane(b, c, l, double4(a0, qn))
        else:
            for l in range(LANES):
                qp, qn, qx = lane_neighbours(q, c, cp, cx, first, last, l)
                r = controls4(qp, qn, qx, fo, fi)
                store_lane(a, c, l, r[0])
                store_lane(b, c, l, r[1])


@rowloop(rows=0)
def _lane_squad_controls(q, nk, s):
    """:func:`quatarray.interpolation.squad_controls` of every lane (`s` a copy of `q`)."""
    ng = q.shape[0] // (nk * G4)
    for i in prange(ng * (nk - 2)):
        g = i // (nk - 2)
        n = i - g * (nk - 2) + 1
        c = (g * nk + n) * G4
        for l in range(LANES):  # SIMD over lanes
            store_lane(s, c, l, squad_inner4(load_lane(q, c - G4, l), load_lane(q, c, l), load_lane(q, c + G4, l)))


@element
def put_lane_arc(arcs, c, l, p, q):
    """(θ, v) of the fixed arc p → q (as the table's ``put_arc``) at rows c … c + 4 of lane l."""
    th, v = fixed_arc(p, q)  # as splines.put_arc
    E.store1(arcs, c * LANES + l, th)
    E.store1(arcs, (c + 1) * LANES + l, v[0])
    E.store1(arcs, (c + 2) * LANES + l, v[1])
    E.store1(arcs, (c + 3) * LANES + l, v[2])
    E.store1(arcs, (c + 4) * LANES + l, v[3])


@element
def lane_arc(arcs, c, l):
    return (E.load1(arcs, c * LANES + l), E.load1(arcs, (c + 1) * LANES + l), E.load1(arcs, (c + 2) * LANES + l),
            E.load1(arcs, (c + 3) * LANES + l), E.load1(arcs, (c + 4) * LANES + l))


@element
def lane_keys(keys, l):
    """Lane l of a segment's small table: q_n, c_out[n], c_in[n+1], q_{n+1}."""
    return load_lane(keys, 0, l), load_lane(keys, G4, l), load_lane(keys, 2 * G4, l), load_lane(keys, 3 * G4, l)


def _lane_arcs(keys, count, arcs):
    """The fixed arcs of one segment for lanes 0 … count − 1: `keys` (16 LANES,) holds
    q_n, c_out[n], c_in[n+1], q_{n+1} of a group; `arcs` (15 LANES,) gets up to three (θ, v)."""
    for l in range(count):
        p, a, b, r = lane_keys(keys, l)
        if KIND == 1:
            put_lane_arc(arcs, 0, l, p, a)
            put_lane_arc(arcs, 5, l, a, b)
            put_lane_arc(arcs, 10, l, b, r)
        elif KIND == 2:
            put_lane_arc(arcs, 0, l, p, r)
            put_lane_arc(arcs, 5, l, a, b)
        elif KIND == 0:
            put_lane_arc(arcs, 0, l, p, r)


def _lane_eval(keys, arcs, t, count, res):
    """One sample at segment parameter t for lanes 0 … count − 1 (SIMD over lanes) into `res` (4 LANES,)."""
    for l in range(count):
        p, a, b, r = lane_keys(keys, l)
        if KIND == 1:
            v = bezier_seg(p, a, b, r, lane_arc(arcs, 0, l), lane_arc(arcs, 5, l), lane_arc(arcs, 10, l), t)
        elif KIND == 2:
            pq = arc_slerp(p, r, lane_arc(arcs, 0, l), t)
            ps = arc_slerp(a, b, lane_arc(arcs, 5, l), t)
            v = slerp4(pq, ps, like(t, 2.0) * t * (like(t, 1.0) - t), like(t, 0.0))
        elif KIND == 0:
            v = arc_slerp(p, r, lane_arc(arcs, 0, l), t)
        else:
            v = nlerp4(p, r, like(t, 1.0) - t, t)
        store_lane(res, 0, l, v)


LANE_ARCS = LANE_EVAL = None  # bound in each method's copy of _lane_spline


def _lane_spline(times, new_t, q, c_out, c_in, cols, nj, out):
    """Every stream of the lane-layout keys `q` (with controls `c_out`, `c_in`) at
    `new_t`: stream s into column ``cols[s]`` of `out`, flat (M·nj·4,) for (M, nj, 4).

    Blocks of ``BLOCK`` samples run in parallel; in each, for the run of samples
    in one segment (the engine's ``next_run``) and each lane group, the segment's
    keys are copied into a small table, its fixed arcs found once, and each sample
    evaluated for all lanes (SIMD over lanes, in kernels that touch only the small
    tables)."""
    nk = times.shape[0]
    ng = q.shape[0] // (nk * G4)
    ns = cols.shape[0]
    m = new_t.shape[0]
    x0 = like(q, 0.0)
    for blk in prange((m + BLOCK - 1) // BLOCK):
        j = blk * BLOCK
        hi = min(m, j + BLOCK)
        keys = np.empty(4 * G4, q.dtype)
        arcs = np.empty(15 * LANES, q.dtype)
        res = np.empty(G4, q.dtype)
        sg = 0
        while j < hi:
            sg, e = next_run(times, new_t, j, hi, sg)
            t0 = times[sg]
            h = times[sg + 1] - t0
            for g in range(ng):
                b0 = (g * nk + sg) * G4
                b1 = b0 + G4
                count = min(LANES, ns - g * LANES)
                vec = min(LANES, (count + 7) // 8 * 8)  # whole SIMD steps (spare lanes hold the identity)
                for c in range(G4):
                    keys[c] = q[b0 + c]
                    keys[G4 + c] = c_out[b0 + c]
                    keys[2 * G4 + c] = c_in[b1 + c]
                    keys[3 * G4 + c] = q[b1 + c]
                LANE_ARCS(keys, vec, arcs)
                for i in range(j, e):
                    LANE_EVAL(keys, arcs, like(x0, (new_t[i] - t0) / h), vec, res)
                    for l in range(count):
                        o = 4 * (i * nj + cols[g * LANES + l])
                        out[o] = res[l]
                        out[o + 1] = res[LANES + l]
                        out[o + 2] = res[2 * LANES + l]
                        out[o + 3] = res[3 * LANES + l]
            j = e


# multi-threaded by the size of `out` (4 per joint-sample): a sample costs one evaluation per stream
_LANE_SPLINE = {
    name: rowloop(rows=7)(specialise(_lane_spline, f"_{name}",
                                     LANE_ARCS=rowloop(specialise(_lane_arcs, f"_{name}", KIND=m.kind), parallel=False),
                                     LANE_EVAL=rowloop(specialise(_lane_eval, f"_{name}", KIND=m.kind), parallel=False)))
    for name, m in TABLED.items()
}


def resample_streams(t, nt, keys, cols, method, out):
    """Many streams on one time plan: ``resample_unit`` of each stream ``keys[:, cols[s]]``
    (raw keys (K, J, 4), normalised and unflipped here per stream), at times `t` and
    new times `nt` (1-D, any order) as :func:`plan_times` gives them, into
    ``out[:, cols]`` (C-contiguous (M, J', 4) of the keys' dtype): bit for bit what
    :func:`spline` gives each stream alone, in one pass (see the module docstring)."""
    nk = t.shape[0]
    cols = np.asarray(cols, np.int64)
    if method not in _LANE_SPLINE:  # cubic: one global system per stream
        return resample_each(t, nt, keys, cols, method, out)
    dt = out.dtype
    q = np.empty(lane_groups(len(cols)) * nk * G4, dt)
    _gather_unit(keys, cols, q)
    c_out = c_in = q
    if method == "bezier":
        f_out, f_in = tangent_scales(np.diff(t))
        c_out = np.empty_like(q)
        c_in = np.empty_like(q)
        _lane_bezier_controls(q, f_out.astype(dt), f_in.astype(dt), c_out, c_in)
    elif method == "squad":
        c_out = c_in = q.copy()
        if nk > 2:
            _lane_squad_controls(q, nk, c_out)
    if nt.shape[0]:
        _LANE_SPLINE[method](t, nt, q, c_out, c_in, cols, out.shape[1], out.reshape(-1))
    return out


def resample_each(t, nt, keys, cols, method, out):
    """What :func:`resample_streams` gives, stream by stream through the spline
    engine (:func:`quatarray.splines.resample_unit`): for the cubic spline, and
    for small clips, whose streams the engine's own kernels serve without
    compiling the lane kernels."""
    for j in cols:
        out[:, j] = resample_unit(t, nt, unit_keys([np.ascontiguousarray(keys[:, j])]), method)
    return out
