"""Straight-line element functions as builtins: run on symbols, not compiled.

A function decorated with :func:`traced` is plain arithmetic on floats and
tuples of floats: ``+ - * /``, unary ``-``, ``abs``, ``np.sqrt``,
``np.rint``, ``np.floor``, ``np.copysign``, comparisons, ``& | ~ != ==`` of
their results, a comparison's result times a float (0 or 1), :func:`select`,
a choice of constants by type (:func:`float_bits`), and calls of other traced
functions, :func:`quatarray._jit.like` and :func:`quatarray._jit.fmuladd`.
In plain Python it runs as written. In a kernel it is a builtin of the caller,
as ``like`` is: numba types a call by running the function on symbols that
carry only their numba type, and lowers it by running it once more on symbols
that carry LLVM values, each operation emitting its instruction into the
caller's IR. There is no numba compile of its own. Compiled on its own (an
``inline`` element function), each cost 0.02-0.2 s of numba typing, lowering
and LLVM work per argument type, for code that LLVM then inlined anyway: the
first call of ``spline(method="squad", order=2)`` compiled about 48 such
functions (3.3 s CPU); with the rate rules, slerp's arcs, the trigonometry
and the quaternion products traced it takes 1.8 s.

The instructions are those numba emits for the same code (IEEE ``fadd``,
``fsub``, ``fmul``, ``fdiv`` without fast-math flags, LLVM's ``sqrt``,
``fabs``, ``rint``, ``floor``, ``copysign`` and ``fmuladd``, ordered
comparisons but an unordered ``!=``), so the results are bitwise those of
numba's compile of the same code (``tests/test_trace.py``). Types follow
numba's rules: float32 with float32 stays float32, float32 with float64 or an
integer gives float64; a Python number meets a symbol at the symbol's type,
as ``like`` would give it (no float64 literal slips into float32 code).
Python control flow on a symbol (``if``, ``and``, ``a if c else b``) is a
typing error at the call: use :func:`select`.
"""

import builtins
import dis
import inspect
import numbers
import threading
import types as _pytypes
from contextlib import contextmanager

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import lower_builtin, type_callable

class _Stack(threading.local):
    """A stack of each thread's own: two threads may compile at once (numba's
    compiler lock serialises its own compiles today, but nothing here relies on it)."""

    def __init__(self):
        self.items = [None]

    def __getitem__(self, i):
        return self.items[i]

    def append(self, x):
        self.items.append(x)

    def pop(self):
        return self.items.pop()


_NOW = _Stack()  # (context, builder) of the call being lowered; None while typing


class Sym:
    """A traced value: its numba type and, while lowering, its LLVM value."""

    __slots__ = ("ty", "v")

    def __init__(self, ty, v=None):
        self.ty = ty
        self.v = v

    def like(self, c):
        """`c` as a constant of this symbol's float type (``like(x, c)`` while tracing)."""
        ty = self.ty if isinstance(self.ty, types.Float) else types.float64
        return Sym(ty, _const(ty, c))

    def __bool__(self):
        raise TypeError("a traced function cannot branch on a value (if, and, or, a if c else b): use select()")

    def __float__(self):
        raise TypeError("a traced function cannot convert a value to a Python float")

    # arithmetic
    def __add__(self, o):
        return _binop("+", self, o)

    def __radd__(self, o):
        return _binop("+", o, self)

    def __sub__(self, o):
        return _binop("-", self, o)

    def __rsub__(self, o):
        return _binop("-", o, self)

    def __mul__(self, o):
        return _binop("*", self, o)

    def __rmul__(self, o):
        return _binop("*", o, self)

    def __truediv__(self, o):
        return _binop("/", self, o)

    def __rtruediv__(self, o):
        return _binop("/", o, self)

    def __neg__(self):
        return _unary("neg", self)

    def __abs__(self):
        return _unary("fabs", self)

    # comparisons (ordered: false with a nan; != unordered: true with a nan)
    def __lt__(self, o):
        return _compare("<", self, o)

    def __le__(self, o):
        return _compare("<=", self, o)

    def __gt__(self, o):
        return _compare(">", self, o)

    def __ge__(self, o):
        return _compare(">=", self, o)

    def __eq__(self, o):
        return _compare("==", self, o)

    def __ne__(self, o):
        return _compare("!=", self, o)

    __hash__ = None

    # logic on comparisons' results
    def __and__(self, o):
        return _logic("and_", self, o)

    __rand__ = __and__

    def __or__(self, o):
        return _logic("or_", self, o)

    __ror__ = __or__

    def __invert__(self):
        return _logic("not_", self)

    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        name = _UFUNCS.get(ufunc.__name__)
        if method != "__call__" or kwargs or name is None:
            return NotImplemented
        if name == "copysign":
            return _copysign(*inputs)
        return _unary(name, *inputs)


