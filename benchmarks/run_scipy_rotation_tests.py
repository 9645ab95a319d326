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

import sys

from _scipy_tests import run


def main(argv):
    files = ["test_rotation.py", "test_rotation_groups.py", "test_rotation_spline.py"]
    return run(files, ["Rotation", "Slerp", "RotationSpline"], argv)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
