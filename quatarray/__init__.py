"""quatarray: fast batched quaternions for large rotation streams.

Quaternions are plain ``(..., 4)`` float arrays in **(w, x, y, z)** order
(scalar first), Hamilton algebra, active rotations in right-handed frames.
Every operation runs in a numba-compiled batched kernel.

Submodules are imported on first use, so ``import quatarray`` stays cheap
and numba is loaded (and kernels compiled or read from the cache) only when
a function is first called.
"""

import importlib

__version__ = "0.1.0"

_MODULES = {
    "algebra": [
        "multiply", "conjugate", "inverse", "norm", "normalize", "dot", "exp", "log",
        "power", "cumprod", "identity", "random", "canonical", "angle", "distance", "mean", "approx_equal",
    ],
    "vectors": ["rotate"],  # not `rotate.py`: importing it would shadow the function
    "conversions": [
        "as_matrix", "from_matrix", "as_rotvec", "from_rotvec", "as_axis_angle", "from_axis_angle",
        "as_mrp", "from_mrp", "as_gibbs", "from_gibbs",
    ],
    "layouts": [
        "as_xyzw", "from_xyzw", "to_scipy", "from_scipy", "as_left_matrix", "as_right_matrix",
        "as_su2", "from_su2",
    ],
    "euler": ["as_euler", "from_euler"],
    "davenport": ["as_davenport", "from_davenport"],
    "symmetry": ["create_group", "reduce"],
    "interpolation": [
        "lerp", "nlerp", "slerp", "double", "bisect", "bezier_controls", "bezier",
        "squad", "unflip", "angular_velocity",
    ],
    "splines": ["spline"],  # not `spline.py`: importing it would shadow the function
    "transforms": ["VQS", "VQM", "interpolate"],
    "align": ["align_vectors", "rotation_between"],
    "kinematics": ["integrate_angular_velocity"],
    "classes.rotation": ["Rotation"],
    "rigid": [
        "pose_compose", "pose_inverse", "pose_apply", "pose_as_matrix", "pose_from_matrix",
        "as_dual_quat", "from_dual_quat", "as_exp_coords", "from_exp_coords",
        "sclerp", "pose_power", "pose_mean", "pose_spline",
    ],
    "classes.rigid_transform": ["RigidTransform"],
    "classes.spline": ["Slerp", "RotationSpline", "BezierSpline"],
    "_warmup": ["warmup"],  # not `warmup.py`: importing it would shadow the function
}
_WHERE = {name: mod for mod, names in _MODULES.items() for name in names}
__all__ = sorted(_WHERE)


def __getattr__(name):
    mod = _WHERE.get(name)
    if mod is None:
        raise AttributeError(f"module 'quatarray' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{mod}", __name__), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
