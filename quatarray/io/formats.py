"""Format detection and the column names each format uses."""

import os

from .errors import DataError, UsageError

FORMATS = ("auto", "npy", "csv", "tum", "euroc", "parquet", "bvh", "kitti")
OUT_FORMATS = {".npy": "npy", ".csv": "csv", ".parquet": "parquet", ".pq": "parquet", ".tum": "tum", ".txt": "tum"}

# accepted header names (lower case) for each role in csv and parquet inputs
TIME_NAMES = ("t", "time", "timestamp")
POS_NAMES = (("x", "y", "z"), ("tx", "ty", "tz"), ("px", "py", "pz"))
QUAT_NAMES = (("qw", "qx", "qy", "qz"), ("w", "x", "y", "z"))
VEC_NAMES = (("x", "y", "z"), ("vx", "vy", "vz"))
RATE_NAMES = (("wx", "wy", "wz"),)  # angular velocity (``integrate``)

TUM_NAMES = ["timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"]
KITTI_NAMES = [f"r{i}{j}" if j < 3 else f"t{i}" for i in range(3) for j in range(4)]
EUROC_TIME = "timestamp"
EUROC_POS = ["p_RS_R_x", "p_RS_R_y", "p_RS_R_z"]
EUROC_QUAT = ["q_RS_w", "q_RS_x", "q_RS_y", "q_RS_z"]
EUROC_RATE = ["w_RS_S_x", "w_RS_S_y", "w_RS_S_z"]  # EuRoC IMU files (gyroscope, rad/s)


def by_extension(path):
    ext = os.path.splitext(str(path))[1].lower()
    return {".npy": "npy", ".parquet": "parquet", ".pq": "parquet", ".bvh": "bvh"}.get(ext)


def is_zarr(path):
    """Whether `path` names a zarr store (a folder whose name ends in ``.zarr``)."""
    return os.fspath(path).rstrip("/" + os.sep).endswith(".zarr")


def output_format(path):
    """The writer for OUT, chosen by its extension."""
    ext = os.path.splitext(str(path))[1].lower()
    fmt = OUT_FORMATS.get(ext)
    if fmt is None:
        zarr = " (a .zarr store is written by convert and resample with --scheduler)" if ext == ".zarr" else ""
        raise UsageError(
            f"{path}: cannot tell the output format from the extension {ext or '(none)'!r}; "
            f"use .npy, .csv, .parquet, or .tum/.txt (TUM){zarr}"
        )
    return fmt


def empty(name):
    return DataError(f"{name}: empty file (no data rows)")


def is_number(s):
    """Whether the text `s` reads as a float."""
    try:
        float(s)
        return True
    except ValueError:
        return False


def plain_number(x):
    """A number as messages show it: plain and exact (``1311868164.5``, not ``np.float64(…)``)."""
    return repr(float(x))


def shown(text, limit=60):
    """`text` as an error message may show it: characters that are not printable
    (control characters, undecodable bytes) escaped as ``repr`` escapes them
    (``\\x00``), and cut to `limit` characters with ``…``.

    Examples
    --------
    >>> shown("ab\\x00c")
    'ab\\\\x00c'
    >>> shown(b"\\xff\\xfe" + b"x" * 70, limit=10)
    '\\\\xff\\\\xfex…'
    """
    if isinstance(text, bytes):
        text = text.decode("utf-8", "backslashreplace")
    s = "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(text))
    return s if len(s) <= limit else s[: limit - 1] + "…"


def unquoted(name):
    """A header name without the quotes a spreadsheet may have put around it."""
    name = name.strip()
    if len(name) >= 2 and name[0] == name[-1] and name[0] in "\"'":
        return name[1:-1].strip()
    return name
