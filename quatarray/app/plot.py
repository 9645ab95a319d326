"""``quatarray plot``: draw a rotation stream as a person wants to see it.

Three panels over time: Euler angles (the file's own sequence for BVH,
otherwise intrinsic ``ZYX`` yaw/pitch/roll; unwrapped so a turn past 180°
stays continuous), the rotation angle from the first sample, and the angular
speed. Given a second, resampled stream (``after=``), both are drawn: the
original keys as dots, the resampled curve as a line.

Needs matplotlib (the optional ``plot`` extra); without it
:func:`plot_file` prints a one-line message and returns 2.
"""

import os
import sys

import numpy as np

MAX_POINTS = 20_000  # longer streams are thinned (every k-th row) for drawing
MISSING = "quatarray plot needs matplotlib (pip install matplotlib)"


def have_matplotlib():
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return False
    return True


def _read(path, fmt="auto", layout=None, joint=None, chunk=None, on_invalid="error"):
    """Times (or None), quaternions and a description of a stream file, thinned to ≤ MAX_POINTS rows."""
    from .. import io

    kw = dict(fmt=fmt, layout=layout, joint=joint, on_invalid=on_invalid)
    if chunk:
        kw["chunk"] = chunk
    reader = io.open_stream(path, **kw)
    step = 1
    if reader.rows and reader.rows > MAX_POINTS:
        step = -(-reader.rows // MAX_POINTS)
    ts, qs, seen = [], [], 0
    for c in reader:
        # keep rows whose global index is a multiple of step
        first = (-seen) % step
        idx = slice(first, None, step)
        seen += len(c)
        qs.append(np.asarray(c.data[idx], dtype=np.float64))
        if c.t is not None:
            ts.append(np.asarray(c.t[idx], dtype=np.float64))
    q = np.concatenate(qs) if qs else np.empty((0, 4))
    t = np.concatenate(ts) if ts else None
    if reader.kind != "quat":
        raise io.DataError(f"{path}: plot draws rotation streams, this file holds vectors")
    seq = getattr(reader, "seq", None)
    what = f"{path}" + (f" (joint {reader.joint})" if getattr(reader, "joint", None) else "")
    return t, q, seq, what, step


def _curves(t, q, seq, rate=None):
    """Euler angles (deg, unwrapped), angle from the first sample (deg) and angular speed (deg/s)."""
    import quatarray as qa

    q = qa.normalize(q) if len(q) else q  # (signs do not matter: Euler angles and distances ignore them)
    if t is None:
        t = np.arange(len(q)) / (rate or 1.0)
    ok = np.isfinite(q).all(axis=1)
    eul = np.full((len(q), 3), np.nan)
    if ok.any():
        eul[ok] = np.unwrap(qa.as_euler(q[ok], seq, degrees=True, suppress_warnings=True), period=360, axis=0)
    ang = np.degrees(qa.distance(q[:1], q)) if len(q) else np.empty(0)
    speed = np.full(len(q), np.nan)
    if len(q) > 1:
        dt = np.diff(t)
        step = np.degrees(qa.distance(q[:-1], q[1:]))
        with np.errstate(divide="ignore", invalid="ignore"):
            mid = step / dt
        speed[1:] = mid  # speed over (t[i-1], t[i]], drawn at t[i]
    return t, eul, ang, speed


def plot_streams(out_png, t, q, seq=None, after=None, title="", labels=("keys", "resampled"), extra=None):
    """Draw one stream, or keys and a resampled stream, into ``out_png``.

    Parameters
    ----------
    out_png : str
        The image to write; its extension names the format (``.png``, ``.pdf``, ``.svg``, ``.jpg`` …).
    t : ndarray (n,) or None
        Times in seconds (None: row index; the speed is then in degrees per row).
    q : ndarray (n, 4)
        (w, x, y, z) quaternions; normalised and unflipped for drawing.
    seq : str, optional
        Euler sequence for the first panel (default ``"ZYX"``, intrinsic yaw/pitch/roll).
    after : (t2, q2), optional
        A resampled version drawn as a line over the keys (drawn as dots).
    extra : list of (t3, q3, label), optional
        More resampled curves to compare (e.g. slerp beside Bézier), dashed.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    seq = seq or "ZYX"
    # a fourth panel shows how far apart the resampled curves are, where they share times
    pairs = []
    if after is not None:
        for t3, q3, lab in extra or ():
            if len(q3) == len(after[1]) and (t3 is None or after[0] is None or np.array_equal(t3, after[0])):
                pairs.append((q3, lab))
    npanel = 4 if pairs else 3
    fig = Figure(figsize=(11, 8.5 if npanel == 3 else 10.5), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(npanel, 1, sharex=True, height_ratios=[3, 2, 2, 1.5][:npanel])
    colors = ("tab:blue", "tab:orange", "tab:green")
    t0 = 0.0
    if t is not None and len(t) and abs(t[0]) > 1e4:  # epoch timestamps: draw time since the first sample
        t0 = float(t[0])
        t = t - t0
        if after is not None:
            after = (None if after[0] is None else after[0] - t0, after[1])
        extra = [(None if a is None else a - t0, b, c) for a, b, c in extra or ()]
    t1, e1, a1, s1 = _curves(t, q, seq)
    keys_style = dict(ls="", marker="o", ms=2.5) if after is not None else dict(lw=1.2)
    key_label = labels[0] if after is not None else None
    for k in range(3):
        axes[0].plot(t1, e1[:, k], color=colors[k], label=f"{seq[k]} ({key_label})" if key_label else seq[k],
                     **keys_style)
    axes[1].plot(t1, a1, color="black", label=key_label, **keys_style)
    axes[2].plot(t1, s1, color="black", label=key_label, **keys_style)
    curves = []
    if after is not None:
        curves.append((after[0], after[1], labels[1], "-"))
    for t3, q3, lab in extra or ():
        curves.append((t3, q3, lab, "--"))
    for t2, q2, lab, ls in curves:
        t2, e2, a2, s2 = _curves(t2, q2, seq)
        for k in range(3):
            axes[0].plot(t2, e2[:, k], color=colors[k], lw=1.0, ls=ls, alpha=0.9,
                         label=f"{seq[k]} ({lab})" if ls == "-" else None)
        axes[1].plot(t2, a2, lw=1.0, ls=ls, label=lab)
        axes[2].plot(t2, s2, lw=1.0, ls=ls, label=lab)
    if pairs:
        import quatarray as qa

        t2 = after[0] if after[0] is not None else np.arange(len(after[1]))
        if t0 and after[0] is None:
            t2 = t2 - t0
        for q3, lab in pairs:
            axes[3].plot(t2, np.degrees(qa.distance(after[1], q3)), lw=0.9, color="tab:red",
                         label=f"{labels[1]} vs {lab}")
        axes[3].set_ylabel("difference (deg)")
        axes[3].legend(loc="upper right", fontsize=7)
    xlabel = "row" if t is None else ("time (s)" if not t0 else f"time since t0 = {t0:.6f} (s)")
    axes[0].set_ylabel(f"Euler {seq} (deg)")
    axes[1].set_ylabel("angle from first sample (deg)")
    axes[2].set_ylabel("angular speed (deg/s)" if t is not None else "angular speed (deg/row)")
    axes[-1].set_xlabel(xlabel)
    intrinsic = seq.isupper()
    axes[0].set_title(f"Euler angles, {'intrinsic' if intrinsic else 'extrinsic'} {seq}, unwrapped", fontsize=9)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=7, ncol=2 if after is not None else 3)
    if after is not None or extra:
        axes[1].legend(loc="upper right", fontsize=7)
        axes[2].legend(loc="upper right", fontsize=7)
    if title:
        fig.suptitle(title, fontsize=11)
    return _save(fig, out_png)


def _save(fig, out):
    """Write `fig` to `out` in the format its extension names, beside it and renamed:
    a failed run never leaves a partial image."""
    from ..io import Writer

    fmt = image_format(out)
    with Writer(out, suffix=f".{fmt}") as w:
        fig.savefig(w.tmp, format=fmt)
    return out


def image_format(path):
    """The image format OUT's extension names (as matplotlib's ``savefig`` reads it).

    Raises :class:`~quatarray.io.UsageError` for an extension matplotlib does not write.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from ..io import UsageError

    known = FigureCanvasAgg(Figure()).get_supported_filetypes()
    ext = os.path.splitext(os.fspath(path))[1].lower().lstrip(".")
    if ext not in known:
        named = repr("." + ext) if ext else "(none)"
        raise UsageError(f"{path}: cannot tell the image format from the extension {named}; "
                         f"use one of {', '.join('.' + k for k in sorted(known))}")
    return ext


