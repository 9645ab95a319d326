"""``Slerp``, ``RotationSpline`` (scipy 1.17's classes) and ``BezierSpline`` on quatarray's spline kernels.

:class:`Slerp` and :class:`RotationSpline` have scipy's public API and rules
(the checks, their exception types and messages, extrapolation refused by
``Slerp`` and done by ``RotationSpline``, scalar or 1-D times) and give
scipy's quaternions, signs included, within 1e-10. They evaluate with the
compiled loops of ``quatarray.spline(method="slerp")`` (on a segment table of
scipy's arcs, see :func:`_slerp_plan`) and ``quatarray.spline(method="cubic")``
(q_n ⊗ Exp(ρ(τ)), ρ a cubic in τ: scipy's own curve), and each construction
keeps what its calls reuse (the table; the coefficients and the keys).

:class:`BezierSpline` is quatarray's own: ``quatarray.spline`` with any of
its methods (Shoemake's Bézier spline by default) behind ``RotationSpline``'s
call interface, its controls and segment table built once.

The keys' step r_n = Log(q_n* ⊗ q_{n+1}) is scipy's: the relative rotation
made canonical (w > 0; a half turn, w = 0, takes the sign that makes its
first non-zero component of (x, y, z) positive), so that keys exactly half a
turn apart turn the way scipy turns (:func:`_scipy_signs`).
"""

import numpy as np

from .. import _cubic
from .. import splines as _sp
from .._jit import rowloop
from .._validate import as_float, as_times, check_core, key_times, spline_order
from .rotation import Rotation

_F64 = np.dtype(np.float64)


# ---- the keys


def _keys(rotations):
    """(house array (..., 4) as stored, single) of a quatarray or scipy ``Rotation``;
    ``TypeError`` for anything else (scipy's message)."""
    if isinstance(rotations, Rotation):
        return rotations.wxyz, rotations.single
    if _is_scipy_rotation(rotations):
        return np.asarray(rotations.as_quat(scalar_first=True)), rotations.single  # scipy's Rotation
    raise TypeError("`rotations` must be a `Rotation` instance.")


def _is_scipy_rotation(x):
    return type(x).__module__.startswith("scipy.spatial.transform") and type(x).__name__ == "Rotation"


def _unit64(q):
    """The keys (K, 4) as unit float64 quaternions (a new array)."""
    q = np.array(q, _F64)
    q /= np.sqrt(np.einsum("ij,ij->i", q, q))[:, None]
    return q


def _scipy_signs(q):
    """σ (K − 1,) = ±1 of the unit float64 keys q (K, 4): σ_n q_n* ⊗ q_{n+1} is the
    relative rotation ``R[n].inv() * R[n + 1]`` made canonical, as scipy's ``as_rotvec``
    takes it before its Log r_n (scipy's step from key n to key n + 1): w > 0, or w = 0
    (a half turn) and the first non-zero of (x, y, z) positive. Keys exactly a half
    turn apart (identity, 180° about x, identity) so turn on the same way round, as in
    scipy; a nan row keeps its sign."""
    sign = np.empty(q.shape[0] - 1)
    _signs(q, sign)
    return sign


@rowloop(parallel=False)
def _signs(q, sign):
    """:func:`_scipy_signs` into `sign` (one pass: the dozen numpy calls it takes on
    arrays of steps cost more than scipy's whole construction at a few keys)."""
    for n in range(q.shape[0] - 1):
        p0, p1, p2, p3 = q[n, 0], q[n, 1], q[n, 2], q[n, 3]
        b0, b1, b2, b3 = q[n + 1, 0], q[n + 1, 1], q[n + 1, 2], q[n + 1, 3]
        w = p0 * b0 + p1 * b1 + p2 * b2 + p3 * b3  # q_n* ⊗ q_{n+1}
        x = p0 * b1 - b0 * p1 - (p2 * b3 - p3 * b2)
        y = p0 * b2 - b0 * p2 - (p3 * b1 - p1 * b3)
        z = p0 * b3 - b0 * p3 - (p1 * b2 - p2 * b1)
        first = x if x != 0.0 else (y if y != 0.0 else z)
        sign[n] = -1.0 if w < 0.0 or (w == 0.0 and first < 0.0) else 1.0


