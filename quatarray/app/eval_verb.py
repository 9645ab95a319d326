"""``quatarray eval``: read two pose streams, evaluate them (:mod:`quatarray.trajectory`), report.

Inputs are read with the same readers as the other verbs (TUM, EuRoC, KITTI,
csv/parquet with columns ``t x y z qw qx qy qz``), and pose arrays:

``.npy`` / ``.zarr`` pose arrays
    float arrays of shape ``(N, 8)``: ``t x y z qw qx qy qz`` a row, or
    ``(N, 7)``: ``x y z qw qx qy qz`` (no times: compared pose by pose).
    When both inputs are pose arrays they are evaluated in chunks of
    ``chunk`` rows (:func:`run_chunked`), so streams larger than memory work:
    one pass for the alignment's :class:`~quatarray.trajectory.Moments`, one
    for the errors, each block of the shorter stream associated with the
    window of the other that its times can reach (found by bisection on the
    other's times column, read a value at a time), errors written to ``out``
    block by block. Only the errors are held (8 bytes a pair, for the
    median). APE, and RPE with a delta in frames, run this way; ``--plot``,
    ``--interpolate``, RPE in metres or seconds and unsorted times read the
    streams whole.

The job prints the statistics, and on request writes them as JSON
(``json_path``), the per-pose errors with their times (``out``: csv or parquet
with columns ``t`` (when the reference has times), ``pose`` (RPE: ``pose0``,
``pose``), ``error``) and a plot (errors over time, aligned trajectories).
"""

import json
import os
import sys

import numpy as np

from .. import trajectory as T
from ..algebra import normalize
from ..io import DEFAULT_CHUNK, Cleaner, DataError, UsageError, check_output, concat, open_stream, open_writer

TITLES = {"trans": "translation part", "rot": "rotation angle", "full": "full transformation"}
ALIGN_TITLES = {"none": "not aligned", "se3": "SE(3) Umeyama alignment", "sim3": "Sim(3) Umeyama alignment",
                "scale": "scale corrected"}


# --------------------------------------------------------------------------
# reading


POSE_LAYOUTS = "floats of shape (N, 8), t x y z qw qx qy qz a row, or (N, 7), x y z qw qx qy qz"


def pose_array(path, name=None):
    """A memory-mapped (npy) or lazy (zarr) pose array ``(N, 8)`` or ``(N, 7)`` of floats, or None
    if `path` is no npy/zarr array (a file numpy cannot read is left to the stream readers, which
    say what is wrong). An array of another shape or dtype is a :class:`DataError` naming eval's
    layouts (:data:`POSE_LAYOUTS`), its shape and its dtype."""
    from ..io.formats import is_zarr

    name = name or path
    if is_zarr(path):
        from ..io.readers import import_zarr

        try:
            arr = import_zarr(name).open_array(path, mode="r")
        except Exception:  # not a zarr array: the stream readers say what it is
            return None
    elif str(path).lower().endswith(".npy") and os.path.isfile(path):
        try:
            arr = np.load(path, mmap_mode="r")
        except (ValueError, OSError, EOFError):
            return None
    else:
        return None
    dtype = np.dtype(arr.dtype)
    if len(arr.shape) == 2 and arr.shape[1] in (7, 8) and dtype.kind == "f" and dtype.fields is None:
        if arr.shape[0] == 0:
            raise DataError(f"{name}: no rows")
        return arr
    raise DataError(f"{name}: eval reads a pose array as {POSE_LAYOUTS}; this one holds {dtype} "
                    f"of shape {tuple(arr.shape)}")


def _poses_of_rows(rows, name, row0=0):
    """Poses from rows of a pose array (checked: finite, non-zero quaternions)."""
    rows = np.asarray(rows, dtype=np.float64)
    k = rows.shape[1] - 7
    bad = ~np.all(np.isfinite(rows), axis=1) | ~np.any(rows[:, k + 3:] != 0, axis=1)
    if bad.any():
        r = int(np.flatnonzero(bad)[0])
        raise DataError(f"{name}: row {row0 + r}: not a pose (a non-finite number or a zero quaternion)")
    t = rows[:, 0].copy() if k else None
    return T.Poses(t, np.ascontiguousarray(rows[:, k:k + 3]), normalize(np.ascontiguousarray(rows[:, k + 3:])))


