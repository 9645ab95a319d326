"""The ``quatarray`` command line: batch processing of large rotation streams.

Every verb streams its input chunk by chunk (``--chunk ROWS``), so memory
stays bounded whatever the file size; reading and writing live in
:mod:`quatarray.io`, what a convert or resample job is (targets, new times,
the drivers) in :mod:`quatarray.jobs`, the ``--scheduler`` jobs in
:mod:`quatarray.dask.files`; this module is the argument parsing over them. Exit status: 0 success, 1 bad data, 2 bad usage (an
output that cannot be written, or no memory, included), 128 + N when stopped
by signal N (SIGINT, SIGTERM, SIGHUP: the temporary output is removed).
Errors are one line on stderr naming the file, the line or row and what is
wrong; a user error never prints a traceback. ``convert``, ``resample``,
``unflip`` and ``info`` take several inputs in one process (:func:`_each_input`).
A verb imports only what it needs (no numba for reading and checking rows,
pyarrow for text and parquet only, tqdm for a shown bar only).
"""

import argparse
import contextlib
import importlib
import os
import signal
import sys
import threading

import numpy as np

from .. import jobs
from ..io import DEFAULT_CHUNK, Cleaner, DataError, UsageError, check_output, open_stream, open_writer
from ..io.clean import clean_pair, dots as row_dots, norms as row_norms
from ..io.formats import FORMATS, is_zarr, output_format, plain_number
from ..io.streams import pair_rows, paired
from ..jobs import METHODS, QUAT_FIELDS, TARGETS, library_error, no_rows


# --------------------------------------------------------------------------
# shared pieces


def _open(args, path, kind="quat"):
    return open_stream(
        path, args.format, kind=kind, layout=args.layout, joint=args.joint, chunk=args.chunk,
        on_invalid=args.on_invalid,
    )


