"""Trajectory evaluation: compare an estimated pose stream with a reference, as evo does.

A pose stream is a :class:`Poses`: times (or ``None`` for streams without
times, such as KITTI's), positions ``(N, 3)`` and rotations ``(N, 4)`` as
(w, x, y, z) quaternions (active: the rotation takes body coordinates to
world coordinates, as a pose matrix ``[R | p]`` does).

The steps follow the evo tool (``evo_ape``, ``evo_rpe``) and give the same
numbers (within 1e-9 relative) on the same inputs:

1. :func:`associate` pairs the poses by time (evo's
   ``associate_trajectories``: nearest within ``t_max_diff`` after
   ``t_offset``), or resamples one stream at the other's times:
   ``interpolate=True`` (``"evo"``) is evo's ``--sync_method interpolation``
   (the denser stream by slerp at the sparser one's matched times),
   ``interpolate="spline"`` the estimate at the reference times by
   :func:`quatarray.spline`. Streams without times are paired pose by pose.
2. :func:`umeyama` / :func:`align` fit Umeyama's least-squares similarity
   (``"sim3"``), rigid motion (``"se3"``), scale only (``"scale"``, evo's
   ``correct_scale`` alone) or nothing (``"none"``). The fit needs only the
   means and a 3×3 covariance (:class:`Moments`), so long streams can be
   fitted chunk by chunk.
3. :func:`ape` and :func:`rpe` give per-pose errors for a pose relation:
   ``"trans"`` (metres), ``"rot"`` (rotation angle in degrees) or ``"full"``
   (‖E − I‖_F of the SE(3) error matrix E); :func:`statistics` gives rmse,
   mean, median, std, min, max and sse.

:func:`evaluate` runs the three steps. The pose algebra runs in quatarray's
batched kernels: no Python loop over poses. The SE(3) error matrix is never
formed: with E = (R, t), ‖E − I‖_F² = ‖R − I‖_F² + ‖t‖² = 8 sin²(θ/2) + ‖t‖²,
θ the rotation angle of R.
"""

from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from . import _elements as E
from ._jit import element, prange, rowloop
from .algebra import normalize

RELATIONS = ("trans", "rot", "full")
ALIGNMENTS = ("none", "se3", "sim3", "scale")
METRICS = ("ape", "rpe")
DELTA_UNITS = ("frames", "m", "s")
STATISTICS = ("rmse", "mean", "median", "std", "min", "max", "sse")
UNITS = {"trans": "m", "rot": "deg", "full": "1"}


@dataclass(frozen=True)
class Poses:
    """A pose stream: times (or None), positions (N, 3), quaternions (N, 4) as (w, x, y, z)."""

    t: np.ndarray
    pos: np.ndarray
    q: np.ndarray

    def __len__(self):
        return self.pos.shape[0]

    def replace(self, **kw):
        """A copy with some fields replaced."""
        return replace(self, **kw)

    def take(self, idx):
        """The poses at `idx` (an index array or slice)."""
        return Poses(None if self.t is None else self.t[idx], self.pos[idx], self.q[idx])


def poses(t, pos, q):
    """A :class:`Poses` from array-likes, checked and as float64 (quaternions normalised).

    Examples
    --------
    >>> from quatarray.trajectory import poses
    >>> p = poses([0.0, 0.1], [[0, 0, 0], [1, 0, 0]], [[2.0, 0, 0, 0], [1, 0, 0, 0]])
    >>> len(p), p.q[0]
    (2, array([1., 0., 0., 0.]))
    """
    pos = np.ascontiguousarray(pos, dtype=np.float64)
    q = np.ascontiguousarray(q, dtype=np.float64)
    if pos.ndim != 2 or pos.shape[1] != 3:
        raise ValueError(f"positions must have shape (N, 3), got {pos.shape}")
    if q.shape != (pos.shape[0], 4):
        raise ValueError(f"quaternions must have shape ({pos.shape[0]}, 4), got {q.shape}")
    if t is not None:
        t = np.ascontiguousarray(t, dtype=np.float64)
        if t.shape != (pos.shape[0],):
            raise ValueError(f"times must have shape ({pos.shape[0]},), got {t.shape}")
    return Poses(t, pos, normalize(q))


# --------------------------------------------------------------------------
# 1. association


def match_times(stamps_1, stamps_2, max_diff=0.01, offset_2=0.0):
    """Indices of the best matching times, exactly as evo's ``matching_time_indices``.

    For each time of `stamps_1` (in order) the nearest time of
    ``stamps_2 + offset_2`` within `max_diff`; unmatched times are skipped and
    a time of `stamps_2` may be matched more than once. When `stamps_2` is
    non-decreasing (repeated times allowed), ties go as in evo's binary search
    (the later of two equally near times below, the last of repeated times);
    otherwise as its linear search (the first index of the smallest difference).

    Returns
    -------
    i1, i2 : ndarray of int
        Matched indices into `stamps_1` and `stamps_2`.

    Examples
    --------
    >>> from quatarray.trajectory import match_times
    >>> match_times([0.0, 1.0, 2.0, 3.0], [0.004, 2.0, 2.0, 2.5], max_diff=0.01)
    (array([0, 2]), array([0, 2]))
    """
    s1 = _c64(stamps_1).reshape(-1)
    s2 = _c64(stamps_2).reshape(-1)
    if s2.size == 0 or s1.size == 0:
        return np.zeros(0, np.intp), np.zeros(0, np.intp)
    i1, i2 = np.empty(s1.size, np.intp), np.empty(s1.size, np.intp)
    m = _match_sorted(s1, s2, float(offset_2), float(max_diff), i1, i2)
    if m >= 0:
        return i1[:m], i2[:m]
    s2 = s2 + offset_2
    # Unsorted: the first index (in file order) of the smallest |s2 - s1|. In a
    # stable sort the first of equal times is that index; compare both neighbours.
    order = np.argsort(s2, kind="stable")
    s = s2[order]
    k = np.searchsorted(s, s1, side="left")  # first sorted time >= s1
    hi = np.minimum(k, s.size - 1)
    lo_val = s[np.maximum(k - 1, 0)]
    lo = np.searchsorted(s, lo_val, side="left")  # first of the times equal to the one below
    d_hi = np.abs(s[hi] - s1)
    d_lo = np.where(k > 0, np.abs(lo_val - s1), np.inf)
    o_hi, o_lo = order[hi], order[lo]
    take_lo = (d_lo < d_hi) | ((d_lo == d_hi) & (o_lo < o_hi))
    best = np.where(take_lo, o_lo, o_hi)
    d = np.where(take_lo, d_lo, d_hi)
    keep = d <= max_diff
    return np.flatnonzero(keep), best[keep]


