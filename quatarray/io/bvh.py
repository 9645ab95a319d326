"""BVH files: whole clips (:func:`read_bvh`, :func:`write_bvh`) and one joint as a stream.

:class:`BvhReader` (what :func:`quatarray.io.open_stream` opens for a
``.bvh`` file) reads one joint of a BVH file as a rotation stream;
:func:`read_bvh` and :func:`write_bvh` read and write every joint at once as
a :class:`quatarray.skeleton.Clip`.

Reading: each joint's rotation channels, in the order the file lists them,
are an intrinsic Euler sequence in degrees (``Zrotation Xrotation
Yrotation`` → ``"ZXY"``, any of the six orders, joint by joint; a hinge's
one or two axes, ``"X"``, ``"YX"``); a joint's
position channels (root or child, any subset of X, Y, Z) replace its OFFSET
components in its local translation, as Blender and bvhio read BVH. Several
roots are allowed. End Sites become leaf joints named ``<parent>_End``
without channels. The MOTION block is parsed by numpy in one pass (a
100 000-frame clip of 30 joints reads in a few seconds).

Writing: the hierarchy as read, each joint's own channel order, angles in
degrees at full precision (shortest repr). The angles are chosen so that they
reproduce each rotation to about 1e-15 rad, frames at or near gimbal lock
included (see :func:`exact_euler`).
"""

import os
import warnings

import numpy as np

from .._compat import write_csv
from . import formats as F
from .errors import DataError, UsageError
from .formats import is_number
from .streams import Chunk, Reader

END_SUFFIX = "_End"
# BVH angles beyond this many degrees are refused: a float64 angle of 1e9 degrees
# still resolves 1e-7 degrees, one of 1e308 nothing at all (the angle is not reduced
# mod 360, which would only hide that its rotation is lost)
MAX_DEGREES = 1e9  # the clip reader and the stream reader alike


def _err(name, lineno, what):
    return DataError(f"{name}:{lineno}: {what}")


def _plain(s):
    """Whether the word `s` is a number as numpy reads the MOTION block: what Python's
    ``float`` reads, without its extras (``6_0``, digits of other scripts)."""
    return s.isascii() and "_" not in s and is_number(s)


def _floats(tok, name, lineno, what, n):
    if len(tok) != n:
        raise _err(name, lineno, f"{what} needs {n} numbers, got {len(tok)}")
    bad = next((s for s in tok if not _plain(s)), None)
    if bad is not None:
        raise _err(name, lineno, f"not a number: '{F.shown(bad)}'")
    return [float(s) for s in tok]