def _increasing(times, message):
    """Raise scipy's ``ValueError`` (`message`, then the first offending pair) unless
    `times` strictly increases (nan is not increasing)."""
    dt = np.diff(times)
    bad = ~(dt > 0)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"{message} Got times[{i + 1}] = {times[i + 1]} after times[{i}] = {times[i]}.")
    return dt


def _house_dtype(q):
    """The float type the results keep: float32 for float32 keys, else float64."""
    return q.dtype if q.dtype in (np.float32, np.float64) else _F64


def _as_rotation(out, single):
    return Rotation._from_house(out[0] if single else out, single)


def _eval_cubic(order, times, nt, keys, coef, dtype):
    """The compiled loop of ``spline(method="cubic")`` on a plan: segment n of `times`
    (float64, (K,)) is ``keys[n] ⊗ Exp(ρ(τ))`` with ρ the cubic of ``coef[n]``
    (flat, see :mod:`quatarray._cubic`); `nt` flat float64. Returns (M, 4) or (M, 3)."""
    width = 3 if order else 4
    out = np.empty(nt.shape[0] * width, dtype)
    if out.shape[0]:
        _sp._EVAL_CUBIC[order](times, nt, (keys, coef), out)
    return out.reshape(-1, width)


def _new_times(times, message):
    """Scalar or 1-D times as flat float64 and whether they were a scalar."""
    nt = np.asarray(times, dtype=float)
    if nt.ndim > 1:
        raise ValueError(message)
    return np.ascontiguousarray(nt.reshape(-1)), nt.ndim == 0


# ---- Slerp


class Slerp:
    """Spherical linear interpolation of rotations: scipy 1.17's
    ``scipy.spatial.transform.Slerp`` on quatarray's kernels.

    Between consecutive keys the rotation turns about a fixed axis at a
    constant rate, the shortest way (keys exactly a half turn apart turn as in
    scipy). The same rules as scipy: at least 2 keys in a 1-D stack, strictly
    increasing `times`, new times within ``[times[0], times[-1]]`` (else
    ``ValueError``), a scalar time gives a single rotation. The results are
    scipy's quaternions (their signs too) within 1e-10.

    Parameters
    ----------
    times : array_like, shape (N,)
        Times of the keys, N ≥ 2.
    rotations : Rotation, length N
        The keys: a :class:`quatarray.Rotation` (or a scipy ``Rotation``).

    Notes
    -----
    Beyond scipy: float32 rotations give float32 results (the times stay
    float64); the call is one compiled pass over the new times, in any
    order. For other curves through the same keys (Shoemake's Bézier spline,
    squad, ...), see :class:`BezierSpline`.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> from quatarray import Rotation, Slerp
    >>> keys = Rotation.from_wxyz(qa.from_rotvec([[0, 0, 0], [0, 0, np.pi / 2], [np.pi / 2, 0, 0]]))
    >>> slerp = Slerp([0, 1, 3], keys)
    >>> np.round(np.degrees(qa.as_rotvec(slerp([0.5, 1.0]).wxyz)), 9) + 0.0
    array([[ 0.,  0., 45.],
           [ 0.,  0., 90.]])
    >>> slerp(2.0).single
    True
    >>> slerp(3.5)
    Traceback (most recent call last):
        ...
    ValueError: Interpolation times must be within the range [0.0, 3.0], both inclusive.
    """

    def __init__(self, times, rotations):
        q, single = _keys(rotations)
        if single or q.shape[0] <= 1:
            raise ValueError("`rotations` must be a sequence of at least 2 rotations.")
        if q.ndim > 2:
            raise ValueError("Rotations with more than 1 leading dimension are not supported.")
        times = np.asarray(times, dtype=float)
        if times.ndim != 1:
            raise ValueError(
                f"Expected times to be specified in a 1 dimensional array, got {times.ndim} dimensions.")
        if times.shape[0] != q.shape[0]:
            raise ValueError(
                "Expected number of rotations to be equal to number of timestamps given, "
                f"got {q.shape[0]} rotations and {times.shape[0]} timestamps.")
        _increasing(times, "Times must be in strictly increasing order.")
        self.times = times
        self.rotations = rotations
        self._dtype = _house_dtype(q)
        self._rev_times, self._seg = _slerp_plan(times, q)

    def __call__(self, times):
        """Interpolate rotations at `times` (a scalar or 1-D, within the keys' times).

        Returns
        -------
        Rotation
            Single for a scalar `times`, else a stack of ``len(times)``.
        """
        nt, single = _new_times(times, "`times` must be at most 1-dimensional.")
        t0, t1 = self.times[0], self.times[-1]
        if nt.size and not (nt.min() >= t0 and nt.max() <= t1):  # nan fails too
            raise ValueError(f"Interpolation times must be within the range [{t0}, {t1}], both inclusive.")
        out = np.empty((nt.shape[0], 4), self._dtype)
        if nt.shape[0]:
            _sp._EVALS["slerp"](self._rev_times, np.negative(nt), self._seg, out.reshape(-1))
        return _as_rotation(out, single)


