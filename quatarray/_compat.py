"""Shims for the oldest releases of numpy and pyarrow that quatarray supports
(``pyproject.toml``'s floors, tested by ``noxfile.py``'s ``floor`` session).

Each is a feature test, not a version test: the newer call where the library
has it, the same result by older means where it does not.
"""

import inspect

import numpy as np

try:  # numpy >= 2.1: np.reshape(..., copy=False) raises instead of copying
    _RESHAPE_COPY = "copy" in inspect.signature(np.reshape).parameters
except (TypeError, ValueError):  # pragma: no cover - no signature
    _RESHAPE_COPY = False


def reshape_view(a, shape):
    """A view of the array `a` in `shape` (``np.reshape(a, shape, copy=False)``);
    ValueError where that takes a copy.

    Examples
    --------
    >>> import numpy as np
    >>> a = np.zeros((2, 6))
    >>> reshape_view(a, (3, 4)).base is a
    True
    >>> try:
    ...     reshape_view(a.T, (12,))
    ... except ValueError:
    ...     print("a copy would be needed")
    a copy would be needed
    """
    if _RESHAPE_COPY:
        return np.reshape(a, shape, copy=False)
    v = a.view()
    try:
        v.shape = shape  # numpy < 2.1: in place, or AttributeError where a copy is needed
    except AttributeError:
        raise ValueError(f"cannot reshape this array to {tuple(shape)} without a copy") from None
    return v


_QUOTING_HEADER = []  # [bool]: pyarrow's WriteOptions takes quoting_header (pyarrow >= 22)


def csv_write_options(include_header=True, **options):
    """``(pyarrow.csv.WriteOptions(include_header=…, quoting_header="none", **options),
    by_hand)``: where pyarrow has no ``quoting_header`` (before 22; its header is
    then always quoted), the options leave the header out and `by_hand` is True:
    the caller writes the header line itself, its names joined by the delimiter
    as they are (what ``quoting_header="none"`` writes)."""
    import pyarrow.csv as pcsv

    if not _QUOTING_HEADER:
        try:
            pcsv.WriteOptions(quoting_header="none")
            _QUOTING_HEADER.append(True)
        except TypeError:
            _QUOTING_HEADER.append(False)
    if _QUOTING_HEADER[0]:
        return pcsv.WriteOptions(include_header=include_header, quoting_header="none", **options), False
    return pcsv.WriteOptions(include_header=False, **options), include_header


def header_line(names, delimiter=","):
    """The header line that ``quoting_header="none"`` writes: `names` joined, unquoted."""
    return (delimiter.join(names) + "\n").encode()


def write_csv(table, path, include_header=True, **options):
    """``pyarrow.csv.write_csv`` of `table` to the file `path` with the header unquoted
    (:func:`csv_write_options`)."""
    import pyarrow.csv as pcsv

    opts, by_hand = csv_write_options(include_header=include_header, **options)
    if not by_hand:
        pcsv.write_csv(table, path, write_options=opts)
        return
    with open(path, "wb") as f:
        f.write(header_line(table.schema.names, options.get("delimiter", ",")))
        pcsv.write_csv(table, f, write_options=opts)


_SCALAR_FIRST = []  # [bool]: scipy's Rotation takes scalar_first (scipy >= 1.14)


def _scalar_first():
    if not _SCALAR_FIRST:
        from scipy.spatial.transform import Rotation

        try:
            Rotation.identity().as_quat(scalar_first=True)
            _SCALAR_FIRST.append(True)
        except TypeError:
            _SCALAR_FIRST.append(False)
    return _SCALAR_FIRST[0]


_ND_STACKS = []  # [bool]: scipy's Rotation holds stacks of any dimension, (..., 4) (scipy >= 1.17)


def scipy_nd_stacks():
    """True where scipy's ``Rotation`` takes quaternions of shape (..., 4) with more
    than one leading axis; older releases take (4,) and (N, 4) only."""
    if not _ND_STACKS:
        from scipy.spatial.transform import Rotation

        try:
            Rotation.from_quat(np.array([[[0.0, 0.0, 0.0, 1.0]]]))
            _ND_STACKS.append(True)
        except ValueError:
            _ND_STACKS.append(False)
    return _ND_STACKS[0]


def rotation_from_wxyz(q):
    """``scipy.spatial.transform.Rotation.from_quat(q, scalar_first=True)``, also on
    scipy < 1.14 (which takes (x, y, z, w) only)."""
    from scipy.spatial.transform import Rotation

    if _scalar_first():
        return Rotation.from_quat(q, scalar_first=True)
    return Rotation.from_quat(np.roll(np.asarray(q), -1, axis=-1))


def rotation_as_wxyz(r):
    """``r.as_quat(scalar_first=True)`` of a scipy Rotation, also on scipy < 1.14."""
    if _scalar_first():
        return r.as_quat(scalar_first=True)
    return np.roll(r.as_quat(), 1, axis=-1)
