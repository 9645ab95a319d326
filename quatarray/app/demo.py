"""``quatarray demo``: the main job end to end on a sample shipped in the package.

The sample is a motion-capture walk (``quatarray/data/mocapbank_walk.bvh``,
455 frames at 30 fps, attribution in ``quatarray/data/README.md``). The demo

1. reads every joint's Euler channels as a quaternion stream (:mod:`quatarray.io`);
2. removes sign flips (:func:`quatarray.unflip`);
3. resamples every joint from 30 to 120 fps with Shoemake's Bézier scheme
   (:func:`quatarray.spline`, ``method="bezier"``) and with slerp, and reports
   how far apart the two curves are;
4. holds back every other frame, predicts the held-back frames from the rest
   with both methods and reports the error of each against the recording;
   also as world joint positions (forward kinematics of the whole clip,
   :func:`quatarray.io.read_bvh`, :meth:`quatarray.skeleton.Clip.world`);
5. writes the 120 fps root stream (time, position, quaternion) as CSV for both
   methods, all joints as one CSV, the whole clip at 120 fps as BVH
   (``walk_120fps.bvh``), a JSON summary and, where matplotlib is installed,
   PNGs of the root before and after resampling and of a few joints' world
   trajectories;
6. times the resampling on a long stream (the root walk repeated to 250 000 keys) to
   show the throughput. Its kernels (many keys, multi-threaded) are compiled
   in a second process from the start (:func:`quatarray._warmup.in_background`),
   on the other core, while this one runs steps 1-5: from an empty cache, the
   demo then waits for them no more.
"""

import json
import os
import sys
import time
from importlib import resources

import numpy as np

from ..io import sample_path  # noqa: F401  (the demo's sample, also importable from here)

SAMPLE = "mocapbank_walk.bvh"
RATE = 120.0
LONG_KEYS = 250_000
UNIT_CM = 1.0  # the sample's lengths are centimetres (quatarray/data/README.md)
TRACKED = ("Hips", "Head_End", "LeftWrist_End", "RightAnkle_End")




def _new_folder(base="quatarray-demo"):
    k = 1
    path = base
    while os.path.exists(path):
        k += 1
        path = f"{base}-{k}"
    os.makedirs(path)
    return path


def read_joints(path):
    """``(times, {joint: (n, 4) quaternions}, root positions, Euler sequence of each joint)`` of a BVH file."""
    from .. import io

    first = io.open_stream(path, fmt="bvh")
    streams, seqs = {}, {}
    t = pos = None
    for joint in first.joints:
        reader = io.open_stream(path, fmt="bvh", joint=joint)
        c = io.concat(list(reader))
        streams[joint] = np.asarray(c.data, dtype=np.float64)
        seqs[joint] = reader.seq
        if t is None:
            t, pos = c.t, c.pos
    return t, streams, pos, seqs


def _long_samples(keys):
    """Samples of the long stream of `keys` keys (four per key interval)."""
    return 4 * (keys - 1) + 1


def _deg(x):
    return np.degrees(np.asarray(x, dtype=np.float64))


def _stats(errors_deg):
    e = np.asarray(errors_deg)
    return {"mean": float(e.mean()), "rms": float(np.sqrt((e * e).mean())), "max": float(e.max())}


