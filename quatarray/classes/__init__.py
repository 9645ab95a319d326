"""scipy-compatible classes over quatarray's kernels.

``quatarray.Rotation`` (and the spline and rigid-transform classes) follow
the public API of ``scipy.spatial.transform`` 1.17, so a program switches
by its import line. Each object holds one house ``(..., 4)`` (w, x, y, z)
array; ``r.wxyz`` and ``Rotation.from_wxyz(a)`` pass it both ways without a
copy. The submodules are imported on first use (see ``quatarray._MODULES``).
"""