def _slerp_plan(times, q):
    """What every call of a :class:`Slerp` reuses: (reversed key times, segment table).

    scipy's segment n is ``R[n] * Rotation.from_rotvec(α r_n)``, α = (t − t_n)/h_n in
    (0, 1] (and t_0 in segment 0): the great arc from q_n to σ_n q_{n+1} = q_n ⊗ Exp(r_n)
    (exactly, with scipy's canonical step: :func:`_scipy_signs`), whose quaternion at
    a key time t_{n+1} is the end of segment n, σ_n q_{n+1}, not the key as given.
    The evaluation loop of ``spline(method="slerp")`` puts a time in the segment it
    starts (the last one takes its end too), so it runs on the reversed time axis:
    key times −t_{K−1} < … < −t_0, new times −t, reversed segment j (n = K − 2 − j)
    the arc from σ_n q_{n+1} back to q_n. A table row depends on its two ends only,
    and consecutive segments need not share a key (σ_n = −1 breaks the chain): the
    ends go in pairs, rows (start, end) of every segment, and the table keeps the
    rows of the pairs."""
    dtype = _house_dtype(q)
    q64 = _unit64(q)
    sign = _scipy_signs(q64)
    k = q64.shape[0]
    pairs = np.empty((2 * (k - 1), 4), dtype)
    pairs[0::2] = (q64[1:] * sign[:, None])[::-1]
    pairs[1::2] = q64[:-1][::-1]
    seg = np.empty((2 * k - 3, _sp.NSEG), dtype)
    _sp._SEGMENTS["slerp"](pairs, pairs, pairs, seg)
    return np.ascontiguousarray(-times[::-1]), np.ascontiguousarray(seg[0::2]).reshape(-1)


# ---- RotationSpline