def _hierarchy(lines, name):
    """Parse HIERARCHY lines: joints, parents, offsets, channels, ends, and the MOTION line index."""
    joints, parents, offsets, channels, ends, where = [], [], [], [], [], []
    stack = []  # indices of the open joints
    pending = None  # a joint whose "{" is still to come
    motion = None
    for i, line in enumerate(lines):
        lineno = i + 1
        tok = line.split()
        if not tok:
            continue
        key = tok[0].upper()
        if key == "HIERARCHY" and not joints:
            continue
        if key in ("ROOT", "JOINT") or (key == "END" and len(tok) > 1 and tok[1].upper() == "SITE"):
            if pending is not None:
                raise _err(name, lineno, f"expected '{{' after {joints[pending]!r}")
            opened = tok[-1] == "{"
            tok = tok[:-1] if opened else tok
            end = key == "END"
            if key == "ROOT" and stack:
                raise _err(name, lineno, "ROOT inside a joint (missing '}'?)")
            if key != "ROOT" and not stack:
                raise _err(name, lineno, f"{tok[0]} outside a ROOT")
            parent = stack[-1] if stack else -1
            jname = (joints[parent] + END_SUFFIX) if end else " ".join(tok[1:])
            if not jname:
                raise _err(name, lineno, f"{tok[0]} without a name")
            joints.append(jname)
            parents.append(parent)
            offsets.append(None)
            channels.append(() if end else None)
            ends.append(end)
            where.append(lineno)
            if opened:
                stack.append(len(joints) - 1)
            else:
                pending = len(joints) - 1
        elif key == "{":
            if pending is None:
                raise _err(name, lineno, "unexpected '{'")
            stack.append(pending)
            pending = None
        elif key == "}":
            if not stack:
                raise _err(name, lineno, "unexpected '}'")
            j = stack.pop()
            if offsets[j] is None:
                raise _err(name, where[j], f"joint {joints[j]!r} has no OFFSET")
            if channels[j] is None:
                raise _err(name, where[j], f"joint {joints[j]!r} has no CHANNELS")
        elif key == "OFFSET":
            if not stack:
                raise _err(name, lineno, "OFFSET outside a joint")
            offsets[stack[-1]] = _floats(tok[1:], name, lineno, "OFFSET", 3)
        elif key == "CHANNELS":
            if not stack:
                raise _err(name, lineno, "CHANNELS outside a joint")
            j = stack[-1]
            if ends[j]:
                raise _err(name, lineno, "an End Site has no CHANNELS")
            try:
                k = int(tok[1])
            except (IndexError, ValueError):
                raise _err(name, lineno, "bad CHANNELS line") from None
            chans = tuple(tok[2:])
            if len(chans) != k:
                raise _err(name, lineno, f"CHANNELS says {k} channels, lists {len(chans)}")
            rot = [c[0].upper() for c in chans if c.lower().endswith("rotation")]
            pos = [c[0].upper() for c in chans if c.lower().endswith("position")]
            bad = [c for c in chans if not (c.lower().endswith(("rotation", "position")) and c[0].upper() in "XYZ"
                                            and len(c) == 9)]
            if bad:
                raise _err(name, lineno, f"unknown channel '{F.shown(bad[0])}'")
            if len(set(rot)) != len(rot) or len(set(pos)) != len(pos):
                raise _err(name, lineno, f"joint {joints[j]!r}: rotation channels must name each axis at most once "
                                         "(1, 2 or 3 of X, Y, Z), and so must position channels")
            channels[j] = chans
        elif key == "MOTION":
            if stack or pending is not None:
                raise _err(name, lineno, f"MOTION before the end of joint {joints[(stack or [pending])[-1]]!r} "
                                         "(missing '}'?)")
            motion = i
            break
        else:
            raise _err(name, lineno, f"unexpected '{F.shown(tok[0])}' in the HIERARCHY")
    if motion is None:
        if not joints:
            raise _err(name, 1, "not a BVH file (no HIERARCHY/MOTION sections)")
        raise DataError(f"{name}: no MOTION section")
    if not joints:
        raise _err(name, motion + 1, "no joints before MOTION")
    return joints, parents, offsets, channels, ends, motion


def read_bvh(path, name=None):
    """Read a whole BVH clip: every joint, every frame.

    Parameters
    ----------
    path : str or path-like
    name : str, optional
        The file's name in error messages (default `path`).

    Returns
    -------
    Clip
        See :class:`quatarray.skeleton.Clip`; End Sites are joints
        ``<parent>_End`` without channels.

    Raises
    ------
    DataError
        A one-line message naming the file and line: a joint without
        CHANNELS or OFFSET, a frame with too few or too many numbers, a word
        that is not a number (as numpy reads them: ``6_0`` is not one),
        ``Frames:`` disagreeing with the frames held.

    Notes
    -----
    A joint may have 1, 2 or 3 rotation channels (a hinge: ``CHANNELS 1
    Xrotation``), each axis at most once. A UTF-8 byte-order mark is
    skipped, and lines may end in LF, CR LF or CR alone. ``Frames: 0`` is a
    hierarchy without motion: a clip of 0 frames.

    Examples
    --------
    >>> from quatarray import io
    >>> from quatarray.io import sample_path
    >>> clip = io.read_bvh(sample_path())
    >>> clip.joints[:3], clip.orders[0], clip.rotations.shape, clip.frame_time
    (['Hips', 'Chest', 'Chest2'], 'ZXY', (455, 24, 4), 0.033333)
    """
    from ..skeleton import Clip

    name = os.fspath(path) if name is None else name
    with open(path, "rb") as f:
        data = f.read()
    if data.startswith(b"\xef\xbb\xbf"):  # a UTF-8 byte-order mark
        data = data[3:]
    if not data.strip():
        raise F.empty(name)
    if b"\r" in data:  # CR LF or CR alone (old Mac files) ends a line, as Python's universal newlines
        data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    # the header as text (small); the MOTION block stays bytes for numpy
    head_end = data.find(b"\nFrame Time")
    if head_end < 0:
        head_end = data.lower().find(b"frame time")
    cut = data.find(b"\n", head_end + 1) if head_end >= 0 else -1
    if cut < 0:
        cut = len(data)
    head = data[:cut].decode("utf-8", errors="replace").split("\n")
    joints, parents, offsets, channels, ends, m = _hierarchy(head, name)
    frames = frame_time = frames_line = None
    for i in range(m + 1, len(head)):
        line = head[i].strip()
        low = line.lower()
        if low.startswith("frames:"):
            frames = _num(line.split(":", 1)[1], int, name, i + 1, "frame count")
            frames_line = i + 1
        elif low.startswith("frame time:"):
            frame_time = _num(line.split(":", 1)[1], float, name, i + 1, "frame time")
        elif low:
            raise _err(name, i + 1, "expected 'Frames:' and 'Frame Time:' lines")
    if frame_time is None or not frame_time > 0:
        raise DataError(f"{name}: missing or non-positive 'Frame Time:'")
    first_line = len(head) + 1  # line number of the first byte after the header
    nch = sum(len(c) for c in channels)
    motion = _motion(data[cut + 1:] if cut < len(data) else b"", nch, name, first_line, frames, frames_line)
    return _clip(Clip, name, joints, parents, offsets, channels, ends, motion, frame_time, first_line)


