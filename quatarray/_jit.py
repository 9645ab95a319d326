"""Every numba option quatarray uses, in one place.

Kernels are compiled lazily, on their first call, for the argument types
they meet (float32 and float64, contiguous or strided, writable or
read-only), and cached on disk (``cache=True``) so that later processes
load machine code instead of compiling. The cached code of every kernel is
stamped with all of the package's sources (:class:`_PackageLocator`): a kernel
inlines element functions of other files, which numba's own stamp (the
kernel's file) does not cover.

Environment variables
---------------------
QUATARRAY_NO_CACHE
    Set to ``1`` to keep numba's on-disk cache off (for read-only
    installs or when debugging a kernel).
QUATARRAY_CHECK_BOUNDS
    Set to ``1`` for the debug mode of the kernels: every row load and store
    (:mod:`quatarray._access`) and every numba array index checks its bounds
    and raises ``IndexError`` instead of reading or writing past an array;
    the on-disk cache is off. Slow; for running the test suite once after a
    change to a kernel or to the front end that guards it.
QUATARRAY_CACHE_LOCK
    A file's path: every write of this process to numba's on-disk cache
    holds an exclusive lock on that file (POSIX). For processes that share
    one cache and compile at once (several Dask workers of a machine, the
    warm-up's workers, a test run on every core): numba's index update is
    not atomic across processes, and two of them adding entries to one
    function's index could both pick the same data file name.
NUMBA_CACHE_LOCATOR_CLASSES
    numba's own variable: when it is set, numba uses the locators it names
    instead of its list, and the package stamp above is off (a kernel may
    then load code built from older sources of the files it inlines).
QUATARRAY_PARALLEL_MIN_ROWS
    Batches with at least this many rows run the multi-threaded variant of
    a row loop (default 200000, chosen from ``benchmarks/``). ``0`` means
    always, a huge value never. Inside ``with serial():`` (or
    ``variant("serial")``) the calls of that thread or task run serial
    whatever their size; other threads keep the rule.
QUATARRAY_STREAM_MIN_BYTES
    ``out=`` arrays of at least this many bytes (default 25165824, 24 MiB) are
    written past the caches by the kernels that can (slerp; see
    :func:`quatarray._access.streams`): no cache line is read only to be
    overwritten, and the inputs stay cached. Below it the output is better
    left in the cache for its next use (slerp's figures on a 2-core Xeon:
    1.06-1.23x faster from 10⁶ rows (31 MiB), also with a read of the output
    after it; at 7.5·10⁵ rows 1.13x alone, 0.95x with the read; the same at
    5·10⁵ alone, 0.8x with the read).

The kernel vocabulary
---------------------
Compiled code is written in three ways, and this module holds the machinery
behind them:

:func:`element`
    A per-element formula (scalars and tuples in, a tuple or scalar out; a
    row's formula may read and write rows of arrays). How it is compiled
    follows from its bytecode (:func:`quatarray._trace.untraceable`):
    straight-line arithmetic is *traced*, a builtin of each caller with no
    compile of its own (:mod:`quatarray._trace`: the cheapest to compile);
    a formula that branches, loops, reads arrays or calls compiled functions
    is compiled once per signature, without the CPython and C wrappers
    (:data:`NO_WRAPPERS`; calls from Python run a wrapped twin), cached, and
    marked ``alwaysinline`` for LLVM so that the loops that call it vectorise.
    LLVM inlining gives the SIMD code of numba's IR-level ``inline="always"``,
    which re-runs numba's front end on every callee at every call site, nested
    (that once made the Bézier spline's first call take over a minute).
    ``how="call"`` keeps a long formula an LLVM call; ``how="inline"`` compiles
    a traceable one on its own.
:func:`rowloop`
    A loop: over the leading axis with ``prange``, compiled as a serial and a
    parallel variant that the call picks by the number of rows
    (:class:`RowLoop`); ``parallel=False`` for loops that do not pay on
    threads and for scans and searches; ``far=`` for the formulas exact only
    near unit scale (:class:`FarRows`: a second pass redoes the rare far
    rows); ``inline=True`` for a shallow loop numba inlines into its one
    caller. A row loop called from another kernel is its serial variant.
a public wrapper
    Plain Python in the subject module: validate (:mod:`quatarray._validate`),
    allocate, call the loop.

The same loop or formula for another method, order or output is a *variant*:
:func:`specialise` copies it with some of its globals bound to other values
(a constant such as the spline's ``KIND``, another function to call), each
copy compiled and cached on its own; the rebound globals are named in capitals
at the top of the module, with the variants built beside them.

Helpers
-------
``like(x, c)``
    The constant ``c`` in ``x``'s float type, so float32 kernels stay
    float32 (a bare ``2.0`` would promote them to float64).
``fmuladd(a, b, c)``
    a·b + c as one fused multiply-add where the CPU has the instruction
    (LLVM's ``fmuladd``: one rounding), a multiply and an add elsewhere. The
    polynomial trigonometry and slerp use it for their chains of
    multiply-adds; LLVM makes the same choice for scalar and SIMD code, so a
    row's result never depends on its place in a batch (fast-math's
    ``contract`` flag on every kernel, which fuses whatever pairs LLVM picks,
    gave a float32 spline's SIMD lane groups results other than row by row).
``exponent_scales(m)``
    ``(2^(1-E), 2^E)`` for a positive normal float m = 2^E·f (1 ≤ f < 2),
    read from m's exponent bits: exact powers of two, no division, and
    vectorisable (integer and/sub on the SIMD registers). Used to scale a
    quaternion before squaring its components (``_elements.qscaled``).
``bit_distance(x, lo)``
    The bits of x minus those of lo as an unsigned integer of their width:
    for floats at least lo, how many floats x lies above it; below lo it
    wraps to large values. A range test of a float as one integer subtraction,
    whose ``max`` over a loop stays two SIMD instructions (``_elements.far_excess``).
"""

