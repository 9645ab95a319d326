"""Euler angles: all 12 sequences, extrinsic (``"xyz"``) and intrinsic (``"XYZ"``).

Quaternions are ``(..., 4)`` arrays in (w, x, y, z) order. The sequence
string follows scipy: three letters from ``xyz``; lower case means
extrinsic (rotations about the fixed axes), upper case intrinsic (about the
moving axes); the two cannot be mixed and an axis may not follow itself.
Six sequences are Tait–Bryan (three different axes, e.g. ``"xyz"``), six are
proper Euler (first axis = last axis, e.g. ``"zxz"``).

:func:`as_euler` works on the quaternion directly, by Bernardes & Viollet's
general method ("Quaternion to Euler angles conversion: a direct, general
and computationally efficient method", PLoS ONE 17(11), 2022), the method
scipy uses, with scipy's angle ranges and gimbal-lock rule.

Speed: both conversions are bound by trigonometry. libm's ``atan2``,
``sin`` and ``cos`` are opaque calls that stop LLVM from vectorising a loop,
so this module uses the branch-free ``atan2`` and ``sincos`` of
:mod:`quatarray._trig` (within 2 ulp in float64), and the loops read and
write flat contiguous views (fixed strides 4 and 3), which LLVM turns into
SIMD code.
"""

import math
import warnings

import numpy as np

from . import _elements as E
from . import _trig
from ._jit import element, like, prange, rowloop
from ._trig import atan2, sincos_limit
from ._validate import as_float, check_core

_ALLOWED = (
    "Expected `seq` to be three axes from 'x', 'y', 'z' (lower case: extrinsic) or "
    "'X', 'Y', 'Z' (upper case: intrinsic), not mixed, with no axis twice in a row: "
    "one of the Tait-Bryan sequences 'xyz', 'xzy', 'yxz', 'yzx', 'zxy', 'zyx' or the "
    "proper Euler sequences 'xyx', 'xzx', 'yxy', 'yzy', 'zxz', 'zyz' (or their upper-case "
    "intrinsic versions)"
)

_GIMBAL = (
    "Gimbal lock detected in {n} of {total} rotations. Setting third angle to zero "
    "since it is not possible to uniquely determine all angles."
)

# --------------------------------------------------------------------------
# per-element helpers


@element(how="inline")
def sincos_call(x):
    """:func:`quatarray._trig.sincos` as an element function of its own, compiled
    once and inlined by LLVM into :func:`_from_euler`'s loop (``inline``, like
    :func:`beyond` and :func:`axis_quat`). Inlined at numba-IR level three times
    into that loop it left branches that stop the vectoriser (about 2× slower in
    float64, 4× in float32); left to LLVM's own inlining decisions, whether the
    loop vectorised depended on what else the loop called (it stopped, at half
    the speed, when ``like`` became a cast)."""
    return _trig.sincos(x)


@element(how="inline")
def beyond(x):
    """True where |x| exceeds the range in which :func:`quatarray._trig.sincos`
    is accurate (inf too, not nan): those rows are redone with libm."""
    return abs(x) > sincos_limit(x)


@element
def wrap(a):
    """Bring an angle in [-3π, 3π] into [-π, π] by one step of 2π, as scipy does."""
    pi = like(a, math.pi)
    a = a + like(a, 2 * math.pi) if a < -pi else a
    return a - like(a, 2 * math.pi) if a > pi else a


# --------------------------------------------------------------------------
# batched loops
#
# The loops read and write flat views of C-contiguous arrays (fixed strides 4
# and 3) and keep every per-row decision a select, so LLVM vectorises them.
# A call in the loop stops vectorisation: both bodies are written out in their
# loops (small element functions are LLVM-inlined into them).
# Serial only: numba's parallel (parfor) version of these loops did not
# vectorise and ran slower than the serial SIMD loop with two cores.


@element
def axis_quat(axis, s, c):
    """(cos h, sin h along axis 0/1/2), built with selects."""
    zero = like(s, 0.0)
    return (c, s if axis == 0 else zero, s if axis == 1 else zero, s if axis == 2 else zero)


@element(how="call")
def compose_axes(e0, e1, e2, intrinsic):
    """Product of three elementary quaternions in scipy's order:
    intrinsic (e0 e1) e2, extrinsic e2 (e1 e0)."""
    if intrinsic:
        return E.qmul(E.qmul(e0, e1), e2)
    return E.qmul(e2, E.qmul(e1, e0))


