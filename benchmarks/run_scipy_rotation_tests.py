"""Run scipy's own installed Rotation tests against ``quatarray.Rotation``.

``python benchmarks/run_scipy_rotation_tests.py [pytest options]`` runs
``scipy/spatial/transform/tests/test_rotation.py`` (as installed with scipy;
nothing of it is copied into this project) with ``Rotation`` in that module's
namespace replaced by quatarray's class when the test module is imported, and
prints pytest's summary. Failures are expected where a test reaches into
scipy's internals (its Cython and array-API backends, ``Rotation._quat``), uses
other array libraries, or needs ``Slerp`` while quatarray has none (scipy's own
only accepts scipy's ``Rotation``). Measured on scipy 1.17.1 without quatarray's
Slerp: 289 of 302 pass; the 13 others are the backend-selection test and the
12 Slerp tests.
"""

import os
import sys

import pytest

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


class _Swap:
    """A pytest plugin: before scipy's test module is imported, make
    ``scipy.spatial.transform.Rotation`` quatarray's class and give its methods
    scipy's array-API capability entries (read by the module's test marks)."""

    def pytest_configure(self, config):
        import scipy.spatial.transform as T
        from scipy._lib import _array_api

        import quatarray

        ours, theirs = quatarray.Rotation, T.Rotation
        table = _array_api.xp_capabilities_table
        for name in dir(theirs):
            a, b = getattr(theirs, name, None), getattr(ours, name, None)
            try:
                if a in table and b is not None:
                    table[b] = table[a]
            except TypeError:  # unhashable attributes
                pass
        T.Rotation = ours
        try:  # quatarray's Slerp, where that branch is merged (scipy's accepts only its own Rotation)
            T.Slerp = quatarray.Slerp
        except AttributeError:
            pass


def main(argv):
    import scipy.spatial.transform as T

    import scipy

    root = os.path.dirname(scipy.__file__)
    path = os.path.join(os.path.dirname(T.__file__), "tests", "test_rotation.py")
    args = [path, "-q", "-p", "no:cacheprovider", "-n", "0", "--rootdir", root, "--confcutdir", root, "-c", os.devnull]
    return pytest.main([*args, *argv], plugins=[_Swap()])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