import contextlib
import contextvars
import hashlib
import inspect
import os
import stat
import sys
import threading
import types as _pytypes

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import lower_builtin, type_callable, typeof_impl

from . import _numba_internals as _ni
from . import _trace
from ._numba_internals import rehome
from ._trace import Sym, float_bits, select  # noqa: F401  (select and float_bits: part of the vocabulary)


_ni.defer_blas_probe()

try:
    import fcntl
except ImportError:  # not POSIX: no lock
    fcntl = None
CACHE_LOCK_ENV = "QUATARRAY_CACHE_LOCK"
CAN_LOCK = fcntl is not None


def _flock(f, exclusive):
    fcntl.flock(f, fcntl.LOCK_EX if exclusive else fcntl.LOCK_UN)


def lock_cache_writes(path):
    """Make this process's writes to numba's cache hold an exclusive lock on the
    file `path` (see ``QUATARRAY_CACHE_LOCK``); once per process. False where numba's
    cache differs from the one :mod:`quatarray._numba_internals` knows."""
    return _ni.lock_cache_writes(path, _flock)


_LOCKED = True
if CAN_LOCK and os.environ.get(CACHE_LOCK_ENV):
    _LOCKED = lock_cache_writes(os.environ[CACHE_LOCK_ENV])


def package_stamp(root):
    """sha256 of the ``.py`` files under the folder `root` (their paths relative to
    it and their contents, in sorted order): a stamp that changes when any of them
    does.

    Hidden names (an editor's lock link ``.#_trig.py``), entries that are not
    regular files (a dangling link) and files that cannot be read are left out:
    the stamp never keeps the package from importing. Linked folders are
    followed (each real folder once). Where `root` lies inside an archive (the
    package imported from a zip file), the stamp is the archive's whole content."""
    h = hashlib.sha256()
    if not os.path.isdir(root):
        archive = root
        while archive and not os.path.exists(archive) and os.path.dirname(archive) != archive:
            archive = os.path.dirname(archive)
        try:
            with open(archive, "rb") as f:
                for chunk in iter(lambda: f.read(1 << 20), b""):
                    h.update(chunk)
        except OSError:  # no archive to read: the files' own stamps only
            return "archive:unread"
        return "archive:" + h.hexdigest()
    seen = set()
    for dirpath, dirnames, filenames in os.walk(root, followlinks=True):
        real = os.path.realpath(dirpath)
        if real in seen:  # a link back to a folder already stamped
            dirnames[:] = []
            continue
        seen.add(real)
        dirnames[:] = sorted(d for d in dirnames if d != "__pycache__" and not d.startswith("."))
        for name in sorted(filenames):
            if not name.endswith(".py") or name.startswith("."):
                continue
            path = os.path.join(dirpath, name)
            try:
                if not stat.S_ISREG(os.stat(path).st_mode):  # before open: a fifo would block
                    continue
                with open(path, "rb") as f:
                    data = f.read()
            except OSError:
                continue
            h.update(os.path.relpath(path, root).encode() + b"\0" + data + b"\0")
    return h.hexdigest()


# numba's cache stamped with the package's sources (_numba_internals.PackageLocator)
_PackageLocator = _ni.PackageLocator
_PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))
_STANDARD_LOCATORS = _ni.PackageLocator.standard
_STAMPED = _ni.install_locator(_PACKAGE_DIR, package_stamp)