@rowloop(parallel=False)
def _match_sorted(s1, s2, off, max_diff, i1, i2):
    # match_times for non-decreasing s2 (times s2 + off): per time of s1 the upper and lower
    # neighbours of a right bisection, found by galloping on from the previous one while s1
    # increases. Returns the number of matches, or -1 when s2 is not sorted (nothing written).
    n = s2.shape[0]
    for k in range(1, n):
        if s2[k] + off < s2[k - 1] + off:
            return -1
    first, last = s2[0] + off, s2[n - 1] + off
    m = 0
    lo = 0  # every s2[< lo] + off <= x
    for k in range(s1.shape[0]):
        x = s1[k]
        if k == 0 or x < s1[k - 1]:
            lo = 0
        step = 1
        while lo + step <= n and s2[lo + step - 1] + off <= x:
            lo += step
            step *= 2
        hi = min(lo + step, n)  # s2[hi - 1] + off > x, or hi == n
        while lo < hi:
            mid = (lo + hi) // 2
            if s2[mid] + off <= x:
                lo = mid + 1
            else:
                hi = mid
        idx = min(lo, n - 1)
        if not (x >= first - max_diff and x <= last + max_diff):
            continue
        diff_ub = (s2[idx] + off) - x
        diff_lb = x - (s2[idx - 1] + off) if idx > 0 else np.inf
        if diff_ub <= max_diff and diff_ub < diff_lb:
            i1[m], i2[m] = k, idx
            m += 1
        elif diff_lb <= max_diff and diff_lb <= diff_ub:
            i1[m], i2[m] = k, idx - 1
            m += 1
    return m


INTERPOLATIONS = ("evo", "spline")


class TimeOrderError(ValueError):
    """Times that decrease where interpolation needs them in order: `stream` (``"reference"`` or
    ``"estimate"``) and `row` (the index of the first pose whose time is before its predecessor's)
    say where, for a message that names the file's line."""

    def __init__(self, message, stream, row):
        super().__init__(message)
        self.stream, self.row = stream, row


def _rule(interpolate):
    """The interpolation rule `interpolate` names: None (nearest pairs), "evo" or "spline"."""
    if interpolate is None or interpolate is False:
        return None
    if interpolate is True:
        return "evo"
    if interpolate not in INTERPOLATIONS:
        raise ValueError(f"unknown interpolation {interpolate!r}; expected one of {INTERPOLATIONS}")
    return interpolate


def _check_order(t, stream, strict=False):
    d = np.diff(t)
    bad = d <= 0 if strict else d < 0
    if bad.any():
        i = int(np.argmax(bad)) + 1
        raise TimeOrderError(
            f"interpolation needs the {stream}'s times in order: row {i} (time {float(t[i])!r}) is before "
            f"row {i - 1} (time {float(t[i - 1])!r})", stream, i)


def associate(ref, est, t_max_diff=0.01, t_offset=0.0, interpolate=False):
    """Pair the poses of two streams by time.

    Parameters
    ----------
    ref, est : Poses
        Without times (either one), the streams are paired pose by pose and
        must have the same length.
    t_max_diff : float
        Largest time difference of a pair (seconds), as evo's ``t_max_diff``.
    t_offset : float
        Added to the estimate's times before matching (evo's ``t_offset``).
    interpolate : {False, True, "evo", "spline"}
        False: nearest pairs (evo's ``--sync_method nearest_time``).
        True or ``"evo"``: evo's ``--sync_method interpolation``: the poses of
        the shorter stream (the estimate when the lengths are equal) that have
        a nearest pair as above, with the other stream resampled at their
        times (positions linearly, rotations by slerp between its two poses
        around each time; times outside its span take its first or last pose).
        ``"spline"``: the reference poses whose times lie inside the
        estimate's (offset) time span, with the estimate resampled at those
        times (:func:`quatarray.spline` on rotations, linear on positions; of
        repeated estimate times the first is kept). The resampled stream's
        times must not decrease.

    Returns
    -------
    ref, est : Poses
        Equal lengths; each keeps its own times (a resampled stream: the
        times it was resampled at, in its own time frame). Pairs are in the
        order of the shorter stream (of the estimate when the lengths are
        equal), as evo's ``associate_trajectories``.

    Raises
    ------
    ValueError
        No pair found; lengths that differ for streams without times;
        interpolation of streams without times; times that decrease in the
        stream resampled (:class:`TimeOrderError`, naming the row).

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray.trajectory import poses, associate
    >>> q = np.tile([1.0, 0, 0, 0], (4, 1))
    >>> ref = poses([0.0, 1.0, 2.0, 3.0], np.c_[np.arange(4.0), np.zeros((4, 2))], q)
    >>> est = poses([1.004, 2.05, 2.999], np.zeros((3, 3)), q[:3])
    >>> r, e = associate(ref, est)
    >>> r.t, e.t
    (array([1., 3.]), array([1.004, 2.999]))
    >>> r, e = associate(ref, est, interpolate=True)  # evo's: the reference at the estimate's times
    >>> r.t, r.pos[:, 0]
    (array([1.004, 2.999]), array([1.004, 2.999]))
    """
    rule = _rule(interpolate)
    if ref.t is None or est.t is None:
        if rule is not None:
            which = "the reference and the estimate have" if ref.t is None and est.t is None else \
                f"the {'reference' if ref.t is None else 'estimate'} has"
            raise ValueError(f"interpolation needs times; {which} none (streams without times are compared "
                             f"pose by pose: leave interpolation out)")
        if len(ref) != len(est):
            raise ValueError(f"streams without times are compared pose by pose: the reference has "
                             f"{len(ref)} poses, the estimate {len(est)}")
        return ref, est
    if rule == "spline":
        return _resample(ref, est, t_offset)
    second_longer = len(est) > len(ref)
    if rule == "evo":  # the stream resampled must be in order (evo's would give wrong poses)
        long, name = (est, "estimate") if second_longer else (ref, "reference")
        _check_order(long.t, name)
        if len(long) < 2:
            raise ValueError(f"interpolation needs at least 2 poses of the {name}, got {len(long)}")
    if second_longer:
        i_ref, i_est = match_times(ref.t, est.t, t_max_diff, t_offset)
    else:
        i_est, i_ref = match_times(est.t, ref.t, t_max_diff, -t_offset)
    if i_ref.size == 0:
        raise ValueError(f"no matching times between the reference and the estimate with "
                         f"t_max_diff {t_max_diff} s and t_offset {t_offset} s")
    if rule == "evo":
        if second_longer:
            ref = ref.take(_as_slice(i_ref))
            return ref, _interpolated(est, ref.t - t_offset)
        est = est.take(_as_slice(i_est))
        return _interpolated(ref, est.t + t_offset), est
    return ref.take(_as_slice(i_ref)), est.take(_as_slice(i_est))


