"""Skeletons: whole motion-capture clips and their forward kinematics.

A :class:`Clip` holds every joint of a skeleton over every frame: the local
rotation and translation of each joint relative to its parent (as BVH stores
them), the hierarchy, and the frame times. :meth:`Clip.world` composes them
down the hierarchy (VQS composition with s = 1) into world rotations and
world joint positions in one numba kernel over frames × joints;
:meth:`Clip.resample` interpolates every joint as :func:`quatarray.spline` does, all
joints in one pass over the frames (one time plan, SIMD over the joints).

Read and write clips with :func:`quatarray.io.read_bvh` and
:func:`quatarray.io.write_bvh`.
"""

import numpy as np

from . import _elements as E
from ._jit import prange, rowloop
from ._spline_lanes import resample_each, resample_streams
from ._validate import as_times, first_not_increasing, key_times, not_increasing
from .algebra import multiply, normalize
from .splines import check_method, plan_times

AXES = "XYZ"
# Clip.resample runs every joint in one pass (quatarray._spline_lanes) from this many output
# joint-samples on; below, joint by joint through the engine's own kernels (the same
# bits), so that a small clip does not wait for the one-pass kernels to compile (about
# 3 s of a first call)
LANES_MIN_SAMPLES = 200_000


@rowloop(rows=1)
def _world(parents, rot, trans, q_out, p_out):
    """World rotations and positions, frame by frame, joints in topological order
    (``parents[j] < j``): q_w[j] = q_w[p] ⊗ q[j], p_w[j] = p_w[p] + q_w[p] (t[j])."""
    for f in prange(rot.shape[0]):
        for j in range(rot.shape[1]):
            q = (rot[f, j, 0], rot[f, j, 1], rot[f, j, 2], rot[f, j, 3])
            t = (trans[f, j, 0], trans[f, j, 1], trans[f, j, 2])
            p = parents[j]
            if p >= 0:
                qp = (q_out[f, p, 0], q_out[f, p, 1], q_out[f, p, 2], q_out[f, p, 3])
                q = E.qmul(qp, q)
                v = E.qrotate(qp, t)
                t = (p_out[f, p, 0] + v[0], p_out[f, p, 1] + v[1], p_out[f, p, 2] + v[2])
            q_out[f, j, 0], q_out[f, j, 1], q_out[f, j, 2], q_out[f, j, 3] = q
            p_out[f, j, 0], p_out[f, j, 1], p_out[f, j, 2] = t