# The debug mode of the row accessors (QUATARRAY_CHECK_BOUNDS=1): every load and
# store checks its index, and so does numba's own indexing; such code is never
# cached (it would be loaded by processes without the checks, and vice versa).
CHECK_BOUNDS = os.environ.get("QUATARRAY_CHECK_BOUNDS", "0") == "1"
# The cache is on unless asked off, and only where each kernel's stamp covers the
# whole package and processes that share it can lock their writes when asked to.
CACHE = (os.environ.get("QUATARRAY_NO_CACHE", "0").lower() in ("", "0", "false", "no") and _STAMPED and _LOCKED
         and not CHECK_BOUNDS)
PARALLEL_MIN_ROWS = int(os.environ.get("QUATARRAY_PARALLEL_MIN_ROWS", "200000"))
STREAM_MIN_BYTES = int(os.environ.get("QUATARRAY_STREAM_MIN_BYTES", str(24 * 2**20)))

# error_model="numpy": 1/0 gives inf or nan instead of raising, as numpy does.
_OPTIONS = dict(cache=CACHE, nogil=True, error_model="numpy", **({"boundscheck": True} if CHECK_BOUNDS else {}))

prange = numba.prange
# jit_options of an ``@overload`` that LLVM inlines into every caller (see ``inline``)
INLINE_OPTIONS = _ni.supported_options({"cache": CACHE, "forceinline": True})


# The CPython wrapper (boxing and unboxing the arguments and the result) and the
# C-callable wrapper of a compiled function serve only calls from Python and cfunc
# pointers; a kernel calls the function itself. Element functions are compiled
# without them: for tuple arguments the wrappers are most of a small function's
# code, and leaving them out cut the first calls of the VQS, interpolate and
# align_vectors warm-up entries by 0.3-1 s CPU each (about 0.03 s per function).
NO_WRAPPERS = dict.fromkeys(_ni.WRAPPER_OPTIONS, True)


def _njit(fn, element=False, **options):
    """``numba.njit(**_OPTIONS, **options)(fn)`` whose calls from other kernels compile
    for the arguments' plain types, not for each literal value (a constant argument,
    the 16 of a table column: the spline's small table accessors compiled up to five
    times each, 0.1-0.3 s apiece); `element`: without the wrappers
    (:data:`NO_WRAPPERS`), a call from Python running a twin compiled with them, in
    memory only. See :func:`quatarray._numba_internals.njit`."""
    return _ni.njit(fn, element, **{**_OPTIONS, **options})


def element(fn=None, *, how=None):
    """Decorator of a per-element formula: ``@element`` or ``@element(how=...)``.

    `how` is how it becomes part of the loops that call it:

    ``None`` (the default)
        ``"trace"`` when the function is straight-line arithmetic that can be
        traced (:func:`quatarray._trace.traceable`, read from its bytecode),
        else ``"inline"``.
    ``"trace"``
        a builtin of each caller, its instructions emitted into the caller's IR
        (:mod:`quatarray._trace`); no compile of its own: the cheapest to compile.
    ``"inline"``
        compiled once per signature (cached) and marked for LLVM to inline into
        every caller before the loop vectoriser runs: for formulas that branch,
        loop, read arrays or call compiled functions, inside loops that must
        vectorise.
    ``"call"``
        compiled once per signature and called: for long formulas used by many
        kernels that need not vectorise (LLVM still inlines small ones).

    Called from Python, the function runs compiled (a twin with the CPython
    wrapper) or, traced, as plain Python."""
    if fn is None:
        return lambda f: element(f, how=how)
    if how not in (None, "trace", "inline", "call"):
        raise ValueError(f"Expected `how` to be None, 'trace', 'inline' or 'call', got {how!r}.")
    if how is None:
        why = _trace.untraceable(fn, also=(like, fmuladd))
        ELEMENTS[f"{fn.__module__}.{fn.__qualname__}"] = why
        how = "inline" if why else "trace"
    if how == "trace":
        return _trace.traced(fn)
    return _njit(fn, element=True, **({"forceinline": True} if how == "inline" else {}))


# For each element function decorated without `how`: None where it is traced, else why not.
ELEMENTS = {}


def _ir_inline(fn):
    """`fn` compiled as numba-IR inlined into its callers (``inline="always"``):
    see :func:`rowloop`'s `inline`."""
    return _njit(fn, inline="always")