def plot_file(in_path, out_png, fmt="auto", layout=None, joint=None, chunk=None, on_invalid="error",
              after=None, seq=None, stream=None, **_ignored):
    """Draw the stream in ``in_path`` (and, with ``after=``, a resampled version of it) into ``out_png``.

    Parameters
    ----------
    in_path : str
        Any stream ``quatarray`` reads (npy, csv, tum, euroc, parquet, bvh ...).
    out_png : str
        The image to write; its extension names the format (see :func:`image_format`).
    fmt, layout, joint, chunk, on_invalid
        As for the other commands (see ``quatarray --help``).
    after : str, optional
        A second stream (e.g. the output of ``quatarray resample``) drawn over the first.
    seq : str, optional
        Euler sequence for the first panel (default: the BVH joint's own, else ``"ZYX"``).

    Returns
    -------
    int
        0 on success, 2 when matplotlib is missing (a message goes to stderr).
    """
    err = stream or sys.stderr
    if not have_matplotlib():
        print(MISSING, file=err)
        return 2
    image_format(out_png)  # before the reading
    opts = dict(fmt=fmt, layout=layout, joint=joint, chunk=chunk, on_invalid=on_invalid)
    t, q, file_seq, what, step = _read(in_path, **opts)
    if len(q) == 0:
        from ..io import DataError

        raise DataError(f"{in_path}: no rows to plot")
    second = None
    title = what
    if after is not None:
        t2, q2, _, what2, _ = _read(after, fmt="auto", layout=layout, joint=joint, on_invalid=on_invalid)
        second = (t2, q2)
        title = f"{what} (dots) and {what2} (line)"
    if step > 1:
        title += f"  [every {step}th row drawn]"
    plot_streams(out_png, t, q, seq=seq or file_seq, after=second, title=title,
                 labels=("original", "resampled"))
    return 0