def _num(s, typ, name, lineno, what):
    s = s.strip()
    try:
        if not _plain(s):
            raise ValueError(s)
        return typ(s)
    except ValueError:
        raise _err(name, lineno, f"bad {what} '{F.shown(s)}'") from None


def _motion(buf, nch, name, first_line, frames, frames_line):
    """The frames of a MOTION block as an (F, nch) array, with per-line checks done by numpy.

    Returns (values, line numbers of the frames)."""
    b = np.frombuffer(buf, np.uint8)
    ws = b <= 32  # space, tab, CR, LF (and other control bytes) separate numbers
    starts = np.flatnonzero(~ws & np.concatenate([[True], ws[:-1]]))
    nl = np.flatnonzero(b == 10)
    line_of = np.searchsorted(nl, starts)  # 0-based line index of each number
    counts = np.bincount(line_of, minlength=nl.size + 1)
    held = np.flatnonzero(counts)  # lines holding a frame
    wrong = held[counts[held] != nch]
    if wrong.size:
        i = int(wrong[0])
        raise _err(name, first_line + i, f"expected {nch} numbers, got {int(counts[i])}")
    if frames is not None and held.size != frames:
        raise _err(name, frames_line, f"'Frames:' says {frames} frame{'s' if frames != 1 else ''}, "
                                      f"the file holds {held.size}")
    if held.size == 0 and frames != 0:  # "Frames: 0" is a hierarchy without motion
        raise DataError(f"{name}: no frames in the MOTION section")
    if held.size == 0:
        return np.empty((0, nch)), held + first_line
    text = buf.decode("latin-1")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # older numpy warns and stops at a word that is not a number
            vals = np.fromstring(text, dtype=np.float64, sep=" ")
    except ValueError:  # newer numpy raises
        vals = None
    if vals is None or vals.size != held.size * nch:  # find the first word that is not a number
        lines = text.split("\n")
        for i in held:
            bad = next((s for s in lines[i].split() if not _plain(s)), None)
            if bad is not None:
                raise _err(name, first_line + int(i), f"not a number: '{F.shown(bad)}'")
        raise DataError(f"{name}: the MOTION section could not be read as numbers")  # pragma: no cover
    return vals.reshape(held.size, nch), held + first_line


def _clip(Clip, name, joints, parents, offsets, channels, ends, motion, frame_time, first_line):
    from ..euler import from_euler

    vals, lines = motion
    F_, J = vals.shape[0], len(joints)
    rot = np.empty((F_, J, 4))
    rot[:] = (1.0, 0.0, 0.0, 0.0)
    offsets = np.array(offsets, dtype=np.float64).reshape(J, 3)
    trans = np.broadcast_to(offsets, (F_, J, 3)).copy()
    c0 = 0
    for j, chans in enumerate(channels):
        ri = [c0 + k for k, c in enumerate(chans) if c.lower().endswith("rotation")]
        for k, c in enumerate(chans):
            if c.lower().endswith("position"):
                trans[:, j, "XYZ".index(c[0].upper())] = vals[:, c0 + k]
        if ri:
            ang = vals[:, ri]
            bad = ~(np.abs(ang) <= MAX_DEGREES).all(axis=1)
            if bad.any():
                i = int(np.argmax(bad))
                v = ang[i][np.argmax(~(np.abs(ang[i]) <= MAX_DEGREES))]
                raise _err(name, int(lines[i]), f"joint {joints[j]!r}: angle {float(v)!r} out of range "
                                                f"(finite, |angle| ≤ {MAX_DEGREES:.0e} degrees)")
            order = "".join(chans[k - c0][0].upper() for k in ri)
            rot[:, j] = from_euler(order, ang, degrees=True)
        c0 += len(chans)
    if not np.isfinite(trans).all():
        i, j = np.argwhere(~np.isfinite(trans).all(axis=2))[0]
        raise _err(name, int(lines[i]), f"joint {joints[j]!r}: position is not finite")
    return Clip(joints, parents, offsets, channels, rot, trans, frame_time, ends=ends)