class RowLoop:
    """A batched kernel with a serial and a parallel variant.

    ``rows`` is the index of the argument whose first axis is the loop
    length; calls with fewer than :func:`min_rows` rows (``PARALLEL_MIN_ROWS``
    unless a :func:`variant` is asked for) use the serial variant.

    numba's ``workqueue`` threading layer (the one left when neither TBB nor
    OpenMP is installed) cannot run two parallel kernels at once: it aborts
    the process. So one parallel kernel at a time runs under :data:`_PARALLEL`
    (taken without waiting); a thread that finds it taken runs the serial
    variant instead. Once a parallel call has shown the layer to be TBB or
    OpenMP, which are safe, the lock is no longer used.
    """

    def __init__(self, fn, rows=0, parallel=True, tuple_loop=None):
        self.py_func = fn
        self.tuple_loop = tuple_loop  # `fn` on its arguments as one tuple, for an `fn` of *args (into)
        self.rows = rows
        self.serial = _njit(fn)
        if parallel:
            # A distinct qualname gives the parallel variant its own cache file.
            twin = _pytypes.FunctionType(
                fn.__code__, fn.__globals__, fn.__name__ + "_parallel", fn.__defaults__, fn.__closure__
            )
            twin.__qualname__ = fn.__qualname__ + "_parallel"
            twin.__module__ = fn.__module__
            self.parallel = _njit(twin, parallel=True)
        else:
            self.parallel = self.serial
        self.__doc__ = fn.__doc__
        self.__name__ = fn.__name__

    def into(self, k, *args):
        """``self(*args, args[k])``: the loop with its output (its last argument) the
        input ``args[k]``, the very same view (:func:`quatarray._validate.elementwise`
        runs ``out=`` equal to an input so).

        Given the output as one more array, LLVM checks at run time whether it
        overlaps an input and, finding it does, runs the scalar loop (float32
        1.9x, float64 1.4x slower). Serial calls run a copy of the loop compiled
        with the input passed twice, the loop inlined at numba's level, so that
        LLVM sees one array: each row is read before it is written and the loop
        vectorises. It compiles on the first such call, for that argument count
        and position. Parallel calls keep the plain loop, which runs as fast."""
        parallel = args[self.rows].shape[0] >= min_rows() and self.parallel is not self.serial
        star = self.py_func.__code__.co_flags & inspect.CO_VARARGS  # numba inlines no *args
        if parallel or (star and self.tuple_loop is None):
            return self(*args, args[k])
        d = self.__dict__.setdefault("_into", {})
        key = (k, len(args))
        if key not in d:
            d[key] = _into_copy(self.tuple_loop if star else self.py_func, k, len(args), bool(star))
        return d[key](*args)

    def __call__(self, *args):
        if args[self.rows].shape[0] < min_rows() or self.parallel is self.serial:
            return self.serial(*args)
        if _SAFE_LAYER:
            return self.parallel(*args)
        if not _PARALLEL.acquire(blocking=False):
            return self.serial(*args)  # another thread is in a parallel kernel
        try:
            return self.parallel(*args)
        finally:
            _check_layer()
            _PARALLEL.release()


def _into_copy(fn, k, nargs, tupled):
    """The dispatcher of ``f(a0, …, a{nargs−1})`` = ``fn(a0, …, a{nargs−1}, a{k})`` (`tupled`:
    ``fn((a0, …, a{k}))``), `fn` inlined at numba's level (see :meth:`RowLoop.into`);
    cached beside `fn`."""
    names = ", ".join(f"a{i}" for i in range(nargs))
    name = f"{fn.__name__}_into{k}_{nargs}"
    scope = {"_LOOP": _ir_inline(fn)}
    call = f"({names}, a{k})" if tupled else f"{names}, a{k}"
    exec(f"def {name}({names}):\n    return _LOOP({call})\n", scope)
    copy = scope[name]
    copy.__code__ = rehome(copy.__code__, fn.__code__)
    copy.__qualname__ = f"{fn.__qualname__}_into{k}_{nargs}"
    copy.__module__ = fn.__module__
    return _njit(copy)


# The variant this thread or task asks for: None (by size), "serial" or "parallel".
# A context variable, so that a task going serial leaves other threads alone.
_VARIANT = contextvars.ContextVar("quatarray_variant", default=None)


def min_rows():
    """The number of rows from which a row loop runs parallel here and now:
    :data:`PARALLEL_MIN_ROWS`, or never inside :func:`serial`, or always inside
    ``variant("parallel")``."""
    v = _VARIANT.get()
    if v is None:
        return PARALLEL_MIN_ROWS
    return sys.maxsize if v == "serial" else 0


@contextlib.contextmanager
def variant(name):
    """Run the row loops called in this thread (or asyncio task) as `name`:
    ``"serial"``, ``"parallel"`` (whatever the size: for compiling both) or
    ``None`` (by size, the default). Nests; other threads are not affected.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import _jit, algebra
    >>> with _jit.variant("serial"):
    ...     n = algebra.normalize(np.ones((3, 4)))
    """
    if name not in (None, "serial", "parallel"):
        raise ValueError(f"Expected `name` to be None, 'serial' or 'parallel', got {name!r}.")
    token = _VARIANT.set(name)
    try:
        yield
    finally:
        _VARIANT.reset(token)