EULER_BLOCK = 256  # rows of _as_euler's block of angle planes (6 KB in float64)


@rowloop(parallel=False)
def _as_euler(q, ci, cj, ck, tb, sign, ext, lamb, scale, lo, hi, out, flags):
    """Bernardes & Viollet, row by row, on q as it is: ``(rows at gimbal lock, rows
    outside)``. ``flags[r]`` (uint8) has bit 0 set when row r is at gimbal lock and
    bit 1 when h1 + h2 (the two half-angle magnitudes of row r, between |q| and
    2|q|) is not strictly between `lo` and `hi`: such a row is outside, its angles
    nan. (Per-row flags, counted after the loop: a reduction inside it kept the
    float32 loop from vectorising.)

    With ``(lo, hi) = (0, inf)`` the rows outside are the zero, inf and nan
    quaternions; :func:`euler_locked` first passes the :data:`_NEAR` bounds, which
    also put the rows far from unit scale outside (where a square of a component
    could overflow or underflow), and runs the kernel again on those rows scaled
    (:func:`_scaled_rows`) with (0, inf): the far-row test is the one the formula
    makes anyway, and one compiled loop serves both passes.

    ``ci, cj, ck`` are the quaternion columns of the extrinsic axis order (k is
    the remaining axis for proper Euler sequences), ``tb`` 1 for Tait–Bryan else
    0, ``sign`` the parity of (i, j, k), ``ext`` True for extrinsic, ``lamb`` π/2
    for Tait–Bryan else 0, ``scale`` 1 or 180/π.

    The body is written out in the loop: as a function (LLVM- or numba-IR-inlined)
    the float64 loop ran about 10 % slower. The angles of EULER_BLOCK rows go into a
    block of three planes (one per angle, in L1 cache), then into their rows of
    `out`: with the rows' stride-3 stores in it, LLVM's cost model for AVX2 CPUs
    (Zen 3) found the loop not worth vectorising (11 against 45 Mq/s there).
    """
    n = q.shape[0]
    plane = np.empty(3 * EULER_BLOCK, out.dtype)
    # parameters in the array's float type, once
    t = like(q, tb)
    sg = like(q, sign)
    lb = like(q, lamb)
    s = like(q, scale)
    low = like(q, lo)
    high = like(q, hi)
    for base in range(0, n, EULER_BLOCK):
        m = min(EULER_BLOCK, n - base)
        for k in range(m):
            r = base + k
            w, x, y, z = E.load4(q, r)
            one = like(w, 1.0)
            zero = like(w, 0.0)
            two = like(w, 2.0)
            qi = x if ci == 1 else (y if ci == 2 else z)
            qj = x if cj == 1 else (y if cj == 2 else z)
            qk = sg * (x if ck == 1 else (y if ck == 2 else z))
            # step 1: permuted (for Tait–Bryan also rotated by π/2 about j) elements
            a = w - t * qj
            b = qi + t * qk
            c = qj + t * w
            d = qk - t * qi
            h1 = np.sqrt(c * c + d * d)  # np: numpy scalars also when run as plain Python
            h2 = np.sqrt(a * a + b * b)
            # step 2: middle angle. Gimbal lock when it is within 1e-7 of 0 or π,
            # tested as a ratio (2 atan2(h1, h2) <= 1e-7 ⇔ h1 <= tan(5e-8) h2),
            # which is as sharp near π as near 0, also in float32.
            mid = two * atan2(h1, h2)
            tiny = like(w, 5e-8)
            hh = h1 + h2
            ok = (hh > low) & (hh < high)  # not zero, inf or nan (nor far from unit scale)
            case1 = (h1 <= tiny * h2) & ok
            case2 = (h2 <= tiny * h1) & ok  # excludes case1 when ok (tiny² < 1)
            lock = case1 | case2
            # step 3: first and third angles; at gimbal lock scipy's rule: the
            # third angle is 0 and the first carries the whole rotation
            hs = atan2(b, a)
            hd = atan2(d, c)
            g = two * hs if case1 else (-two * hd if ext else two * hd)
            u = hs - hd if not lock else (g if ext else zero)  # first angle slot
            v = hs + hd if not lock else (zero if ext else g)  # third angle slot
            v = v * (sg if tb == 1 else one)
            nan = like(w, math.nan)
            plane[k] = nan if not ok else wrap(u if ext else v) * s
            plane[EULER_BLOCK + k] = nan if not ok else (mid - lb) * s  # no wrap: mid in [0, π], lamb 0 or π/2
            plane[2 * EULER_BLOCK + k] = nan if not ok else wrap(v if ext else u) * s
            flags[r] = np.uint8(lock) | (np.uint8(0) if ok else np.uint8(2))
        for k in range(m):
            E.store3(out, base + k, (plane[k], plane[EULER_BLOCK + k], plane[2 * EULER_BLOCK + k]))
    nl = 0
    nf = 0
    for r in range(n):
        nl += flags[r] & 1
        nf += flags[r] >> 1
    return nl, nf