class Clip:
    """A motion-capture clip: a joint hierarchy and every joint's local motion.

    Joints are listed parents first (the order of a BVH file, depth first).
    End Sites are joints too (leaf "end" joints without channels, named
    ``<parent>_End``, as bvhio and Blender read them as end bones): their
    world positions are the tips of the chains (head top, finger and toe tips).

    Parameters
    ----------
    joints : list of str
        Joint names, parents before children.
    parents : array_like of int, shape (J,)
        Index of each joint's parent, −1 for a root (several roots allowed).
    offsets : array_like, shape (J, 3)
        Each joint's OFFSET (its rest translation in its parent's frame).
    channels : list of tuple of str
        Each joint's channels as in the file (``("Xposition", "Yposition",
        "Zposition", "Zrotation", "Xrotation", "Yrotation")``); empty for an
        End Site.
    rotations : array_like, shape (F, J, 4)
        Local rotations (w, x, y, z) of every joint in every frame.
    translations : array_like, shape (F, J, 3)
        Local translations: the OFFSET, replaced by the joint's position
        channels wherever it has them.
    frame_time : float
        Seconds per frame (BVH ``Frame Time``).
    times : array_like, shape (F,), optional
        Frame times in seconds (default ``frame_time × arange(F)``).
    ends : array_like of bool, shape (J,), optional
        Which joints are End Sites (default: none).

    Attributes
    ----------
    orders : list of str
        Each joint's intrinsic Euler sequence in the order of its rotation
        channels (``"ZXY"``), ``""`` for a joint without rotation channels.

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> from quatarray.skeleton import Clip
    >>> rot = qa.from_euler("ZXY", [[[90, 0, 0], [0, 0, 0]]], degrees=True)  # 1 frame, 2 joints
    >>> clip = Clip(["hip", "knee"], [-1, 0], [[0, 0, 0], [1, 0, 0]],
    ...             [("Zrotation", "Xrotation", "Yrotation")] * 2, rot, [[[0, 0, 0], [1, 0, 0]]], 1 / 30)
    >>> q, p = clip.world()
    >>> np.round(p[0, 1], 12)  # the knee, 1 along x turned 90° about z
    array([0., 1., 0.])
    """

    def __init__(self, joints, parents, offsets, channels, rotations, translations, frame_time,
                 times=None, ends=None):
        self.joints = [str(j) for j in joints]
        J = len(self.joints)
        self.parents = np.asarray(parents, dtype=np.int64).reshape(J)
        if np.any(self.parents >= np.arange(J)) or np.any(self.parents < -1):
            raise ValueError("Expected every joint's parent to come before it (parents[j] < j, −1 for a root).")
        self.offsets = np.asarray(offsets, dtype=np.float64).reshape(J, 3)
        self.channels = [tuple(c) for c in channels]
        if len(self.channels) != J:
            raise ValueError(f"Expected channels for {J} joints, got {len(self.channels)}.")
        self.orders = [order_of(c) for c in self.channels]
        self.rotations = np.asarray(rotations, dtype=np.float64)
        self.translations = np.asarray(translations, dtype=np.float64)
        F = self.rotations.shape[0] if self.rotations.ndim == 3 else -1
        if self.rotations.shape != (F, J, 4) or self.translations.shape != (F, J, 3):
            raise ValueError(f"Expected rotations (F, {J}, 4) and translations (F, {J}, 3), got "
                             f"{self.rotations.shape} and {self.translations.shape}.")
        self.frame_time = float(frame_time)
        if not (self.frame_time > 0 and np.isfinite(self.frame_time)):
            raise ValueError(f"Expected a positive, finite `frame_time` (seconds per frame), got {frame_time!r}.")
        self.times = (np.arange(F) * self.frame_time if times is None
                      else np.asarray(times, dtype=np.float64).reshape(F))
        self.ends = np.zeros(J, bool) if ends is None else np.asarray(ends, dtype=bool).reshape(J)

    @property
    def frames(self):
        """Number of frames F."""
        return self.rotations.shape[0]

    def __repr__(self):
        ft = self.frame_time  # checked by the constructor, but an attribute may be set since
        fps = f"{1 / ft:.6g} fps" if isinstance(ft, (int, float)) and ft > 0 else f"frame time {ft!r}"
        return (f"<Clip: {len(self.joints)} joints ({int(np.sum(self.ends))} end sites), {self.frames} "
                f"frame{'' if self.frames == 1 else 's'} at {fps}>")

    def positional(self):
        """Indices of the joints with at least one position channel."""
        return [j for j, c in enumerate(self.channels) if any(s.lower().endswith("position") for s in c)]

    def world(self):
        """Forward kinematics: world rotations and world joint positions.

        One batched pass down the hierarchy (numba, frames × joints):
        q_w[j] = q_w[parent] ⊗ q[j] and p_w[j] = p_w[parent] + q_w[parent] t[j];
        a root's world pose is its local one.

        Returns
        -------
        q : ndarray, shape (F, J, 4)
            World rotations.
        p : ndarray, shape (F, J, 3)
            World joint positions, in the file's units.

        Examples
        --------
        >>> from quatarray import io
        >>> from quatarray.io import sample_path
        >>> q, p = io.read_bvh(sample_path()).world()
        >>> q.shape, p.shape
        ((455, 24, 4), (455, 24, 3))
        """
        rot = np.ascontiguousarray(self.rotations)
        trans = np.ascontiguousarray(self.translations)
        q = np.empty_like(rot)
        p = np.empty_like(trans)
        _world(self.parents, rot, trans, q, p)
        return q, p

    def replace(self, **kw):
        """A copy with some of the constructor's arguments replaced."""
        args = dict(joints=self.joints, parents=self.parents, offsets=self.offsets, channels=self.channels,
                    rotations=self.rotations, translations=self.translations, frame_time=self.frame_time,
                    times=self.times, ends=self.ends)
        args.update(kw)
        return Clip(**args)

    def resample(self, rate=None, times=None, method="bezier"):
        """The clip at new times: rotations by :func:`quatarray.spline`, translations linearly.

        Parameters
        ----------
        rate : float, optional
            New frames at ``times[0] + k / rate`` up to the last frame.
        times : array_like, optional
            Explicit new times (1-D, strictly increasing: a clip's frames are
            in time order; within the clip's time span).
        method : {"bezier", "slerp", "nlerp", "squad", "cubic"}
            Rotation interpolation (see :func:`quatarray.spline`; it unflips
            each joint's keys). A joint with 1 or 2 rotation channels (a
            hinge) keeps to its axes: its interpolated rotation is taken back
            to them (:func:`few_axes_angles`; a hinge's keys turn about one
            axis, and so does the spline between them, up to rounding).
            Translations of joints with position channels are interpolated
            linearly (the others are their OFFSET).

        Returns
        -------
        Clip
            With ``frame_time`` ``1 / rate`` (or the median step of `times`;
            the clip's own for fewer than two new times). A clip of one
            frame holds still: its span is one instant, and every new time
            there gets that frame (rotations normalised, as ``spline``
            normalises keys). A clip without frames gives one without frames.

        Raises
        ------
        ValueError
            Both or neither of `rate` and `times`, a rate that is not
            positive, `times` that repeat or decrease (the message names the
            first such time) or fall outside the clip's time span, an
            unknown method.

        Examples
        --------
        >>> from quatarray import io
        >>> from quatarray.io import sample_path
        >>> clip = io.read_bvh(sample_path())
        >>> clip.resample(rate=120)
        <Clip: 24 joints (5 end sites), 1816 frames at 120 fps>
        """
        if (rate is None) == (times is None):
            raise ValueError("Expected exactly one of `rate` and `times`.")
        check_method(method)
        t = self.times
        F, J = t.size, len(self.joints)
        if rate is not None:
            rate = float(rate)
            if not (rate > 0 and np.isfinite(rate)):
                raise ValueError(f"Expected a positive `rate`, got {rate}.")
            n = int(np.floor((t[-1] - t[0]) * rate + 1e-9)) + 1 if F else 0
            nt = t[0] + np.arange(n) / rate if F else np.empty(0)
            nt = nt[nt <= t[-1]] if F else nt
            frame_time = 1.0 / rate
        else:
            # a clip's frames are in time order, at one frame time: new times that
            # repeat or go back would give a frame time of 0 or less (BVH refuses it)
            nt = as_times(times, "times").reshape(-1)
            i = first_not_increasing(nt)
            if i is not None:
                err = not_increasing("times", i, nt[i], nt[i + 1])
                raise ValueError(f"{err} A clip's frames are in time order.")
            frame_time = float(np.median(np.diff(nt))) if nt.size > 1 else self.frame_time
        if F == 0:  # no frames: no time span, nothing to interpolate
            if nt.size:
                raise ValueError(f"Expected no new times for a clip without frames, got {nt.size}.")
            return self.replace(frame_time=frame_time, times=np.empty(0))
        # the time plan once for every joint (spline's checks and conversion; the
        # span check of a 1-frame clip: new times at its one instant only)
        t, nt = plan_times(key_times(t, F), nt)
        nt = np.ascontiguousarray(nt, dtype=np.float64)
        cols = [j for j in range(J) if self.orders[j]]
        rot = np.empty((nt.size, J, 4))
        trans = np.empty((nt.size, J, 3))
        trans[:] = self.offsets
        pj = self.positional()
        if F == 1:  # one frame: it holds still (each new frame is that frame, normalised as spline's keys)
            rot[:] = normalize(self.rotations[0])
            trans[:, pj] = self.translations[0, pj]
            return self.replace(rotations=rot, translations=trans, frame_time=frame_time, times=nt)
        for j in range(J):
            if not self.orders[j]:  # no rotation channels: the clip's constant rotation (the identity)
                rot[:, j] = normalize(self.rotations[0, j])
        if cols:  # every joint as spline(t, rotations[:, j], nt, method)
            big = nt.size * len(cols) >= LANES_MIN_SAMPLES
            (resample_streams if big else resample_each)(t, nt, self.rotations, cols, method, rot)
            few = [j for j in cols if len(self.orders[j]) < 3]
            if few:  # a joint of 1 or 2 rotation channels keeps to its axes (a hinge stays a hinge)
                from .euler import from_euler

                for j in few:
                    rot[:, j] = from_euler(self.orders[j], few_axes_angles(rot[:, j], self.orders[j]))
        if pj:
            k = np.clip(np.searchsorted(t, nt, side="right") - 1, 0, max(t.size - 2, 0))
            k1 = np.minimum(k + 1, t.size - 1)
            h = t[k1] - t[k]
            u = np.divide(nt - t[k], h, out=np.zeros_like(nt), where=h > 0)[:, None, None]
            tp = self.translations[:, pj]  # (F, P, 3): only the joints that move
            trans[:, pj] = (1.0 - u) * tp[k] + u * tp[k1]
        return self.replace(rotations=rot, translations=trans, frame_time=frame_time, times=nt)

    def tree(self):
        """The hierarchy as indented text lines: name, channel order (and position channels).

        Examples
        --------
        >>> from quatarray import io
        >>> from quatarray.io import sample_path
        >>> print("\\n".join(io.read_bvh(sample_path()).tree()[:3]))
        Hips  ZXY + XYZ position
          Chest  ZXY
            Chest2  ZXY
        """
        depth = np.zeros(len(self.joints), np.int64)
        lines = []
        for j, name in enumerate(self.joints):
            p = self.parents[j]
            depth[j] = 0 if p < 0 else depth[p] + 1
            pos = "".join(c[0].upper() for c in self.channels[j] if c.lower().endswith("position"))
            what = "end site" if self.ends[j] else (self.orders[j] or "no rotation")
            if pos:
                what += f" + {pos} position"
            lines.append(f"{'  ' * depth[j]}{name}  {what}")
        return lines