_EVO_EPS = 4.0 * np.finfo(np.float64).eps  # evo's quaternion_slerp: keys nearer than this give the first


def _interpolated(p, times):
    """The poses of `p` (times in order) at `times`, as evo's ``PoseTrajectory3D.interpolate``:
    positions by lerp, rotations by slerp between the poses either side (of repeated times the
    first), times outside the span clamped to the first or last pose."""
    from .interpolation import slerp  # the engine only where a stream is interpolated (CLI start-up)

    n = len(p)
    idx = np.clip(np.searchsorted(p.t, times, side="left"), 1, n - 1)
    t_prev, t_next = p.t[idx - 1], p.t[idx]
    dt = t_next - t_prev
    frac = np.clip(np.where(dt > 0.0, (times - t_prev) / np.where(dt > 0.0, dt, 1.0), 0.0), 0.0, 1.0)
    pos = p.pos[idx - 1] + frac[:, None] * (p.pos[idx] - p.pos[idx - 1])
    q0, q1 = normalize(p.q[idx - 1]), normalize(p.q[idx])
    d = _rowdot(q0, q1)  # the dot product as evo's numpy.dot, rounded the same way
    q = slerp(q0, np.where((d < 0.0)[:, None], -q1, q1), frac, shortest=False)  # evo's flip: d < 0 only
    first = (frac == 0.0) | (np.abs(np.abs(d) - 1.0) < _EVO_EPS)
    q = np.where(first[:, None], q0, np.where((frac == 1.0)[:, None], q1, q))
    return Poses(np.array(times, dtype=np.float64), pos, q)


def _resample(ref, est, t_offset):
    from .splines import spline  # the engine only where an estimate is interpolated (CLI start-up)

    te = est.t + t_offset
    keep = np.concatenate([[True], np.diff(te) > 0])
    if not keep.all():
        _check_order(te, "estimate")
        te, est = te[keep], est.take(np.flatnonzero(keep))
    inside = np.flatnonzero((ref.t >= te[0]) & (ref.t <= te[-1]))
    if te.size < 2 or inside.size == 0:
        raise ValueError("no reference time inside the estimate's time span")
    ref = ref.take(inside)
    pos = np.column_stack([np.interp(ref.t, te, est.pos[:, k]) for k in range(3)])
    q = spline(te, est.q, ref.t)
    return ref, Poses(ref.t - t_offset, pos, normalize(q))


# --------------------------------------------------------------------------
# 2. alignment


@dataclass
class Moments:
    """Sums Umeyama's fit needs, mergeable chunk by chunk (Chan's pairwise update).

    For points x (estimate) and y (reference): the count, both means,
    ``sxx = Σ |x − x̄|²`` and ``cyx = Σ (y − ȳ)(x − x̄)ᵀ``. Each chunk's sums are
    taken about its own means and merged exactly, so the result does not
    suffer from cancellation when the positions are far from the origin.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray.trajectory import Moments
    >>> x = np.random.default_rng(0).normal(size=(100, 3))
    >>> whole = Moments.of(x, 2 * x)
    >>> parts = Moments.of(x[:30], 2 * x[:30]).merge(Moments.of(x[30:], 2 * x[30:]))
    >>> np.allclose(whole.cyx, parts.cyx), np.allclose(whole.mean_x, parts.mean_x)
    (True, True)
    """

    n: int = 0
    mean_x: np.ndarray = field(default_factory=lambda: np.zeros(3))
    mean_y: np.ndarray = field(default_factory=lambda: np.zeros(3))
    sxx: float = 0.0
    cyx: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))

    @classmethod
    def of(cls, x, y, origin=None):
        """The moments of a batch of point pairs, shapes (n, 3) (with `origin`, a pair of points
        (ox, oy): of the pairs ``x − ox``, ``y − oy``, subtracted in the kernel).

        Taken over blocks of :data:`MOMENT_BLOCK` pairs, merged in order (more accurate than one
        sum, and what :class:`MomentsFeed` gives bit for bit, fed in pieces of any size).
        """
        x, y = _c64(x), _c64(y)
        ox, oy = _origin(origin)
        m = cls()
        for a in range(0, x.shape[0], MOMENT_BLOCK):
            m = m.merge(cls._block(x[a:a + MOMENT_BLOCK], y[a:a + MOMENT_BLOCK], ox, oy))
        return m

    @classmethod
    def _block(cls, x, y, ox, oy):
        mx, my, cyx = np.empty(3), np.empty(3), np.empty(9)
        sxx = _moments_kernel(x, y, ox, oy, mx, my, cyx)
        return cls(x.shape[0], mx, my, sxx, cyx.reshape(3, 3))

    def merge(self, other):
        """The moments of both batches together."""
        if other.n == 0:
            return self
        if self.n == 0:
            return other
        n = self.n + other.n
        f = self.n * other.n / n
        dx, dy = other.mean_x - self.mean_x, other.mean_y - self.mean_y
        return Moments(
            n, self.mean_x + dx * (other.n / n), self.mean_y + dy * (other.n / n),
            self.sxx + other.sxx + f * float(dx @ dx), self.cyx + other.cyx + f * np.outer(dy, dx),
        )


