"""The test matrix: ``python -m pip install nox`` then ``python -m nox`` (every session).

Sessions
--------
``tests-3.10`` … ``tests-3.13``
    The newest releases of every dependency that pip resolves for each CPython.
``floor``
    Every minimum that ``pyproject.toml`` declares (the project's dependencies and
    its ``test`` extra) pinned exactly, on the oldest CPython it supports.
``mid-numba0.61`` (Python 3.10), ``mid-numba0.62`` (Python 3.11)
    Two cells between the floor and the newest: numba, numpy, scipy and pyarrow
    pinned to a release series each (``MIDDLE`` below), the rest newest.

``python -m nox`` runs the whole matrix (seven cells, one after the other; about
an hour and a half on 2 cores, most of it numba compiling into each cell's empty
cache); ``python -m nox -l`` lists them.

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
# pinned release series between the floor and the newest: (cell, CPython, pins)
MIDDLE = [
    ("mid-numba0.61", "3.10", ["numba==0.61.*", "numpy==2.1.*", "scipy==1.14.*", "pyarrow==22.*"]),
    ("mid-numba0.62", "3.11", ["numba==0.62.*", "numpy==2.2.*", "scipy==1.14.*", "pyarrow==18.*"]),
]

nox.options.sessions = [f"tests-{p}" for p in PYTHONS] + ["floor"] + [name for name, _, _ in MIDDLE]


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
    _pinned(session, _minimums(), "floor")
    _pytest(session)


def _pinned(session, pins, label):
    """Install the project and its ``test`` extra with `pins` as pip constraints."""
    constraints = pathlib.Path(session.create_tmp()) / f"{label}.txt"
    constraints.write_text("\n".join(pins) + "\n")
    session.log(f"{label} pins: " + ", ".join(pins))
    session.install("-c", str(constraints), ".[test]")


def _middle_session(name, python, pins):
    def middle(session):
        _pinned(session, pins, name)
        _pytest(session)

    middle.__doc__ = f"numba, numpy, scipy, pyarrow pinned ({', '.join(pins)}), the rest newest."
    return nox.session(name=name, python=python)(middle)


for _name, _python, _pins in MIDDLE:
    globals()[_name.replace("-", "_").replace(".", "_")] = _middle_session(_name, _python, _pins)