def read_poses(path, fmt="auto", layout=None, chunk=None, on_invalid="error", err=None, locate=False):
    """The whole pose stream of a file as :class:`~quatarray.trajectory.Poses`.

    With `locate`, also ``where(i)``: the place of pose i in the file for a message
    (``"traj.txt:12"``; ``"traj.npy: row 11"``), rows dropped with ``on_invalid="drop"`` counted.

    Examples
    --------
    >>> import os, tempfile
    >>> from quatarray.app.eval_verb import read_poses
    >>> path = os.path.join(tempfile.mkdtemp(), "traj.txt")
    >>> _ = open(path, "w").write("# t x y z qx qy qz qw\\n0 1 2 3 0 0 0 1\\n0.1 1 2 3 0 0 1 0\\n")
    >>> p = read_poses(path, "tum")
    >>> p.t, p.q[1]
    (array([0. , 0.1]), array([0., 0., 0., 1.]))
    """
    arr = pose_array(path) if fmt in ("auto", "npy") else None
    if arr is not None:
        p = _poses_of_rows(arr[:], path)
        return (p, lambda i: f"{path}: row {i}") if locate else p
    kw = {} if chunk is None else {"chunk": chunk}
    reader = open_stream(path, fmt, kind="quat", layout=layout, on_invalid=on_invalid, **kw)
    if not reader.has_pos:
        raise DataError(f"{path}: no positions; eval compares pose streams (position and rotation), "
                        f"e.g. TUM, EuRoC, KITTI, or csv with columns t x y z qw qx qy qz")
    clean = Cleaner(reader, on_invalid)
    chunks, rows = [], []  # rows: the reader's rows of the poses each chunk keeps
    for c in reader:
        ch, good = clean.check(c)
        if good.all():
            rows.append(range(c.row0, c.row0 + len(c)))
        else:
            keep = np.flatnonzero(good)
            clean.dropped += good.size - keep.size
            ch = ch.take(keep)
            rows.append(c.row0 + keep)
        if len(ch):
            chunks.append(ch)
    if not chunks:
        raise DataError(f"{path}: no valid rows left")
    whole = concat(chunks)
    if err is not None:
        reader.say(err)
        clean.report(err)
    t = None if whole.t is None else np.asarray(whole.t, dtype=np.float64)
    p = T.Poses(t, np.ascontiguousarray(whole.pos, dtype=np.float64), np.ascontiguousarray(whole.data, np.float64))
    if not locate:
        return p

    def where(i):
        for r in rows:
            if i < len(r):
                return reader.where(int(r[i]))
            i -= len(r)
        raise IndexError(i)
    return p, where


def _read_both(ref_path, est_path, err, **kw):
    """Both streams, read in two threads (the text parser releases the GIL), each as
    ``(poses, where)`` (see :func:`read_poses`); their notes go to `err` in order, reference
    first."""
    import io as _io
    from concurrent.futures import ThreadPoolExecutor

    notes = [_io.StringIO(), _io.StringIO()]
    with ThreadPoolExecutor(2) as pool:
        jobs = [pool.submit(read_poses, p, err=n, locate=True, **kw) for p, n in zip((ref_path, est_path), notes)]
        try:
            ref = jobs[0].result()
        finally:
            err.write(notes[0].getvalue())
        try:
            est = jobs[1].result()
        finally:
            err.write(notes[1].getvalue())
    return ref, est


