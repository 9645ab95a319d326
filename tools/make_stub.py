"""Write ``quatarray/__init__.pyi``, the type stub of the top-level names.

Run ``python tools/make_stub.py`` after adding a public function; the test
``tests/test_typing.py`` fails while the stub and ``quatarray.__all__``
disagree. Array arguments are ``ArrayLike``, arrays returned
``NDArray[floating]``; the names below give the other arguments' types.
"""

import inspect
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # this checkout's quatarray

import quatarray  # noqa: E402

ARG = {
    "out": "FloatArray | None",
    "degrees": "bool", "shortest": "bool", "assume_valid": "bool", "suppress_warnings": "bool",
    "return_sensitivity": "bool", "copy": "bool", "verbose": "bool",
    "seq": "str", "method": "str", "frame": "str", "hold": "str",
    "dtype": "DTypeLike", "shape": "int | tuple[int, ...]", "n": "int | None",
    "rng": "int | np.random.Generator | None", "atol": "float | None",
    "order": "int", "processes": "int | None", "names": "Sequence[str] | None", "rotation": "Any",
}
# Names whose type depends on the function.
ARG_OF = {
    ("cumprod", "axis"): "int", ("unflip", "axis"): "int", ("mean", "axis"): "int | tuple[int, ...] | None",
}
RETURNS = {
    "as_axis_angle": "tuple[FloatArray, FloatArray]",
    "bezier_controls": "tuple[FloatArray, FloatArray]",
    "align_vectors": "tuple[FloatArray, FloatArray] | tuple[FloatArray, FloatArray, FloatArray]",
    "approx_equal": "NDArray[np.bool_]",
    "as_su2": "NDArray[np.complexfloating[Any, Any]]",
    "to_scipy": "Any",
    "warmup": "Any",
    "interpolate": "Any",
}

HEAD = '''"""Type stub of quatarray's top-level names (written by tools/make_stub.py)."""

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, DTypeLike, NDArray

FloatArray = NDArray[np.floating[Any]]

__version__: str
'''


def _param(fn, p):
    kind = ARG_OF.get((fn, p.name)) or ARG.get(p.name, "ArrayLike")
    if p.default is None and "None" not in kind:
        kind += " | None"
    text = f"{p.name}: {kind}"
    if p.default is not inspect.Parameter.empty:
        text += " = ..."
    return text


def stub():
    lines = [HEAD]
    for name in quatarray.__all__:
        obj = getattr(quatarray, name)
        if inspect.isclass(obj):
            lines.append(f"from {obj.__module__} import {name} as {name}")
            continue
        sig = inspect.signature(obj)
        params, star = [], False
        for p in sig.parameters.values():
            if p.name.startswith("_"):  # private keywords stay out of the public types
                continue
            if p.kind is p.KEYWORD_ONLY and not star:
                params.append("*")
                star = True
            params.append(_param(name, p))
        lines.append(f"def {name}({', '.join(params)}) -> {RETURNS.get(name, 'FloatArray')}: ...")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    path = pathlib.Path(quatarray.__file__).with_name("__init__.pyi")
    path.write_text(stub())
    print(f"wrote {path}")
