"""Drawn at documentation build time (docs/guide/interpolation.md)."""
import numpy as np
import matplotlib.pyplot as plt
import quatarray as qa

times = np.array([0.0, 1.0, 2.0, 3.5, 4.0, 5.0])
keys = qa.unflip(qa.from_rotvec([[0, 0, 0], [0.9, 0.2, 0], [1.2, 1.0, 0.3],
                                 [0.2, 1.6, 0.5], [-0.4, 1.2, 0.9], [-0.6, 0.3, 1.4]]))
t = np.linspace(times[0], times[-1], 600)
fig, ax = plt.subplots()
for method in ["slerp", "squad", "bezier", "cubic"]:
    w = qa.spline(times, keys, t, method=method, order=1)
    ax.plot(t, np.linalg.norm(w, axis=1), label=method)
for k in times:
    ax.axvline(k, color="0.85", lw=0.8, zorder=0)
ax.set_xlabel("time (s)")
ax.set_ylabel("angular speed (rad/s)")
ax.legend()
fig.tight_layout()
