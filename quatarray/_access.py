"""Row access for the kernels: the one set of loads and stores of a scalar, a
vector, a quaternion and a 3×3 matrix.

=====================  ==============================================================
``load1(a, i)``        element i of a 1-D array; ``store1(out, i, x)``
``load3(a, i)``        row i of an (n, 3) array as a 3-tuple; ``store3(out, i, v)``
``load4(a, i)``        quaternion i as a 4-tuple: row i of an (n, 4) array, or
                       elements 4i … 4i + 3 of a flat (4n,) array; ``store4(out, i, q)``
``load33(a, i)``       matrix i of an (n, 3, 3) array as a row-major 9-tuple;
                       ``store33(out, i, m)``
``loads(a, j, k)``     elements j … j + k − 1 of a C-contiguous buffer as a k-tuple
                       (k literal); ``stores(out, j, x)``: a flat table's row
``loads_at(a, j, s,    elements j, j + s, …, j + (k − 1)s of a C-contiguous buffer
k)``                   (k literal); ``stores_at(out, j, s, x)``: a column of planes
                       (SIMD lanes side by side, such as a tile's)
``stream4(out, i, q)`` ``store4`` past the caches, for an output that :func:`streams`;
                       ``stream_end()`` after a loop's last one
``prefetch(a, j)``     a hint: element j of a C-contiguous buffer is read soon
=====================  ==============================================================

Compiled, a C-contiguous array is addressed as a flat buffer at a literal
stride (element ``k*i + c``), without negative-index wraparound, so LLVM can
bound the addresses and vectorise the row loops (numba addresses ``a[i, c]``
with the run-time row length ``a.shape[1]``, which keeps it from doing so);
other layouts (strided, broadcast) are addressed by their strides. The row
length must be exactly the one named (the front end guarantees it). Without
the JIT the plain-Python bodies run. With ``QUATARRAY_CHECK_BOUNDS=1`` (the
debug mode, see :mod:`quatarray._jit`) every access checks its index and raises
``IndexError`` past the array.
"""

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import lower_builtin, type_callable

from ._jit import CHECK_BOUNDS, STREAM_MIN_BYTES, element, statement


def load1(a, i):
    return a[i]


def store1(out, i, x):
    out[i] = x


def load3(a, i):
    return (a[i, 0], a[i, 1], a[i, 2])


def store3(out, i, v):
    out[i, 0] = v[0]
    out[i, 1] = v[1]
    out[i, 2] = v[2]


def load4(a, i):
    if a.ndim == 1:
        return (a[4 * i], a[4 * i + 1], a[4 * i + 2], a[4 * i + 3])
    return (a[i, 0], a[i, 1], a[i, 2], a[i, 3])


def store4(out, i, q):
    if out.ndim == 1:
        out[4 * i], out[4 * i + 1], out[4 * i + 2], out[4 * i + 3] = q
    else:
        out[i, 0] = q[0]
        out[i, 1] = q[1]
        out[i, 2] = q[2]
        out[i, 3] = q[3]


@element(how="call")
def load33(a, i):
    """Matrix ``a[i]`` of an ``(n, 3, 3)`` array: numba's indexing, an element
    function (not a builtin at the literal stride 9, as :func:`store33`): that
    let LLVM vectorise ``from_matrix(assume_valid=True)``'s loop with its
    matrices gathered element by element, 1.5× slower than the scalar loop."""
    return (
        a[i, 0, 0], a[i, 0, 1], a[i, 0, 2],
        a[i, 1, 0], a[i, 1, 1], a[i, 1, 2],
        a[i, 2, 0], a[i, 2, 1], a[i, 2, 2],
    )  # fmt: skip


