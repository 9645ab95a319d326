"""What numba compiles inside a block (shared by the tests that count compiles)."""

import contextlib

from numba.core import event


@contextlib.contextmanager
def compiles():
    """The names of the functions numba compiles inside the block, in order (a list
    filled as they start)."""
    names = []

    class Listener(event.Listener):
        def on_start(self, ev):
            names.append(ev.data["dispatcher"].py_func.__name__)

        def on_end(self, ev):
            pass

    with event.install_listener("numba:compile", Listener()):
        yield names
