"""The test matrix: ``python -m pip install nox`` then ``python -m nox`` (every session).

Sessions
--------
``tests-3.10`` … ``tests-3.13``
    The newest releases of every dependency that pip resolves for each CPython.
``floor``
    Every minimum that ``pyproject.toml`` declares (the project's dependencies and
    its ``test`` extra) pinned exactly, on the oldest CPython it supports.

Arguments after ``--`` go to pytest in place of the default ``-n auto`` (the whole
suite): ``python -m nox -s floor -- tests/test_io.py -n 2``. The CPythons are found
on ``PATH`` and in pyenv's versions (``pyenv root``); a missing one fails the session
(``python -m nox --error-on-missing-interpreters`` is the default here).
"""

import os
import pathlib
import re
import shutil
import subprocess

import nox

ROOT = pathlib.Path(__file__).resolve().parent
PYTHONS = ["3.10", "3.11", "3.12", "3.13"]
OLDEST = PYTHONS[0]

nox.options.error_on_missing_interpreters = True
nox.options.sessions = [f"tests-{p}" for p in PYTHONS] + ["floor"]


def _add_pyenv_pythons():
    """Put the ``bin`` folder of pyenv's newest patch release of each of PYTHONS on
    PATH (nox finds ``python3.X`` there), when pyenv is installed."""
    root = os.environ.get("PYENV_ROOT")
    if not root and shutil.which("pyenv"):
        root = subprocess.run(["pyenv", "root"], capture_output=True, text=True, check=False).stdout.strip()
    versions = pathlib.Path(root or os.path.expanduser("~/.pyenv")) / "versions"
    if not versions.is_dir():
        return
    found = []
    for minor in PYTHONS:
        patches = [p for p in versions.glob(f"{minor}.*") if re.fullmatch(rf"{re.escape(minor)}\.\d+", p.name)]
        if patches:
            best = max(patches, key=lambda p: int(p.name.rsplit(".", 1)[1]))
            found.append(str(best / "bin"))
    os.environ["PATH"] = os.pathsep.join(found + [os.environ.get("PATH", "")])


_add_pyenv_pythons()


def _minimums():
    """``name==version`` for each requirement of the project and its ``test`` extra
    that declares a ``>=`` minimum (markers kept), from pyproject.toml."""
    text = (ROOT / "pyproject.toml").read_text()
    try:
        import tomllib
    except ImportError:  # Python 3.10 running nox
        import tomli as tomllib
    project = tomllib.loads(text)["project"]
    pins = []
    for req in project["dependencies"] + project["optional-dependencies"]["test"]:
        m = re.fullmatch(r"\s*([A-Za-z0-9_.\-]+)(\[[^\]]*\])?\s*>=\s*([0-9][0-9.]*)[^;]*(;.*)?", req)
        if m:
            pins.append(f"{m.group(1)}=={m.group(3)}{m.group(4) or ''}")
    return pins


def _pytest(session):
    # each session's own numba cache: two numba releases must not share one index
    session.env["NUMBA_CACHE_DIR"] = str(pathlib.Path(session.virtualenv.location) / "numba-cache")
    session.run("python", "-c", "import sys, numba, numpy, scipy, pyarrow; "
                "print('versions: Python', sys.version.split()[0], 'numba', numba.__version__, "
                "'numpy', numpy.__version__, 'scipy', scipy.__version__, 'pyarrow', pyarrow.__version__)")
    session.run("python", "-m", "pytest", *(session.posargs or ["-n", "auto"]))


@nox.session(python=PYTHONS)
def tests(session):
    """The newest releases on this CPython: the README's two commands."""
    session.install(".[test]")
    _pytest(session)


@nox.session(python=OLDEST)
def floor(session):
    """Every declared minimum pinned, on the oldest CPython."""
    constraints = pathlib.Path(session.create_tmp()) / "floor.txt"
    constraints.write_text("\n".join(_minimums()) + "\n")
    session.log("floor pins: " + ", ".join(_minimums()))
    session.install("-c", str(constraints), ".[test]")
    _pytest(session)