class RotationSpline:
    """Interpolate rotations with continuous angular rate and acceleration: scipy
    1.17's ``scipy.spatial.transform.RotationSpline`` on quatarray's kernels.

    The rotation vector between consecutive keys is a cubic in time, chosen
    so that the angular rate and acceleration are continuous (C²). The same
    rules as scipy: at least 2 keys in a 1-D stack, strictly increasing
    `times`; times outside the keys' extrapolate the end segments' cubics (as
    scipy's, which does not refuse them); a scalar time gives a single
    rotation (or one vector). The results are scipy's within 1e-10 (the
    rotations' quaternions with their signs, the rates, the accelerations).

    Parameters
    ----------
    times : array_like, shape (N,)
        Times of the keys, N ≥ 2.
    rotations : Rotation, length N
        The keys: a :class:`quatarray.Rotation` (or a scipy ``Rotation``).

    Notes
    -----
    Beyond scipy: float32 rotations give float32 results (the spline's
    coefficients are solved in float64); the coefficients are solved once,
    at construction, and each call is one compiled pass over the new times.
    It is ``quatarray.spline(method="cubic")``; for Shoemake's Bézier spline
    and the other curves behind this call interface, see :class:`BezierSpline`.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> from quatarray import Rotation, RotationSpline
    >>> keys = Rotation.from_wxyz(qa.from_rotvec([[0, 0, 0], [0, 0, 0.5], [0, 0, 1.0]]))
    >>> spline = RotationSpline([0, 1, 2], keys)
    >>> np.round(qa.as_rotvec(spline([0.5, 1.5]).wxyz), 12) + 0.0
    array([[0.  , 0.  , 0.25],
           [0.  , 0.  , 0.75]])
    >>> np.round(spline(1.0, order=1), 12) + 0.0  # rad per time unit, body frame
    array([0. , 0. , 0.5])
    >>> spline(0.5, order=2).shape
    (3,)
    """

    def __init__(self, times, rotations):
        q, single = _keys(rotations)
        if single:
            raise ValueError("`rotations` must be a sequence of rotations.")
        if q.ndim > 2:
            raise ValueError("Rotations with more than 1 leading dimension are not supported.")
        if q.shape[0] < 2:
            raise ValueError("`rotations` must contain at least 2 rotations.")
        times = np.asarray(times, dtype=float)
        if times.ndim != 1:
            raise ValueError("`times` must be 1-dimensional.")
        if times.shape[0] != q.shape[0]:
            raise ValueError(
                "Expected number of rotations to be equal to number of timestamps given, "
                f"got {q.shape[0]} rotations and {times.shape[0]} timestamps.")
        _increasing(times, "Values in `times` must be in a strictly increasing order.")
        self.times = np.ascontiguousarray(times)
        self.rotations = rotations
        self._dtype = _house_dtype(q)
        q64 = _unit64(q)
        sign = _scipy_signs(q64)
        # the keys signed so that each step is scipy's canonical one (the tie rule),
        # for the coefficients; the evaluation starts each segment from the key as given
        chain = np.concatenate([[1.0], np.cumprod(sign)])
        coef, _ = _cubic.coefficients(self.times, q64 * chain[:, None])
        self._keys = np.ascontiguousarray(q64, self._dtype).reshape(-1)
        self._coef = coef.astype(self._dtype).reshape(-1)

    def __call__(self, times, order=0):
        """The rotations (``order=0``), angular rates (1) or angular accelerations (2) at `times`.

        Parameters
        ----------
        times : float or array_like, shape (M,)
        order : {0, 1, 2}, optional

        Returns
        -------
        Rotation, or ndarray of shape (M, 3) or (3,)
            Rates in radians per time unit, accelerations in radians per time
            unit squared, in the body frame (scipy's).
        """
        if order not in (0, 1, 2):
            raise ValueError("`order` must be 0, 1 or 2.")
        order = int(order)
        nt, single = _new_times(times, "`times` must be at most 1-dimensional.")
        if order == 0 and not np.isfinite(nt).all():
            i = int(np.argmax(~np.isfinite(nt)))
            raise ValueError(f"Found non-finite times: times[{i}] = {nt[i]} gives no rotation.")
        out = _eval_cubic(order, self.times, nt, self._keys, self._coef, self._dtype)
        if order == 0:
            return _as_rotation(out, single)
        return out[0] if single else out


# ---- BezierSpline