# h1 + h2 inside these bounds puts |q|² (h1² + h2², between (h1 + h2)²/2 and
# (h1 + h2)²) inside E.NEAR_64 / E.NEAR_32, where the formulas on q as it is
# are exact to rounding.
_NEAR = {
    np.dtype(np.float64): (2.0 * math.sqrt(E.NEAR_64[0]), math.sqrt(E.NEAR_64[1])),
    np.dtype(np.float32): (2.0 * math.sqrt(E.NEAR_32[0]), math.sqrt(E.NEAR_32[1])),
}


@rowloop(parallel=False)
def _scaled_rows(q, out):
    """``out[r]`` = row r of q scaled by a power of two (E.qscaled): squares that
    neither overflow nor underflow."""
    for r in prange(q.shape[0]):
        E.store4(out, r, E.qscaled(E.load4(q, r))[0])


@rowloop(parallel=False)
def _from_euler(angles, a0, a1, a2, intrinsic, unit, out, far):
    """q = product of the three axis rotations; ``far[r]`` flags rows whose half
    angles lie beyond the fast sin/cos range (or are inf): :func:`_from_euler_far`
    redoes those with libm."""
    n = angles.shape[0]
    af = angles.reshape(n * 3)
    of = out.reshape(n * 4)
    k = like(angles, unit) * like(angles, 0.5)
    for r in prange(n):
        h0 = af[3 * r] * k
        h1 = af[3 * r + 1] * k
        h2 = af[3 * r + 2] * k
        s0, c0 = sincos_call(h0)
        s1, c1 = sincos_call(h1)
        s2, c2 = sincos_call(h2)
        e0 = axis_quat(a0, s0, c0)
        e1 = axis_quat(a1, s1, c1)
        e2 = axis_quat(a2, s2, c2)
        # compose_axes, written out so the loop vectorises
        qw, qx, qy, qz = E.qmul(E.qmul(e0, e1), e2) if intrinsic else E.qmul(e2, E.qmul(e1, e0))
        of[4 * r] = qw
        of[4 * r + 1] = qx
        of[4 * r + 2] = qy
        of[4 * r + 3] = qz
        far[r] = beyond(h0) | beyond(h1) | beyond(h2)


@rowloop(parallel=False)
def _from_euler_far(angles, a0, a1, a2, intrinsic, unit, out, far):
    """The rows flagged in ``far`` again, with libm's sin and cos."""
    k = like(angles, unit) * like(angles, 0.5)
    for r in prange(angles.shape[0]):
        if far[r]:
            h0 = angles[r, 0] * k
            h1 = angles[r, 1] * k
            h2 = angles[r, 2] * k
            e0 = axis_quat(a0, np.sin(h0), np.cos(h0))
            e1 = axis_quat(a1, np.sin(h1), np.cos(h1))
            e2 = axis_quat(a2, np.sin(h2), np.cos(h2))
            E.store4(out, r, compose_axes(e0, e1, e2, intrinsic))


# --------------------------------------------------------------------------
# public functions


def _seq_params(seq):
    """(axes 0..2 in the order of ``seq``, intrinsic, the as_euler kernel's
    sequence arguments) for a valid ``seq``."""
    axes = tuple("xyz".index(ch) for ch in seq.lower())
    intrinsic = seq.isupper()
    # Bernardes & Viollet work on the extrinsic order: reverse intrinsic sequences
    i, j, k = axes[::-1] if intrinsic else axes
    tait_bryan = i != k
    if not tait_bryan:
        k = 3 - i - j  # the remaining axis
    sign = (i - j) * (j - k) * (k - i) // 2  # parity of (i, j, k): ±1
    lamb = math.pi / 2 if tait_bryan else 0.0
    return axes, intrinsic, (i + 1, j + 1, k + 1, int(tait_bryan), sign, not intrinsic, lamb)