# --------------------------------------------------------------------------
# writing


def exact_euler(q, order):
    """Intrinsic Euler angles (radians) that reproduce unit quaternions `q` exactly.

    :func:`quatarray.as_euler` follows scipy's gimbal-lock rule: within
    about 1e-7 rad of lock it sets the third angle to zero, which loses up to
    2e-7 rad of the rotation. Its angles are kept where ``from_euler`` of them
    gives back the rotation within 1e-13 rad; elsewhere (at and near lock)
    the angles are solved so that each step leaves an exactly solvable rest:
    with q = A(a) B(b) C(c) and v = q e_C, the first angle makes A(a) e_B
    perpendicular to v (a = atan2(−v·e_B, v·(e_A × e_B)), ill-conditioned near
    lock but with a residual of the order of the rounding), then b and c follow
    from the two-axis rest A(a)⁻¹ q = B(b) C(c), which has no lock.

    Parameters
    ----------
    q : array_like, shape (N, 4)
    order : str
        Intrinsic sequence of three distinct axes, e.g. ``"ZXY"``.

    Returns
    -------
    ndarray, shape (N, 3)

    Examples
    --------
    >>> import numpy as np, quatarray as qa
    >>> from quatarray.io.bvh import exact_euler
    >>> q = qa.from_euler("ZXY", [[10, 90 - 1e-6, 20]], degrees=True)  # nearly locked
    >>> a = exact_euler(q, "ZXY")
    >>> float(qa.distance(qa.from_euler("ZXY", a), q)[0]) < 1e-14
    True
    """
    from ..algebra import distance, multiply
    from ..euler import as_euler, from_euler
    from ..vectors import rotate

    q = np.asarray(q, dtype=np.float64)
    ang = as_euler(q, order, suppress_warnings=True)
    err = distance(from_euler(order, ang), q)
    fix = np.flatnonzero(~(err <= 1e-13))
    if not fix.size:
        return ang
    iA, iB, iC = ("XYZ".index(c) for c in order)
    s = 1.0 if (iB - iA) % 3 == 1 else -1.0  # e_A × e_B = s e_C, e_B × e_C = s e_A
    eye = np.eye(3)
    r = q[fix]
    v = rotate(r, np.broadcast_to(eye[iC], (len(r), 3)))
    a = np.arctan2(-v[:, iB], s * v[:, iC])
    b = c = None
    for _ in range(2):  # the branch of a that puts b in [−π/2, π/2]
        rest = multiply(_axis_quat(iA, -a), r)  # A(a)⁻¹ q = B(b) C(c)
        w = rotate(rest, np.broadcast_to(eye[iC], (len(r), 3)))
        b = np.arctan2(s * w[:, iA], w[:, iC])
        wide = np.abs(b) > np.pi / 2
        if not wide.any():
            break
        a = np.where(wide, a + np.pi, a)
        a = (a + np.pi) % (2 * np.pi) - np.pi
    rc = multiply(_axis_quat(iB, -b), rest)  # C(c)
    c = 2.0 * np.arctan2(rc[:, 1 + iC], rc[:, 0])
    c = (c + np.pi) % (2 * np.pi) - np.pi
    ang[fix] = np.column_stack([a, b, c])
    return ang


def _axis_quat(i, angle):
    out = np.zeros((len(angle), 4))
    out[:, 0] = np.cos(angle / 2)
    out[:, 1 + i] = np.sin(angle / 2)
    return out


def _fmt(x):
    return repr(float(x))