@rowloop(parallel=False)
def _moments_kernel(x, y, ox, oy, mx, my, cyx):
    # two passes: the means, then the sums about them (writes mx, my, cyx (flat, 9); returns sxx),
    # of the points x - ox, y - oy
    n = x.shape[0]
    sx0 = sx1 = sx2 = sy0 = sy1 = sy2 = 0.0
    for i in range(n):
        sx0 += x[i, 0] - ox[0]
        sx1 += x[i, 1] - ox[1]
        sx2 += x[i, 2] - ox[2]
        sy0 += y[i, 0] - oy[0]
        sy1 += y[i, 1] - oy[1]
        sy2 += y[i, 2] - oy[2]
    mx0, mx1, mx2, my0, my1, my2 = sx0 / n, sx1 / n, sx2 / n, sy0 / n, sy1 / n, sy2 / n
    sxx = c00 = c01 = c02 = c10 = c11 = c12 = c20 = c21 = c22 = 0.0
    for i in range(n):
        a0, a1, a2 = (x[i, 0] - ox[0]) - mx0, (x[i, 1] - ox[1]) - mx1, (x[i, 2] - ox[2]) - mx2
        b0, b1, b2 = (y[i, 0] - oy[0]) - my0, (y[i, 1] - oy[1]) - my1, (y[i, 2] - oy[2]) - my2
        sxx += a0 * a0 + a1 * a1 + a2 * a2
        c00 += b0 * a0
        c01 += b0 * a1
        c02 += b0 * a2
        c10 += b1 * a0
        c11 += b1 * a1
        c12 += b1 * a2
        c20 += b2 * a0
        c21 += b2 * a1
        c22 += b2 * a2
    mx[0], mx[1], mx[2], my[0], my[1], my[2] = mx0, mx1, mx2, my0, my1, my2
    cyx[0], cyx[1], cyx[2], cyx[3], cyx[4] = c00, c01, c02, c10, c11
    cyx[5], cyx[6], cyx[7], cyx[8] = c12, c20, c21, c22
    return sxx


MOMENT_BLOCK = 1 << 16
_ZERO3 = np.zeros(3)


def _origin(origin):
    """(ox, oy) as float64 3-vectors (zeros for None: x − 0 is x, bit for bit)."""
    if origin is None:
        return _ZERO3, _ZERO3
    return tuple(np.ascontiguousarray(o, np.float64).reshape(3) for o in origin)


class MomentsFeed:
    """:meth:`Moments.of` of point pairs that come in pieces of any size (a stream read in chunks):
    the same numbers, bit for bit, as on all the pairs at once.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray.trajectory import Moments, MomentsFeed
    >>> x = np.random.default_rng(0).normal(size=(1000, 3))
    >>> feed = MomentsFeed()
    >>> for a in range(0, 1000, 300):
    ...     feed.add(x[a:a + 300], 2 * x[a:a + 300])
    >>> bool(np.all(feed.moments().cyx == Moments.of(x, 2 * x).cyx))
    True
    """

    def __init__(self, origin=None):
        self._done = Moments()
        self._origin = origin
        self._o = _origin(origin)
        self._x, self._y = np.empty((0, 3)), np.empty((0, 3))

    def add(self, x, y):
        """Feed the next pairs, shapes (n, 3)."""
        x, y = np.concatenate([self._x, x]), np.concatenate([self._y, y])
        full = x.shape[0] - x.shape[0] % MOMENT_BLOCK
        for a in range(0, full, MOMENT_BLOCK):
            self._done = self._done.merge(Moments._block(x[a:a + MOMENT_BLOCK], y[a:a + MOMENT_BLOCK], *self._o))
        self._x, self._y = x[full:], y[full:]

    def moments(self):
        """The moments of all the pairs fed."""
        return self._done.merge(Moments.of(self._x, self._y, self._origin))


class Alignment(NamedTuple):
    """A similarity y = s R x + t: rotation as matrix and quaternion, translation, scale.

    A fitted alignment also keeps the points it was fitted about, `origin_x` (an estimate
    position) and `origin_y` (a reference position), and the translation between them,
    `t_local`: y = origin_y + (s R (x − origin_x) + t_local). Far from the origin (UTM
    coordinates, 10⁷ m) s R x + t loses the digits the errors are made of; :meth:`frame`
    gives both streams about those points, where the errors are computed exactly.
    """

    r: np.ndarray
    q: np.ndarray
    t: np.ndarray
    s: float
    origin_x: np.ndarray = None
    origin_y: np.ndarray = None
    t_local: np.ndarray = None

    def apply(self, p):
        """The poses `p` moved by this transform (positions s R x + t, rotations R ∘ q)."""
        moved = self.local(p)
        return moved if self.origin_y is None else moved.replace(pos=moved.pos + self.origin_y)

    def local(self, est):
        """`est` moved by this transform less `origin_y`: ``s R (est.pos − origin_x) + t_local``
        (:meth:`apply` when the alignment has no origins), without the rounding of positions
        far from the origin."""
        if self is IDENTITY:
            return est
        pos, q = _c64(est.pos), _c64(est.q)
        out_pos, out_q = np.empty_like(pos), np.empty_like(q)
        t = self.t if self.t_local is None else self.t_local
        o = _ZERO3 if self.origin_x is None else self.origin_x
        _apply_kernel(np.asarray(self.q, np.float64), float(self.s), np.asarray(t, np.float64), o,
                      pos, q, out_pos, out_q)
        return Poses(est.t, out_pos, out_q)

    def frame(self, ref, est):
        """`ref` and `est` moved by this transform, both less `origin_y` (a translation, which no
        error depends on; as given when the alignment has no origins): ``ref.pos − origin_y`` and
        :meth:`local`. :func:`ape` and :func:`rpe` of them are exact far from the origin."""
        if self.origin_y is None:
            return ref, self.local(est)
        return ref.replace(pos=_c64(ref.pos) - self.origin_y), self.local(est)