class PoseFile:
    """A pose array (npy or zarr, see :func:`pose_array`) read a block of rows at a time.

    An npy block is a memory map of those rows alone, dropped once copied, so
    resident memory stays bounded by the block whatever the file's size.
    """

    def __init__(self, path, arr):
        self.path, self.rows, self.width = path, int(arr.shape[0]), int(arr.shape[1])
        self.has_t = self.width == 8
        self.dtype = np.dtype(arr.dtype)
        self.npy = isinstance(arr, np.memmap)
        self.offset = arr.offset if self.npy else None
        self.arr = None if self.npy else arr

    @classmethod
    def open(cls, path):
        """A PoseFile for `path`, or None when it is no pose array that can be read in blocks."""
        arr = pose_array(path)
        if arr is None or (isinstance(arr, np.memmap) and not arr.flags.c_contiguous):
            return None
        return cls(path, arr)

    def _raw(self, a, b):
        if not self.npy:
            return np.asarray(self.arr[a:b])
        row = self.width * self.dtype.itemsize
        m = np.memmap(self.path, self.dtype, "r", offset=self.offset + a * row, shape=(b - a, self.width))
        try:
            return np.array(m, dtype=np.float64)
        finally:
            del m

    def block(self, a, b):
        """Rows a to b as checked :class:`~quatarray.trajectory.Poses`."""
        return _poses_of_rows(self._raw(a, b), self.path, a)

    def time(self, k):
        """The time of row k."""
        return float(self._raw(k, k + 1)[0, 0]) if self.npy else float(self.arr[k, 0])

    def times(self, a, b):
        """The times of rows a to b."""
        return np.ascontiguousarray(self._raw(a, b)[:, 0])

    def bisect(self, x, off, right):
        """The first row whose time + `off` is above `x` (`right`) or not below it."""
        lo, hi = 0, self.rows
        while lo < hi:
            mid = (lo + hi) // 2
            v = self.time(mid) + off
            if v <= x if right else v < x:
                lo = mid + 1
            else:
                hi = mid
        return lo

    def sorted(self, chunk):
        """Whether the times never decrease (read block by block)."""
        last = -np.inf
        for a in range(0, self.rows, chunk):
            t = self.times(a, min(a + chunk, self.rows))
            if t[0] < last or np.any(np.diff(t) < 0):
                return False
            last = t[-1]
        return True


def _blocks(ref_f, est_f, chunk, t_max_diff, t_offset):
    """The associated pairs, block by block: (ref Poses, est Poses) as :func:`trajectory.associate`
    gives them for the whole streams (the pairs in the same order), or None when the times do
    not allow it (the inner stream's times not sorted)."""
    if not (ref_f.has_t and est_f.has_t):
        if ref_f.rows != est_f.rows:
            raise ValueError(f"streams without times are compared pose by pose: the reference has "
                             f"{ref_f.rows} poses, the estimate {est_f.rows}")

        def by_row():
            for a in range(0, ref_f.rows, chunk):
                b = min(a + chunk, ref_f.rows)
                r, e = ref_f.block(a, b), est_f.block(a, b)
                yield r.replace(t=None), e.replace(t=None)
        by_row.most = ref_f.rows  # pairs at the most
        return by_row
    # as associate: the pairs follow the shorter stream (the estimate when equal)
    outer, inner, off = (ref_f, est_f, t_offset) if est_f.rows > ref_f.rows else (est_f, ref_f, -t_offset)
    if not inner.sorted(chunk):
        return None

    def by_time():
        found = False
        for a in range(0, outer.rows, chunk):
            o = outer.block(a, min(a + chunk, outer.rows))
            # the window of inner rows these times can reach (a little slack for rounding), and one
            # row more on each side: match_times then sees the neighbours it sees on the whole stream
            slack = t_max_diff + 1e-9 * (1.0 + abs(float(o.t[0])))
            wa = max(inner.bisect(float(o.t.min()) - slack, off, right=False) - 1, 0)
            wb = min(inner.bisect(float(o.t.max()) + slack, off, right=True) + 1, inner.rows)
            w = inner.block(wa, wb)
            i_o, i_w = T.match_times(o.t, w.t, t_max_diff, off)
            if i_o.size == 0:
                continue
            found = True
            o, w = o.take(i_o), w.take(i_w)
            yield (w, o) if outer is est_f else (o, w)
        if not found:
            raise ValueError(f"no matching times between the reference and the estimate with "
                             f"t_max_diff {t_max_diff} s and t_offset {t_offset} s")
    by_time.most = outer.rows
    return by_time


