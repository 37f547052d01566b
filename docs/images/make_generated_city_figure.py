"""Top-down map of the bundled generated city (``docs/images/generated_city_map.png``).

Buildings coloured by material (red outline: written wound inward; black: textured glTF/OBJ),
street centre lines from ``truth.json`` labelled with name, angle and width, the terrain's slope
start line dashed.  Run from the repository root: ``PYTHONPATH=. python3 docs/images/make_generated_city_figure.py``.
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Polygon  # noqa: E402

from envcap.scene.city_files import TEXTURED_GLTF, TEXTURED_OBJ  # noqa: E402
from envcap.scene.city_layout import MATERIALS, CitySpec, generate_city_layout  # noqa: E402

layout = generate_city_layout(CitySpec())
fig, ax = plt.subplots(figsize=(12, 6.2), dpi=110)
for i, b in enumerate(layout.buildings):
    edge = "black" if i in (TEXTURED_GLTF, TEXTURED_OBJ) else ("red" if b.inward else "0.3")
    ax.add_patch(Polygon(b.footprint, closed=True, facecolor=np.array(MATERIALS[b.material]) ** (1 / 2.2),
                         edgecolor=edge, linewidth=1.6 if edge != "0.3" else 0.4))
for s in layout.streets:
    (x0, z0), (x1, z1) = s.p0, s.p1
    ax.plot([x0, x1], [z0, z1], color="tab:blue", linewidth=1.0)
    ax.annotate(f"{s.name}\n{s.angle_deg:.0f}°, {s.width:g} m", ((x0 + x1) / 2, (z0 + z1) / 2), fontsize=6.5,
                color="tab:blue", ha="center", va="center", bbox=dict(boxstyle="round,pad=0.15", fc="white", alpha=0.7, lw=0))
ax.axvline(layout.spec.slope_start_x, color="0.5", linestyle="--", linewidth=0.8)
ax.text(layout.spec.slope_start_x + 3, layout.bounds[1] + 6, f"terrain rises {layout.spec.slope * 100:.0f} % east of here", fontsize=7, color="0.35")
ax.set_xlim(layout.bounds[0], layout.bounds[2])
ax.set_ylim(layout.bounds[3], layout.bounds[1])  # +Z down: the view from +Y with +X right
ax.set_aspect("equal")
ax.set_xlabel("world x (m)")
ax.set_ylabel("world z (m), +Z down")
ax.set_title(f"generated city: {len(layout.buildings)} buildings, {len(layout.streets)} streets "
             f"(red outline: file wound inward; black: textured glTF / OBJ)", fontsize=9)
fig.tight_layout()
out = Path(__file__).resolve().parent / "generated_city_map.png"
fig.savefig(out)
print(out)
