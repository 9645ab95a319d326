"""Run scipy's own installed RigidTransform tests against ``quatarray.RigidTransform``.

``python benchmarks/run_scipy_rigid_transform_tests.py [--rotation] [pytest options]``
runs ``scipy/spatial/transform/tests/test_rigid_transform.py`` (as installed
with scipy; nothing of it is copied into this project) with
``RigidTransform`` in that module's namespace replaced by quatarray's class
when the test module is imported (``--rotation``: ``Rotation`` too, as a user
who switches both imports), and prints pytest's summary. Failures are
expected where a test reaches into scipy's internals (its array-API backends
and private helpers) or checks float32 promotion (quatarray keeps float32).

Measured on scipy 1.17.1 (numpy backend; 95 tests): 91 pass, with or without
``--rotation``. The 4 others: ``test_pow`` x3 reads scipy's private
``tf._matrix`` (with that attribute patched in, they pass) and
``test_copy_flag`` wants ``copy=False`` to share the caller's 4x4 matrix
(quatarray stores quaternions and translations: see ``from_components_wxyz``).
"""

import os
import sys

import pytest

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


class _Swap:
    """A pytest plugin: before scipy's test module is imported, make the classes
    of ``scipy.spatial.transform`` quatarray's and give their methods scipy's
    array-API capability entries (read by the module's test marks)."""

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


def main(argv):
    import scipy
    import scipy.spatial.transform as T

    names = ["RigidTransform"]
    if "--rotation" in argv:
        argv = [a for a in argv if a != "--rotation"]
        names.append("Rotation")
    root = os.path.dirname(scipy.__file__)
    path = os.path.join(os.path.dirname(T.__file__), "tests", "test_rigid_transform.py")
    args = [path, "-q", "-p", "no:cacheprovider", "-n", "0", "--rootdir", root, "--confcutdir", root, "-c", os.devnull]
    return pytest.main([*args, *argv], plugins=[_Swap(names)])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