def run_chunked(ref_f, est_f, metric, align, relation, delta, all_pairs, n_to_align, t_max_diff,
                t_offset, chunk, out=None, keep_errors=True):
    """:func:`trajectory.evaluate` of two :class:`PoseFile` streams, a block at a time.

    Equal to the in-memory evaluation (APE; RPE with a delta in frames). Errors go to `out`
    (as :func:`write_errors` writes them) block by block. Memory: a few blocks, and the errors
    (8 bytes a pair, for the median); with `keep_errors` False their statistics are taken in
    place (no copy), and the errors returned are in no particular order.

    Returns
    -------
    Result or None
        A :class:`~quatarray.trajectory.Result` without poses, index or times (those went to
        `out`), or None when the streams must be read whole (times not sorted).
    """
    blocks = _blocks(ref_f, est_f, chunk, t_max_diff, t_offset)
    if blocks is None:
        return None
    n = 0
    a = T.IDENTITY
    if align != "none":
        feed = origin = None  # as trajectory.fit: about the first pair (but a scale correction)
        for r, e in blocks():
            k = len(r) if n_to_align is None else max(min(len(r), int(n_to_align) - n), 0)
            if k == 0 and n_to_align is not None:
                break
            if feed is None:
                origin = None if align == "scale" else (e.pos[0].copy(), r.pos[0].copy())
                feed = T.MomentsFeed(origin)
            feed.add(e.pos[:k], r.pos[:k])
            n += len(r)
        a = T.fit_moments((feed or T.MomentsFeed()).moments(), align, origin)
    if out is None:
        return _chunked_errors(blocks, a, metric, relation, delta, all_pairs, keep_errors, None)
    w, errors_only = error_writer(out, metric, ref_f.has_t)
    with w:
        return _chunked_errors(blocks, a, metric, relation, delta, all_pairs, keep_errors,
                               lambda cols, t: _write_rows(w, errors_only, cols, t))


def _chunked_errors(blocks, a, metric, relation, delta, all_pairs, keep_errors, write):
    # the errors, in one buffer of the most there can be (pages never written are never resident)
    errors, m, n = np.empty(blocks.most), 0, 0  # m errors so far, n: associated poses before this block
    carry = None  # RPE: the last `delta` associated poses (ref, est), first poses of the next pairs
    for r, e in blocks():
        e, size = a.local(e), len(r)  # about the alignment's origin (see trajectory.evaluate)
        if metric == "ape":
            err = T.ape(r, e, relation, a.origin_y)
            cols, t = [np.arange(n, n + size), err], r.t
        else:
            if carry is not None:
                r, e = _joined(carry[0], r), _joined(carry[1], e)
            g = n + size - len(r)  # the associated index of the buffer's first pose
            j = np.arange(max(n, g + delta), n + size)
            if not all_pairs:
                j = j[j % delta == 0]
            err = T.rpe_of_pairs(r, e, j - g - delta, j - g, relation)
            cols, t = [j - delta, j, err], None if r.t is None else r.t[j - g]
            keep = slice(max(len(r) - delta, 0), None)
            carry = (r.take(keep), e.take(keep))
        n += size
        errors[m:m + err.size] = err
        m += err.size
        if write is not None and err.size:
            write(cols, t)
    errors = errors[:m]
    if m == 0:
        raise ValueError(f"delta = {delta} (frames) gives no pair among {n} poses; try a smaller delta")
    stats = T.statistics(errors.copy() if keep_errors else errors, overwrite_input=True)
    return T.Result(stats, errors, None, None, None, None, None, a, metric, relation, T.UNITS[relation])


def _joined(p, q):
    return T.Poses(None if p.t is None else np.concatenate([p.t, q.t]), np.concatenate([p.pos, q.pos]),
                   np.concatenate([p.q, q.q]))


# --------------------------------------------------------------------------
# reporting


def title(result, align, n_to_align=None, delta=None, delta_unit=None, all_pairs=False):
    """evo's title of a result, e.g. ``APE w.r.t. translation part (m)`` and the alignment."""
    head = f"{result.metric.upper()} w.r.t. {TITLES[result.relation]} ({result.unit})"
    if result.metric == "rpe":
        head += f"\nfor delta = {delta} ({delta_unit}) using {'all' if all_pairs else 'consecutive'} pairs"
    head += f"\n({ALIGN_TITLES[align]})"
    if align != "none" and n_to_align is not None:
        head += f" (aligned poses: {n_to_align})"
    return head