def _c64(a):
    """`a` as a C-contiguous float64 array (a copy only when it is not one): the kernels
    below are compiled for that layout alone."""
    return np.ascontiguousarray(a, dtype=np.float64)


@rowloop(rows=3)
def _apply_kernel(aq, s, t, o, pos, q, out_pos, out_q):
    # s R (x - o) + t (R from its quaternion once, as qa.rotate does for one rotation) and aq ∘ q
    a = (aq[0], aq[1], aq[2], aq[3])
    m = E.qmatrix(a)
    for i in prange(pos.shape[0]):
        x, y, z = pos[i, 0] - o[0], pos[i, 1] - o[1], pos[i, 2] - o[2]
        out_pos[i, 0] = (m[0] * x + m[1] * y + m[2] * z) * s + t[0]
        out_pos[i, 1] = (m[3] * x + m[4] * y + m[5] * z) * s + t[1]
        out_pos[i, 2] = (m[6] * x + m[7] * y + m[8] * z) * s + t[2]
        E.store4(out_q, i, E.qmul(a, E.load4(q, i)))


IDENTITY = Alignment(np.eye(3), np.array([1.0, 0, 0, 0]), np.zeros(3), 1.0)


def umeyama(x, y=None, with_scale=True, origin=None):
    """Umeyama's least-squares similarity taking points `x` onto points `y`.

    Minimises Σ |y_i − (s R x_i + t)|² (with s = 1 unless `with_scale`), as
    evo's ``umeyama_alignment`` (which takes the points as columns).

    Parameters
    ----------
    x, y : array_like, shape (n, 3), or a :class:`Moments` as `x` (then no `y`)
    with_scale : bool
    origin : (array_like, array_like), optional
        A point of each set the fit is made about (see :class:`Alignment`): the
        moments are taken of ``x − origin[0]`` and ``y − origin[1]`` (given `x`
        and `y`: default the first pair; given :class:`Moments`: they are the
        moments of points so shifted).

    Returns
    -------
    Alignment

    Raises
    ------
    ValueError
        Fewer than 3 points; all points of either set equal; points on a line
        (the rotation about that line is not determined): the second singular
        value of their covariance at most :data:`LINE_TOLERANCE` times the first,
        a test that does not depend on the units.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> from quatarray.trajectory import umeyama
    >>> x = np.random.default_rng(1).normal(size=(10, 3))
    >>> q = qa.from_rotvec([0.1, 0.2, 0.3])
    >>> y = 2.0 * qa.rotate(np.tile(q, (10, 1)), x) + [1, 2, 3]
    >>> a = umeyama(x, y)
    >>> round(a.s, 12), np.allclose(a.t, [1, 2, 3]), np.allclose(a.r, qa.as_matrix(q))
    (2.0, True, True)
    """
    from .conversions import from_matrix  # only once an alignment is found (CLI start-up)

    if isinstance(x, Moments):
        m = x
    else:
        x, y = _c64(x), _c64(y)
        if origin is None and x.shape[0]:
            origin = (x[0].copy(), y[0].copy())  # the first pair: x - origin is exact near it
        m = Moments.of(x, y, origin)
    if m.n < 3:
        raise ValueError(f"alignment needs at least 3 poses, got {m.n}")
    if m.sxx == 0.0:
        raise ValueError("alignment is not possible: all positions are equal in the estimate")
    if not np.any(m.cyx):
        raise ValueError("alignment is not possible: all positions are equal in the reference "
                         "(or do not vary with the estimate's at all)")
    u, d, vt = np.linalg.svd(m.cyx / m.n)
    # relative: the fit does not depend on the units, so neither does the test (a motion of
    # 1e-8 units is no less determined than one of 1e8)
    if not d[1] > LINE_TOLERANCE * d[0]:
        raise ValueError(
            f"alignment is not possible: the positions lie on a line (the covariance's second singular "
            f"value is {d[1] / d[0]:.3g} of its first, at most {LINE_TOLERANCE:g}), so the rotation "
            f"about that line is not determined")
    sign = np.ones(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0.0:
        sign[2] = -1.0
    r = (u * sign) @ vt
    s = float(d @ sign) / (m.sxx / m.n) if with_scale else 1.0
    t = m.mean_y - s * (r @ m.mean_x)
    if origin is None:
        return Alignment(r, from_matrix(r), t, s)
    ox, oy = (np.asarray(o, np.float64).reshape(3).copy() for o in origin)
    return Alignment(r, from_matrix(r), (oy - s * (r @ ox)) + t, s, ox, oy, t)


LINE_TOLERANCE = 1e-12  # umeyama: positions on a line when σ₂ ≤ this × σ₁ of their covariance


def fit(ref, est, method="sim3", n_to_align=None):
    """The alignment of `est` onto `ref` (paired poses) for `method`, on the first `n_to_align` poses.

    ``"scale"`` keeps only the scale of the similarity fit (evo's
    ``correct_scale`` without ``align``); ``"none"`` is the identity.
    """
    if method not in ALIGNMENTS:
        raise ValueError(f"unknown alignment {method!r}; expected one of {ALIGNMENTS}")
    if method == "none":
        return IDENTITY
    k = slice(None) if n_to_align is None else slice(0, int(n_to_align))
    x, y = _c64(est.pos[k]), _c64(ref.pos[k])
    origin = None if method == "scale" or x.shape[0] == 0 else (x[0].copy(), y[0].copy())
    return fit_moments(Moments.of(x, y, origin), method, origin)


def fit_moments(moments, method="sim3", origin=None):
    """:func:`fit` from the :class:`Moments` of the (estimate, reference) positions, e.g. merged
    chunk by chunk; with `origin` (an estimate and a reference position), the moments of the
    positions less those (see :func:`umeyama`)."""
    if method not in ALIGNMENTS:
        raise ValueError(f"unknown alignment {method!r}; expected one of {ALIGNMENTS}")
    if method == "none":
        return IDENTITY
    if method == "scale":  # evo's correct_scale: s x, about the origin of the coordinates
        if origin is not None:
            raise ValueError("a scale correction is fitted about the origin of the coordinates (no origin)")
        return Alignment(IDENTITY.r, IDENTITY.q, IDENTITY.t, umeyama(moments).s)
    return umeyama(moments, with_scale=method != "se3", origin=origin)


def align(ref, est, method="sim3", n_to_align=None):
    """`est` aligned onto `ref` (paired poses) and the :class:`Alignment` used.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> from quatarray.trajectory import poses, align
    >>> rng = np.random.default_rng(2)
    >>> ref = poses(None, rng.normal(size=(20, 3)), qa.random(20, rng=rng))
    >>> est = poses(None, 0.5 * ref.pos - 1.0, ref.q)
    >>> moved, a = align(ref, est, "sim3")
    >>> round(a.s, 12), np.allclose(moved.pos, ref.pos)
    (2.0, True)
    """
    a = fit(ref, est, method, n_to_align)
    return a.apply(est), a


# --------------------------------------------------------------------------
# 3. metrics


def _relation(relation):
    if relation not in RELATIONS:
        raise ValueError(f"unknown pose relation {relation!r}; expected one of {RELATIONS}")


_CODES = {r: k for k, r in enumerate(RELATIONS)}


@element
def _error(code, dx, dy, dz, qa_, qb):
    """The error of the SE(3) error E between rotations qa_, qb (E's rotation angle is their
    distance, as qa.distance) and the translation difference (dx, dy, dz) (‖t_E‖ is its norm),
    for relation `code` (the index of the relation in RELATIONS)."""
    d2 = dx * dx + dy * dy + dz * dz
    if code == 0:
        return np.sqrt(d2)
    theta = 2.0 * E.half_angle(E.qmul(E.qconj(E.qscaled(qa_)[0]), E.qscaled(qb)[0]))
    if code == 1:
        return theta * (180.0 / np.pi)  # np.rad2deg
    half = np.sin(0.5 * theta)
    return np.sqrt(8.0 * half * half + d2)


@rowloop(rows=1)
def _ape_kernel(code, ref_pos, o, ref_q, est_pos, est_q, out):
    # the reference positions less o (the estimate's are given about o: Alignment.local)
    for i in prange(out.shape[0]):
        e = E.load3(est_pos, i)
        out[i] = _error(code, e[0] - (ref_pos[i, 0] - o[0]), e[1] - (ref_pos[i, 1] - o[1]),
                        e[2] - (ref_pos[i, 2] - o[2]), E.load4(est_q, i), E.load4(ref_q, i))


@element
def _relative(pos, q, i, j):
    # p_i⁻¹ p_j: rotation q_i* q_j, translation R_i^T (x_j − x_i)
    qi = E.qconj(E.load4(q, i))
    xi, xj = E.load3(pos, i), E.load3(pos, j)
    return E.qmul(qi, E.load4(q, j)), E.qrotate(qi, (xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]))