def order_of(channels):
    """The intrinsic Euler sequence of a joint's rotation channels (``"ZXY"``), ``""`` if it has none.

    Examples
    --------
    >>> from quatarray.skeleton import order_of
    >>> order_of(["Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"])
    'ZXY'
    """
    return "".join(c[0].upper() for c in channels if c.lower().endswith("rotation"))


def few_axes_angles(q, order):
    """Intrinsic angles (radians) of rotations about the 1 or 2 axes of `order`, as a
    BVH joint with 1 or 2 rotation channels holds them: exact for rotations those axes
    make (q = A(a) or q = A(a) B(b)), the nearest such rotation's for others in the
    sense below.

    One axis (a hinge): a = 2 atan2(q_A, q_w), the twist of q about e_A (the rotation
    about e_A nearest to q). Two axes: B(b) keeps e_B, so a turns e_B about e_A to
    where q puts it, as nearly as it can (a = atan2(s q e_B · e_C, q e_B · e_B), with
    e_A × e_B = s e_C); b is then the twist about e_B of A(a)⁻¹ q. Angles in
    [−π, π).

    Parameters
    ----------
    q : array_like, shape (N, 4)
        Quaternions (normalised here).
    order : str
        One or two distinct axes of ``"XYZ"`` (intrinsic).

    Returns
    -------
    ndarray, shape (N, len(order))

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> from quatarray.skeleton import few_axes_angles
    >>> q = qa.from_euler("YX", [[30, -40]], degrees=True)
    >>> np.degrees(few_axes_angles(q, "YX")).round(9)
    array([[ 30., -40.]])
    """
    from .vectors import rotate

    q = normalize(np.asarray(q, dtype=np.float64).reshape(-1, 4))
    iA = AXES.index(order[0])
    if len(order) == 1:
        ang = (2.0 * np.arctan2(q[:, 1 + iA], q[:, 0]))[:, None]
    else:
        iB = AXES.index(order[1])
        iC = 3 - iA - iB
        s = 1.0 if (iB - iA) % 3 == 1 else -1.0
        v = rotate(q, np.broadcast_to(np.eye(3)[iB], (len(q), 3)))  # B(b) keeps e_B: q e_B = A(a) e_B
        a = np.arctan2(s * v[:, iC], v[:, iB])
        undo = np.zeros((len(q), 4))
        undo[:, 0], undo[:, 1 + iA] = np.cos(a / 2), -np.sin(a / 2)  # A(a)⁻¹
        rest = multiply(undo, q)
        ang = np.column_stack([a, 2.0 * np.arctan2(rest[:, 1 + iB], rest[:, 0])])
    return (ang + np.pi) % (2 * np.pi) - np.pi
