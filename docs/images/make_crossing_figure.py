"""Plan view of the bundled crossing's probes with the crossing probe (``docs/images/crossing_probes.png``).

The 60 m segments of both streets that ``envcap evaluate crossing --bake 60 --crossings`` bakes:
corridors (facades) in grey, the crossing region (where the corridors overlap) shaded, the
uniform probes as dots and the crossing probe at the centre as a star (a probe of east_west, shared
by north_south).  With a report (``report.json`` of that command), the evaluation positions are
drawn too, coloured by the error of ``depth_refine`` at w = 64 (sun out of the sky).  Run from the
repository root: ``PYTHONPATH=. python3 docs/images/make_crossing_figure.py [DIR/report.json]``.
"""

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Polygon  # noqa: E402

from envcap.probeset.bake import _crossing_placements  # noqa: E402
from envcap.probeset.crossings import corridor, detect_crossings  # noqa: E402
from envcap.probeset.placement import place_probes  # noqa: E402
from envcap.scene import load_scene  # noqa: E402
from envcap.scene.segment import street_segment  # noqa: E402

scene = street_segment(load_scene("crossing"), 60.0)
placements = [place_probes(st, 5.0, 2.0) for st in scene.streets]
placements, table = _crossing_placements(scene, placements, 2.0, 5.0, None)
fig, ax = plt.subplots(figsize=(7.5, 7.5), dpi=110)
for st, colour in zip(scene.streets, ("tab:blue", "tab:orange")):
    c = corridor(st)
    lo = np.zeros((4, 2))
    corners = [(c.start, c.fmin), (c.end, c.fmin), (c.end, c.fmax), (c.start, c.fmax)]
    for k, (a, x) in enumerate(corners):
        lo[k] = (a, x) if c.along == 0 else (x, a)
    ax.add_patch(Polygon(lo, closed=True, facecolor=colour, alpha=0.08, edgecolor="0.4", linewidth=0.8))
    p = np.array([q.position for q in placements[scene.streets.index(st)]])
    ax.plot(p[:, 0], p[:, 2], "o", color=colour, markersize=5, label=f"{st.name} probes ({len(p)})")
for m, si, pi in table:
    a, b = (corridor(scene.streets[i]) for i in m.streets[:2])
    region = np.array([[max(b.fmin, a.start), max(a.fmin, b.start)], [min(b.fmax, a.end), max(a.fmin, b.start)],
                       [min(b.fmax, a.end), min(a.fmax, b.end)], [max(b.fmin, a.start), min(a.fmax, b.end)]])
    ax.add_patch(Polygon(region, closed=True, facecolor="tab:green", alpha=0.25, edgecolor="tab:green",
                         label="crossing region"))
    ax.plot(*m.centre, "*", color="black", markersize=16, label="crossing probe (shared)")
if len(sys.argv) > 1:
    rep = json.loads(Path(sys.argv[1]).read_text())
    rows = [r for r in rep["positions"] if r["method"] == "depth_refine" and r["lobe_power"] == 64.0 and not r["sun"]]
    xs = np.array([r["position"] for r in rows])
    sc = ax.scatter(xs[:, 0], xs[:, 2], c=[r["rel_rmse"] for r in rows], cmap="magma_r", marker="x", s=40,
                    label="evaluation positions")
    fig.colorbar(sc, ax=ax, shrink=0.6, label="depth_refine relative RMSE, w = 64")
assert detect_crossings(scene.streets)
ax.set_xlim(-32, 32)
ax.set_ylim(32, -32)   # +Z down: the view from +Y with +X right
ax.set_aspect("equal")
ax.set_xlabel("world x (m)")
ax.set_ylabel("world z (m), +Z down")
ax.legend(loc="lower left", fontsize=7)
ax.set_title("crossing (60 m of each street): probes every 5 m and the crossing probe", fontsize=9)
fig.tight_layout()
fig.savefig(Path(__file__).with_name("crossing_probes.png"))
