"""The front end: validation, dtype rules, broadcasting and ``out=``.

Kernels never check anything; every public function runs its arguments
through here first. Every shape error uses one template::

    Expected `q` to have shape (..., 4), got (10, 3).
"""

import contextlib
import contextvars
import math
import operator

import numpy as np

from ._compat import reshape_view

_F32 = np.dtype(np.float32)
_F64 = np.dtype(np.float64)
_FLOATS = (_F32, _F64)
_WEAK = (float, int, bool)


def _spec(core):
    return "(" + ", ".join(["..."] + [str(c) for c in core]) + ")"


def shape_error(name, expected, got):
    """The one message template for a bad shape."""
    return ValueError(f"Expected `{name}` to have shape {expected}, got {tuple(got)}.")


# Where the arrays a function is given start in a larger array: set by quatarray.dask
# for each block, so that messages name the row of the whole array.
_ORIGIN = contextvars.ContextVar("quatarray_origin", default=())


@contextlib.contextmanager
def origin(start):
    """Messages from :func:`where` inside this block count rows from `start`
    (the first index, along the leading axes, of the arrays being passed)."""
    token = _ORIGIN.set(tuple(int(k) for k in start))
    try:
        yield
    finally:
        _ORIGIN.reset(token)


def where(flat_index, lead):
    """The item `flat_index` of a batch of leading shape `lead`, as messages name it:
    ``row 3``, ``index (1, 2)``, or ``the single input`` (counted in the whole array
    inside a block: see :func:`origin`)."""
    if len(lead) == 0:
        return "the single input"
    index = np.unravel_index(int(flat_index), lead)
    start = _ORIGIN.get() or (0,) * len(lead)
    index = tuple(int(i) + k for i, k in zip(index, start))
    return f"row {index[0]}" if len(lead) == 1 else f"index {index}"


def is_weak(x):
    """Python scalars (``0.5``, ``3``) do not take part in dtype promotion."""
    return type(x) in _WEAK


def refuse_masked(x, name):
    """Raise ``TypeError`` for a masked array: the kernels would read the
    masked-out values as numbers (quatarray does not guess what a mask means)."""
    if isinstance(x, np.ma.MaskedArray):
        raise TypeError(
            f"Expected `{name}` to be a plain array, got a masked array "
            f"(its mask would be ignored; fill or compress it first, e.g. `{name}.filled(np.nan)`)."
        )


def as_float(x, name, dtype=None):
    """``x`` as a native float32 or float64 ndarray (no copy where none is needed).

    float32 and float64 are kept, in either byte order (the result is in the
    native order); float16 becomes float32; longer floats, integers, booleans
    and lists become float64; complex, object and strings raise ``TypeError``,
    and so do masked arrays (see :func:`refuse_masked`). ``dtype`` forces a
    float dtype.
    """
    if isinstance(x, np.ndarray):
        refuse_masked(x, name)
        a = np.asarray(x)  # drops subclasses such as np.memmap, never copies
    else:
        try:
            a = np.asarray(x)
        except (ValueError, TypeError) as exc:
            raise TypeError(f"Expected `{name}` to be an array of real numbers: {exc}") from None
    kind = a.dtype.kind
    if kind == "f":
        if a.dtype not in _FLOATS:  # float16, non-native byte order, long double
            a = a.astype(_F32 if a.dtype.itemsize <= 4 else _F64)
    elif kind in "biu":
        a = a.astype(np.float64)
    else:
        raise TypeError(f"Expected `{name}` to have a real (float, integer or bool) dtype, got {a.dtype}.")
    if dtype is not None and a.dtype != dtype:
        a = a.astype(dtype)
    return a


def integer(x, name):
    """`x` as a Python int: an integer or a 0-d integer array (as numpy takes
    them, through ``operator.index``); booleans, floats and strings raise the
    house ``TypeError``."""
    if not isinstance(x, (bool, np.bool_)):
        try:
            return operator.index(x)
        except TypeError:
            pass
    raise TypeError(f"Expected `{name}` to be an integer, got {type(x).__name__} {x!r}.")


def leading_shape(shape, name):
    """A leading-shape argument (``identity(shape)``, ``random(n)``) as a tuple:
    a non-negative integer (or 0-d integer array) or a sequence of them.
    Anything else raises ``TypeError``, a negative size ``ValueError``, both
    naming the argument."""
    try:
        dims = (integer(shape, name),)
    except TypeError:
        try:
            dims = tuple(integer(k, name) for k in shape)
        except TypeError:
            raise TypeError(
                f"Expected `{name}` to be a non-negative integer or a tuple of them, "
                f"got {type(shape).__name__} {shape!r}."
            ) from None
    if any(k < 0 for k in dims):
        raise ValueError(f"Expected `{name}` to be a non-negative integer or a tuple of them, got {shape!r}.")
    return dims


