"""Make docs/images/capture_culling.png: which chunks each cube face draws for one canyon probe.

Run from the repository root: ``python3 docs/images/capture_make_culling_figure.py``.
Left: chunk boxes in x-z (top view) near the probe, colored by the number of faces that draw
them (boxes thinner than 1.5 m in z, the facade details, are widened to 1.5 m to show); right: the captured probe (6 x 128^2, culled) as a cube cross.
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Rectangle

from envcap.capture.culling import chunk_face_visibility
from envcap.capture.renderer import CubeCapture
from envcap.gpu.context import create_context
from envcap.formats.png_preview import cross_image
from envcap.scene import load_scene

sc = load_scene("canyon")
sky = sc.sky.build()
ctx = create_context()
p = np.array([10.3, 1.7, 0.4])
with CubeCapture.from_scene(sc, 128, sky=sky, ctx=ctx) as cap:
    got = cap.capture(p)
    ch = cap.chunks
    vis = chunk_face_visibility(ch.lo, ch.hi, p, cap.near, cap.far)
    faces_per_chunk = vis.sum(axis=0)
    tris = [int(ch.count[vis[f]].sum()) for f in range(6)]
fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 4.2), gridspec_kw={"width_ratios": [3, 2]})
cmap = plt.get_cmap("viridis", 7)
for c in np.argsort(-(ch.hi - ch.lo)[:, [0, 2]].max(axis=1)):  # big boxes underneath
    lo, hi = ch.lo[c], ch.hi[c]
    if hi[0] < p[0] - 120 or lo[0] > p[0] + 120:
        continue
    z0, z1 = lo[2], hi[2]
    if z1 - z0 < 1.5:  # facade details are flat in z: widen them so they show
        z0, z1 = 0.5 * (z0 + z1) - 0.75, 0.5 * (z0 + z1) + 0.75
    ax.add_patch(Rectangle((lo[0], z0), hi[0] - lo[0], z1 - z0, fc=cmap(faces_per_chunk[c]), ec="k", lw=0.3))
ax.plot(p[0], p[2], "r*", ms=12, label="probe")
ax.set_xlim(p[0] - 120, p[0] + 120)
ax.set_ylim(-40, 40)
ax.set_aspect("equal")
ax.set_xlabel("x (m)")
ax.set_ylabel("z (m)")
sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(-0.5, 6.5))
fig.colorbar(sm, ax=ax, ticks=range(7), label="faces drawing the chunk", fraction=0.025)
names = ["+X", "-X", "+Y", "-Y", "+Z", "-Z"]
ax.set_title("triangles per face: " + ", ".join(f"{n} {t}" for n, t in zip(names, tris))
             + f"  (all: {sc.mesh.triangle_count})", fontsize=9)
ax.legend(loc="upper right", fontsize=8)
bx.imshow(cross_image(got.rgba))
bx.set_axis_off()
bx.set_title("captured probe (culled), 6 x 128^2", fontsize=9)
fig.tight_layout()
out = Path(__file__).with_name("capture_culling.png")
fig.savefig(out, dpi=100)
print(out)