@rowloop(rows=1)
def _rpe_kernel(code, i, j, ref_pos, ref_q, est_pos, est_q, out):
    for k in prange(out.shape[0]):
        q_ref, t_ref = _relative(ref_pos, ref_q, i[k], j[k])
        q_est, t_est = _relative(est_pos, est_q, i[k], j[k])
        out[k] = _error(code, t_est[0] - t_ref[0], t_est[1] - t_ref[1], t_est[2] - t_ref[2], q_ref, q_est)


def ape(ref, est, relation="trans", origin=None):
    """Absolute pose error of paired (aligned) poses, one value per pose.

    E = est⁻¹ ref, as evo's ``APE``: ``"trans"`` ‖p_est − p_ref‖ (metres),
    ``"rot"`` the rotation angle of E (degrees), ``"full"`` ‖E − I‖_F.
    With `origin` (a point), the estimate's positions are given less it
    (:meth:`Alignment.local`, `origin` its ``origin_y``): ‖p_est − (p_ref − origin)‖.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> from quatarray.trajectory import poses, ape
    >>> ref = poses(None, [[0, 0, 0], [1, 0, 0]], qa.identity(2))
    >>> est = poses(None, [[0, 0, 0], [1, 3, 4]], qa.from_rotvec([[0, 0, 0], [0, 0, np.pi / 2]]))
    >>> ape(ref, est, "trans"), ape(ref, est, "rot")
    (array([0., 5.]), array([ 0., 90.]))
    """
    _relation(relation)
    out = np.empty(len(est))
    o = _ZERO3 if origin is None else np.ascontiguousarray(origin, np.float64).reshape(3)
    _ape_kernel(_CODES[relation], _c64(ref.pos), o, _c64(ref.q), _c64(est.pos), _c64(est.q), out)
    return out


@rowloop(parallel=False)
def _consecutive_by_distance(steps, delta):
    # evo's filter_pairs_by_path (consecutive): restart the running sum at each kept pose
    n = steps.shape[0] + 1
    ids = np.empty(n, np.int64)
    ids[0] = 0
    k, run = 1, 0.0
    for i in range(1, n):
        run += steps[i - 1]
        if run >= delta:
            ids[k] = i
            k += 1
            run = 0.0
    return ids[:k]