def serial():
    """``variant("serial")``: the row loops called in this thread run on it
    alone (inside Dask tasks, where the scheduler is the parallel layer)."""
    return variant("serial")


# One parallel kernel at a time until the threading layer is known to be safe
# (see RowLoop); numba.threading_layer() answers only after a parallel call.
_PARALLEL = threading.Lock()
_SAFE_LAYER = False


def _check_layer():
    global _SAFE_LAYER
    try:
        _SAFE_LAYER = numba.threading_layer() in ("tbb", "omp")
    except ValueError:  # no parallel kernel has run yet
        pass


def rowloop(fn=None, *, rows=0, parallel=True, far=None, inline=False):
    """Decorator of a loop: ``@rowloop`` or ``@rowloop(rows=1, parallel=False, ...)``.

    ``@rowloop``
        a loop over the leading axis of argument `rows`, written once with
        ``prange``: a serial and a parallel variant, the call picking one by
        the number of rows (:class:`RowLoop`).
    ``parallel=False``
        the serial variant only: the loops that do not pay to run on threads,
        and whole-array kernels that are not row loops (scans, searches). A
        row loop may call another (its serial variant).
    ``far=scaled``
        the decorated function is the per-row formula ``plain(i, args)`` of a
        formula exact only near unit scale; the loop runs it on every row and
        ``scaled(i, args)`` on the rows it flags (:class:`FarRows`).
    ``inline=True``
        a serial loop that numba inlines into the one loop that calls it, at its
        IR level (``inline="always"``): rarely, since nesting multiplies compile
        time. A loop also called on its own is better called as the loop it is
        (its callers reuse its typing); a shallow one called from one place only
        (the spline's runs, inlined into its evaluation loop) may be inlined.
    """
    if fn is None:
        return lambda f: rowloop(f, rows=rows, parallel=parallel, far=far, inline=inline)
    if inline:
        return _ir_inline(fn)
    if far is not None:
        return FarRows(fn, far, parallel=parallel)
    return RowLoop(fn, rows=rows, parallel=parallel)


@typeof_impl.register(RowLoop)
def _typeof_row_loop(loop, context):
    # a row loop called from another kernel is its serial variant
    return typeof_impl(loop.serial, context)


def specialise(fn, suffix, home=None, **names):
    """A copy of the plain function `fn` with the global `names` rebound (another
    kernel to call, say), named ``fn.__name__ + suffix``: its own qualname gives it
    its own cache file, and each copy compiles only what it calls. The copy sees a
    snapshot of the module's globals taken now.

    `home`, a function, makes the copy belong to home's module and source file:
    numba then keeps its cache beside home's and drops it when that file changes
    (numba checks only the file of the function it compiles, and the copy's
    behaviour lives in the functions rebound from there). The copy takes home's
    first line too (:func:`quatarray._numba_internals.rehome`): numba reads the
    source at a function's file and first line for its cache, and from Python 3.13
    ``inspect`` reads a block from exactly that line."""
    scope = dict(fn.__globals__)
    scope.update(names)
    code = fn.__code__
    if home is not None:
        home = getattr(home, "py_func", home)  # a dispatcher's Python function
        code = rehome(code, home.__code__)
    copy = _pytypes.FunctionType(code, scope, fn.__name__ + suffix, fn.__defaults__, fn.__closure__)
    copy.__qualname__ = fn.__qualname__ + suffix
    copy.__module__ = fn.__module__ if home is None else home.__module__
    copy.__doc__ = fn.__doc__
    return copy


def like(x, c):
    """``c`` converted to the float type of ``x`` (identity in plain Python; a
    constant of the symbol's type in a traced function, :mod:`quatarray._trace`)."""
    return x.like(c) if type(x) is Sym else c


@type_callable(like)
def _type_like(context):
    # typed and lowered directly (a cast), not an @overload: an overload is a
    # whole numba compile for each pair of argument types it meets (0.3-0.6 s of
    # a spline's first call). Element functions that a loop needs inlined must
    # be ``inline``: plain ``element`` ones are inlined by LLVM's heuristics,
    # which this changes (from_euler's loop stopped vectorising until its
    # sin/cos became ``inline``).
    def typer(x, c):
        ftype = x.dtype if isinstance(x, types.Array) else x
        if isinstance(ftype, types.Float) and isinstance(types.unliteral(c), (types.Number, types.Boolean)):
            return ftype

    return typer