def store33(out, i, m):
    """``out[i] = m`` for an ``(n, 3, 3)`` array.

    Compiled, a C-contiguous output is written as a flat buffer at the
    literal stride 9 (as ``store4`` does at stride 4), which lets LLVM
    vectorise the row loop: into a freshly allocated output, whose pages the
    system faults in during the loop, about 20 % faster (N = 2·10⁶); into a
    warm ``out=`` the same (memory-bound either way). Other layouts are
    addressed by their strides.
    """
    out[i, 0, 0], out[i, 0, 1], out[i, 0, 2] = m[0], m[1], m[2]
    out[i, 1, 0], out[i, 1, 1], out[i, 1, 2] = m[3], m[4], m[5]
    out[i, 2, 0], out[i, 2, 1], out[i, 2, 2] = m[6], m[7], m[8]


# ---- compiled: typed and lowered in place (numba's low-level extension API)
#
# Each accessor is a builtin of the caller, like ``_jit.like``: its typing is a
# Python test and its lowering emits the loads or stores into the caller's own
# LLVM IR. An ``@overload`` or element function here was a whole numba compile
# for each array type it met (0.02-0.08 s apiece, several in every kernel's
# first call) for a few instructions that LLVM inlined anyway.

# each accessor: the elements of its rows
_ROWS = {load1: 1, load3: 3, load4: 4}
_STORES = {store1: 1, store3: 3, store4: 4, store33: 9}


def _rows_of(a, width):
    """True (at compile time) for the arrays an accessor of `width` elements per row
    reads: 1-D (flat rows), (n, width) or, for 9, (n, 3, 3)."""
    if not isinstance(a, types.Array):
        return False
    return a.ndim == 1 or (width in (3, 4) and a.ndim == 2) or (width == 9 and a.ndim == 3)


