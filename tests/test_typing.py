"""The type stub: it names exactly the public API, and a type checker reads it."""

import ast
import pathlib
import subprocess
import sys

import pytest

import quatarray

HERE = pathlib.Path(__file__).parent
STUB = pathlib.Path(quatarray.__file__).with_name("__init__.pyi")


def _stub_names():
    tree = ast.parse(STUB.read_text())
    names = set()
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            names.add(node.name)
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("quatarray"):
            names.update(a.asname or a.name for a in node.names)
    return names


def test_stub_names_the_public_api():
    names = _stub_names()
    assert names == set(quatarray.__all__), (
        f"missing from the stub: {sorted(set(quatarray.__all__) - names)}; "
        f"not public: {sorted(names - set(quatarray.__all__))} (run tools/make_stub.py)")


def test_py_typed_ships():
    assert STUB.with_name("py.typed").exists()


def _mypy(script):
    pytest.importorskip("mypy")
    root = HERE.parent
    return subprocess.run([sys.executable, "-m", "mypy", "--no-incremental", "--follow-imports=silent",
                           "--ignore-missing-imports", str(HERE / "typing" / script)],
                          capture_output=True, text=True, cwd=root)


def test_a_user_script_type_checks():
    res = _mypy("user_script.py")
    assert res.returncode == 0, res.stdout + res.stderr


def test_the_checker_sees_the_stub():
    res = _mypy("user_mistakes.py")
    assert res.returncode == 1, res.stdout + res.stderr
    out = res.stdout
    assert 'Argument 2 to "as_euler" has incompatible type "int"' in out
    assert '"shortest"' in out and "no_such_function" in out