@lower_builtin(like, types.Any, types.Any)
def _lower_like(context, builder, sig, args):
    return context.cast(builder, args[1], types.unliteral(sig.args[1]), sig.return_type)


def fmuladd(a, b, c):
    """a·b + c as LLVM's ``fmuladd``: one FMA instruction (one rounding) on CPUs
    that have one (x86-64 since Haswell and Zen, every AArch64), a multiply and an
    add elsewhere; in plain Python ``a * b + c``. a, b and c are one float type.

    For the long chains of multiply-adds in the polynomial trigonometry and in
    slerp: one instruction of four cycles instead of two of three shortens them
    (the slerp loop 15 % faster on Zen 3). Unlike fast-math's ``contract`` flag,
    which lets LLVM fuse any pair it finds, the pairs are fixed here, and LLVM
    makes the same choice (FMA or not) for scalar and SIMD code of a type: a
    row's result does not depend on which part of a loop computes it, nor on the
    batch size.
    Not for code that relies on an exact cancellation (``a·b − b·a`` = 0, as in
    the quaternion products), which a fused multiply-add breaks."""
    if Sym in (type(a), type(b), type(c)):  # in a traced function (quatarray._trace)
        return _trace.fmuladd(a, b, c)
    return a * b + c


@type_callable(fmuladd)
def _type_fmuladd(context):
    # typed and lowered directly, as `like` (no overload to compile per type)
    def typer(a, b, c):
        a, b, c = (types.unliteral(x) for x in (a, b, c))
        if isinstance(a, types.Float) and a == b == c:
            return a

    return typer


@lower_builtin(fmuladd, types.Float, types.Float, types.Float)
def _lower_fmuladd(context, builder, sig, args):
    ty = args[0].type
    name = "llvm.fmuladd.f32" if sig.return_type.bitwidth == 32 else "llvm.fmuladd.f64"
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ty, [ty, ty, ty]), name)
    return builder.call(fn, args)


# LLVM's tuning flags that keep its vectoriser and code generator from gathers and
# scatters (as LLVM tunes for Intel CPUs with the Gather Data Sampling mitigation)
NO_GATHER_FEATURES = _ni.NO_GATHER_FEATURES


def prefer_no_gather():
    """Compile the function this is called in without vector gathers and scatters.

    Call it inside a row loop's ``prange`` body (numba outlines that body into a
    function of its own). On AVX-512 targets LLVM vectorises rows of nine (3×3
    matrices) by gathering and scattering every element; on Zen 4 that ran
    ``as_matrix(out=)`` at 31–38 % of the STREAM triad and ``from_matrix(assume_valid=True)``
    at 22–28 %, against 79–87 % and 49–55 % with the shuffles LLVM chooses instead
    (a loop that picks its columns at run time, as ``euler._as_euler``, needs its
    gathers: without them it ran 4× slower). The
    function gets LLVM's ``target-features`` attribute: the target machine's own
    features and :data:`NO_GATHER_FEATURES`, which change only the instructions
    chosen (the results are bitwise the same). The flags are LLVM 17's: with an
    older LLVM (numba 0.60 and 0.61 have 14 and 15), where numba's codegen has
    no ``_tm_features`` or where llvmlite does not print the attribute, the
    function is left as it is
    (:func:`quatarray._numba_internals.add_target_features`). In plain Python
    (``NUMBA_DISABLE_JIT=1``) it does nothing."""


def statement(fn, emit):
    """Make `fn`, a function of no arguments that returns nothing, a builtin of the
    kernels that call it: typed and lowered in place, as ``like``, its lowering
    ``emit(context, builder)`` (an attribute on the caller's function, a fence).
    Returns `fn`, which does nothing in plain Python."""
    type_callable(fn)(lambda context: lambda: types.none)

    @lower_builtin(fn)
    def lower(context, builder, sig, args):
        emit(context, builder)
        return context.get_dummy_value()

    return fn


statement(prefer_no_gather, lambda context, builder: _ni.add_target_features(context, builder, NO_GATHER_FEATURES))


def scratch(n, like_array):
    """A new 1-D array of `n` zeros of `like_array`'s dtype, inside a kernel:
    ``np.zeros(n, like_array.dtype)`` without numba's overloads to compile
    (:func:`quatarray._numba_internals.new_zeros`). For a kernel's work arrays; in
    plain Python it is ``np.zeros``."""
    return np.zeros(n, like_array.dtype)


@type_callable(scratch)
def _type_scratch(context):
    def typer(n, like_array):
        if isinstance(n, types.Integer) and isinstance(like_array, types.Array):
            return types.Array(like_array.dtype, 1, "C")

    return typer