def run(out_dir=None, rate=RATE, long_keys=LONG_KEYS, stream=None):
    """Run the demo; returns the exit status (0).

    Parameters
    ----------
    out_dir : str, optional
        Folder for the outputs (created if missing; default: a new folder
        ``quatarray-demo[-k]`` in the working directory).
    rate : float
        Target rate in Hz (the sample is at 30 fps).
    long_keys : int
        Length of the long stream timed for throughput (0 skips it).
    stream : file, optional
        Where the summary goes (default stdout).
    """
    import quatarray as qa

    from .. import _jit, _warmup, io
    from .plot import have_matplotlib, plot_streams, plot_trajectories
    from ..splines import PIECES_MIN_KEYS

    out = stream or sys.stdout
    if out_dir is None:
        out_dir = _new_folder()
    else:
        os.makedirs(out_dir, exist_ok=True)
    src = sample_path()
    wall = time.perf_counter()
    ahead = None
    if long_keys >= PIECES_MIN_KEYS:  # the throughput section's kernels compile on another core meanwhile
        loops = "parallel" if _long_samples(long_keys) >= _jit.min_rows() else "serial"
        ahead = _warmup.in_background([f"spline[{m}, many keys]" for m in ("bezier", "slerp")], variants=(loops,))

    # 1. read
    t0 = time.perf_counter()
    t, streams, pos, seqs = read_joints(src)
    t_read = time.perf_counter() - t0
    joints = list(streams)
    root = joints[0]
    n = len(t)
    fps = 1.0 / np.median(np.diff(t))
    flips_raw = {j: int(np.sum(qa.dot(q[1:], q[:-1]) < 0)) for j, q in streams.items()}
    norm_dev = max(float(np.max(np.abs(qa.norm(q) - 1))) for q in streams.values())

    # 2. unflip (spline also does this itself; done here to show and count it)
    t0 = time.perf_counter()
    clean = {j: qa.unflip(qa.normalize(q)) for j, q in streams.items()}
    t_unflip = time.perf_counter() - t0
    flips_left = sum(int(np.sum(qa.dot(q[1:], q[:-1]) < 0)) for q in clean.values())

    # 3. resample every joint 30 -> 120 fps, Bézier and slerp
    new_t = t[0] + np.arange(int(np.floor((t[-1] - t[0]) * rate + 1e-9)) + 1) / rate
    new_t = new_t[new_t <= t[-1]]
    t0 = time.perf_counter()
    bez = {j: qa.spline(t, q, new_t, method="bezier") for j, q in clean.items()}
    t_bez = time.perf_counter() - t0
    t0 = time.perf_counter()
    slp = {j: qa.spline(t, q, new_t, method="slerp") for j, q in clean.items()}
    t_slp = time.perf_counter() - t0
    apart = np.concatenate([_deg(qa.distance(bez[j], slp[j])) for j in joints])
    # both curves pass through the keys: check it on the samples that fall on keys
    on_key = np.isin(np.round(new_t * fps).astype(np.int64), np.round(t * fps).astype(np.int64)) & (
        np.abs(new_t * fps - np.round(new_t * fps)) < 1e-6
    )
    key_idx = np.round((new_t[on_key] - t[0]) * fps).astype(np.int64)
    at_keys = max(float(_deg(qa.distance(bez[j][on_key], clean[j][key_idx])).max()) for j in joints)

    # 4. hold-out test: keys = even frames, predict the odd frames
    kt = t[0::2]
    inside = t[1::2] < kt[-1]
    ht = t[1::2][inside]
    err = {"bezier": [], "slerp": []}
    for j in joints:
        keys = clean[j][0::2]
        truth = clean[j][1::2][inside]
        for m in err:
            err[m].append(_deg(qa.distance(qa.spline(kt, keys, ht, method=m), truth)))
    hold = {m: _stats(np.concatenate(v)) for m, v in err.items()}
    hold_root = {m: _stats(v[0]) for m, v in err.items()}
    # ... and as world joint positions: every joint of the whole clip (End Sites included)
    # by forward kinematics, keys = even frames resampled at the odd frames' times
    t0 = time.perf_counter()
    clip = io.read_bvh(src)
    truth_p = clip.world()[1][1::2][inside]
    even = clip.replace(rotations=clip.rotations[0::2], translations=clip.translations[0::2], times=clip.times[0::2])
    hold_pos = {}
    for m in ("bezier", "slerp"):
        d = np.linalg.norm(even.resample(times=ht, method=m).world()[1] - truth_p, axis=2)
        hold_pos[m] = _stats(d * UNIT_CM)
    t_clip = time.perf_counter() - t0

    # 5. write
    files = []
    root_pos = None
    if pos is not None:
        root_pos = np.column_stack([np.interp(new_t, t, pos[:, k]) for k in range(3)])
    for m, res in (("bezier", bez), ("slerp", slp)):
        path = os.path.join(out_dir, f"walk_{root}_{m}_{int(rate)}fps.csv")
        with io.open_writer(path, ["qw", "qx", "qy", "qz"], time=True, pos=root_pos is not None) as w:
            w.write(res[root], new_t, root_pos)
        files.append(path)
    path = os.path.join(out_dir, f"walk_all_joints_bezier_{int(rate)}fps.csv")
    fields = [f"{j}.{c}" for j in joints for c in ("qw", "qx", "qy", "qz")]
    with io.open_writer(path, fields, time=True) as w:
        w.write(np.concatenate([bez[j] for j in joints], axis=1), new_t)
    files.append(path)

    # the whole clip at the new rate, every joint, as BVH
    t0 = time.perf_counter()
    clip_new = clip.resample(rate=rate)
    path = os.path.join(out_dir, f"walk_{int(rate)}fps.bvh")
    io.write_bvh(path, clip_new)
    t_bvh = time.perf_counter() - t0
    files.append(path)

    plot_note = None
    # the root, and the joint where the two methods differ most
    busiest = max(joints, key=lambda j: float(np.max(qa.distance(bez[j], slp[j]))))
    if have_matplotlib():
        for j in dict.fromkeys([root, busiest]):
            png = os.path.join(out_dir, f"walk_{j}.png")
            plot_streams(
                png, t, clean[j], seq=seqs[j], after=(new_t, bez[j]),
                extra=[(new_t, slp[j], f"slerp {int(rate)} fps")],
                title=f"{SAMPLE}, joint {j}: {fps:.0f} fps keys (dots), Bézier {int(rate)} fps (line), "
                      f"slerp (dashed)",
                labels=(f"keys {fps:.0f} fps", f"Bézier {int(rate)} fps"),
            )
            files.append(png)
        # a few joints' world trajectories: keys (30 fps) and the 120 fps clip
        show = [clip.joints.index(j) for j in TRACKED if j in clip.joints] or [0]
        png = os.path.join(out_dir, "walk_trajectories.png")
        plot_trajectories(png, clip.times, clip.world()[1][:, show], [clip.joints[k] for k in show],
                          after=(clip_new.times, clip_new.world()[1][:, show]),
                          title=f"{SAMPLE}: world trajectories, {fps:.0f} fps frames (dots), "
                                f"Bézier {int(rate)} fps clip (line)")
        files.append(png)
    else:
        plot_note = "plot skipped: matplotlib is not installed (pip install matplotlib)"

    # 6. throughput on a long stream: the root walk repeated, a time step of 1/fps throughout
    if ahead is not None:
        ahead.wait()  # its kernels are ready (and it no longer takes a core from the timing)
    long = None
    if long_keys:
        reps = -(-int(long_keys) // n)
        lq = np.tile(clean[root], (reps, 1))[:long_keys]
        lt = t[0] + np.arange(long_keys) / fps
        lnew = np.linspace(lt[0], lt[-1], _long_samples(long_keys))
        long = {"keys": int(long_keys), "samples": int(lnew.size)}
        for m in ("bezier", "slerp"):
            qa.spline(lt[:64], lq[:64], lnew[:200], method=m)  # compile / load the cache
            best = np.inf
            for _ in range(3):
                t0 = time.perf_counter()
                qa.spline(lt, lq, lnew, method=m)
                best = min(best, time.perf_counter() - t0)
            long[m] = {"seconds": best, "Msamples_per_s": lnew.size / best / 1e6}

    summary = {
        "sample": SAMPLE,
        "joints": len(joints),
        "frames": n,
        "fps": fps,
        "rate": rate,
        "samples_per_joint": int(new_t.size),
        "sign_flips_raw": flips_raw,
        "sign_flips_after_unflip": flips_left,
        "max_norm_deviation": norm_dev,
        "bezier_vs_slerp_deg": _stats(apart),
        "bezier_at_keys_max_deg": at_keys,
        "holdout_all_joints_deg": hold,
        "holdout_root_deg": hold_root,
        "holdout_world_positions_cm": hold_pos,
        "seconds": {"read": t_read, "unflip": t_unflip, "bezier": t_bez, "slerp": t_slp, "clip_holdout": t_clip,
                    "clip_resample_write": t_bvh},
        "long_stream": long,
        "files": [os.path.abspath(f) for f in files],
    }
    path = os.path.join(out_dir, "summary.json")
    with open(path, "w") as f:
        json.dump(summary, f, indent=1)
    files.append(path)

    p = lambda *a: print(*a, file=out)  # noqa: E731
    total = len(joints) * new_t.size
    p(f"quatarray demo: {SAMPLE} (packaged sample, Mocapbank), {len(joints)} joints × {n} frames at {fps:.0f} fps")
    p(f"  read: BVH Euler channels -> quaternions for every joint in {t_read * 1e3:.0f} ms; "
      f"largest | |q| - 1 | = {norm_dev:.2g}")
    p(f"  unflip: {sum(flips_raw.values())} sign flips in the raw streams "
      f"(root {root!r}: {flips_raw[root]}), {flips_left} left")
    p(f"  resample {fps:.0f} -> {rate:g} fps with Shoemake's Bézier scheme: {new_t.size} samples per joint, "
      f"{total:,} in all, in {t_bez * 1e3:.1f} ms (slerp: {t_slp * 1e3:.1f} ms)")
    s = summary["bezier_vs_slerp_deg"]
    p(f"  Bézier vs slerp at {rate:g} fps: mean {s['mean']:.3f}°, max {s['max']:.3f}° apart; "
      f"Bézier passes through the keys (max {at_keys:.1e}°)")
    p(f"  hold-out test (drop every other frame, predict it from the {fps / 2:.0f} fps rest), error vs recording:")
    for m in ("bezier", "slerp"):
        a, r = hold[m], hold_root[m]
        p(f"    {m:<7} all joints: mean {a['mean']:.3f}°, rms {a['rms']:.3f}°, max {a['max']:.2f}°   "
          f"root: mean {r['mean']:.3f}°, max {r['max']:.2f}°")
    p(f"    as world joint positions ({len(clip.joints)} joints incl. End Sites, forward kinematics; "
      "file units = cm):")
    for m in ("bezier", "slerp"):
        a = hold_pos[m]
        p(f"    {m:<7} mean {a['mean']:.3f} cm, rms {a['rms']:.3f} cm, max {a['max']:.2f} cm")
    ratio = hold["slerp"]["rms"] / hold["bezier"]["rms"]
    p(f"    -> Bézier's rms error is {ratio:.2f}× smaller than slerp's" if ratio >= 1 else
      f"    -> slerp's rms error is {1 / ratio:.2f}× smaller than Bézier's")
    if long:
        p(f"  throughput on a long stream ({long['keys']:,} keys -> {long['samples']:,} samples): "
          f"Bézier {long['bezier']['Msamples_per_s']:.1f} Msamples/s, slerp {long['slerp']['Msamples_per_s']:.1f} Msamples/s")
    if plot_note:
        p(f"  {plot_note}")
    p(f"  wrote to {os.path.abspath(out_dir)}:")
    for f in files:
        p(f"    {os.path.basename(f)}")
    p(f"  done in {time.perf_counter() - wall:.1f} s")
    return 0
