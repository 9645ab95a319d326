"""Drawn at documentation build time (docs/gallery.md)."""
import numpy as np
import matplotlib.pyplot as plt
import quatarray as qa

times = np.array([0.0, 1.0, 2.0, 3.5, 4.0, 5.0])
keys = qa.unflip(qa.from_rotvec([[0, 0, 0], [0.9, 0.2, 0], [1.2, 1.0, 0.3],
                                 [0.2, 1.6, 0.5], [-0.4, 1.2, 0.9], [-0.6, 0.3, 1.4]]))
t = np.linspace(times[0], times[-1], 600)
fig, (ax, bx) = plt.subplots(1, 2, figsize=(9, 3.8))
for method in ["slerp", "squad", "bezier", "cubic"]:
    q = qa.spline(times, keys, t, method=method)
    x = qa.rotate(q, [1.0, 0.0, 0.0])
    ax.plot(x[:, 1], x[:, 2], label=method)
    bx.plot(t, np.linalg.norm(qa.spline(times, keys, t, method=method, order=1), axis=1), label=method)
k = qa.rotate(keys, [1.0, 0.0, 0.0])
ax.plot(k[:, 1], k[:, 2], "ko", ms=4, label="keys")
ax.set_aspect("equal")
ax.set_title("x axis of the body (y, z components)")
ax.legend(fontsize=8)
bx.set_title("angular speed (rad/s)")
bx.set_xlabel("time (s)")
fig.tight_layout()