@lower_builtin(scratch, types.Integer, types.Array)
def _lower_scratch(context, builder, sig, args):
    n = context.cast(builder, args[0], sig.args[0], types.intp)
    return _ni.new_zeros(context, builder, sig.return_type, n)


def prefer_wide_vectors():
    """Compile the function this is called in with 512-bit vectors where the CPU has them.

    LLVM's tuning for AVX-512 CPUs prefers 256-bit vectors; a kernel whose loop is
    long arithmetic on registers (no memory-bound streaming), evaluated as SIMD lanes,
    runs faster with twice the lanes (the Bézier spline's rate tiles). The function
    gets LLVM's ``"prefer-vector-width"="512"`` attribute
    (:func:`quatarray._numba_internals.add_wide_vectors`): it changes the
    instructions chosen only (each lane computes what it did), and nothing on CPUs
    without AVX-512. Call it in the kernel's body (a ``prange`` body is a function of
    its own). In plain Python it does nothing."""


statement(prefer_wide_vectors, _ni.add_wide_vectors)


def exponent_scales(m):
    """``(r, c) = (2^(1-E), 2^E)`` for a positive normal float ``m = 2^E·f``,
    1 ≤ f < 2, in m's float type: r·m lies in [2, 4) and c·r = 2, both exactly
    (powers of two, normal for every normal m). Compiled, they come from m's
    exponent bits (no division, branch-free, vectorisable); for other m they
    are meaningless (zero and subnormal m give c = 0 and r = inf, inf and nan
    give c = inf and r = 0): callers select on ``(c > 0) & (r > 0)``."""
    t = type(m) if isinstance(m, np.floating) else np.float64
    info = np.finfo(t)
    if not np.isfinite(m):
        return t(0.0), t(np.inf)
    if abs(m) < info.tiny:
        return t(np.inf), t(0.0)
    e = int(np.frexp(m)[1])  # m = f' 2^e, 0.5 ≤ f' < 1: E = e - 1
    return np.ldexp(t(1.0), 2 - e), np.ldexp(t(1.0), e - 1)


# exponent_scales and bit_distance are builtins (typed and lowered in place, as
# ``like``): an overload was a numba compile per float type in every process.
@type_callable(exponent_scales)
def _type_exponent_scales(context):
    def typer(m):
        if isinstance(m, types.Float):
            return types.UniTuple(m, 2)

    return typer


@lower_builtin(exponent_scales, types.Float)
def _lower_exponent_scales(context, builder, sig, args):
    bits = sig.args[0].bitwidth
    mant = 52 if bits == 64 else 23
    ity = ir.IntType(bits)
    fty = context.get_value_type(sig.args[0])
    mask = ir.Constant(ity, ((1 << (bits - 1 - mant)) - 1) << mant)  # the exponent field
    e = builder.and_(builder.bitcast(args[0], ity), mask)
    r = builder.bitcast(builder.sub(mask, e), fty)  # exponent field 2·bias + 1 - e: 2^(1-E)
    c = builder.bitcast(e, fty)  # 2^E
    return context.make_tuple(builder, sig.return_type, [r, c])


def bit_distance(x, lo):
    """The bits of `x` minus those of `lo` (floats of one type), as an unsigned
    integer of their width, wrapping: for x >= lo >= 0, how many floats x lies
    above lo (inf and nan lie above every finite float); x below lo, and
    negative x (also a nan with its sign bit set), wrap to large values
    (``_elements.far_excess`` uses both). Compiled, one integer subtraction of
    the bit patterns (vectorisable)."""
    t, u = (np.float32, np.uint32) if isinstance(x, np.float32) else (np.float64, np.uint64)
    w = 32 if u is np.uint32 else 64
    bits = [int(np.asarray(a, t).view(u)) for a in (x, lo)]
    return u((bits[0] - bits[1]) % (1 << w))


def bits_type(x):
    """The unsigned integer type of :func:`bit_distance` of floats of numba type `x`."""
    return types.uint32 if x.bitwidth == 32 else types.uint64


def lower_bit_distance(builder, x, lo, bits):
    """:func:`bit_distance` of the LLVM floats `x` and `lo` of `bits` bits."""
    ity = ir.IntType(bits)
    return builder.sub(builder.bitcast(x, ity), builder.bitcast(lo, ity))


@type_callable(bit_distance)
def _type_bit_distance(context):
    def typer(x, lo):
        if isinstance(x, types.Float) and x == lo:
            return bits_type(x)

    return typer


@lower_builtin(bit_distance, types.Float, types.Float)
def _lower_bit_distance(context, builder, sig, args):
    return lower_bit_distance(builder, args[0], args[1], sig.args[0].bitwidth)


# ---- the loops of formulas exact only near unit scale (rowloop(far=...))