def plot_trajectories(out_png, t, p, names, after=None, title="", up=1):
    """World trajectories of a few joints: height over time and the ground-plane path.

    Parameters
    ----------
    out_png : str
    t : ndarray (F,)
        Frame times (s).
    p : ndarray (F, k, 3)
        World positions of the k joints drawn.
    names : list of str
        The k joint names.
    after : (t2, p2), optional
        A resampled version (``(F2, k, 3)``) drawn as lines over the frames (dots).
    up : int
        Index of the vertical axis (BVH: y, 1).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 8), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    ax_h, ax_g = fig.subplots(2, 1, height_ratios=[1, 1.2])
    ground = [k for k in range(3) if k != up]
    for k, name in enumerate(names):
        color = f"C{k}"
        style = dict(ls="", marker="o", ms=2) if after is not None else dict(lw=1.0)
        ax_h.plot(t, p[:, k, up], color=color, label=name, **style)
        ax_g.plot(p[:, k, ground[0]], p[:, k, ground[1]], color=color, label=name, **style)
        if after is not None:
            t2, p2 = after
            ax_h.plot(t2, p2[:, k, up], color=color, lw=0.9)
            ax_g.plot(p2[:, k, ground[0]], p2[:, k, ground[1]], color=color, lw=0.9)
    axis = "XYZ"
    ax_h.set_xlabel("time (s)")
    ax_h.set_ylabel(f"height ({axis[up]}, file units)")
    ax_g.set_xlabel(axis[ground[0]])
    ax_g.set_ylabel(axis[ground[1]])
    ax_g.set_aspect("equal", adjustable="datalim")
    ax_h.set_title("world joint positions: frames (dots), resampled (line)" if after is not None
                   else "world joint positions", fontsize=9)
    for ax in (ax_h, ax_g):
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=7)
    if title:
        fig.suptitle(title, fontsize=11)
    return _save(fig, out_png)