class BezierSpline:
    """Shoemake's Bézier spline of rotations (or another of ``quatarray.spline``'s
    curves) behind ``RotationSpline``'s call interface: ``spl(t, order=0|1|2)``.

    What scipy lacks: Shoemake's curve, the library's default spline (each
    segment a de Casteljau construction of slerps on the sphere, C¹: for
    uneven key times its tangents are scaled so that the angular velocity is
    continuous in time across keys), squad, piecewise nlerp and the choice
    among them on one class; the analytic angular velocity and acceleration
    of every one of them (``order=1, 2``); float32 kept; new times of any
    shape; integer key times such as nanosecond stamps taken exactly. It is
    ``quatarray.spline(times, keys, t, method=method, order=order)`` with its
    controls and segment table built once, at construction.

    Parameters
    ----------
    times : array_like, shape (K,)
        Strictly increasing key times (floats, or integers such as
        nanosecond stamps), K ≥ 2.
    rotations : Rotation or array_like, shape (K, 4)
        The keys: a :class:`quatarray.Rotation` (or a scipy ``Rotation``), or
        house (w, x, y, z) quaternions. They are normalised and unflipped (sign
        continuity), as :func:`quatarray.spline` does.
    method : {"bezier", "squad", "slerp", "nlerp", "cubic"}, optional
        The curve (see :func:`quatarray.spline`); ``"cubic"`` is scipy's
        ``RotationSpline`` curve.

    Notes
    -----
    New times outside ``[times[0], times[-1]]`` raise ``ValueError`` naming the
    first one (no extrapolation).

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> from quatarray import BezierSpline, Rotation
    >>> keys = Rotation.from_wxyz(qa.from_rotvec([[0, 0, 0], [0, 0, 0.5], [0, 0, 1.0]]))
    >>> spline = BezierSpline([0, 1, 2], keys)
    >>> np.round(qa.as_rotvec(spline([0.5, 1.5]).wxyz), 12) + 0.0
    array([[0.  , 0.  , 0.25],
           [0.  , 0.  , 0.75]])
    >>> np.round(spline([0.25, 1.0], order=1), 12) + 0.0  # rad per time unit, body frame
    array([[0. , 0. , 0.5],
           [0. , 0. , 0.5]])
    >>> BezierSpline([0, 1, 2], keys, method="squad")(np.zeros((2, 3))).shape
    (2, 3)
    """

    def __init__(self, times, rotations, method="bezier"):
        _sp.check_method(method)
        q = rotations
        if isinstance(rotations, Rotation) or _is_scipy_rotation(rotations):
            q, single = _keys(rotations)
            if single:
                raise ValueError("`rotations` must be a sequence of rotations.")
        q = check_core(as_float(q, "rotations"), "rotations", (4,))
        if q.ndim != 2:
            raise ValueError("Rotations with more than 1 leading dimension are not supported."
                             if q.ndim > 2 else f"Expected `rotations` to have shape (K, 4), got {q.shape}.")
        if q.shape[0] < 2:
            raise ValueError("`rotations` must contain at least 2 rotations.")
        self.method = method
        self.times = key_times(as_times(times, "times"), q.shape[0])
        self.rotations = rotations
        self._q = _sp.unit_keys([q])
        t, _ = _sp.seconds(self.times, self.times[:1], self.times[0])
        self._t = t
        m = _sp._METHODS[method]
        if m.resample is not None:  # cubic: the coefficients of one system over all keys
            coef, _ = _cubic.coefficients(t, self._q)
            self._coef = coef.astype(self._q.dtype).reshape(-1)
            self._flat = np.ascontiguousarray(self._q).reshape(-1)
        else:  # a table method: the controls, and the segment table when a call needs it
            self._controls = m.controls(self._q, t)
            self._seg = None

    def _table(self):
        if self._seg is None:
            seg = np.zeros((self._q.shape[0] - 1, _sp.NSEG), self._q.dtype)  # zeros: the rate loops read every arc column
            c_out, c_in = self._controls
            _sp._SEGMENTS[self.method](self._q, c_out, c_in, seg)
            self._seg = seg.reshape(-1)
        return self._seg

    def __call__(self, times, order=0):
        """The rotations (``order=0``), angular velocities (1) or angular accelerations (2) at `times`.

        Parameters
        ----------
        times : float or array_like, any shape
            Within ``[times[0], times[-1]]`` of the keys.
        order : {0, 1, 2}, optional

        Returns
        -------
        Rotation of ``times``' shape, or ndarray of shape ``times.shape + (3,)``
            Rates in radians per time unit of the keys' times (per nanosecond
            for nanosecond stamps), accelerations per time unit squared, in the
            body frame (as scipy's ``RotationSpline``).
        """
        order = spline_order(order)
        _, nt = _sp.plan_times(self.times, as_times(times, "new_times"))
        shape = nt.shape
        flat = np.ascontiguousarray(nt.reshape(-1))
        q = self._q
        m = flat.shape[0]
        if self.method == "cubic":
            out = _eval_cubic(order, self._t, flat, self._flat, self._coef, q.dtype)
        elif order:
            out = np.empty((m, 3), q.dtype)
            if m:
                _sp._RATES[self.method, order](self._t, flat, self._table(), out.reshape(-1))
        else:
            out = np.empty((m, 4), q.dtype)
            if q.shape[0] >= _sp.PIECES_MIN_KEYS and m > 1 and (flat[1:] >= flat[:-1]).all():
                c_out, c_in = self._controls
                _sp._PIECES[self.method](self._t, flat, q, c_out, c_in, out.reshape(-1))
            elif m:
                _sp._EVALS[self.method](self._t, flat, self._table(), out.reshape(-1))
        if order:
            return out.reshape(shape + (3,))
        out = out.reshape(shape + (4,))
        return Rotation._from_house(out, out.ndim == 1)
