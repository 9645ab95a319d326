"""Every use of a numba or llvmlite internal, each behind a feature test.

quatarray builds on numba's documented extension API (``numba.extending``'s
``type_callable``, ``lower_builtin`` and ``overload``, ``numba.core.types``,
``numba.core.cgutils`` and llvmlite's IR builder for the lowerings). What it
takes beyond that, for compile time and run time only, lives here:

=========================  ==============================================  ======================================
what                       the internal                                    without it
=========================  ==============================================  ======================================
package stamp of the       ``CacheImpl._locator_classes`` (a list of       numba's on-disk cache is off for
cache                      locators with ``from_function`` and             quatarray's kernels (every process
                           ``get_source_stamp``)                           compiles)
cache write lock           ``IndexDataCacheFile.save(self, key, data)``    with ``QUATARRAY_CACHE_LOCK`` set, the
                                                                           cache is off; the background warm-up
                                                                           does not start
deferred BLAS probe        ``numba.np.linalg.ensure_blas``                 numba imports scipy.linalg (0.25 s)
plain-type calls between   a dispatcher's class swapped for a subclass     a compile per literal argument value
kernels                    overriding ``get_call_template(args, kws)``
element functions without  ``no_cpython_wrapper``, ``no_cfunc_wrapper``    element functions keep the wrappers
wrappers                   options and the class swap above                (slower first compiles)
``forceinline``            numba's ``forceinline`` option                  LLVM decides what to inline
``prefer_no_gather``       ``codegen()._tm_features``, llvmlite's          the function keeps the target's
                           ``FunctionAttributes`` as a set whose members   features (the same results, maybe
                           print as written, LLVM >= 17                    slower on AVX-512)
``prefer_wide_vectors``    llvmlite's ``FunctionAttributes`` as a set      256-bit vectors on AVX-512 (the same
                           whose members print as written                  results, slower)
compile counts             ``numba.core.event``'s compile listener         the warm-up reports no count
``scratch`` arrays         ``context.nrt.meminfo_alloc_aligned(builder,    ``np.zeros`` compiled into the kernel
                           size, align)``, ``numba.np.arrayobj.            (its overloads: 0.08 s more per
                           populate_array(array, data, shape, strides,     first call that allocates)
                           itemsize, meminfo)``
=========================  ==============================================  ======================================

Each is tested when first needed. Where one is missing or has changed,
quatarray still imports and computes the same numbers, and the first such
case of a process warns once (:class:`NumbaInternalsWarning`);
:func:`missing` lists them all. ``tests/test_numba_internals.py`` takes each
away in turn.

Function copies (``_jit.specialise`` and its kin) are made here too
(:func:`copy_function`): numba's cache names a function by its qualified name
and first line, and reads its source (``inspect.getsourcelines``) for the
annotation it stores, so a copy gets a qualified name of its own and the file
name *and* first line of one real function (from Python 3.13 on,
``inspect`` reads a block from the very line given).
"""

import importlib.util
import inspect
import os
import sys
import threading
import warnings

import llvmlite
import numba

#: The newest numba release that quatarray is tested with (``pyproject.toml``'s
#: upper bound is the next minor release).
TESTED_NUMBA = "0.68"


class NumbaInternalsWarning(RuntimeWarning):
    """A numba or llvmlite internal that quatarray uses is missing or has changed:
    quatarray computes the same results without it, maybe slower."""


_MISSING = {}  # feature: why
_WARNED = [False]
_LOCK = threading.Lock()


def degrade(feature, why):
    """Record that `feature` is off (`why`), warning at the first such record of
    the process only."""
    with _LOCK:
        if feature in _MISSING:
            return
        _MISSING[feature] = why
        first = not _WARNED[0]
        _WARNED[0] = True
    if first:
        warnings.warn(
            f"quatarray: numba {numba.__version__} (llvmlite {llvmlite.__version__}) lacks an internal that "
            f"quatarray uses ({feature}: {why}); the results are the same without it, but may take longer. "
            f"quatarray is tested with numba <= {TESTED_NUMBA}; quatarray._numba_internals.missing() lists "
            "every such feature of this process.",
            NumbaInternalsWarning, stacklevel=3,
        )


def missing():
    """The features turned off in this process, ``{feature: reason}``."""
    return dict(_MISSING)