@rowloop(parallel=False)
def _all_pairs_by_distance(dist, delta, tol):
    # evo's filter_pairs_by_path (all pairs): for each i the j > i whose
    # dist[j] - dist[i] is nearest delta (the first on ties), kept within tol.
    # dist is non-decreasing, so |dist[j] - dist[i] - delta| is unimodal in j.
    n = dist.shape[0]
    out_i = np.empty(max(n - 1, 0), np.int64)
    out_j = np.empty(max(n - 1, 0), np.int64)
    m = 0
    for i in range(n - 1):
        lo, hi = i + 1, n  # first j in (i, n) with dist[j] - dist[i] >= delta, else n
        while lo < hi:
            mid = (lo + hi) // 2
            if dist[mid] - dist[i] >= delta:
                hi = mid
            else:
                lo = mid + 1
        best = -1
        err = np.inf
        if lo > i + 1:  # the plateau below: its first index
            v = dist[lo - 1]
            a, b = i + 1, lo - 1
            while a < b:
                mid = (a + b) // 2
                if dist[mid] >= v:
                    b = mid
                else:
                    a = mid + 1
            best = a
            err = abs(dist[a] - dist[i] - delta)
        if lo < n:
            e = abs(dist[lo] - dist[i] - delta)
            if e < err:
                best, err = lo, e
        if err <= tol:
            out_i[m] = i
            out_j[m] = best
            m += 1
    return out_i[:m], out_j[:m]


def _step_lengths(pos, all_pairs):
    """The lengths of the steps between consecutive positions, rounded as evo rounds them
    (so that a running length that lands exactly on delta picks the pairs evo picks): its
    consecutive pairs take ``np.linalg.norm`` of each step (a dot product, as numpy's
    ``vecdot``), its all-pairs distances ``np.linalg.norm(..., axis=1)`` (a sum of squares)."""
    pos = _c64(pos)
    if all_pairs:
        return np.linalg.norm(pos[:-1] - pos[1:], axis=1)
    step = pos[1:] - pos[:-1]
    return np.sqrt(_rowdot(step, step))


def _rowdot(a, b):
    """The dot product of each row pair, rounded as ``np.dot`` of two vectors rounds it (its
    inner loop, BLAS's ``ddot`` where numpy has it), which evo calls one row at a time."""
    if hasattr(np, "vecdot"):  # numpy >= 2
        return np.vecdot(a, b)
    return (a[:, None, :] @ b[:, :, None])[:, 0, 0]  # pragma: no cover - numpy 1.26


def pairs(est, delta=1, delta_unit="frames", all_pairs=False, rel_delta_tol=0.1):
    """Index pairs (i, j) for the relative pose error, as evo's ``id_pairs_from_delta``.

    Parameters
    ----------
    est : Poses
        The poses the pairs are chosen on (evo chooses on the aligned estimate).
    delta : int or float
        In frames, metres travelled (``"m"``) or seconds (``"s"``).
    delta_unit : {"frames", "m", "s"}
        Seconds work as metres do, with the time elapsed in place of the path
        length (evo has no time unit here).
    all_pairs : bool
        Every i with its j (evo's ``all_pairs``); default consecutive pairs
        (each j is the next pair's i).
    rel_delta_tol : float
        With `all_pairs` in metres or seconds: a pair is kept when its
        distance is within ``delta * rel_delta_tol`` of `delta`.

    Returns
    -------
    i, j : ndarray of int

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> from quatarray.trajectory import poses, pairs
    >>> p = poses(np.arange(5.0), np.c_[np.arange(5.0), np.zeros((5, 2))], qa.identity(5))
    >>> pairs(p, 2)
    (array([0, 2]), array([2, 4]))
    >>> pairs(p, 3, "m", all_pairs=True)
    (array([0, 1]), array([3, 4]))
    """
    n = len(est)
    if delta_unit not in DELTA_UNITS:
        raise ValueError(f"unknown delta unit {delta_unit!r}; expected one of {DELTA_UNITS}")
    if not delta > 0:
        raise ValueError(f"delta must be positive, got {delta}")
    if delta_unit == "frames":
        if int(delta) != delta:
            raise ValueError(f"delta in frames must be a whole number, got {delta}")
        d = int(delta)
        if all_pairs:
            i = np.arange(max(n - d, 0))
            j = i + d
        else:
            ids = np.arange(0, n, d)
            i, j = ids[:-1], ids[1:]
    else:
        if delta_unit == "m":
            steps = _step_lengths(est.pos, all_pairs)
        else:
            if est.t is None:
                raise ValueError("a delta in seconds needs times")
            steps = np.diff(est.t)
            if np.any(steps < 0):
                raise ValueError("a delta in seconds needs non-decreasing times")
        delta = float(delta)
        if all_pairs:
            dist = np.concatenate([[0.0], np.cumsum(steps)]) if delta_unit == "m" else est.t - est.t[0]
            i, j = _all_pairs_by_distance(dist, delta, delta * rel_delta_tol)
        else:
            ids = _consecutive_by_distance(np.ascontiguousarray(steps), delta)
            i, j = ids[:-1], ids[1:]
    if i.size == 0:
        raise ValueError(f"delta = {delta} ({delta_unit}) gives no pair among {n} poses; try a smaller delta")
    return i, j


def rpe(ref, est, relation="trans", delta=1, delta_unit="frames", all_pairs=False, rel_delta_tol=0.1):
    """Relative pose error of paired (aligned) poses over the pairs of :func:`pairs`.

    E = (Q_i⁻¹ Q_j)⁻¹ (P_i⁻¹ P_j) for reference poses Q and estimated poses P,
    as evo's ``RPE``; relations as :func:`ape`.

    Returns
    -------
    errors : ndarray, shape (m,)
    i, j : ndarray of int, shape (m,)
        The pairs.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> from quatarray.trajectory import poses, rpe
    >>> ref = poses(None, [[0, 0, 0], [1, 0, 0], [2, 0, 0]], qa.identity(3))
    >>> est = poses(None, [[0, 0, 0], [1, 0, 0], [2, 1, 0]], qa.identity(3))
    >>> rpe(ref, est)[0]
    array([0., 1.])
    """
    _relation(relation)
    i, j = pairs(est, delta, delta_unit, all_pairs, rel_delta_tol)
    return rpe_of_pairs(ref, est, i, j, relation), i, j


