"""Run scipy's own installed Rotation, Slerp and RotationSpline tests against quatarray's classes.

``python benchmarks/run_scipy_rotation_tests.py [pytest options]`` runs
``scipy/spatial/transform/tests/test_rotation.py``, ``test_rotation_groups.py`` and
``test_rotation_spline.py`` (as installed with scipy; nothing of them is copied into
this project) with ``Rotation``, ``Slerp`` and ``RotationSpline`` replaced by
quatarray's classes before the test modules import them, and prints pytest's
summary. Failures are expected where a test reaches into scipy's internals (its
Cython and array-API backends), uses other array libraries, or asks for bitwise
equality. Measured on scipy 1.17.1 with quatarray's three classes: 539 of 541 pass;
the 2 others are the backend-selection test and ``test_slerp_call_scalar_time``,
which asks a slerp and a ``from_euler`` to agree within 1e-16 (quatarray's differ
by one ulp, 2.2e-16).
"""

import os
import sys

import pytest

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


class _Swap:
    """A pytest plugin: before scipy's test modules are imported, make
    ``scipy.spatial.transform.Rotation`` (``Slerp``, ``RotationSpline``) quatarray's
    class and give its methods scipy's array-API capability entries (read by the
    modules' test marks)."""

    def pytest_configure(self, config):
        import scipy.spatial.transform as T
        from scipy._lib import _array_api

        import quatarray

        table = _array_api.xp_capabilities_table
        for cls in ("Rotation", "Slerp", "RotationSpline"):
            ours, theirs = getattr(quatarray, cls, None), getattr(T, cls)
            if ours is None:  # a class not merged yet
                continue
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

    root = os.path.dirname(scipy.__file__)
    tests = os.path.join(os.path.dirname(T.__file__), "tests")
    paths = [os.path.join(tests, f) for f in ("test_rotation.py", "test_rotation_groups.py", "test_rotation_spline.py")]
    args = [*paths, "-q", "-p", "no:cacheprovider", "-n", "0", "--rootdir", root, "--confcutdir", root, "-c", os.devnull]
    return pytest.main([*args, *argv], plugins=[_Swap()])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