def _params(fn):
    try:
        return list(inspect.signature(fn).parameters)
    except (TypeError, ValueError):
        return None


# ---------------------------------------------------------------- numba.np.linalg.ensure_blas


def defer_blas_probe():
    """Keep numba from importing ``scipy.linalg`` in every process that compiles or
    loads a kernel (0.25 s CPU, 0.15 s wall; a third of a warm command-line call).

    numba's ``np.arraymath``, imported by its first compile or cache load, sets
    ``_HAVE_BLAS`` at import by calling ``numba.np.linalg.ensure_blas``, which imports
    ``scipy.linalg.cython_blas``; only ``np.dot``-like functions read the answer, and
    quatarray's kernels use none. Until that import, ``ensure_blas`` is replaced by a
    probe that answers the same question by finding ``scipy.linalg`` without running
    it, and puts the real function back at its first call. Any later caller (numba's
    linear algebra, when some kernel uses it) runs the real one, which imports scipy
    then. Nothing changes where ``np.arraymath`` is already imported or numba differs
    (then numba imports scipy.linalg as it would without quatarray)."""
    try:
        from numba.np import linalg
    except ImportError:
        return degrade("deferred BLAS probe", "no numba.np.linalg")
    real = getattr(linalg, "ensure_blas", None)
    if real is None or _params(real) != []:
        return degrade("deferred BLAS probe", "numba.np.linalg.ensure_blas is missing or changed")
    if "numba.np.arraymath" in sys.modules:
        return None

    def probe():
        linalg.ensure_blas = real
        if importlib.util.find_spec("scipy.linalg") is None:
            raise ImportError("scipy.linalg is not installed")

    linalg.ensure_blas = probe
    return None


# ---------------------------------------------------------------- the cache's locators


def _locator_list():
    """numba's list of cache locator classes, or None where it is not one."""
    try:
        from numba.core.caching import CacheImpl
    except ImportError:
        return None
    classes = getattr(CacheImpl, "_locator_classes", None)
    if not isinstance(classes, list) or not classes:
        return None
    for c in classes:
        if not (callable(getattr(c, "from_function", None)) and callable(getattr(c, "get_source_stamp", None))):
            return None
    return classes


class PackageLocator:
    """A numba cache locator for the functions of one package's files: numba's
    own (the first of its standard locators that takes the function), with a
    source stamp that also holds :attr:`stamp` (``_jit.package_stamp`` of the
    package).

    numba stamps a function's cached code with the hash of its own source file
    only, while a kernel also holds the code of the element functions of other
    files that it inlines: a kernel of ``conversions.py`` compiled before a change
    of ``_trig.py`` would keep loading the old trigonometry (after an upgrade that
    changed ``_trig.py`` alone, for instance, where the cache outlives the
    sources). With the package's stamp, a change of any source file makes every
    kernel compile again."""

    package_dir = None  # set by install_locator
    stamp_of = None  # the package's stamp: a function of package_dir
    _stamp = None  # computed at the first locator
    standard = []  # numba's own locators, in order
    _quatarray_locator = True  # tells this class (and its copies after a reload) apart

    def __init__(self, inner):
        self._inner = inner

    def __getattr__(self, name):
        if name == "_inner":  # not set yet (copy, pickle): no recursion
            raise AttributeError(name)
        return getattr(self._inner, name)

    def get_source_stamp(self):
        if PackageLocator._stamp is None:
            PackageLocator._stamp = PackageLocator.stamp_of(PackageLocator.package_dir)
        return self._inner.get_source_stamp(), PackageLocator._stamp

    @classmethod
    def from_function(cls, py_func, py_file):
        root = PackageLocator.package_dir
        try:
            if os.path.commonpath([os.path.abspath(py_file), root]) != root:
                return None
        except ValueError:  # another drive (Windows)
            return None
        for locator in PackageLocator.standard:
            inner = locator.from_function(py_func, py_file)
            if inner is not None:
                return cls(inner)
        return None


def install_locator(package_dir, stamp_of):
    """Put :class:`PackageLocator` first in numba's cache locators for the files
    under `package_dir` (in place of any earlier copy of it). False where numba's
    locators are not the list this knows: then the caller must keep the cache off
    (a kernel could load code built from older sources of the files it inlines)."""
    classes = _locator_list()
    if classes is None:
        degrade("package stamp of the cache", "numba's CacheImpl._locator_classes is missing or changed; "
                "quatarray's kernels are not cached on disk")
        return False
    PackageLocator.package_dir = package_dir
    PackageLocator.stamp_of = stamp_of
    classes[:] = [c for c in classes if not getattr(c, "_quatarray_locator", False)]
    PackageLocator.standard[:] = list(classes)
    classes.insert(0, PackageLocator)
    return True