def _few_axes(q, order, joint):
    """:func:`quatarray.skeleton.few_axes_angles` of unit quaternions `q`, or the
    ValueError for a rotation that the 1 or 2 axes of `order` cannot make (more than
    1e-9 rad away, what write_bvh promises)."""
    from ..algebra import distance
    from ..euler import from_euler
    from ..skeleton import few_axes_angles

    ang = few_axes_angles(q, order)
    if len(q):
        err = distance(from_euler(order, ang), q)
        bad = ~(err <= 1e-9)
        if bad.any():
            i = int(np.argmax(bad))
            axes = " and ".join(order)
            raise ValueError(f"Joint {joint!r} has rotation channels about {axes} only, but its rotation in "
                             f"frame {i} is not about {'that axis' if len(order) == 1 else 'those axes'} "
                             f"({float(err[i]):.3g} rad away).")
    return ang


def _check_writable(clip, j):
    """The ValueError for a joint name that read_bvh would not read back as it is
    (empty, leading, trailing or repeated white space, a line break, a trailing '{',
    text that is not UTF-8), or channels that are not BVH's."""
    name = clip.joints[j]
    if not clip.ends[j]:
        try:
            name.encode("utf-8")
            ok = True
        except UnicodeEncodeError:
            ok = False
        words = name.split()
        if not ok or not words or name != " ".join(words) or words[-1] == "{":
            raise ValueError(f"Joint {j} has the name {name!r}, which BVH cannot hold (read back, it would be "
                             "another name or none): expected words separated by single spaces, without line "
                             "breaks or a trailing '{'.")
    chans = clip.channels[j]
    ok = all(isinstance(c, str) and len(c) == 9 and c[0].upper() in "XYZ"
             and c[1:].lower() in ("rotation", "position") for c in chans)
    rot = [c[0].upper() for c in chans if ok and c.lower().endswith("rotation")]
    pos = [c[0].upper() for c in chans if ok and c.lower().endswith("position")]
    if not ok or len(set(rot)) != len(rot) or len(set(pos)) != len(pos) or (clip.ends[j] and chans):
        raise ValueError(f"Joint {name!r} has channels {tuple(chans)!r}, which BVH cannot hold: expected "
                         "Xrotation … Zposition, each axis at most once among the rotations and among the "
                         "positions (none for an End Site).")


