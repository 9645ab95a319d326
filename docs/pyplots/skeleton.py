"""Drawn at documentation build time (docs/gallery.md)."""
import numpy as np
import matplotlib.pyplot as plt
from quatarray import io
from quatarray.io import sample_path

clip = io.read_bvh(sample_path())
_, p = clip.world()
names = ["LeftAnkle", "RightAnkle", "LeftWrist", "RightWrist"]
fig, (ax, bx) = plt.subplots(1, 2, figsize=(9, 3.8))
for n in names:
    j = clip.joints.index(n)
    ax.plot(p[:, j, 0], p[:, j, 2], lw=0.9, label=n)
    bx.plot(clip.times, p[:, j, 1], lw=0.9, label=n)
ax.set_aspect("equal")
ax.set_title("from above (x, z)")
ax.legend(fontsize=7)
bx.set_title("height over time")
bx.set_xlabel("time (s)")
fig.tight_layout()