# numpy's functions of one float that a traced function may call, and LLVM's intrinsics for them
# (those numba's lowering of the same calls emits)
_UFUNCS = {"sqrt": "sqrt", "absolute": "fabs", "fabs": "fabs", "rint": "rint", "floor": "floor",
           "copysign": "copysign"}


def float_bits(x):
    """32 or 64: the width of x's float type (a symbol's, or a numpy scalar's; a Python
    float's is 64), for a choice of constants by type, fixed at compile time."""
    if isinstance(x, Sym):
        return x.ty.bitwidth
    return 32 if isinstance(x, np.float32) else 64


def _const(ty, c):
    return _NOW[-1][0].get_constant(ty, c) if _NOW[-1] else None


def _float_of(a, b):
    """numba's type of an arithmetic result of a and b (symbols or Python numbers)."""
    ta = a.ty if isinstance(a, Sym) else None
    tb = b.ty if isinstance(b, Sym) else None
    # a comparison's result in arithmetic is 0 or 1 of the other operand's float type (numba's rule)
    if isinstance(ta, types.Boolean) or isinstance(tb, types.Boolean):
        t = tb if isinstance(ta, types.Boolean) else ta
        if not isinstance(t, types.Float):
            raise TypeError("a traced function has a comparison's result in arithmetic with a float symbol only")
        return t
    if ta is None and tb is None:
        raise TypeError("a traced function meets two Python numbers here: make one a symbol with like()")
    if ta is None or tb is None:  # a Python number takes the symbol's type (as like() would give it)
        t = ta or tb
        other = b if ta is not None else a
        if isinstance(t, types.Integer) and isinstance(other, float):
            return types.float64
        return t
    if ta == tb:
        return ta
    if isinstance(ta, types.Float) and isinstance(tb, types.Float):
        return ta if ta.bitwidth > tb.bitwidth else tb
    if isinstance(ta, types.Integer) and isinstance(tb, types.Integer):
        return types.intp
    return types.float64


def _value(x, ty):
    """The LLVM value of x (a symbol or a Python number) at type ty."""
    if not isinstance(x, Sym):
        return _const(ty, x)
    if x.ty == ty:
        return x.v
    context, builder = _NOW[-1]
    return context.cast(builder, x.v, x.ty, ty)


_FLOAT_OPS = {"+": "fadd", "-": "fsub", "*": "fmul", "/": "fdiv"}
_INT_OPS = {"+": "add", "-": "sub", "*": "mul"}


def _binop(op, a, b):
    ty = _float_of(a, b)
    if isinstance(ty, types.Integer) and op not in _INT_OPS:
        raise TypeError(f"a traced function has no integer {op!r}")
    if _NOW[-1] is None:
        return Sym(ty)
    builder = _NOW[-1][1]
    ops = _FLOAT_OPS if isinstance(ty, types.Float) else _INT_OPS
    return Sym(ty, getattr(builder, ops[op])(_value(a, ty), _value(b, ty)))


def _copysign(a, b):
    ty = _float_of(a, b)
    if not isinstance(ty, types.Float):
        raise TypeError(f"a traced function has copysign of floats only, not of {ty}")
    if _NOW[-1] is None:
        return Sym(ty)
    return Sym(ty, _intrinsic(f"llvm.copysign.f{ty.bitwidth}", ty, _value(a, ty), _value(b, ty)))


def _intrinsic(name, ty, *args):
    builder = _NOW[-1][1]
    lty = args[0].type
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(lty, [lty] * len(args)), name)
    return builder.call(fn, list(args))


def _unary(name, a):
    if not isinstance(a.ty, types.Float):
        raise TypeError(f"a traced function has {name} of floats only, not of {a.ty}")
    if _NOW[-1] is None:
        return Sym(a.ty)
    builder = _NOW[-1][1]
    if name == "neg":
        return Sym(a.ty, builder.fneg(a.v))
    return Sym(a.ty, _intrinsic(f"llvm.{name}.f{a.ty.bitwidth}", a.ty, a.v))


def _compare(op, a, b):
    if all(isinstance(x, Sym) and isinstance(x.ty, types.Boolean) for x in (a, b)) and op in ("==", "!="):
        if _NOW[-1] is None:
            return Sym(types.boolean)
        return Sym(types.boolean, _NOW[-1][1].icmp_unsigned(op, a.v, b.v))
    ty = _float_of(a, b)
    if _NOW[-1] is None:
        return Sym(types.boolean)
    builder = _NOW[-1][1]
    x, y = _value(a, ty), _value(b, ty)
    if isinstance(ty, types.Float):
        v = builder.fcmp_unordered(op, x, y) if op == "!=" else builder.fcmp_ordered(op, x, y)
    else:
        v = builder.icmp_signed(op, x, y)
    return Sym(types.boolean, v)