def write_bvh(path, clip):
    """Write a :class:`~quatarray.skeleton.Clip` as BVH text.

    The hierarchy as read (End Sites as End Site blocks), each joint's own
    channels in their own order, the rotations as intrinsic Euler angles in
    degrees from :func:`exact_euler` and positions, both at full precision
    (the shortest text that reads back to the same float): ``read_bvh`` of
    the file gives the same rotations within 1e-9 rad and world positions
    within 1e-9 units. ``Frame Time`` is ``clip.frame_time`` (uneven
    ``clip.times`` are not kept: BVH has no per-frame times). The file is
    written beside `path` and renamed at the end.

    A joint without rotation channels must have the identity rotation, a
    joint with 1 or 2 rotation channels (a hinge) a rotation about those
    axes (within 1e-9 rad; :meth:`Clip.resample <quatarray.skeleton.Clip.resample>`
    keeps them so), and a joint's translation components without position
    channels its OFFSET (as ``read_bvh`` gives them), or a ``ValueError`` is
    raised; so is a joint name that ``read_bvh`` would not read back as it is
    (empty, with a line break, leading, trailing or repeated white space). End
    Sites are written as End Site blocks wherever they are (one in another
    included); their names are not in the file (``read_bvh`` names them
    ``<parent>_End``). A clip without frames is written as ``Frames: 0``.

    Examples
    --------
    >>> import os, tempfile, numpy as np, quatarray as qa
    >>> from quatarray import io
    >>> from quatarray.io import sample_path
    >>> clip = io.read_bvh(sample_path())
    >>> out = os.path.join(tempfile.mkdtemp(), "walk.bvh")
    >>> io.write_bvh(out, clip)
    >>> back = io.read_bvh(out)
    >>> float(qa.distance(back.rotations, clip.rotations).max()) < 1e-9
    True
    """
    F_, J = clip.rotations.shape[:2]
    ft = clip.frame_time
    if not (isinstance(ft, (int, float, np.floating)) and ft > 0 and np.isfinite(ft)):
        raise ValueError(f"Expected a positive, finite `frame_time`, got {ft!r} (read_bvh would refuse the file).")
    for j in range(J):
        _check_writable(clip, j)
    out = ["HIERARCHY"]
    kids = [[] for _ in range(J)]
    for j, p in enumerate(clip.parents):
        if p >= 0:
            kids[p].append(j)

    def emit(j, d):
        ind = "\t" * d
        off = " ".join(_fmt(v) for v in clip.offsets[j])
        if clip.ends[j]:  # its name is not written: read_bvh names it <parent>_End
            out.extend([f"{ind}End Site", f"{ind}{{", f"{ind}\tOFFSET {off}"])
        else:
            out.append(f"{ind}{'ROOT' if clip.parents[j] < 0 else 'JOINT'} {clip.joints[j]}")
            out.append(f"{ind}{{")
            out.append(f"{ind}\tOFFSET {off}")
            out.append(f"{ind}\tCHANNELS {len(clip.channels[j])} {' '.join(clip.channels[j])}".rstrip())
        for k in kids[j]:  # an End Site's children too (read_bvh reads an End Site in an End Site)
            emit(k, d + 1)
        out.append(f"{ind}}}")

    # a depth-first walk of each root keeps the joints in the file's order
    # (and must give them back in clip order, or the channel columns would not match)
    order = []

    def walk(j):
        order.append(j)
        for k in kids[j]:
            walk(k)

    for j in range(J):
        if clip.parents[j] < 0:
            walk(j)
            emit(j, 0)
    if order != list(range(J)):
        raise ValueError("Expected the joints in depth-first order (as read_bvh gives them).")
    cols = []
    for j in range(J):
        chans = clip.channels[j]
        order_j = clip.orders[j]
        ang = None
        if len(order_j) == 3:
            ang = np.degrees(exact_euler(clip.rotations[:, j], order_j))
        elif order_j:  # a hinge (1 axis) or 2 axes
            ang = np.degrees(_few_axes(clip.rotations[:, j], order_j, clip.joints[j]))
        elif not (np.abs(np.abs(clip.rotations[:, j, 0]) - 1.0) <= 1e-12).all():
            raise ValueError(f"Joint {clip.joints[j]!r} has no rotation channels but turns.")
        fixed = [a for a in range(3) if "XYZ"[a] not in "".join(c[0].upper() for c in chans
                                                                   if c.lower().endswith("position"))]
        dev = np.abs(clip.translations[:, j, fixed] - clip.offsets[j, fixed])
        if not (dev <= 1e-9 * np.maximum(1.0, np.abs(clip.offsets[j, fixed]))).all():
            raise ValueError(f"Joint {clip.joints[j]!r} moves along an axis it has no position channel for.")
        r = 0
        for c in chans:
            if c.lower().endswith("rotation"):
                cols.append(ang[:, r])
                r += 1
            else:
                cols.append(clip.translations[:, j, "XYZ".index(c[0].upper())])
    out.append("MOTION")
    out.append(f"Frames: {F_}")
    out.append(f"Frame Time: {_fmt(clip.frame_time)}")
    from .writers import Writer

    with Writer(path) as w, open(w.tmp, "wb") as f:
        f.write(("\n".join(out) + "\n").encode("utf-8"))
        if cols:
            _write_rows(f, np.column_stack(cols))
        else:
            f.write(b"\n" * F_)


def _write_rows(f, m):
    """Rows of floats, space separated, shortest round-trip text (pyarrow's CSV writer)."""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    table = pa.table([pa.array(np.ascontiguousarray(m[:, k])) for k in range(m.shape[1])],
                     names=[f"c{k}" for k in range(m.shape[1])])
    opts = pcsv.WriteOptions(include_header=False, delimiter=" ", quoting_style="none", batch_size=1 << 14)
    pcsv.write_csv(table, f, write_options=opts)