def _pointer(context, builder, aryty, ary, i, c, width):
    """The address of element c of row i: a C-contiguous buffer at the literal
    stride `width` (no wraparound, so LLVM can bound the addresses and vectorise
    the row loops); other layouts (strided, broadcast) by their strides."""
    i = context.cast(builder, i[0], types.unliteral(i[1]), types.intp)
    j = builder.add(builder.mul(i, context.get_constant(types.intp, width)), context.get_constant(types.intp, c))
    if aryty.layout == "C":
        if CHECK_BOUNDS:  # the debug mode: the flat index within the buffer
            cgutils.do_boundscheck(context, builder, j, ary.nitems)
        return builder.gep(ary.data, [j], inbounds=True)
    if aryty.ndim == 1:
        index = [j]
    elif aryty.ndim == 2:
        index = [i, context.get_constant(types.intp, c)]
    else:
        index = [i, context.get_constant(types.intp, c // 3), context.get_constant(types.intp, c % 3)]
    shape = cgutils.unpack_tuple(builder, ary.shape, aryty.ndim)
    strides = cgutils.unpack_tuple(builder, ary.strides, aryty.ndim)
    return cgutils.get_item_pointer2(context, builder, ary.data, shape, strides, aryty.layout, index,
                                     boundscheck=CHECK_BOUNDS)


def _align(aryty):
    return None if aryty.aligned else 1


def _load_run(context, builder, aryty, a, i, width, count):
    """The LLVM values of elements 0 … count − 1 of row i (a value and its type) of
    `width` elements of the array `a` of type `aryty`."""
    ary = context.make_array(aryty)(context, builder, a)
    return [builder.load(_pointer(context, builder, aryty, ary, i, c, width), align=_align(aryty))
            for c in range(count)]


def _store_run(context, builder, aryty, a, i, width, values):
    """Store `values` (LLVM values and their types) into elements 0, 1, … of row i
    of `width` elements of the array `a` of type `aryty`, cast to its dtype."""
    ary = context.make_array(aryty)(context, builder, a)
    for c, (x, t) in enumerate(values):
        v = context.cast(builder, x, types.unliteral(t), aryty.dtype)
        builder.store(v, _pointer(context, builder, aryty, ary, i, c, width), align=_align(aryty))
    return context.get_dummy_value()


def _tuple_items(builder, x, xty):
    return [(builder.extract_value(x, c), xty.types[c]) for c in range(len(xty))]


def _typer_load(width):
    def typer(a, i):
        if _rows_of(a, width) and isinstance(i, types.Integer):
            return a.dtype if width == 1 else types.UniTuple(a.dtype, width)

    return typer


def _lower_load(width):
    def lower(context, builder, sig, args):
        aryty = sig.args[0]
        vals = _load_run(context, builder, aryty, args[0], (args[1], sig.args[1]), width, width)
        if width == 4 and aryty.ndim == 1 and aryty.layout == "C":
            # "+ 0" keeps LLVM from folding a select of two loaded values into a
            # load through a selected pointer, which the vectoriser cannot bound
            zero = context.get_constant(aryty.dtype, 0.0)
            vals = [builder.fadd(v, zero) for v in vals]
        if width == 1:
            return vals[0]
        return context.make_tuple(builder, sig.return_type, vals)

    return lower


def _typer_store(width):
    def typer(out, i, x):
        fits = isinstance(x, types.Number) if width == 1 else isinstance(x, types.BaseTuple) and len(x) == width
        if _rows_of(out, width) and out.mutable and isinstance(i, types.Integer) and fits:
            return types.none

    return typer


def _lower_store(width):
    def lower(context, builder, sig, args):
        aryty, ity, xty = sig.args
        values = [(args[2], xty)] if width == 1 else _tuple_items(builder, args[2], xty)
        return _store_run(context, builder, aryty, args[0], (args[1], ity), width, values)

    return lower


def loads(a, j, k):
    """Elements j … j + k − 1 of a C-contiguous array's buffer, as a k-tuple (k a
    literal integer): a row of a flat table such as the spline's segment rows."""
    return tuple(a.reshape(-1)[j : j + k])


def stores(out, j, x):
    """The tuple x into elements j … j + len(x) − 1 of a C-contiguous array's buffer."""
    out.reshape(-1)[j : j + len(x)] = x


@type_callable(loads)
def _type_loads(context):
    def typer(a, j, k):
        if (isinstance(a, types.Array) and a.layout == "C" and isinstance(j, types.Integer)
                and isinstance(k, types.IntegerLiteral)):
            return types.UniTuple(a.dtype, k.literal_value)

    return typer


@lower_builtin(loads, types.Array, types.Integer, types.IntegerLiteral)
def _lower_loads(context, builder, sig, args):
    aryty, ity, kty = sig.args
    vals = _load_run(context, builder, aryty, args[0], (args[1], ity), 1, kty.literal_value)
    return context.make_tuple(builder, sig.return_type, vals)


@type_callable(stores)
def _type_stores(context):
    def typer(out, j, x):
        if (isinstance(out, types.Array) and out.layout == "C" and out.mutable and isinstance(j, types.Integer)
                and isinstance(x, types.BaseTuple)):
            return types.none

    return typer


@lower_builtin(stores, types.Array, types.Integer, types.BaseTuple)
def _lower_stores(context, builder, sig, args):
    aryty, ity, xty = sig.args
    return _store_run(context, builder, aryty, args[0], (args[1], ity), 1, _tuple_items(builder, args[2], xty))


def loads_at(a, j, step, k):
    """Elements j, j + step, …, j + (k − 1)·step of a C-contiguous array's buffer, as a
    k-tuple (k a literal integer): one lane's column of planes laid side by side."""
    return tuple(a.reshape(-1)[j : j + k * step : step])


def stores_at(out, j, step, x):
    """The tuple x into elements j, j + step, … of a C-contiguous array's buffer."""
    out.reshape(-1)[j : j + len(x) * step : step] = x


def _strided_pointers(context, builder, aryty, a, j, step, count):
    """The addresses of elements j + c·step, c < count, of the C-contiguous array `a`."""
    ary = context.make_array(aryty)(context, builder, a)
    j = context.cast(builder, j[0], types.unliteral(j[1]), types.intp)
    step = context.cast(builder, step[0], types.unliteral(step[1]), types.intp)
    ptrs = []
    for c in range(count):
        idx = builder.add(j, builder.mul(step, context.get_constant(types.intp, c)))
        if CHECK_BOUNDS:
            cgutils.do_boundscheck(context, builder, idx, ary.nitems)
        ptrs.append(builder.gep(ary.data, [idx], inbounds=True))
    return ptrs


@type_callable(loads_at)
def _type_loads_at(context):
    def typer(a, j, step, k):
        if (isinstance(a, types.Array) and a.layout == "C" and isinstance(j, types.Integer)
                and isinstance(step, types.Integer) and isinstance(k, types.IntegerLiteral)):
            return types.UniTuple(a.dtype, k.literal_value)

    return typer


@lower_builtin(loads_at, types.Array, types.Integer, types.Integer, types.IntegerLiteral)
def _lower_loads_at(context, builder, sig, args):
    aryty, jty, sty, kty = sig.args
    ptrs = _strided_pointers(context, builder, aryty, args[0], (args[1], jty), (args[2], sty), kty.literal_value)
    vals = [builder.load(p, align=_align(aryty)) for p in ptrs]
    return context.make_tuple(builder, sig.return_type, vals)


@type_callable(stores_at)
def _type_stores_at(context):
    def typer(out, j, step, x):
        if (isinstance(out, types.Array) and out.layout == "C" and out.mutable and isinstance(j, types.Integer)
                and isinstance(step, types.Integer) and isinstance(x, types.BaseTuple)):
            return types.none

    return typer


@lower_builtin(stores_at, types.Array, types.Integer, types.Integer, types.BaseTuple)
def _lower_stores_at(context, builder, sig, args):
    aryty, jty, sty, xty = sig.args
    ptrs = _strided_pointers(context, builder, aryty, args[0], (args[1], jty), (args[2], sty), len(xty))
    for p, (x, t) in zip(ptrs, _tuple_items(builder, args[3], xty)):
        builder.store(context.cast(builder, x, types.unliteral(t), aryty.dtype), p, align=_align(aryty))
    return context.get_dummy_value()


for _fn, _width in _ROWS.items():
    type_callable(_fn)(lambda context, w=_width: _typer_load(w))
    lower_builtin(_fn, types.Array, types.Integer)(_lower_load(_width))
for _fn, _width in _STORES.items():
    type_callable(_fn)(lambda context, w=_width: _typer_store(w))
    lower_builtin(_fn, types.Array, types.Integer, types.Any)(_lower_store(_width))


# ---- non-temporal stores: a large output written past the caches


def streams(out):
    """Whether a kernel should write `out` with :func:`stream4`: a C-contiguous float
    array of at least ``STREAM_MIN_BYTES`` (this module's copy of
    :data:`quatarray._jit.STREAM_MIN_BYTES`, ``QUATARRAY_STREAM_MIN_BYTES``) whose
    buffer is 16-byte aligned (the non-temporal vector stores need it; numpy's
    allocations are).

    An ordinary store first reads the cache line it writes into (write-allocate):
    for a large output, a quarter of slerp's memory traffic went to reading lines
    only to overwrite them, and the output then evicted the inputs. For an output the
    caller gives (``out=``): into a new array, whose pages the system zeroes as they
    are first touched, leaving the zeros in the cache, ordinary stores are faster."""
    return (out.nbytes >= STREAM_MIN_BYTES and out.flags.c_contiguous and out.dtype.kind == "f"
            and out.ctypes.data % 16 == 0)


def stream4(out, i, q):
    """``store4(out, i, q)`` with the non-temporal hint: 16-byte vector stores that
    bypass the caches (``movntpd`` on x86), for a C-contiguous output that
    :func:`streams`. Other layouts, and rows not 16-byte aligned (checked as they are
    stored), are stored as ``store4`` does. The stores are weakly ordered: the loop
    ends with :func:`stream_end`."""
    store4(out, i, q)


def stream_end():
    """A store fence: the non-temporal stores before it are ordered before any later
    store (``sfence`` on x86, which the locked instruction of LLVM's ``fence`` is not
    documented to do for these stores; a ``fence`` elsewhere), so that whoever the
    loop hands its output to sees it."""


@type_callable(stream4)
def _type_stream4(context):
    return _typer_store(4)


@lower_builtin(stream4, types.Array, types.Integer, types.Any)
def _lower_stream4(context, builder, sig, args):
    aryty, ity, xty = sig.args
    values = _tuple_items(builder, args[2], xty)
    if aryty.layout != "C" or aryty.dtype not in (types.float32, types.float64):
        return _store_run(context, builder, aryty, args[0], (args[1], ity), 4, values)
    ary = context.make_array(aryty)(context, builder, args[0])
    first = _pointer(context, builder, aryty, ary, (args[1], ity), 0, 4)
    if CHECK_BOUNDS:
        _pointer(context, builder, aryty, ary, (args[1], ity), 3, 4)  # the row's last element checked too
    vals = [context.cast(builder, x, types.unliteral(t), aryty.dtype) for x, t in values]
    lanes = 16 // context.get_abi_sizeof(vals[0].type)  # two float64 or four float32
    vec = ir.VectorType(vals[0].type, lanes)
    hint = builder.module.add_metadata([ir.Constant(ir.IntType(32), 1)])
    intp = context.get_value_type(types.intp)
    # the vector stores fault on a row that is not 16-byte aligned (an array type does
    # not say where its buffer starts): such a row is stored as store4 does
    aligned = builder.icmp_unsigned("==", builder.and_(builder.ptrtoint(first, intp), intp(15)), intp(0))
    with builder.if_else(aligned, likely=True) as (streamed, plain):
        with streamed:
            for c in range(0, 4, lanes):
                v = ir.Constant(vec, ir.Undefined)
                for k in range(lanes):
                    v = builder.insert_element(v, vals[c + k], ir.Constant(ir.IntType(32), k))
                ptr = builder.gep(first, [context.get_constant(types.intp, c)], inbounds=True)
                builder.store(v, builder.bitcast(ptr, vec.as_pointer()), align=16).set_metadata("nontemporal", hint)
        with plain:
            _store_run(context, builder, aryty, args[0], (args[1], ity), 4, values)
    return context.get_dummy_value()


def _fence(context, builder):
    if builder.module.triple.startswith(("x86_64", "i686", "i386")):
        sfence = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), []), "llvm.x86.sse.sfence")
        builder.call(sfence, [])
    else:
        builder.fence("seq_cst")