def rpe_of_pairs(ref, est, i, j, relation="trans"):
    """The relative pose errors (see :func:`rpe`) of the given index pairs (i, j)."""
    _relation(relation)
    out = np.empty(np.size(i))
    _rpe_kernel(_CODES[relation], np.ascontiguousarray(i, np.int64), np.ascontiguousarray(j, np.int64),
                _c64(ref.pos), _c64(ref.q), _c64(est.pos), _c64(est.q), out)
    return out


def _as_slice(idx):
    """`idx` as a slice when it is an arithmetic progression, else itself."""
    if idx.size > 1:
        step = int(idx[1] - idx[0])
        if step > 0 and np.all(np.diff(idx) == step):
            return slice(int(idx[0]), int(idx[-1]) + 1, step)
    return idx


def statistics(errors, overwrite_input=False):
    """evo's statistics of per-pose errors: rmse, mean, median, std, min, max, sse.

    No temporary as large as `errors` is made (std is merged over blocks, Chan's update), except
    the median's copy, which `overwrite_input` saves (`errors` is then reordered).

    Examples
    --------
    >>> from quatarray.trajectory import statistics
    >>> s = statistics([3.0, 4.0])
    >>> s["rmse"] ** 2, s["mean"], s["sse"], s["std"]
    (12.5, 3.5, 25.0, 0.5)
    """
    e = np.asarray(errors, dtype=np.float64)
    if e.size == 0:
        raise ValueError("no errors to summarise")
    n = e.size
    sse = float(np.dot(e, e))
    mean = float(np.mean(e))
    count, mu, m2 = 0, 0.0, 0.0  # std: blocks' (count, mean, Σ(x − mean)²) merged
    for a in range(0, n, MOMENT_BLOCK):
        b = e[a:a + MOMENT_BLOCK]
        mb = float(np.mean(b))
        d = b - mb
        k = count + b.size
        m2 += float(np.dot(d, d)) + (mb - mu) ** 2 * count * b.size / k
        mu += (mb - mu) * b.size / k
        count = k
    out = {"rmse": float(np.sqrt(sse / n)), "mean": mean, "median": 0.0, "std": float(np.sqrt(m2 / n)),
           "min": float(np.min(e)), "max": float(np.max(e)), "sse": sse}
    out["median"] = float(np.median(e, overwrite_input=overwrite_input))
    return out


@dataclass
class Result:
    """What :func:`evaluate` found.

    Attributes
    ----------
    stats : dict
        :func:`statistics` of `errors`.
    errors : ndarray
        Per-pose (APE) or per-pair (RPE) errors.
    t : ndarray or None
        Reference time of each error (RPE: of the pair's second pose).
    index : ndarray
        Index of each error's pose in the associated streams (RPE: the second of the pair).
    i0 : ndarray or None
        RPE: index of the pair's first pose.
    ref, est : Poses
        The associated reference and the aligned estimate.
    alignment : Alignment
    metric, relation, unit : str
    """

    stats: dict
    errors: np.ndarray
    t: np.ndarray
    index: np.ndarray
    i0: np.ndarray
    ref: Poses
    est: Poses
    alignment: Alignment
    metric: str
    relation: str
    unit: str


def evaluate(ref, est, metric="ape", align="none", relation="trans", delta=1, delta_unit="frames",
             all_pairs=False, n_to_align=None, t_max_diff=0.01, t_offset=0.0, interpolate=False):
    """Associate, align and measure, as ``evo_ape`` / ``evo_rpe`` do.

    Parameters
    ----------
    ref, est : Poses
    metric : {"ape", "rpe"}
    align : {"none", "se3", "sim3", "scale"}
        evo's ``--align`` (se3), ``--align --correct_scale`` (sim3) and
        ``--correct_scale`` alone (scale).
    relation : {"trans", "rot", "full"}
        evo's ``trans_part``, ``angle_deg`` and ``full``.
    delta, delta_unit, all_pairs
        RPE pairs, see :func:`pairs`.
    n_to_align : int, optional
        Fit the alignment on the first n associated poses only.
    t_max_diff, t_offset, interpolate
        Association, see :func:`associate` (`interpolate`: False, True or
        ``"evo"``, ``"spline"``).

    Returns
    -------
    Result

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> from quatarray.trajectory import poses, evaluate
    >>> rng = np.random.default_rng(3)
    >>> t = np.arange(50) * 0.1
    >>> ref = poses(t, np.cumsum(rng.normal(size=(50, 3)), axis=0), qa.random(50, rng=rng))
    >>> est = poses(t + 0.002, 3.0 * ref.pos, ref.q)
    >>> r = evaluate(ref, est, "ape", align="sim3")
    >>> round(r.alignment.s, 12), r.stats["max"] < 1e-12
    (0.333333333333, True)
    """
    if metric not in METRICS:
        raise ValueError(f"unknown metric {metric!r}; expected one of {METRICS}")
    _relation(relation)
    ref, est = associate(ref, est, t_max_diff, t_offset, interpolate)
    a = fit(ref, est, align, n_to_align)
    # the errors about the alignment's origins (exact far from the origin of the coordinates); RPE
    # compares each stream's own relative motions, so the reference needs no shift
    est_l = a.local(est)
    if metric == "ape":
        errors = ape(ref, est_l, relation, a.origin_y)
        index, i0 = np.arange(errors.size), None
    else:
        errors, i0, index = rpe(ref, est_l, relation, delta, delta_unit, all_pairs)
    est = est_l if a.origin_y is None else est_l.replace(pos=est_l.pos + a.origin_y)  # = a.apply(est)
    t = None if ref.t is None else ref.t[_as_slice(index)]  # APE, RPE in frames: a view
    return Result(statistics(errors), errors, t, index, i0, ref, est, a, metric, relation, UNITS[relation])