def _logic(name, a, b=None):
    args = (a,) if b is None else (a, b)
    if not all(isinstance(x, Sym) and isinstance(x.ty, types.Boolean) for x in args):
        raise TypeError("a traced function has & | ~ of comparisons' results only")
    if _NOW[-1] is None:
        return Sym(types.boolean)
    return Sym(types.boolean, getattr(_NOW[-1][1], name)(*(x.v for x in args)))


def select(c, a, b):
    """``a if c else b``, component by component for tuples (both already computed):
    one LLVM ``select`` each, which keeps row loops vectorisable."""
    if isinstance(a, tuple):
        return tuple(select(c, x, y) for x, y in zip(a, b, strict=True))
    if not isinstance(c, Sym):
        return a if c else b
    ty = _float_of(a, b)
    if _NOW[-1] is None:
        return Sym(ty)
    if not isinstance(c.ty, types.Boolean):  # a number's truth, as Python's and numba's: c != 0 (nan is true)
        c = _compare("!=", c, 0)
    return Sym(ty, _NOW[-1][1].select(c.v, _value(a, ty), _value(b, ty)))


# select in compiled code too (an element that is not traced may call it): typed and
# lowered in place, one LLVM select per component, as while tracing
@type_callable(select)
def _type_select(context):
    def typer(c, a, b):
        c, a, b = (types.unliteral(x) for x in (c, a, b))
        scalar = (types.Float, types.Integer, types.Boolean)
        leaves = a.types if isinstance(a, types.BaseTuple) else (a,)
        if isinstance(c, scalar) and a == b and all(isinstance(x, scalar) for x in leaves):
            return a

    return typer


@lower_builtin(select, types.Any, types.Any, types.Any)
def _lower_select(context, builder, sig, args):
    cty, ty = sig.args[0], sig.return_type
    c = args[0]
    if not isinstance(cty, types.Boolean):  # a number's truth: c != 0 (nan is true)
        zero = context.get_constant(cty, 0)
        c = builder.fcmp_unordered("!=", c, zero) if isinstance(cty, types.Float) else builder.icmp_signed("!=", c, zero)
    if isinstance(ty, types.BaseTuple):
        items = [builder.select(c, builder.extract_value(args[1], k), builder.extract_value(args[2], k))
                 for k in range(len(ty))]
        return context.make_tuple(builder, ty, items)
    return builder.select(c, args[1], args[2])


# ---- typing and lowering of a traced function's calls


def _symbols(ty, value=None, builder=None):
    """The traced form of an argument of numba type ty (tuples as tuples of symbols)."""
    ty = types.unliteral(ty)
    if isinstance(ty, types.BaseTuple):
        return tuple(
            _symbols(t, None if value is None else builder.extract_value(value, i), builder)
            for i, t in enumerate(ty.types)
        )
    if isinstance(ty, (types.Float, types.Integer, types.Boolean)):
        return Sym(ty, value)
    raise TypeError(f"a traced function takes numbers and tuples of them, not {ty}")


def _type_of(out):
    if isinstance(out, tuple):
        return types.BaseTuple.from_types([_type_of(x) for x in out])
    if isinstance(out, Sym):
        return out.ty
    raise TypeError(f"a traced function returns symbols and tuples of them, not {out!r} (use like())")


def _pack(context, builder, out, ty):
    if isinstance(out, tuple):
        return context.make_tuple(builder, ty, [_pack(context, builder, x, t) for x, t in zip(out, ty.types)])
    return out.v


@contextmanager
def _tracing(now):
    _NOW.append(now)
    try:
        yield
    finally:
        _NOW.pop()


# the functions a traced function may call besides other traced ones (and the
# callers' additions: ``_jit.like`` and ``_jit.fmuladd``)
CALLABLE = {abs, np.sqrt, np.fabs, np.absolute, np.rint, np.floor, np.copysign}
TRACED = set()  # every traced function

# opcodes of code that is not straight-line arithmetic on symbols (control flow,
# loops, stores into arrays or attributes, containers, closures, exceptions)
_REFUSED = ("JUMP", "FOR_ITER", "GET_ITER", "STORE_SUBSCR", "DELETE", "STORE_ATTR", "STORE_GLOBAL",
            "RAISE", "RERAISE", "YIELD", "SEND", "SETUP", "BUILD_LIST", "BUILD_MAP", "BUILD_SET",
            "LIST_", "DICT_", "SET_", "IMPORT", "MAKE_FUNCTION", "LOAD_CLOSURE", "LOAD_DEREF",
            "RETURN_GENERATOR", "WITH_", "BEFORE_WITH", "CHECK_EXC", "PUSH_EXC", "POP_EXCEPT")