# ---------------------------------------------------------------- the cache write lock


def _index_file_class():
    try:
        from numba.core.caching import IndexDataCacheFile
    except ImportError:
        return None
    save = getattr(IndexDataCacheFile, "save", None)
    if not callable(save) or _params(save) != ["self", "key", "data"]:
        return None
    return IndexDataCacheFile


def cache_lock_path():
    """The file whose lock this process's cache writes hold, or None."""
    cls = _index_file_class()
    return None if cls is None else getattr(cls.save, "lock_path", None)


def lock_cache_writes(path, flock):
    """Make this process's writes to numba's cache hold ``flock(f, LOCK_EX)`` on the
    file `path`; once per process. False where numba's cache file class is not the one
    this knows (the caller must then keep the cache off, or not share it)."""
    cls = _index_file_class()
    if cls is None:
        degrade("cache write lock", "numba's IndexDataCacheFile.save is missing or changed")
        return False
    save = cls.save
    if getattr(save, "lock_path", None) is not None:
        return True

    def locked_save(self, key, data):
        with open(path, "a") as f:
            flock(f, True)
            try:
                save(self, key, data)
            finally:
                flock(f, False)

    locked_save.lock_path = path
    cls.save = locked_save
    return True


# ---------------------------------------------------------------- dispatchers

try:
    from numba.core.registry import CPUDispatcher
except ImportError:  # pragma: no cover - numba moved it
    CPUDispatcher = None


def _target_option(name):
    try:
        from numba.core.cpu import CPUTargetOptions
    except ImportError:
        return False
    return hasattr(CPUTargetOptions, name)


def _call_template_known():
    fn = getattr(CPUDispatcher, "get_call_template", None) if CPUDispatcher is not None else None
    return fn is not None and _params(fn) == ["self", "args", "kws"]


_CALL_TEMPLATE = _call_template_known()
if CPUDispatcher is not None and not _CALL_TEMPLATE:
    degrade("plain-type calls between kernels", "numba's Dispatcher.get_call_template is missing or changed")

if CPUDispatcher is not None:  # module-level classes: a dispatcher pickles by reference to its class
    from numba.core import types as _types

    class Dispatcher(CPUDispatcher):
        """numba's dispatcher, except that a call from another kernel compiles for the
        arguments' plain types. numba types a constant argument as a literal (the 16 of
        a table column) and compiles an overload for each literal value: the spline's
        small table accessors compiled up to five times each, 0.1-0.3 s apiece."""

        if _CALL_TEMPLATE:
            def get_call_template(self, args, kws):
                args = tuple(_types.unliteral(a) for a in args)
                kws = {k: _types.unliteral(v) for k, v in kws.items()}
                return super().get_call_template(args, kws)

    class Element(Dispatcher):
        """The dispatcher of an element function (compiled without the CPython and C
        wrappers). A call from Python (a test, a REPL) runs a twin compiled with the
        wrappers, in memory only (one on-disk cache index serves both, and the twin's
        code must not be taken for the element's or the other way round); the kernels
        never go this way."""

        def __call__(self, *args, **kws):
            twin = self.__dict__.get("_python_twin")
            if twin is None:
                twin = self.__dict__["_python_twin"] = numba.njit(**self.__dict__["_twin_options"])(self.py_func)
            return twin(*args, **kws)
else:  # pragma: no cover - numba moved its CPU dispatcher
    Dispatcher = Element = None

WRAPPER_OPTIONS = ("no_cpython_wrapper", "no_cfunc_wrapper")


def supported_options(options):
    """`options` less the numba target options this numba does not have (each
    recorded, see :func:`missing`)."""
    keep = {}
    for k, v in options.items():
        if k in ("no_cpython_wrapper", "no_cfunc_wrapper", "forceinline") and not _target_option(k):
            degrade(f"numba option {k}", "not a CPU target option of this numba")
            continue
        keep[k] = v
    return keep