_SEQS = {
    s: _seq_params(s)
    for a in "xyz"
    for b in "xyz"
    for c in "xyz"
    if a != b and b != c
    for s in (a + b + c, (a + b + c).upper())
}


def _parse_seq(seq):
    """Look ``seq`` up among the 24 valid sequences (see :func:`_seq_params`)."""
    if not isinstance(seq, str):
        raise TypeError(f"{_ALLOWED}; got {type(seq).__name__} {seq!r}.")
    params = _SEQS.get(seq)
    if params is None:
        raise ValueError(f"{_ALLOWED}; got {seq!r}.")
    return params


_SHORT = {
    s: tuple("xyz".index(ch) for ch in s.lower()) for a in "xyz" for b in ("", *"xyz") if a != b
    for s in (a + b, (a + b).upper())
}

_ALLOWED_SHORT = (
    "Expected `seq` to be one to three axes from 'x', 'y', 'z' (lower case: extrinsic) or "
    "'X', 'Y', 'Z' (upper case: intrinsic), not mixed, with no axis twice in a row"
)


def _parse_from_seq(seq):
    """(three axes, intrinsic, number of axes given) for :func:`from_euler`, which
    also takes scipy's one- and two-axis sequences: they are padded with a zero
    angle about a further axis (an exact identity factor)."""
    if isinstance(seq, str) and seq in _SHORT:
        axes = _SHORT[seq]
        return axes + (0,) * (3 - len(axes)), seq.isupper(), len(axes)
    if isinstance(seq, str) and len(seq) == 3 and seq in _SEQS:
        axes, intrinsic, _ = _SEQS[seq]
        return axes, intrinsic, 3
    if not isinstance(seq, str):
        raise TypeError(f"{_ALLOWED_SHORT}; got {type(seq).__name__} {seq!r}.")
    raise ValueError(f"{_ALLOWED_SHORT}; got {seq!r}.")


def _contiguous_rows(a, core):
    """``a`` as a C-contiguous ``(n,) + core`` array (a copy only when ``a`` is strided)."""
    return np.ascontiguousarray(a.reshape((-1,) + core))