def as_times(x, name):
    """Sample times as an ndarray of a real, non-boolean dtype (floats or
    integers such as nanosecond stamps, kept as they are); else ``TypeError``
    naming the argument."""
    refuse_masked(x, name)
    t = np.asarray(x)
    if t.dtype.kind not in "iuf":
        raise TypeError(f"Expected `{name}` to have a real (float or integer) dtype, got {t.dtype}.")
    return t


def spline_order(order):
    """A spline's derivative `order`: 0, 1 or 2 as a Python int (not a bool, not a float)."""
    if isinstance(order, (bool, np.bool_)) or not isinstance(order, (int, np.integer)) or order not in (0, 1, 2):
        raise ValueError(f"Expected `order` to be 0, 1 or 2, got {order!r}.")
    return int(order)


def float_dtype(dtype):
    """A `dtype` argument checked to be float32 or float64."""
    d = np.dtype(dtype)
    if d not in _FLOATS:
        raise TypeError(f"Expected `dtype` to be float32 or float64, got {d}.")
    return d


def check_core(a, name, core):
    """Raise the template ``ValueError`` unless ``a.shape`` ends with ``core``."""
    k = len(core)
    if a.ndim < k or (k and a.shape[a.ndim - k :] != tuple(core)):
        raise shape_error(name, _spec(core), a.shape)
    return a


def result_dtype(arrays, weak=()):
    """float32 when every non-weak input is float32, else float64."""
    strong = [a.dtype for a, w in zip(arrays, weak or [False] * len(arrays)) if not w]
    if strong and all(d == np.float32 for d in strong):
        return np.dtype(np.float32)
    return np.dtype(np.float64)


def leading(arrays, cores, names):
    """The broadcast leading shape of ``arrays`` (each with its core shape)."""
    leads = [a.shape[: a.ndim - len(c)] for a, c in zip(arrays, cores)]
    first = leads[0]
    if all(s == first for s in leads):
        return first
    try:
        return np.broadcast_shapes(*leads)
    except ValueError:
        pairs = " and ".join(f"`{n}` {a.shape}" for n, a in zip(names, arrays))
        raise ValueError(f"Expected the leading dimensions of {pairs} to broadcast.") from None


def flatten(a, lead, core):
    """``a`` broadcast to ``lead + core`` and viewed as ``(n,) + core``."""
    core = tuple(core)
    if a.shape[: a.ndim - len(core)] != lead:
        a = np.broadcast_to(a, lead + core)
    if len(lead) == 1:
        return a
    return a.reshape((math.prod(lead),) + core)


def check_out(out, shape, dtype):
    """Raise ``ValueError`` unless ``out`` is a writeable array of this shape and dtype."""
    if not isinstance(out, np.ndarray) or isinstance(out, np.ma.MaskedArray):
        raise ValueError(f"Expected `out` to be a numpy array, got {type(out).__name__}.")
    if out.shape != tuple(shape) or out.dtype != dtype:
        raise ValueError(
            f"Expected `out` to have shape {tuple(shape)} and dtype {np.dtype(dtype)}, "
            f"got shape {out.shape} and dtype {out.dtype}."
        )
    if not out.flags.writeable:
        raise ValueError("Expected `out` to be writeable, got a read-only array.")
    return out


def _same_view(a, b):
    return (
        a.shape == b.shape
        and a.strides == b.strides
        and a.__array_interface__["data"][0] == b.__array_interface__["data"][0]
    )