def _swap(d, cls):
    """Make the dispatcher `d` one of class `cls` (a subclass of its own class with
    the same layout); False where that cannot be done."""
    if cls is None or not isinstance(d, CPUDispatcher) or type(d) is not CPUDispatcher:
        return False
    try:
        d.__class__ = cls
    except TypeError:
        return False
    return True


def njit(fn, element=False, **options):
    """``numba.njit(**options)(fn)`` as a :class:`Dispatcher` (an :class:`Element`
    where `element`: without wrappers where numba has those options). Where the class
    cannot be swapped, numba's own dispatcher (an element keeps its wrappers)."""
    if element:
        wrapped = dict(options)
        options = supported_options({**options, **{k: True for k in WRAPPER_OPTIONS}})
    else:
        options = supported_options(options)
    d = numba.njit(**options)(fn)
    if not hasattr(d, "py_func"):  # NUMBA_DISABLE_JIT=1: the plain function
        return d
    if _swap(d, Element if element else Dispatcher):
        if element:
            # the twin in memory only: on disk it would share the element's cache index
            d.__dict__["_twin_options"] = {k: v for k, v in supported_options(wrapped).items()
                                           if k not in WRAPPER_OPTIONS and k != "cache"}
        return d
    degrade("dispatcher subclass", f"numba's dispatcher class {type(d).__qualname__} cannot be subclassed "
            "in place")
    if element and any(k in options for k in WRAPPER_OPTIONS):  # callable from Python: with its wrappers
        return numba.njit(**supported_options(wrapped))(fn)
    return d


# ---------------------------------------------------------------- function copies


def rehome(code, home):
    """`code` with the file name and first line of the code object `home` (a real
    function's), a consistent pair for numba's cache and ``inspect``."""
    return code.replace(co_filename=home.co_filename, co_firstlineno=home.co_firstlineno)


# ---------------------------------------------------------------- target features

NO_GATHER_FEATURES = "+prefer-no-gather,+prefer-no-scatter"
_FEATURES_OK = []  # [bool] once probed


def _llvm_version():
    try:
        from llvmlite import binding
        return tuple(binding.llvm_version_info)
    except Exception:  # noqa: BLE001 - any failure: unknown
        return (0,)


def _probe_string_attribute():
    """True where llvmlite prints a string member of a function's attribute set
    as written (``set.add`` past its check of LLVM's enumerated attributes)."""
    from llvmlite import ir

    try:
        module = ir.Module()
        fn = ir.Function(module, ir.FunctionType(ir.VoidType(), []), "probe")
        attrs = fn.attributes
        if not isinstance(attrs, set):
            return False
        set.add(attrs, '"quatarray-probe"="1"')
        ir.IRBuilder(fn.append_basic_block()).ret_void()
        return '"quatarray-probe"="1"' in str(module)
    except Exception:  # noqa: BLE001 - any failure: not supported
        return False


def add_target_features(context, builder, extra=NO_GATHER_FEATURES):
    """Give the function being lowered LLVM's ``target-features`` attribute: the
    target machine's own features and `extra` (tuning flags that change only the
    instructions chosen). Nothing where LLVM is older than 17 (which lacks the
    ``prefer-no-gather`` flags), where numba's codegen has no string
    ``_tm_features`` or where llvmlite does not print the attribute."""
    if not _FEATURES_OK:
        ok = _llvm_version() >= (17,)  # the flags' LLVM: no feature LLVM does not know (it warns on stderr)
        if ok and not isinstance(getattr(context.codegen(), "_tm_features", None), str):
            degrade("prefer_no_gather", "numba's codegen has no _tm_features string")
            ok = False
        if ok and not _probe_string_attribute():
            degrade("prefer_no_gather", "llvmlite's function attributes do not print a string attribute")
            ok = False
        _FEATURES_OK.append(ok)
    if not _FEATURES_OK[0]:
        return
    features = context.codegen()._tm_features
    joined = f"{features},{extra}" if features else extra
    set.add(builder.function.attributes, f'"target-features"="{joined}"')


_WIDE_OK = []  # [bool] once probed


