"""A user's script, type-checked by tests/test_typing.py against quatarray's stub."""

import numpy as np

import quatarray as qa

q = qa.random(100, rng=0)
p = qa.multiply(q, qa.from_axis_angle([0, 1, 0], np.pi / 2))
v = qa.rotate(p, [[0.0, 1.0, 1.0]])
angles = qa.as_euler(p, "ZYX", degrees=True)
axis, angle = qa.as_axis_angle(p)
r, rssd = qa.align_vectors(v, v)[:2]
m: np.ndarray = qa.as_matrix(p)
resampled = qa.spline(np.arange(100.0), qa.unflip(q), np.linspace(0, 99, 500), method="squad", order=1)
same = qa.approx_equal(q, q)
t = qa.VQS(np.zeros(3), q[0], 2.0)
print(angles.shape, axis.shape, angle.shape, r.shape, m.shape, resampled.shape, same.all(), t)