def report(result, head, out=sys.stdout):
    """Print the title, the pair count and the statistics, one a line."""
    print(head, file=out)
    print(f"{'pairs':>8}  {result.errors.size}", file=out)
    for k in T.STATISTICS:
        print(f"{k:>8}  {result.stats[k]:.9g}", file=out)


def as_json(result, head, ref_name, est_name, options):
    a = result.alignment
    return {
        "title": head, "ref": ref_name, "est": est_name, "metric": result.metric,
        "pose_relation": result.relation, "unit": result.unit, "pairs": int(result.errors.size),
        "stats": result.stats, "options": options,
        "alignment": {"rotation": a.r.tolist(), "quaternion": a.q.tolist(), "translation": a.t.tolist(),
                      "scale": a.s},
    }


def error_writer(path, metric, timed):
    """An open writer for per-pose errors, and whether it takes the errors alone (npy).

    csv and parquet get columns ``t`` (when `timed`), ``pose`` (RPE: ``pose0``, ``pose``) and
    ``error``; npy the errors alone.
    """
    from ..io.formats import output_format

    if output_format(path) == "npy":
        return open_writer(path, ["error"], core=()), True  # shape (N,)
    fields = (["pose0"] if metric == "rpe" else []) + ["pose", "error"]
    return open_writer(path, fields, time=timed), False


def _write_rows(writer, errors_only, cols, t):
    """One block of errors (`cols`: [pose0,] pose, error) to a writer of :func:`error_writer`."""
    if errors_only:
        writer.write(np.ascontiguousarray(cols[-1], np.float64))
    else:
        writer.write(np.column_stack([np.asarray(c, np.float64) for c in cols]), t)


def write_errors(path, result):
    """Per-pose errors (with reference times when there are) to csv, parquet (or npy: errors only)."""
    cols = ([result.i0] if result.metric == "rpe" else []) + [result.index, result.errors]
    w, errors_only = error_writer(path, result.metric, result.t is not None)
    with w:
        _write_rows(w, errors_only, cols, result.t)