def add_wide_vectors(context, builder):
    """Give the function being lowered LLVM's ``"prefer-vector-width"="512"``: on
    AVX-512 targets, whose LLVM tuning prefers 256-bit vectors, its loops vectorise
    with 512-bit ones (a tuning attribute: elsewhere nothing changes, and the
    instructions of a lane, so the results, are the same). Nothing where llvmlite does
    not print a string attribute."""
    if not _WIDE_OK:
        ok = _probe_string_attribute()
        if not ok:
            degrade("prefer_wide_vectors", "llvmlite's function attributes do not print a string attribute")
        _WIDE_OK.append(ok)
    if _WIDE_OK[0]:
        set.add(builder.function.attributes, '"prefer-vector-width"="512"')


# ---------------------------------------------------------------- arrays allocated in a kernel


def new_zeros(context, builder, arrtype, n):
    """The LLVM value of a new 1-D C-contiguous array of type `arrtype` with `n` (an
    LLVM intp) elements, all zero, as a new reference, emitted in place: the runtime's
    allocation (``context.nrt.meminfo_alloc_aligned``), a ``memset`` and numba's array
    structure (``numba.np.arrayobj.populate_array``). numba's ``np.zeros`` compiles
    three functions of its own (its overloads and the allocator's) in every process
    that compiles a kernel calling it: 0.08 s of the Bézier spline's first calls.
    Where an internal is missing or changed, ``np.zeros`` is compiled in."""
    from numba.core import cgutils, types
    from numba.core.imputils import impl_ret_new_ref

    try:
        from numba.np.arrayobj import populate_array
    except ImportError:
        populate_array = None
    alloc = getattr(getattr(context, "nrt", None), "meminfo_alloc_aligned", None)
    if populate_array is None or (_params(populate_array) or [])[:6] != ["array", "data", "shape", "strides",
                                                                        "itemsize", "meminfo"]:
        degrade("scratch arrays", "numba.np.arrayobj.populate_array is missing or changed")
    elif alloc is None or _params(alloc) != ["builder", "size", "align"]:
        degrade("scratch arrays", "numba's NRT context has no meminfo_alloc_aligned(builder, size, align)")
    else:
        datatype = context.get_data_type(arrtype.dtype)
        itemsize = context.get_constant(types.intp, context.get_abi_sizeof(datatype))
        prod = builder.smul_with_overflow(n, itemsize)
        size = builder.extract_value(prod, 0)
        bad = builder.or_(builder.extract_value(prod, 1), builder.icmp_signed("<", n, n.type(0)))
        with builder.if_then(bad, likely=False):
            context.call_conv.return_user_exc(builder, ValueError, ("quatarray: a work array of negative or too "
                                                                    "many elements",))
        meminfo = alloc(builder, size, 64)
        # (numba's NRT context raises MemoryError itself on a null result in current
        # releases; the check stays for those that return it)
        with builder.if_then(cgutils.is_null(builder, meminfo), likely=False):
            context.call_conv.return_user_exc(builder, MemoryError, ("quatarray: a kernel's work array",))
        data = context.nrt.meminfo_data(builder, meminfo)
        cgutils.memset(builder, data, size, 0)
        ary = context.make_array(arrtype)(context, builder)
        populate_array(ary, data=builder.bitcast(data, datatype.as_pointer()), shape=[n], strides=[itemsize],
                       itemsize=itemsize, meminfo=meminfo)
        return impl_ret_new_ref(context, builder, arrtype, ary._getvalue())
    import numpy as np

    dtype = np.dtype(str(arrtype.dtype))
    return context.compile_internal(builder, lambda k: np.zeros(k, dtype), arrtype(types.intp), [n])


# ---------------------------------------------------------------- compile events


class CompileCounter:
    """``with CompileCounter() as c: …``; then ``c.count``: the number of functions numba
    compiled meanwhile (this thread's and others'), or None where numba's event API is
    not the one this knows."""

    def __init__(self):
        self.count = None
        self._cm = self._rec = None

    def __enter__(self):
        try:
            from numba.core import event

            self._rec = event.RecordingListener()
            self._cm = event.install_listener("numba:compile", self._rec)
            self._cm.__enter__()
        except Exception:  # noqa: BLE001 - any failure: no count
            degrade("compile events", "numba.core.event's listener API is missing or changed")
            self._cm = None
        return self

    def __exit__(self, *exc):
        if self._cm is not None:
            self._cm.__exit__(*exc)
            try:
                self.count = sum(1 for _, ev in self._rec.buffer if ev.is_start)
            except Exception:  # noqa: BLE001
                self.count = None
        return False