def untraceable(fn, also=()):
    """Why `fn` cannot be traced (:func:`traced`), or None when it can: read from its
    bytecode, it must be straight line (no branch, loop or exception), index only by
    constants (tuples, not arrays), read no attribute but a module's function, and
    call only traced functions, :data:`CALLABLE`, :func:`select`,
    :func:`float_bits` and the functions `also`; its globals are numbers, tuples of
    them and those functions, all defined when it is asked (define a function's
    callees above it). Conservative: a reason for whatever it cannot tell (the
    function is then compiled instead, which is always right)."""
    code = getattr(fn, "__code__", None)
    if code is None or code.co_flags & (inspect.CO_GENERATOR | inspect.CO_COROUTINE) or code.co_freevars:
        return "not a plain function"
    ok = CALLABLE | TRACED | {select, float_bits} | set(also)
    ins = list(dis.get_instructions(fn))
    for k, x in enumerate(ins):
        op = x.opname
        if any(r in op for r in _REFUSED):
            return f"{op} (control flow, a loop, a store or a container)"
        prev = ins[k - 1] if k else None
        if op == "BINARY_SUBSCR" and not (  # a constant index or slice (of a tuple)
                prev.opname == "LOAD_CONST"
                or prev.opname == "BUILD_SLICE" and all(y.opname == "LOAD_CONST" for y in ins[k - 1 - prev.arg:k - 1])):
            return "an index that is not a constant"
        if op == "BINARY_SLICE" and not all(y.opname == "LOAD_CONST" for y in ins[k - 2:k]):
            return "a slice that is not constant"
        if op in ("LOAD_ATTR", "LOAD_METHOD") and prev.opname not in ("LOAD_GLOBAL", "LOAD_ATTR", "LOAD_METHOD"):
            return f"the attribute {x.argval!r} of a value"  # an array's shape, say: only a module's names
        if op == "LOAD_GLOBAL":
            obj = _resolve(fn, ins, k)
            if obj is _MISSING:
                return f"the global {x.argval!r} is not defined yet"
            if isinstance(obj, _pytypes.ModuleType):
                return f"the module {x.argval!r} as a value"
            if callable(obj) and obj not in ok or not callable(obj) and not _is_number(obj):
                return f"the global {x.argval!r} is not a number or a traceable function"
    return None


_MISSING = object()


def _resolve(fn, ins, k):
    """The object the LOAD_GLOBAL at ins[k] and the attribute loads after it name."""
    name = ins[k].argval
    obj = fn.__globals__.get(name, getattr(builtins, name, _MISSING))
    for x in ins[k + 1:]:
        if x.opname not in ("LOAD_ATTR", "LOAD_METHOD") or not isinstance(obj, _pytypes.ModuleType):
            break
        obj = getattr(obj, x.argval, _MISSING)
    return obj


def _is_number(x):
    if isinstance(x, tuple):
        return all(_is_number(y) for y in x)
    return isinstance(x, (numbers.Number, np.number))


def traced(fn):
    """Make `fn` (straight-line arithmetic, see the module docstring) a builtin of the
    kernels that call it; it stays a plain function in Python."""
    signature = inspect.signature(fn)
    known = {}  # argument types: result type

    @type_callable(fn)
    def _type(context):
        def typer(*args):
            key = tuple(types.unliteral(a) for a in args)
            if key not in known:  # numba may type a call several times
                try:
                    with _tracing(None):
                        known[key] = _type_of(fn(*(_symbols(a) for a in key)))
                except TypeError as e:  # reported by numba at the call, as its own typing errors
                    raise TypingError(f"traced function {fn.__qualname__}{key}: {e}") from None
            return known[key]

        typer.__signature__ = signature  # numba binds a call's arguments by it (no *args folding)
        return typer

    @lower_builtin(fn, types.VarArg(types.Any))
    def _lower(context, builder, sig, args):
        with _tracing((context, builder)):
            out = fn(*(_symbols(t, v, builder) for t, v in zip(sig.args, args)))
            return _pack(context, builder, out, sig.return_type)

    TRACED.add(fn)
    return fn


def fmuladd(a, b, c):
    """``_jit.fmuladd`` while tracing: LLVM's ``fmuladd`` of a, b, c at their float type."""
    ty = _float_of(Sym(_float_of(a, b)), c)
    if _NOW[-1] is None:
        return Sym(ty)
    return Sym(ty, _intrinsic(f"llvm.fmuladd.f{ty.bitwidth}", ty, *(_value(x, ty) for x in (a, b, c))))