class _NoBar:
    """What :func:`_progress` gives when no bar is shown (tqdm is then not imported)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def update(self, n):
        pass


def _progress(args, total, desc):
    show = args.progress if args.progress is not None else sys.stderr.isatty()
    if not show:
        return _NoBar()
    from tqdm import tqdm

    return tqdm(total=total, unit="row", unit_scale=True, desc=desc, file=sys.stderr,
                leave=False, dynamic_ncols=True)


# --------------------------------------------------------------------------
# convert


def prepare_convert(args):
    """Check ``--to`` once, before any input runs (each run makes its own converter)."""
    if not args.scheduler and args.to != "positions":
        jobs.target(args.to, args.degrees)


def cmd_convert(args):
    if args.to == "positions":
        return _clip_positions(args)
    if args.scheduler:
        return _dask_call("convert_file", args.IN, args.OUT, to=args.to, degrees=args.degrees,
                          layout=args.layout or "wxyz", chunk=args.chunk, scheduler=args.scheduler,
                          on_invalid=args.on_invalid, force=args.force)
    fields, core, fn = jobs.target(args.to, args.degrees)
    if args.to != "quat" and output_format(args.OUT) == "tum":
        raise UsageError(f"{args.OUT}: a TUM output holds quaternions only (written qx qy qz qw); --to {args.to} "
                         "cannot go in it: use --to quat, or a .csv, .parquet or .npy output")
    reader = _open(args, args.IN)
    check_output(args.OUT, [args.IN], args.force)
    clean = Cleaner(reader, args.on_invalid)
    with open_writer(args.OUT, fields, core, time=reader.has_time, pos=reader.has_pos) as w, \
            _progress(args, reader.rows, "convert") as bar:
        jobs.convert_stream(reader, clean, fn, w, bar)
    clean.report(sys.stderr)
    jobs.gimbal_note(args.IN, getattr(fn, "locked", 0), sys.stderr)
    return 0


# --------------------------------------------------------------------------
# resample


def prepare_resample(args):
    """What all inputs share, checked before any runs: the new times of ``--times``."""
    args.new_times = jobs.FileTimes.load(args.times) if args.times and not args.scheduler else None


def cmd_resample(args):
    screw = getattr(args, "poses", "linear") == "screw"
    if _is_bvh(args, args.IN) and os.path.splitext(args.OUT)[1].lower() == ".bvh":
        if screw:
            raise UsageError("--poses screw is for pose streams (a position column), not BVH clips")
        return _resample_clip(args)
    if screw and args.scheduler:
        raise UsageError("--poses screw is not available with --scheduler")
    if args.scheduler:
        if args.in_times:
            raise UsageError("--in-times is not available with --scheduler; give --in-rate HZ")
        if args.method in jobs.GLOBAL_METHODS:
            raise UsageError(f"--method {args.method} is not available with --scheduler: its C² spline is one "
                             "system over all keys (Dask's blocks are resampled apart); run without --scheduler")
        return _dask_call("resample_file", args.IN, args.OUT, rate=args.rate, times=args.times,
                          method=args.method, chunk=args.chunk, scheduler=args.scheduler, force=args.force,
                          in_rate=args.in_rate, layout=args.layout, on_invalid=args.on_invalid)
    newt = jobs.new_times(args.rate, args.times, args.new_times)
    reader = _open(args, args.IN)
    jobs.check_key_times(args.IN, reader.has_time, args.in_rate, args.in_times, err=sys.stderr)
    in_times = jobs.FileTimes(args.in_times, "auto", "increasing") if args.in_times and not reader.has_time else None
    check_output(args.OUT, [args.IN] + [f for f in (args.times, args.in_times) if f], args.force)
    if screw and not reader.has_pos:
        raise UsageError(f"--poses screw needs positions: {args.IN} has no position column")
    clean = Cleaner(reader, args.on_invalid, ordered=True)
    with open_writer(args.OUT, QUAT_FIELDS, time=True, pos=reader.has_pos) as w, \
            _progress(args, reader.rows, "resample") as bar:
        jobs.resample_stream(reader, clean, newt, w, args.method, args.chunk, args.in_rate, in_times, bar,
                             poses="screw" if screw else "linear")
    clean.report(sys.stderr)
    return 0


# --------------------------------------------------------------------------
# unflip


def cmd_unflip(args):
    import quatarray as qa

    reader = _open(args, args.IN)
    check_output(args.OUT, [args.IN], args.force)
    clean = Cleaner(reader, args.on_invalid)
    flips = 0
    with open_writer(args.OUT, QUAT_FIELDS, time=reader.has_time, pos=reader.has_pos) as w, \
            _progress(args, reader.rows, "unflip") as bar:
        last = None
        for ch in reader:
            n = len(ch)
            ch = clean(ch)
            if len(ch):
                src = ch.data if last is None else np.concatenate([last[None], ch.data])
                q = qa.unflip(src)
                flips += int(np.count_nonzero(np.signbit(q[:, 0]) != np.signbit(src[:, 0])))
                q = q if last is None else q[1:]
                last = q[-1]
                w.write(q, ch.t, ch.pos)
            bar.update(n)
        if w.rows == 0:
            raise no_rows(args.IN)
    clean.report(sys.stderr)
    return 0


# --------------------------------------------------------------------------
# integrate


def cmd_integrate(args):
    """The orientation stream of an angular-velocity stream, chunk by chunk: each chunk
    continues from the last row of the one before (its time, rate and orientation)."""
    import quatarray as qa

    reader = _open(args, args.IN, kind="rate")
    if not reader.has_time:
        raise UsageError(f"{args.IN}: has no time column; integrate needs the sample times (column t)")
    check_output(args.OUT, [args.IN], args.force)
    clean = Cleaner(reader, args.on_invalid, ordered=True)
    scale = np.pi / 180 if args.degrees else 1.0
    with open_writer(args.OUT, QUAT_FIELDS, time=True) as w, _progress(args, reader.rows, "integrate") as bar:
        last = None  # (time, rate, orientation) of the last row written
        for ch in reader:
            n = len(ch)
            ch = clean(ch)
            bar.update(n)
            if not len(ch):
                continue
            # EuRoC's integer ns give exact steps (rad/ns against them); else seconds
            t, rate = (ch.ns, ch.data * (scale * 1e-9)) if ch.ns is not None else (ch.t, ch.data * scale)
            q0 = None
            if last is not None:
                t, rate, q0 = np.r_[last[0], t], np.r_[last[1][None], rate], last[2]
            try:
                q = qa.integrate_angular_velocity(rate, t, q0=q0, frame=args.frame, hold=args.hold)
            except ValueError as exc:
                raise library_error(args.IN, exc) from None
            q = q if last is None else q[1:]
            last = (t[-1], rate[-1], q[-1])
            w.write(q, ch.t)
        if w.rows == 0:
            raise no_rows(args.IN)
    clean.report(sys.stderr)
    return 0


# --------------------------------------------------------------------------
# paired verbs: rotate, compose


def _run_paired(args, verb, ra, rb, fields, poses, compute):
    """Drive a two-input verb: chunks in step, row pairs checked together, results
    written with the first input's times (else the second's).

    ``compute(a, b, m, buffer)`` returns ``(rows, positions or None)`` for ``m`` rows;
    ``buffer(dtype)`` is where a kernel may write them (an ``.npy`` OUT's next rows).
    """
    check_output(args.OUT, [ra.name, rb.name], args.force)
    ca, cb = Cleaner(ra, args.on_invalid), Cleaner(rb, args.on_invalid)
    tsrc = ra if ra.has_time else (rb if rb.has_time else None)
    total = ra.rows if ra.rows not in (None, 1) else rb.rows
    with open_writer(args.OUT, fields, time=tsrc is not None, pos=poses) as w, \
            _progress(args, total, verb) as bar:
        for a, b, n in paired(ra, rb, args.chunk):
            a, b = clean_pair(ca, cb, a, b)
            m = pair_rows(a, b)
            if m:
                out, pos = compute(a, b, m, lambda dtype: w.buffer(m, dtype))
                t = None
                if tsrc is not None:
                    t = np.broadcast_to((a if tsrc is ra else b).t, (m,))
                w.write(out, t, pos)
            bar.update(n)
        if w.rows == 0:
            raise no_rows(ra.name)
    ca.report(sys.stderr)
    cb.report(sys.stderr)
    return 0


def cmd_rotate(args):
    import quatarray as qa

    rq, rv = _open(args, args.QUATS), _open(args, args.VECTORS, kind="vector")

    def compute(a, b, m, buffer):
        return qa.rotate(a.data, b.data, out=buffer(np.result_type(a.data, b.data))), None

    return _run_paired(args, "rotate", rq, rv, ["x", "y", "z"], False, compute)


def cmd_compose(args):
    import quatarray as qa

    ra, rb = _open(args, args.A), _open(args, args.B)
    poses = ra.has_pos or rb.has_pos

    def compute(a, b, m, buffer):
        if not poses:
            return qa.multiply(a.data, b.data, out=buffer(np.result_type(a.data, b.data))), None
        # a pose is a VQS with s = 1: (v_a, q_a) ∘ (v_b, q_b) = (v_a + q_a v_b q_a⁻¹, q_a q_b)
        va = a.pos if a.pos is not None else np.zeros((len(a), 3))
        vb = b.pos if b.pos is not None else np.zeros((len(b), 3))
        ab = qa.VQS(va, a.data, np.ones(len(a))) @ qa.VQS(vb, b.data, np.ones(len(b)))
        return np.broadcast_to(ab.q, (m, 4)), np.broadcast_to(ab.v, (m, 3))

    return _run_paired(args, "compose", ra, rb, QUAT_FIELDS, poses, compute)


# --------------------------------------------------------------------------
# info


def cmd_info(args):
    reader = _open(args, args.IN)
    n = bad = flips = 0
    first_bad = None
    nmin, nmax, nsum = np.inf, -np.inf, 0.0
    t_first = t_last = None
    dt_min, dt_max, back = np.inf, -np.inf, 0
    last_q = None
    dtype = None
    with _progress(args, reader.rows, "info") as bar:
        for ch in reader:
            k = len(ch)
            if not k:
                continue
            dtype = dtype or ch.data.dtype
            norms = row_norms(ch.data) if reader.kind == "quat" else np.linalg.norm(ch.data, axis=1)
            good = np.isfinite(norms) & (norms > 0)
            if ch.t is not None:
                good &= np.isfinite(ch.t)
            if not good.all():
                bad += int(k - np.count_nonzero(good))
                if first_bad is None:
                    i = int(np.argmin(good))
                    first_bad = reader.where(ch.row0 + i)
            g = norms[good]
            if g.size:
                nmin, nmax, nsum = min(nmin, g.min()), max(nmax, g.max()), nsum + float(g.sum())
            q = ch.data[good]
            if len(q):
                src = q if last_q is None else np.concatenate([last_q[None], q])
                flips += int(np.count_nonzero(row_dots(src[1:], src[:-1]) < 0))
                last_q = q[-1]
            if ch.t is not None:
                t = ch.t[good]
                if t.size:
                    tt = t if t_last is None else np.concatenate([[t_last], t])
                    if tt.size > 1:
                        d = np.diff(tt)
                        dt_min, dt_max = min(dt_min, d.min()), max(dt_max, d.max())
                        back += int(np.count_nonzero(d <= 0))
                    t_first = t[0] if t_first is None else t_first
                    t_last = t[-1]
            n += k
            bar.update(k)
    ok = n - bad
    lines = [
        ("file", args.IN),
        ("format", reader.format),
        ("rows", f"{n}" + (f" ({reader.skipped} unparsable rows skipped)" if reader.skipped else "")),
        ("columns", " ".join(str(c) for c in reader.columns)),
        ("layout", f"{reader.layout}" + (" → read as (w, x, y, z)" if reader.kind == "quat" else "")),
        ("dtype", str(dtype)),
    ]
    if getattr(reader, "joint", None):
        others = ", ".join(reader.joints[:8]) + (f", … ({len(reader.joints)} in all)" if len(reader.joints) > 8 else "")
        lines.append(("joint", f"{reader.joint} (joints: {others}; choose with --joint)"))
    if reader.has_time and t_first is not None:
        span = float(t_last - t_first)
        lines.append(("time", f"{plain_number(t_first)} .. {plain_number(t_last)} s (span {span:.6g} s)"))
        if not np.isfinite(dt_min):  # no step: a single timed row
            lines.append(("rate", "- (one row)"))
        else:
            mean = f"{(ok - 1) / span:.6g} Hz mean" if span > 0 else "- (no time elapses)"
            lines.append(("rate", f"{mean}; step min {dt_min:.6g} s, max {dt_max:.6g} s"
                          + (f"; {back} steps not increasing" if back else "; strictly increasing")))
    else:
        lines.append(("time", "none (no time column)"))
    lines.append(("position", "x y z" if reader.has_pos else "none"))
    if ok:
        lines.append(("norm", f"min {nmin:.9g}, max {nmax:.9g}, mean {nsum / ok:.9g}, "
                      f"largest | |q| - 1 | {max(abs(nmin - 1), abs(nmax - 1)):.3g}"))
    lines.append(("sign flips", f"{flips} (consecutive rows with q·q_prev < 0)"))
    lines.append(("invalid rows", f"{bad}" + (f" (first at {first_bad})" if first_bad else "")))
    width = max(len(k) for k, _ in lines)
    if getattr(args, "gap", False):
        print()
    for k, v in lines:
        print(f"{k + ':':<{width + 1}} {v}")
    if reader.format == "bvh":
        _clip_tree(args)
    reader.say(sys.stderr)
    return 0


# --------------------------------------------------------------------------
# whole BVH clips (every joint): resample BVH -> BVH, convert --to positions, info's tree


def _is_bvh(args, path):
    from ..io.formats import by_extension

    return args.format == "bvh" or (args.format == "auto" and by_extension(path) == "bvh")


def _read_clip(args):
    from ..io import read_bvh

    if not _is_bvh(args, args.IN):
        raise UsageError(f"{args.IN}: a whole clip is read from a BVH file")
    return read_bvh(args.IN)


def _resample_clip(args):
    if args.scheduler or args.in_rate is not None or args.in_times:
        raise UsageError("a BVH clip is resampled in memory: --scheduler, --in-rate and --in-times do not apply")
    from ..io import write_bvh

    check_output(args.OUT, [args.IN] + ([args.times] if args.times else []), args.force)
    clip = _read_clip(args)
    times = None
    if args.times:
        times = jobs.FileTimes(args.times, "auto").times
    try:
        out = clip.resample(rate=args.rate, times=times, method=args.method)
    except ValueError as exc:
        raise library_error(args.times or args.IN, exc) from None
    write_bvh(args.OUT, out)
    return 0


def _clip_positions(args):
    from ..io.bvh import write_positions

    check_output(args.OUT, [args.IN], args.force)
    clip = _read_clip(args)
    write_positions(args.OUT, clip)
    return 0


def _clip_tree(args):
    clip = _read_clip(args)
    print(f"hierarchy: {len(clip.joints)} joints ({int(clip.ends.sum())} end sites, "
          f"{int((clip.parents < 0).sum())} root{'s' if (clip.parents < 0).sum() != 1 else ''}), "
          "channel order (intrinsic Euler) of each")
    for line in clip.tree():
        print(f"  {line}")


# several inputs in one process: convert, resample, unflip, info


def _folder_form(args):
    """Whether OUT is a folder for the outputs (several inputs, ``--ext``, an existing
    folder or a trailing ``/``) rather than the output file of one input."""
    out = getattr(args, "OUT", None)
    if out is None:  # info
        return len(args.IN) > 1
    return (len(args.IN) > 1 or args.ext is not None or out.endswith(("/", os.sep))
            or (os.path.isdir(out) and not is_zarr(out)))


def _plan(args):
    """The ``(IN, OUT)`` pairs of one run: each output is ``OUT/<input's stem><ext>``.

    What would refuse the run as a whole is a usage error raised here, before any
    input runs: OUT a file, an extension that names no output format, two inputs
    with the same output, an output that would be one of the inputs.
    """
    if not hasattr(args, "OUT"):  # info
        return [(src, None) for src in args.IN]
    folder = args.OUT
    if os.path.exists(folder) and (not os.path.isdir(folder) or is_zarr(folder)):
        raise UsageError(f"{folder}: not a folder; with several inputs (or --ext) OUT is the folder "
                         "the outputs are written to")
    ext = None if args.ext is None else "." + args.ext.lstrip(".")
    inputs = list(args.IN) + ([args.times] if getattr(args, "times", None) else [])
    pairs, seen = [], {}
    for src in args.IN:
        stem, own = os.path.splitext(os.path.basename(os.path.normpath(src)))
        dst = os.path.join(folder, stem + (_default_ext(args, src, own) if ext is None else ext))
        _check_output_kind(args, src, dst)
        key = os.path.normcase(os.path.abspath(dst))
        if key in seen:
            raise UsageError(f"{seen[key]} and {src} would both be written to {dst}; "
                             "give them separate runs (or folders)")
        seen[key] = src
        if os.path.isdir(folder):  # else nothing in it can be an input
            check_output(dst, inputs, force=True)
        pairs.append((src, dst))
    return pairs


def _default_ext(args, src, own):
    """The extension of an input's output in the OUT folder without ``--ext``: the
    input's own, but for a BVH input that of what the verb writes of it: a BVH for
    ``resample`` (the whole clip), ``.npy`` for ``convert --to positions`` (the
    (F, J, 3) array), ``.csv`` for the others (the root joint's stream, with times)."""
    if not _is_bvh(args, src):
        return own
    if args.verb == "resample":
        return ".bvh"
    return ".npy" if getattr(args, "to", None) == "positions" else ".csv"


def _check_output_kind(args, src, dst):
    """The usage error for an output that cannot hold what the verb writes of `src`:
    a ``.bvh`` output is a whole clip (``resample`` of a BVH input only); positions
    go to ``.npy``, ``.csv`` or ``.parquet``; else an extension of a stream writer."""
    if os.path.splitext(dst)[1].lower() == ".bvh":
        if args.verb == "resample" and _is_bvh(args, src):
            return
        raise UsageError(f"{dst}: a BVH output holds a whole clip, written by resample of a BVH input only; "
                         "use --ext npy, csv or parquet")
    fmt = output_format(dst)
    if getattr(args, "to", None) == "positions" and fmt not in ("npy", "csv", "parquet"):
        raise UsageError(f"{dst}: positions are written as .npy, .csv or .parquet")


def _each_input(args):
    """Run the verb on every input in turn, in this one process. A failed input is
    reported in its one line and the others still run; exit 1 if any failed."""
    pairs = _plan(args)
    if pairs[0][1] is not None:
        os.makedirs(args.OUT, exist_ok=True)
    failed = 0
    for k, (src, dst) in enumerate(pairs):
        one = argparse.Namespace(**vars(args))
        one.IN = src
        if dst is not None:
            one.OUT = dst
        one.gap = k > failed  # info: a blank line between the files' blocks
        try:
            failed += int(args.func(one) or 0) != 0
        except BrokenPipeError:
            raise
        except (UsageError, DataError, OSError) as exc:
            _, line = _complaint(args.verb, exc)
            if src not in line and (dst is None or dst not in line):
                line = f"{src}: {line}"
            print(line, file=sys.stderr)
            failed += 1
    if failed and len(pairs) > 1:
        print(f"quatarray {args.verb}: {failed} of {len(pairs)} inputs failed", file=sys.stderr)
    return 1 if failed else 0


def _run(args):
    """The verb on its inputs: one IN (and OUT file) as given, or :func:`_each_input`."""
    prepare = getattr(args, "prepare", None)
    if prepare is not None:
        prepare(args)
    if not isinstance(getattr(args, "IN", None), list):
        return int(args.func(args) or 0)
    if _folder_form(args):
        return _each_input(args)
    args.IN = args.IN[0]
    return int(args.func(args) or 0)


# The exit status of each kind of user error the library raises (quatarray.io.errors;
# OutputError is a UsageError); a failed file operation (OSError) is 1.
EXIT_STATUS = {UsageError: 2, DataError: 1}


def _complaint(verb, exc):
    """``(exit status, the one line for stderr)`` of a user error or a failed file operation."""
    status = next((s for cls, s in EXIT_STATUS.items() if isinstance(exc, cls)), 1)
    if isinstance(exc, UsageError):
        return status, f"quatarray {verb}: error: {exc}"
    if isinstance(exc, DataError):
        return status, str(exc)
    where = f"{exc.filename}: " if exc.filename else ""
    return status, f"quatarray {verb}: error: {where}{exc.strerror or exc}"


# --------------------------------------------------------------------------
# verbs written in other modules


def _optional(module, what):
    try:
        return importlib.import_module(f"quatarray.{module}")
    except ModuleNotFoundError as exc:
        if exc.name == f"quatarray.{module}":
            raise UsageError(f"{what} is not available in this installation (no quatarray.{module})") from None
        raise UsageError(f"{what} needs the package {exc.name!r}: pip install {exc.name}") from None


def _dask_call(fn, *a, **kw):
    getattr(_optional("dask", "--scheduler"), fn)(*a, **kw)
    return 0


def cmd_demo(args):
    return int(_optional("app.demo", "demo").run(out_dir=args.out) or 0)


def cmd_bench(args):
    if args.n is not None and args.n < 1:
        raise UsageError(f"--n must be positive, got {args.n}")
    return int(_optional("app.bench", "bench").run(n=args.n, json_path=args.json) or 0)


def cmd_eval(args):
    return int(_optional("app.eval_verb", "eval").run(
        args.REF, args.EST, metric=args.metric, align=args.align, relation=args.pose_relation,
        delta=args.delta, delta_unit=args.delta_unit,
        all_pairs=args.all_pairs, n_to_align=args.n_to_align, t_max_diff=args.t_max_diff,
        t_offset=args.t_offset, interpolate=(args.interpolate_rule or "evo") if (args.interpolate or args.interpolate_rule) else None, out=args.out, plot_path=args.plot,
        json_path=args.json, fmt=args.format, layout=args.layout, chunk=args.chunk,
        on_invalid=args.on_invalid, force=args.force) or 0)


def cmd_warmup(args):
    from .._warmup import warmup

    summary = warmup(dtype=args.dtype, verbose=sys.stderr.isatty())
    print(summary.table())
    return 1 if summary.failed else 0


def cmd_plot(args):
    mod = _optional("app.plot", "plot")
    if args.seq is not None:
        jobs.euler_seq(args.seq, f"--seq {args.seq}", "--seq ZXY")
    check_output(args.OUT, [args.IN] + ([args.after] if args.after else []), args.force)
    extra = {k: v for k, v in (("after", args.after), ("seq", args.seq)) if v is not None}
    return int(
        mod.plot_file(args.IN, args.OUT, fmt=args.format, layout=args.layout, joint=args.joint,
                      chunk=args.chunk, on_invalid=args.on_invalid, **extra) or 0
    )


# --------------------------------------------------------------------------
# argument parsing


def _row_count(s):
    try:
        v = int(float(s)) if "e" in s.lower() else int(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number of rows, got {s!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected at least 1 row, got {v}")
    return v


def _positive(s):
    try:
        v = float(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {s!r}") from None
    if not (v > 0 and np.isfinite(v)):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {s!r}")
    return v


SEVERAL = ("With several inputs (IN... OUT) OUT is a folder, created if missing; each output keeps its "
           "input's name, with the extension of --ext (default: the input's own; for a BVH input .bvh from "
           "resample, .npy from convert --to positions, else .csv). A failed input is reported "
           "by name and the others still run (exit 1 if any failed).")


def _in_out(s):
    s.add_argument("IN", nargs="+", help="input stream(s)")
    s.add_argument("OUT", help="output file, or the folder for the outputs of several inputs")
    s.add_argument("--ext", metavar="EXT",
                   help="extension (format) of the outputs in the OUT folder: npy, csv, parquet, txt, bvh "
                        "(resample of BVH inputs) (default: each input's own; see above for BVH inputs)")


def build_parser():
    io_opts = argparse.ArgumentParser(add_help=False)
    g = io_opts.add_argument_group("input and output")
    g.add_argument("--format", choices=FORMATS, default="auto",
                   help="input format (default: by extension and header)")
    g.add_argument("--layout", choices=("wxyz", "xyzw"), default=None,
                   help="quaternion column order of inputs without named columns (npy, headerless text; "
                        "default wxyz, said on stderr): 8 headerless numbers a row are t x y z qw qx qy qz "
                        "with commas and TUM's t x y z qx qy qz qw with spaces; --layout or --format tum "
                        "chooses")
    g.add_argument("--joint", metavar="NAME", help="BVH joint to read (default: the root)")
    g.add_argument("--chunk", type=_row_count, default=DEFAULT_CHUNK, metavar="ROWS",
                   help=f"rows per chunk (default {DEFAULT_CHUNK})")
    g.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="progress bar on stderr (default: when stderr is a terminal)")
    g.add_argument("--on-invalid", choices=("error", "drop"), default="error",
                   help="bad rows stop the run (default) or are dropped and counted")
    g.add_argument("--force", action="store_true", help="overwrite OUT if it exists")

    p = argparse.ArgumentParser(
        prog="quatarray",
        description="Batch processing of large rotation streams: convert, clean, resample, rotate, compose.",
        epilog="Quaternions are (w, x, y, z). Exit status: 0 ok, 1 bad data, 2 bad usage or unwritable output, "
               "128 + N on signal N (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP). "
               "Formats: npy, csv (named columns t, x y z, qw qx qy qz), tum, euroc, kitti, parquet, bvh.",
    )
    from .. import __version__

    p.add_argument("--version", action="version", version=f"quatarray {__version__}")
    sub = p.add_subparsers(dest="verb", metavar="VERB")

    s = sub.add_parser("demo", help="the main job end to end on a packaged sample")
    s.add_argument("--out", metavar="DIR", default=None, help="output folder (default: a new folder here)")
    s.set_defaults(func=cmd_demo)

    s = sub.add_parser("info", parents=[io_opts], help="rows, columns, times, norms and sign flips of a stream")
    s.add_argument("IN", nargs="+", help="one or more streams, each reported under its name")
    s.set_defaults(func=cmd_info)

    s = sub.add_parser("convert", parents=[io_opts], help="convert quaternions to another representation",
                       description=f"Targets: {TARGETS}. {SEVERAL}")
    _in_out(s)
    s.add_argument("--to", required=True, metavar="TARGET", help=TARGETS)
    s.add_argument("--degrees", action="store_true", help="angles in degrees (rotvec, axis-angle, euler)")
    s.add_argument("--scheduler", metavar="ADDRESS|local", help="run on a Dask cluster (needs dask)")
    s.set_defaults(func=cmd_convert, prepare=prepare_convert)

    s = sub.add_parser("resample", parents=[io_opts], help="resample a timestamped stream (Shoemake's Bézier)",
                       description=SEVERAL)
    _in_out(s)
    m = s.add_mutually_exclusive_group(required=True)
    m.add_argument("--rate", type=_positive, metavar="HZ", help="new times t0 + k/HZ up to the last key")
    m.add_argument("--times", metavar="FILE", help="new times from a file (npy, one per line, or a stream)")
    s.add_argument("--method", choices=METHODS, default="bezier",
                   help="interpolation (default bezier); cubic is scipy's RotationSpline (C², one system over all "
                        "keys: the keys are held in memory, 40-64 bytes each; not with --scheduler)")
    s.add_argument("--poses", choices=("linear", "screw"), default="linear",
                   help="with a position column: linear positions between the two keys around each new time, "
                        "rotations by --method (default), or screw: rotation and position together by "
                        "screw linear interpolation (ScLERP) between those keys")
    k = s.add_mutually_exclusive_group()
    k.add_argument("--in-rate", type=_positive, metavar="HZ",
                   help="sampling rate of an input without a time column (row i is at i/HZ s)")
    k.add_argument("--in-times", metavar="FILE",
                   help="key times of an input without a time column, one a line (as KITTI's times.txt): "
                        "as many as its rows, strictly increasing")
    s.add_argument("--scheduler", metavar="ADDRESS|local", help="run on a Dask cluster (needs dask)")
    s.set_defaults(func=cmd_resample, prepare=prepare_resample)

    s = sub.add_parser("unflip", parents=[io_opts], help="make the quaternion signs continuous",
                       description=SEVERAL)
    _in_out(s)
    s.set_defaults(func=cmd_unflip)

    s = sub.add_parser("rotate", parents=[io_opts], help="rotate vectors by quaternions, row by row")
    s.add_argument("QUATS")
    s.add_argument("VECTORS")
    s.add_argument("OUT")
    s.set_defaults(func=cmd_rotate)

    s = sub.add_parser("compose", parents=[io_opts], help="compose two rotation (or pose) streams, A∘B")
    s.add_argument("A")
    s.add_argument("B")
    s.add_argument("OUT")
    s.set_defaults(func=cmd_compose)

    s = sub.add_parser("integrate", parents=[io_opts], help="integrate an angular-velocity stream to orientations",
                       description="IN: csv/parquet with columns t, wx wy wz (rad/s), or an EuRoC IMU file "
                                   "(#timestamp [ns], w_RS_S_x [rad s^-1], ...). OUT: t, qw qx qy qz from the "
                                   "identity; each step applies the exact exponential of its held rate.")
    s.add_argument("IN")
    s.add_argument("OUT")
    s.add_argument("--frame", choices=("space", "body"), default="space",
                   help="axes of the rates: the fixed frame (space, default) or the moving one (body, an IMU's)")
    s.add_argument("--hold", choices=("mean", "start"), default="mean",
                   help="rate held over a step: the mean of its two samples (default) or the first one")
    s.add_argument("--degrees", action="store_true", help="rates in degrees per second")
    s.set_defaults(func=cmd_integrate)

    s = sub.add_parser("bench", help="side-by-side throughput against scipy and friends")
    s.add_argument("--n", type=_row_count, default=None, metavar="N", help="batch size")
    s.add_argument("--json", metavar="FILE", help="also write the figures as JSON")
    s.set_defaults(func=cmd_bench)

    s = sub.add_parser("eval", parents=[io_opts], help="compare an estimated pose stream with a reference (APE, RPE) as evo does",
                       description="Pose arrays (.npy/.zarr of floats, (N, 8) rows t x y z qw qx qy qz, or (N, 7) "
                                   "without t) are read as pose streams too. Association: nearest times (evo's "
                                   "--sync_method nearest_time), or --interpolate: evo's --sync_method interpolation "
                                   "(rule evo, the default: the stream with more poses resampled by slerp and lerp at "
                                   "the matched times of the other, so the pairs are the nearest-time ones) or rule "
                                   "spline (the estimate resampled by quatarray's Bezier spline at every reference "
                                   "time inside its span).")
    s.add_argument("REF")
    s.add_argument("EST")
    s.add_argument("--metric", choices=("ape", "rpe"), default="ape", help="absolute or relative pose error (default ape)")
    s.add_argument("--align", choices=("none", "se3", "sim3", "scale"), default="none",
                   help="Umeyama alignment of the estimate (default none)")
    s.add_argument("--pose-relation", choices=("trans", "rot", "full"), default="trans",
                   help="translation (m), rotation angle (deg) or full pose ‖E − I‖ (default trans)")
    s.add_argument("--delta", type=_positive, default=1, metavar="N", help="RPE pair distance (default 1)")
    s.add_argument("--delta-unit", choices=("frames", "m", "s"), default="frames", help="unit of --delta")
    s.add_argument("--all-pairs", action="store_true", help="RPE on all pairs, not consecutive ones")
    s.add_argument("--n-to-align", type=_row_count, metavar="N", help="fit the alignment on the first N poses")
    s.add_argument("--t-max-diff", type=_positive, default=0.01, metavar="S",
                   help="largest time difference of an associated pair (default 0.01 s)")
    s.add_argument("--t-offset", type=float, default=0.0, metavar="S", help="added to the estimate's times")
    s.add_argument("--interpolate", action="store_true",
                   help="resample one stream at the other's times instead of nearest pairs, by --interpolate-rule; "
                        "needs times")
    s.add_argument("--interpolate-rule", choices=("evo", "spline"), default=None, metavar="RULE",
                   help="evo (the default: evo's --sync_method interpolation, the stream with more poses by slerp "
                        "at the other's matched times) or spline (the estimate by the Bezier spline at every "
                        "reference time in its span); implies --interpolate")
    s.add_argument("--out", metavar="ERRORS",
                   help="per-pose errors with times (csv, parquet; .npy: the errors alone, shape (N,))")
    s.add_argument("--plot", metavar="OUT.png",
                   help="errors over time and the (aligned) trajectories; the extension names the format "
                        "(.png, .pdf, .svg …; needs matplotlib)")
    s.add_argument("--json", metavar="FILE", help="the statistics as JSON")
    s.set_defaults(func=cmd_eval)

    s = sub.add_parser("warmup", help="compile every kernel into the on-disk cache (images, CI, clusters)")
    s.add_argument("--dtype", choices=("float64", "float32", "all"), default="all",
                   help="float types to compile for (default all)")
    s.set_defaults(func=cmd_warmup)

    s = sub.add_parser("plot", parents=[io_opts], help="draw a stream (needs matplotlib)")
    s.add_argument("IN")
    s.add_argument("OUT", metavar="OUT.png", help="the image; its extension names the format (.png, .pdf, .svg …)")
    s.add_argument("--after", metavar="FILE", help="a second stream (e.g. resampled) drawn over IN")
    s.add_argument("--seq", metavar="SEQ", help="Euler sequence of the angle panel (default: the BVH's own, else ZYX)")
    s.set_defaults(func=cmd_plot)
    return p


class _Signalled(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised where the program is, as Ctrl-C raises KeyboardInterrupt:
    the writers' ``with`` blocks remove their temporary files on the way out."""

    def __init__(self, signum):
        super().__init__(signum)
        self.signum = signum


@contextlib.contextmanager
def _signals_interrupt():
    """Within: SIGTERM and SIGHUP raise :class:`_Signalled` (unless ignored, e.g. under nohup)."""
    def handler(signum, frame):
        raise _Signalled(signum)

    previous = {}
    if threading.current_thread() is threading.main_thread():  # signal.signal works there only
        for sig in (signal.SIGTERM, signal.SIGHUP):
            if signal.getsignal(sig) is not signal.SIG_IGN:
                previous[sig] = signal.signal(sig, handler)
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def main(argv=None):
    """Run the command line; returns the exit status (0 ok, 1 bad data, 2 bad usage, 128 + N on signal N).

    Parameters
    ----------
    argv : list of str, optional
        The arguments after ``quatarray`` (default ``sys.argv[1:]``).

    Examples
    --------
    >>> import os, tempfile, numpy as np
    >>> from quatarray.app.cli import main
    >>> folder = tempfile.mkdtemp()
    >>> src, out = os.path.join(folder, "q.npy"), os.path.join(folder, "m.npy")
    >>> np.save(src, np.array([[0.0, 0, 0, 1]]))  # 180° about z
    >>> main(["convert", src, out, "--to", "matrix"])
    0
    >>> np.load(out)[0].round(12)
    array([[-1.,  0.,  0.],
           [ 0., -1.,  0.],
           [ 0.,  0.,  1.]])
    """
    # The verbs alternate short parallel kernels with file I/O: idle OpenMP workers
    # should sleep rather than spin and steal the core the I/O runs on.
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, usage errors
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    if not args.verb:
        parser.print_help(sys.stderr)
        return 2
    try:
        with _signals_interrupt():
            return _run(args)
    except (UsageError, DataError) as exc:
        status, line = _complaint(args.verb, exc)
        print(line, file=sys.stderr)
        return status
    except BrokenPipeError:  # `quatarray info x | head`: the reader went away
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:
        status, line = _complaint(args.verb, exc)
        print(line, file=sys.stderr)
        return status
    except MemoryError:
        print(f"quatarray {args.verb}: error: out of memory; try a smaller --chunk", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        signum = exc.signum if isinstance(exc, _Signalled) else signal.SIGINT
        print(f"quatarray: interrupted ({signal.Signals(signum).name})", file=sys.stderr)
        return 128 + signum


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