def write_positions(path, clip, fmt=None):
    """World joint positions of every frame: npy ``(F, J, 3)``, or csv/parquet with
    columns ``t joint x y z`` (one row per frame × joint, frames in order, joints
    in clip order). Written beside `path` and renamed at the end.

    Examples
    --------
    >>> import os, tempfile, numpy as np
    >>> from quatarray import io
    >>> from quatarray.io import sample_path
    >>> out = os.path.join(tempfile.mkdtemp(), "p.npy")
    >>> io.bvh.write_positions(out, io.read_bvh(sample_path()))
    >>> np.load(out).shape
    (455, 24, 3)
    """
    from .writers import Writer

    fmt = fmt or F.output_format(path)
    _, p = clip.world()
    F_, J = p.shape[:2]
    with Writer(path) as w:
        if fmt == "npy":
            with open(w.tmp, "wb") as f:
                np.save(f, p)
            return
        if fmt not in ("csv", "parquet"):
            raise UsageError(f"{path}: positions are written as .npy, .csv or .parquet")
        import pyarrow as pa

        names = pa.DictionaryArray.from_arrays(np.tile(np.arange(J, dtype=np.int32), F_), pa.array(clip.joints))
        flat = p.reshape(-1, 3)
        table = pa.table([pa.array(np.repeat(clip.times, J)), names] + [pa.array(flat[:, k]) for k in range(3)],
                         names=["t", "joint", "x", "y", "z"])
        if fmt == "parquet":
            import pyarrow.parquet as pq

            pq.write_table(table, w.tmp)
        else:
            plain = not any(set(j) & set(',"\n\r') for j in clip.joints)
            write_csv(table.cast(pa.schema([("t", pa.float64()), ("joint", pa.string()), ("x", pa.float64()),
                                            ("y", pa.float64()), ("z", pa.float64())])), w.tmp,
                      quoting_style="none" if plain else "needed", batch_size=1 << 16)


# --------------------------------------------------------------------------
# one joint as a stream


