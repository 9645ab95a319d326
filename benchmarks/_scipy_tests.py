"""What the runners of scipy's own tests share (``run_scipy_rotation_tests.py``,
``run_scipy_rigid_transform_tests.py``): scipy's installed test files (nothing of
them is copied into this project) run with classes of ``scipy.spatial.transform``
replaced by quatarray's before the test modules import them."""

import os
import sys

import pytest

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


class Swap:
    """A pytest plugin: before scipy's test modules are imported, make the classes
    `names` of ``scipy.spatial.transform`` quatarray's and give their methods scipy's
    array-API capability entries (read by the modules' test marks)."""

    def __init__(self, names):
        self.names = names

    def pytest_configure(self, config):
        import scipy.spatial.transform as T
        from scipy._lib import _array_api

        import quatarray

        table = _array_api.xp_capabilities_table
        for cls in self.names:
            ours, theirs = getattr(quatarray, cls), getattr(T, cls)
            for name in dir(theirs):
                a, b = getattr(theirs, name, None), getattr(ours, name, None)
                try:
                    if a in table and b is not None:
                        table[b] = table[a]
                except TypeError:  # unhashable attributes
                    pass
            setattr(T, cls, ours)


def run(files, names, argv):
    """pytest on scipy's installed test `files` with the classes `names` swapped;
    `argv`: more pytest options. Returns pytest's exit code."""
    import scipy
    import scipy.spatial.transform as T

    root = os.path.dirname(scipy.__file__)
    tests = os.path.join(os.path.dirname(T.__file__), "tests")
    args = [*(os.path.join(tests, f) for f in files), "-q", "-p", "no:cacheprovider", "-n", "0", "--rootdir", root,
            "--confcutdir", root, "-c", os.devnull]
    return pytest.main([*args, *argv], plugins=[Swap(names)])