def elementwise(kernel, inputs, out_cores, out=None, result=None):
    """Run a row kernel over broadcast inputs; the one path every element-wise function takes.

    Parameters
    ----------
    kernel : callable
        ``kernel(*inputs_2d, *outputs_2d)``; each input and output is viewed as
        ``(n,) + core``.
    inputs : list of (value, name, core)
        ``core`` is the trailing shape the argument must end with, e.g.
        ``(4,)`` for a quaternion or ``()`` for a scalar parameter.
    out_cores : list of tuple
        Core shapes of the outputs.
    out : ndarray, optional
        Only for a single output: filled and returned.
    result : dtype, optional
        Force the result dtype (defaults to the dtype rule).

    Returns
    -------
    ndarray or tuple of ndarray
    """
    arrays, cores, leads = [], [], []
    all32, strong = True, False
    for value, name, core in inputs:
        if type(value) is np.ndarray and (value.dtype is _F64 or value.dtype is _F32):
            a = value  # the common case, checked without a function call
        else:
            a = as_float(value, name)
        k = len(core)
        shape = a.shape
        if k:
            if len(shape) < k or shape[-k:] != core:
                raise shape_error(name, _spec(core), shape)
            leads.append(shape[:-k])
        else:
            leads.append(shape)
        if type(value) not in _WEAK:
            strong = True
            all32 = all32 and a.dtype == _F32
        arrays.append(a)
        cores.append(core)
    if result is not None:
        dtype = np.dtype(result)
    else:
        dtype = _F32 if (strong and all32) else _F64
    lead = leads[0]
    for s in leads:
        if s != lead:
            lead = leading(arrays, cores, [i[1] for i in inputs])
            break
    n = math.prod(lead)
    flat = [flatten(a if a.dtype == dtype else a.astype(dtype), lead, c) for a, c in zip(arrays, cores)]

    if out is None:
        outs = [np.empty((n,) + c, dtype) for c in out_cores]
        kernel(*flat, *outs)
        res = [o.reshape(lead + c) for o, c in zip(outs, out_cores)]
        res = [r[()] if r.ndim == 0 else r for r in res]
        return res[0] if len(res) == 1 else tuple(res)

    if len(out_cores) != 1:
        raise ValueError("`out` is only accepted by functions with a single result.")
    core = out_cores[0]
    check_out(out, lead + core, dtype)
    # A subclass (np.matrix, say) may reshape to other shapes than asked: the
    # kernels see its plain ndarray view.
    base = out if type(out) is np.ndarray else out.view(np.ndarray)
    try:
        o = reshape_view(base, (n,) + core)
    except ValueError:
        o = None
    target = o if o is not None else np.empty((n,) + core, dtype)
    # An input overlapping `out` other than as the very same view is copied
    # first: a row must never read what an earlier row wrote. The very same view
    # goes to a loop that knows it (RowLoop.into), where the loop has one.
    same = -1
    for i, f in enumerate(flat):
        if np.may_share_memory(f, target):
            if _same_view(f, target):
                same = i
            else:
                flat[i] = f.copy()
    if same >= 0 and hasattr(kernel, "into"):
        kernel.into(same, *flat)
    else:
        kernel(*flat, target)
    if o is None:
        base[...] = target.reshape(base.shape)
    return out


def scan(kernel, q, axis, fname):
    """Run a scan ``kernel(q3, out3)`` along a leading axis of a quaternion array.

    `axis` counts the leading (non-quaternion) axes. The kernel sees ``(K, M, 4)``
    views (the scan runs along the first axis, for each of the M columns) and
    is not called for K = 0.
    """
    axis = integer(axis, "axis")
    a = check_core(as_float(q, "q"), "q", (4,))
    lead = a.ndim - 1
    if lead == 0:
        raise ValueError(f"Expected `q` to have shape (N, ..., 4) for {fname}, got (4,).")
    if not -lead <= axis < lead:
        raise ValueError(f"Expected `axis` in [{-lead}, {lead - 1}] for `q` of shape {a.shape}, got {axis}.")
    m = np.moveaxis(a, axis % lead, 0)
    shape = m.shape
    out = np.empty((shape[0], math.prod(shape[1:-1]), 4), a.dtype)
    if shape[0]:
        kernel(m.reshape(out.shape), out)
    return np.moveaxis(out.reshape(shape), 0, axis % lead)


# ---- key streams: (K, 4) keys and their strictly increasing times


def key_array(keys, name="keys", k_min=2):
    """`keys` as a float array of shape (K, 4) with K ≥ `k_min`."""
    a = check_core(as_float(keys, name), name, (4,))
    if a.ndim != 2:
        raise shape_error(name, "(K, 4)", a.shape)
    if a.shape[0] < k_min:
        raise ValueError(f"Expected `{name}` to hold at least {k_min} keys, got {a.shape[0]}.")
    return a


def key_times(times, k=None, name="times"):
    """`times` as an array of shape (K,) (`k` keys, when given) that strictly increases."""
    t = np.asarray(times)
    check_times(t, k, name)
    i = first_not_increasing(t)
    if i is not None:
        raise not_increasing(name, i, t[i], t[i + 1])
    return t


def check_times(t, k, name):
    """The dtype and shape rules for key times (a numpy or a Dask array)."""
    if t.dtype.kind not in "biuf":
        raise TypeError(f"Expected `{name}` to have a real dtype, got {t.dtype}.")
    if t.ndim != 1 or (k is not None and t.shape[0] != k):
        raise ValueError(f"Expected `{name}` to have shape ({'K' if k is None else k},), got {tuple(t.shape)}.")


def first_not_increasing(t):
    """The first i with ``not t[i] < t[i + 1]`` (nan included), or None."""
    bad = ~(t[1:] > t[:-1])
    return int(np.argmax(bad)) if bad.any() else None


def not_increasing(name, i, before, after):
    """The error for ``name[i + 1] = after`` not above ``name[i] = before``."""
    return ValueError(
        f"Expected `{name}` to be strictly increasing, got {name}[{i + 1}] = {after.item()} "
        f"after {name}[{i}] = {before.item()}."
    )