def plot(path, result, ref_name, est_name, aligned=None):
    """Errors over time (or pose index) and the (aligned) trajectories seen from above (x, y), in
    the image format `path`'s extension names (``.png``, ``.pdf``, ``.svg`` …).

    `aligned`: whether the estimate's legend says "(aligned)" (default: when the result's
    alignment is not the identity)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from .plot import _save

    fig = Figure(figsize=(11, 4.5))
    FigureCanvasAgg(fig)
    ax1, ax2 = fig.subplots(1, 2)
    step = max(1, result.errors.size // 20_000)
    x = (result.t - result.ref.t[0]) if result.t is not None else result.index
    ax1.plot(x[::step], result.errors[::step], lw=0.8)
    ax1.axhline(result.stats["rmse"], color="C3", ls="--", lw=0.8, label=f"rmse {result.stats['rmse']:.4g}")
    ax1.set_xlabel("t − t₀ (s)" if result.t is not None else "pose")
    ax1.set_ylabel(f"{result.metric.upper()} {TITLES[result.relation]} ({result.unit})")
    ax1.legend(loc="upper right")
    s = max(1, len(result.ref) // 20_000)
    ax2.plot(result.ref.pos[::s, 0], result.ref.pos[::s, 1], lw=0.8, label=os.path.basename(ref_name))
    if aligned is None:
        aligned = result.alignment is not T.IDENTITY
    ax2.plot(result.est.pos[::s, 0], result.est.pos[::s, 1], lw=0.8,
             label=os.path.basename(est_name) + (" (aligned)" if aligned else ""))
    ax2.set_xlabel("x (m)")
    ax2.set_ylabel("y (m)")
    ax2.set_aspect("equal", adjustable="datalim")
    ax2.legend(loc="best")
    fig.tight_layout()
    _save(fig, path)


# --------------------------------------------------------------------------
# the job


def run(ref_path, est_path, *, metric="ape", align="none", relation="trans", delta=1, delta_unit="frames",
        all_pairs=False, n_to_align=None, t_max_diff=0.01, t_offset=0.0, interpolate=False, out=None,
        plot_path=None, json_path=None, fmt="auto", layout=None, chunk=None, on_invalid="error",
        force=False, stdout=None, stderr=None):
    """Run ``quatarray eval``: returns the exit status (0), raises DataError / UsageError.

    Examples
    --------
    >>> import os, tempfile, numpy as np
    >>> from quatarray.app.eval_verb import run
    >>> d = tempfile.mkdtemp()
    >>> t = np.arange(5.0)
    >>> ref = np.c_[t, t, t ** 2, np.zeros(5), np.tile([0, 0, 0, 1.0], (5, 1))]
    >>> np.savetxt(os.path.join(d, "ref.txt"), ref)
    >>> np.savetxt(os.path.join(d, "est.txt"), ref + [0, 0.1, 0, 0, 0, 0, 0, 0])
    >>> run(os.path.join(d, "ref.txt"), os.path.join(d, "est.txt"), fmt="tum")  # doctest: +ELLIPSIS
    APE w.r.t. translation part (m)
    (not aligned)
       pairs  5
        rmse  0.1
        mean  0.1
      median  0.1
         std  ...
         min  0.1
         max  0.1
         sse  0.05
    0
    """
    stdout = stdout or sys.stdout
    stderr = stderr or sys.stderr
    if metric == "rpe" and delta_unit == "frames" and int(delta) != delta:
        raise UsageError(f"--delta in frames must be a whole number, got {delta}")
    if metric == "rpe" and delta_unit == "frames":
        delta = int(delta)
    for o in (out, plot_path, json_path):
        if o is not None:
            check_output(o, [ref_path, est_path], force)
    if plot_path is not None:
        from .plot import have_matplotlib, image_format

        if not have_matplotlib():
            raise UsageError("--plot needs matplotlib (pip install matplotlib)")
        image_format(plot_path)  # an extension matplotlib does not write: before the reading
    interpolate = "evo" if interpolate is True else interpolate or False  # False: nearest pairs
    if interpolate not in (None, False) + T.INTERPOLATIONS:
        raise UsageError(f"--interpolate: unknown rule {interpolate!r}; expected one of {', '.join(T.INTERPOLATIONS)}")
    options = dict(metric=metric, align=align, relation=relation, delta=delta, delta_unit=delta_unit,
                   all_pairs=all_pairs, n_to_align=n_to_align, t_max_diff=t_max_diff, t_offset=t_offset,
                   interpolate=interpolate)
    result = None
    files = [PoseFile.open(p) for p in (ref_path, est_path)] if fmt in ("auto", "npy") else [None]
    try:
        chunked = metric == "ape" or delta_unit == "frames"
        if None not in files and chunked and plot_path is None and not interpolate:
            result = run_chunked(*files, metric, align, relation, delta, all_pairs, n_to_align, t_max_diff,
                                 t_offset, chunk or DEFAULT_CHUNK, out, keep_errors=False)
        if result is None:
            (ref, ref_where), (est, est_where) = _read_both(ref_path, est_path, stderr, fmt=fmt, layout=layout,
                                                            chunk=chunk, on_invalid=on_invalid)
            try:
                result = T.evaluate(ref, est, **options)
            except T.TimeOrderError as exc:  # named by the file's line
                where = ref_where if exc.stream == "reference" else est_where
                t = (ref if exc.stream == "reference" else est).t
                raise DataError(f"{where(exc.row)}: time {float(t[exc.row])!r} is before the previous one "
                                f"({float(t[exc.row - 1])!r}); --interpolate needs the times of the stream it "
                                f"resamples in order") from None
            if out is not None:
                write_errors(out, result)
    except ValueError as exc:
        raise DataError(f"{est_path} against {ref_path}: {str(exc).splitlines()[0]}") from None
    if plot_path is not None:
        plot(plot_path, result, ref_path, est_path, aligned=align != "none")
    head = title(result, align, n_to_align, delta, delta_unit, all_pairs)
    report(result, head, stdout)
    if json_path is not None:
        with open(json_path, "w") as f:
            json.dump(as_json(result, head, ref_path, est_path, options), f, indent=2)
            f.write("\n")
    return 0
