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

import sys

from _scipy_tests import run


def main(argv):
    names = ["RigidTransform"]
    if "--rotation" in argv:
        argv = [a for a in argv if a != "--rotation"]
        names.append("Rotation")
    return run(["test_rigid_transform.py"], names, argv)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