FLAG_BLOCK = 4096  # rows per block of range flags (flags_max): 16 kB, below the out= allocation limit


@element
def flags_max(flags, m):
    """The largest of ``flags[:m]``. The batched loops store each row's
    :func:`far_scale` flag in a small array per block of :data:`FLAG_BLOCK`
    rows and reduce it after the block: a reduction inside the row loop makes
    LLVM interleave it (several vectors at a time, wider loads and shuffles,
    spills in the larger loops), so the loop would no longer be the one it was
    without the flag."""
    f = np.int32(0)
    for j in range(m):
        f = max(f, flags[j])
    return f


_PLAIN = _SCALED = _STORE = _FORMULA = _FAR_LOOP = None  # rebound in each copy (see FarRows, redo)


def _far_rows(*args):
    # the first pass of FarRows: each copy rebinds _FAR_LOOP (its _far_loop, inlined)
    return _FAR_LOOP(args)


def _far_loop(args):
    # the loop of _far_rows on its arguments as a tuple (which numba can inline, as
    # RowLoop.into does, where it cannot inline *args): each copy rebinds _PLAIN
    n = args[0].shape[0]
    far = np.int32(0)
    for b in prange((n + FLAG_BLOCK - 1) // FLAG_BLOCK):
        lo = b * FLAG_BLOCK
        m = min(n - lo, FLAG_BLOCK)
        flags = np.empty(FLAG_BLOCK, np.int32)
        prefer_no_gather()
        for j in range(m):
            flags[j] = _PLAIN(lo + j, args)
        far = max(far, flags_max(flags, m))
    return far


def _far_rows_again(*args):
    # the second pass of FarRows: each copy rebinds _SCALED
    for i in range(args[0].shape[0]):
        prefer_no_gather()
        _SCALED(i, args)


def second_pass(scaled, name):
    """The serial kernel ``k(*args)`` that calls ``scaled(i, args)`` on every row:
    the second pass of :class:`FarRows` (and of loops that find their far rows
    otherwise, as ``rotation``'s with :func:`far_excess`)."""
    return RowLoop(specialise(_far_rows_again, "_" + name, home=scaled, _SCALED=scaled), parallel=False)


class FarRows:
    """The batched loop of a formula that is exact only near unit scale, over
    the rows of its first argument; called like a :class:`quatarray._jit.RowLoop`.

    ``plain(i, args)`` computes row i of the arrays ``args`` (the kernel's
    arguments, as one tuple) on the inputs as they are, stores it, and returns
    the row's :func:`far_scale` flag (an ``int32``, 1 where that is not exact:
    far from unit scale, or 0, inf, nan). It should be an :func:`element`
    LLVM inlines (the default for a function that reads arrays), so that the loop vectorises as if written out. The loop keeps the
    flags per block of :data:`FLAG_BLOCK` rows (:func:`flags_max`) and returns
    whether one was set; only then a second, serial kernel calls
    ``scaled(i, args)`` on every row, which redoes the row if it is flagged (on
    the scaled input, say: :func:`qscaled`) and else leaves it. The common case
    costs what the plain formula costs, and the second pass and the scaled
    formulas compile only on the first input that needs them. Where an output
    may be an input, ``plain`` leaves flagged rows holding that input, for
    ``scaled`` to read. A call returns 1 when the second pass ran, else 0.

    The compiled copies are named after `plain` (``_norm_plain`` gives
    ``_far_rows_norm``, their cache files beside `plain`'s);
    ``parallel=False`` keeps the first pass serial. Made by ``rowloop(far=...)``.

    Example: ``quatarray.algebra._norm = rowloop(_norm_plain, far=_norm_scaled)``, the
    two formulas defined beside it.
    """

    # (The arrays go to plain and scaled as one tuple: a star call ``plain(i, *args)``
    # keeps LLVM from vectorising the loop, and so does numba-IR inlining of plain.)

    def __init__(self, plain, scaled, parallel=True):
        name = getattr(plain, "py_func", plain).__name__.strip("_").removesuffix("_plain")
        loop = specialise(_far_loop, "_" + name, home=plain, _PLAIN=plain)
        self.first = RowLoop(specialise(_far_rows, "_" + name, home=plain, _FAR_LOOP=_ir_inline(loop)),
                             parallel=parallel, tuple_loop=loop)
        self.again = second_pass(scaled, name)
        self.__name__ = "_" + name

    def __call__(self, *args):
        far = self.first(*args)
        if far:
            self.again(*args)
        return far

    def into(self, k, *args):
        """``self(*args, args[k])``, the first pass as :meth:`quatarray._jit.RowLoop.into`."""
        far = self.first.into(k, *args)
        if far:
            self.again(*args, args[k])
        return far