class BvhReader(Reader):
    """One joint of a BVH motion-capture file as a quaternion stream.

    The joint's rotation channels, in the order the file lists them, form an
    intrinsic Euler sequence (``Zrotation Xrotation Yrotation`` → ``"ZXY"``;
    a hinge's one or two axes, ``"X"``) in degrees; position channels (the root's) become the position columns;
    frame i is at time i × Frame Time.
    """

    format = "bvh"
    has_time = True

    def __init__(self, path, name, joint, chunk, on_invalid):
        self.path, self.name, self.chunk = path, name, chunk
        self.drop = on_invalid == "drop"
        self.skipped = 0
        self._parse_header(joint)

    def _parse_header(self, want):
        name = self.name
        joints = []  # (name, first channel index, [channel names], line)
        nch = 0
        self.motion_line = None
        with open(self.path, "r", encoding="utf-8", errors="replace") as f:
            lines = iter(enumerate(f, 1))
            current = None
            for lineno, line in lines:
                tok = line.split()
                if not tok:
                    continue
                key = tok[0].upper()
                if key in ("ROOT", "JOINT"):
                    current = " ".join(tok[1:])
                elif key == "CHANNELS":
                    try:
                        k = int(tok[1])
                    except (IndexError, ValueError):
                        raise DataError(f"{name}:{lineno}: bad CHANNELS line") from None
                    chans = tok[2:]
                    if len(chans) != k:
                        raise DataError(f"{name}:{lineno}: CHANNELS says {k} channels, lists {len(chans)}")
                    joints.append((current, nch, chans, lineno))
                    nch += k
                elif key == "MOTION":
                    self.motion_line = lineno
                    break
            if self.motion_line is None:
                if not joints:
                    if os.path.getsize(self.path) == 0:
                        raise F.empty(name)
                    raise DataError(f"{name}:1: not a BVH file (no HIERARCHY/MOTION sections)")
                raise DataError(f"{name}: no MOTION section")
            frames = frame_time = None
            for lineno, line in lines:
                low = line.strip().lower()
                if low.startswith("frames:"):
                    frames = _num(line.split(":", 1)[1], int, name, lineno, "frame count")
                    self.frames_line = lineno
                elif low.startswith("frame time:"):
                    frame_time = _num(line.split(":", 1)[1], float, name, lineno, "frame time")
                    self.data_line = lineno + 1
                    break
                elif low:
                    raise DataError(f"{name}:{lineno}: expected 'Frames:' and 'Frame Time:' lines")
        if frame_time is None or not frame_time > 0:
            raise DataError(f"{name}: missing or non-positive 'Frame Time:'")
        self.frames, self.frame_time, self.nch = frames, frame_time, nch
        self.joints = [j[0] for j in joints]
        if want is None:
            sel = joints[0]
        else:
            sel = next((j for j in joints if j[0] == want), None)
            if sel is None:
                raise UsageError(f"{name}: no joint {want!r} (joints: {', '.join(self.joints)})")
        self.joint, first, chans, lineno = sel
        rot = [(k, c[0].upper()) for k, c in enumerate(chans) if c.lower().endswith("rotation")]
        pos = {c[0].upper(): k for k, c in enumerate(chans) if c.lower().endswith("position")}
        if not rot or len({a for _, a in rot}) != len(rot):
            raise DataError(f"{name}:{lineno}: joint {self.joint!r} has {len(rot)} rotation channels, need 1, 2 "
                            "or 3 about distinct axes")
        self.euler = "".join(a for _, a in rot)  # 1 or 2 axes for a hinge
        self.seq = self.euler if len(rot) == 3 else None  # a sequence of three, for the Euler plots
        self.rot_idx = [first + k for k, _ in rot]
        self.pos_idx = [first + pos[a] for a in "XYZ"] if all(a in pos for a in "XYZ") else None
        self.columns = [f"{self.joint}.{chans[k]}" for k in range(len(chans))]
        self.layout = f"euler {self.euler} (intrinsic, degrees)"
        self.has_pos = self.pos_idx is not None
        self.rows = frames

    def where(self, row):
        return f"{self.name}:{self.data_line + row}"

    def _motion(self):
        """All frames as an (n, channels) array; frame i sits at line data_line + i."""
        name, n = self.name, self.nch
        rows, frame_idx = [], []
        with open(self.path, "r", encoding="utf-8", errors="replace") as f:
            for lineno, line in enumerate(f, 1):
                if lineno < self.data_line:
                    continue
                tok = line.split()
                if not tok:
                    continue
                k = lineno - self.data_line
                if len(tok) != n:
                    if self.drop:
                        self.skipped += 1
                        continue
                    raise DataError(f"{name}:{lineno}: expected {n} numbers, got {len(tok)}")
                try:
                    rows.append(np.array(tok, dtype=np.float64))
                except ValueError:
                    if self.drop:
                        self.skipped += 1
                        continue
                    bad = next(s for s in tok if not is_number(s))
                    raise DataError(f"{name}:{lineno}: not a number: '{F.shown(bad)}'") from None
                frame_idx.append(k)
        held = self.skipped + len(rows)
        if self.frames is not None and held != self.frames:
            what = (f"{name}:{self.frames_line}: 'Frames:' says {self.frames} frame{'s' if self.frames != 1 else ''}, "
                    f"the file holds {held}")
            if not self.drop:
                raise DataError(what)
            self.notes.append(f"{what}; read those {held}")
        if not rows and self.frames != 0:  # "Frames: 0": a hierarchy without motion, no rows
            raise F.empty(name)
        return np.array(rows).reshape(len(rows), n), np.array(frame_idx, dtype=np.int64)

    def __iter__(self):
        from ..euler import from_euler

        motion, idx = self._motion()
        self.rows = len(motion)
        t_all = idx * self.frame_time
        for a in range(0, len(motion), self.chunk):
            m = motion[a : a + self.chunk]
            ang = m[:, self.rot_idx]
            fin = np.isfinite(ang).all(axis=1)
            huge = fin & (np.abs(np.where(fin[:, None], ang, 0)) > MAX_DEGREES).any(axis=1)
            if huge.any():
                i = int(np.argmax(huge))
                if not self.drop:
                    v = float(ang[i][np.argmax(np.abs(ang[i]))])
                    raise DataError(f"{self.where(int(idx[a + i]))}: angle {v!r} out of range "
                                    f"(|angle| > {MAX_DEGREES:.0e} degrees: no precision left for the rotation)")
                fin &= ~huge  # a nan row, dropped by the Cleaner
            q = np.full((len(m), 4), np.nan)
            q[fin] = from_euler(self.euler, ang[fin], degrees=True)
            pos = m[:, self.pos_idx] if self.pos_idx else None
            yield Chunk(q, t_all[a : a + len(m)], pos, int(idx[a]))


def sample_path():
    """Path of the motion-capture sample (a BVH clip) that ships with the package,
    the input of ``quatarray demo``.

    Examples
    --------
    >>> from quatarray.io import sample_path, read_bvh
    >>> read_bvh(sample_path()).rotations.ndim
    3
    """
    from importlib import resources

    return str(resources.files("quatarray").joinpath("data", "mocapbank_walk.bvh"))