statement(stream_end, _fence)


# ---- prefetch hints


def prefetch(a, j):
    """A hint that element j of the C-contiguous array `a` will be read soon: its cache
    line is fetched into the L2 cache (``prefetcht1`` on x86), which never faults, also
    past the array's end. A loop that reads its rows from memory while it computes
    gives the first lines of each 4 KiB page of its next block: the hardware
    prefetcher follows a stream within a page, and starts again at each new one.
    In plain Python it does nothing."""


@type_callable(prefetch)
def _type_prefetch(context):
    def typer(a, j):
        if isinstance(a, types.Array) and a.layout == "C" and isinstance(j, types.Integer):
            return types.none

    return typer


@lower_builtin(prefetch, types.Array, types.Integer)
def _lower_prefetch(context, builder, sig, args):
    ary = context.make_array(sig.args[0])(context, builder, args[0])
    j = context.cast(builder, args[1], sig.args[1], types.intp)
    i8p = ir.IntType(8).as_pointer()
    ptr = builder.bitcast(builder.gep(ary.data, [j]), i8p)  # (no inbounds: it may be past the end)
    i32 = ir.IntType(32)
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32]),
                                        "llvm.prefetch.p0i8")
    builder.call(fn, [ptr, i32(0), i32(2), i32(1)])  # read, locality 2 (L2), data
    return context.get_dummy_value()