def as_euler(q, seq, degrees=False, suppress_warnings=False):
    """Euler angles of rotation quaternions, as scipy's ``Rotation.as_euler``.

    Computed from the quaternion directly (Bernardes & Viollet), for any
    non-zero scale of `q` (no normalising needed); a zero, inf or nan
    quaternion gives nan angles.

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Quaternions (w, x, y, z).
    seq : str
        Three axes (as in scipy, ``as_euler`` has no one- or two-axis form:
        those raise ``ValueError``): ``"xyz"``-style lower case for extrinsic rotations,
        ``"XYZ"``-style upper case for intrinsic ones (not mixed); 6 Tait–Bryan
        sequences (``"xyz"``, ``"zyx"``, …) and 6 proper Euler ones (``"zxz"``, …).
    degrees : bool, optional
        Return degrees instead of radians.
    suppress_warnings : bool, optional
        Do not warn at gimbal lock.

    Returns
    -------
    ndarray, shape (..., 3)
        Angles in the order of `seq`. First and third in [-π, π]; the second
        in [-π/2, π/2] for Tait–Bryan and [0, π] for proper Euler sequences.

    Warns
    -----
    UserWarning
        At most once per call, when any rotation is at gimbal lock (the second
        angle within 1e-7 rad of its singular values). There the third angle
        is set to 0 and the first carries the whole rotation about the
        (then aligned) first and third axes, as scipy does; the angles then
        reproduce the rotation to within 2e-7 rad (twice the middle angle's
        distance from the singular value). The test is
        ``h1 <= tan(5e-8) h2`` on the two half-angle magnitudes, the same as
        scipy's ``|θ₂| <= 1e-7`` up to rounding but equally sharp near π; in
        float32 it sees the data's own rounding (~1e-7), so rotations that close
        to gimbal lock may or may not be flagged.

    Notes
    -----
    Strided input is copied once into a contiguous buffer: the kernel reads rows
    at a fixed stride so that it compiles to SIMD code.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> q = qa.from_euler("zyx", [90, 30, 10], degrees=True)
    >>> np.round(qa.as_euler(q, "zyx", degrees=True), 9)
    array([90., 30., 10.])
    >>> np.round(qa.as_euler([1, 0, 0, 0], "ZXZ", suppress_warnings=True), 9)  # gimbal lock
    array([0., 0., 0.])
    """
    out, locked = euler_locked(q, seq, degrees)
    if locked and not suppress_warnings:
        warnings.warn(_GIMBAL.format(n=locked, total=out.size // 3), UserWarning, stacklevel=2)
    return out


def euler_locked(q, seq, degrees=False):
    """``(as_euler(q, seq, degrees), number of rows at gimbal lock)``, without a warning:
    for callers that count lock across many calls or threads (the command line)."""
    _, _, params = _parse_seq(seq)
    a = check_core(as_float(q, "q"), "q", (4,))
    flat = _contiguous_rows(a, (4,))
    scale = 180.0 / math.pi if degrees else 1.0
    out, locked, far = _euler_rows(flat, params, scale, *_NEAR[a.dtype])
    if far is not None:  # rare: rows far from unit scale (or zero, inf, nan), again scaled
        rows = np.flatnonzero(far)
        scaled = np.empty((rows.size, 4), a.dtype)
        _scaled_rows(flat[rows], scaled)
        out[rows], more, _ = _euler_rows(scaled, params, scale, 0.0, math.inf)
        locked += more
    return out.reshape(a.shape[:-1] + (3,)), locked


def _euler_rows(flat, params, scale, lo, hi):
    """:func:`_as_euler` on the rows of ``flat``: (angles, rows at gimbal lock,
    the flags of the rows outside (lo, hi) where there are any, else None)."""
    n = flat.shape[0]
    out = np.empty((n, 3), flat.dtype)
    flags = np.empty(n, np.uint8)
    nl, nf = _as_euler(flat, *params, scale, lo, hi, out, flags)
    return out, int(nl), (flags >= 2 if nf else None)


def from_euler(seq, angles, degrees=False):
    """Rotation quaternions from Euler angles, as scipy's ``Rotation.from_euler``.

    Parameters
    ----------
    seq : str
        One to three axes, lower case extrinsic or upper case intrinsic (see
        :func:`as_euler`), as scipy: ``"z"``, ``"XY"``, ``"zyx"`` …
    angles : array_like, shape (..., k)
        Angles in the order of `seq` (k = ``len(seq)``); any leading shape.
        For one axis, as in scipy, also a plain scalar (one rotation); a
        ``(N,)`` array of angles about one axis must be given as ``(N, 1)``.
    degrees : bool, optional
        `angles` are in degrees.

    Returns
    -------
    ndarray, shape (..., 4)
        Unit quaternions (w, x, y, z): for ``"XYZ"`` (intrinsic) the product
        q_x(a) q_y(b) q_z(c); for ``"xyz"`` (extrinsic) q_z(c) q_y(b) q_x(a).
        The sign is scipy's (compare rotations with :func:`distance`).

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> np.round(qa.from_euler("xyz", [0, 0, 180], degrees=True), 12)
    array([0., 0., 0., 1.])
    >>> qa.from_euler("ZYX", np.zeros((2, 5, 3))).shape
    (2, 5, 4)
    >>> np.round(qa.from_euler("z", 90, degrees=True), 12)  # one axis
    array([0.70710678, 0.        , 0.        , 0.70710678])
    """
    axes, intrinsic, k = _parse_from_seq(seq)
    a = as_float(angles, "angles")
    if k == 1 and a.ndim == 0:
        a = a[None]
    a = check_core(a, "angles", (k,))
    flat = _contiguous_rows(a, (k,))
    if k < 3:  # zero angles about the padding axis: an exact identity factor
        flat = np.concatenate([flat, np.zeros((flat.shape[0], 3 - k), flat.dtype)], axis=1)
    out = np.empty((flat.shape[0], 4), a.dtype)
    far = np.empty(flat.shape[0], np.bool_)
    args = (flat, axes[0], axes[1], axes[2], intrinsic, math.pi / 180.0 if degrees else 1.0, out, far)
    _from_euler(*args)
    if far.any():  # rare: angles beyond ±2·10⁶ rad (float32: ±65536 rad) or inf
        _from_euler_far(*args)
    return out.reshape(a.shape[:-1] + (4,))
