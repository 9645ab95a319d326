"""Drawn at documentation build time (docs/gallery.md)."""
import numpy as np
import matplotlib.pyplot as plt
import quatarray as qa
from quatarray import trajectory as tj

rng = np.random.default_rng(3)
t = np.linspace(0.0, 60.0, 1201)
pos = np.stack([5 * np.cos(t / 8), 5 * np.sin(t / 8), 0.05 * t], axis=1)
q = qa.from_euler("z", (t / 8 + np.pi / 2)[:, None])
ref = tj.poses(t, pos, q)
drift = np.cumsum(rng.normal(0, 0.01, (t.size, 3)), axis=0)
est_pos = 1.3 * (pos + drift) + [2.0, -1.0, 0.5]
est_q = qa.multiply(q, qa.from_rotvec(rng.normal(0, 0.01, (t.size, 3))))
est = tj.poses(t, est_pos, est_q)
res = tj.evaluate(ref, est, metric="ape", align="sim3", relation="trans")
fig, ax = plt.subplots()
ax.plot(res.t, res.errors, lw=0.8, label="APE (m)")
ax.axhline(res.stats["rmse"], color="C3", ls="--", label=f"rmse {res.stats['rmse']:.3f} m")
ax.set_xlabel("time (s)")
ax.set_ylabel("translation error (m)")
ax.legend()
fig.tight_layout()
