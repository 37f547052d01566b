"""docs/images/architecture.png: envcap's packages in pipeline order and the imports between them,
read from the source (tests/import_graph.py), so the picture cannot drift from the code.

Run: python3 docs/images/make_architecture_figure.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests"))
from import_graph import PIPELINE, import_graph  # noqa: E402

# Row 0: the data path a probe takes; row 1: what it stands on; row 2: the tools around it.
LAYOUT = {
    "scene": (0, 0), "capture": (1, 0), "prefilter": (2, 0), "probeset": (3, 0), "runtime": (4, 0), "dynamic": (5, 0),
    "evaluate": (6, 0), "viewer": (7, 0),
    "sky": (0.5, 1), "formats": (2.5, 1), "outputs": (3.5, 1), "city": (4.5, 1), "placement": (5.5, 1),
    "core": (1.5, 2), "gpu": (3, 2),
    "cli": (6.5, 2), "benchmarks": (6.5, 1), "export": (7.5, 1),
}
# Every stage may use these; their arrows are left out of the picture (counted in the title).
BASE = {"core", "gpu", "outputs"}
TOOLS = {"cli", "benchmarks"}
ROLE = {
    "scene": "TOML streets, meshes", "capture": "HDR cubes + effects", "prefilter": "cos^w lobe chains",
    "probeset": "manifest, bake, store", "runtime": "parallax twin + GLSL", "evaluate": "vs fresh captures",
    "sky": "sky models + sun", "formats": "KTX2, EXR, PNG writers", "outputs": "safe output dirs",
    "core": "cube, lobes, colour, checks", "gpu": "EGL, cube arrays, uniforms", "cli": "envcap COMMAND",
    "benchmarks": "envcap bench NAME", "city": "shards, index, Dask", "dynamic": "spheres, avatars (Eq. 4-7)",
    "viewer": "WebGL2 page", "export": "envcap export TARGET", "placement": "probes where the error is",
}


def main() -> Path:
    g = import_graph(REPO)
    edges = sorted(g.package_edges())
    fig, ax = plt.subplots(figsize=(19, 5.6))
    w, h = 0.86, 0.46
    for pkg in PIPELINE:
        x, y = LAYOUT[pkg]
        y = -1.15 * y
        n = sum(1 for m in g.modules if g.package_of(m) == pkg)
        ax.add_patch(FancyBboxPatch((x - w / 2, y - h / 2), w, h, boxstyle="round,pad=0.02",
                                    fc="#dde8f5" if LAYOUT[pkg][1] == 0 else "#eeeeee", ec="#333333"))
        ax.text(x, y + 0.07, f"{pkg}/", ha="center", va="center", fontsize=11, weight="bold")
        ax.text(x, y - 0.1, f"{ROLE[pkg]}\n{n} modules", ha="center", va="center", fontsize=7.5)
    drawn = [(a, b) for a, b in edges if a in LAYOUT and b in LAYOUT and b not in BASE and a not in TOOLS]
    for a, b in drawn:
        (xa, ya), (xb, yb) = LAYOUT[a], LAYOUT[b]
        same_row = ya == yb
        # Same-row arrows leave and enter through the top edge, bowed upwards (longer ones higher).
        top = 0.23 if same_row else 0.0
        start = (xa, -1.15 * ya + (top if same_row else (-0.23 if yb > ya else 0.23)))
        end = (xb, -1.15 * yb + (top if same_row else (0.23 if yb > ya else -0.23)))
        rad = (-0.25 if xb > xa else 0.25) if same_row else 0.1
        ax.add_patch(FancyArrowPatch(start, end, arrowstyle="-|>", mutation_scale=10, color="#667788", lw=0.8,
                                     shrinkA=2, shrinkB=2, connectionstyle=f"arc3,rad={rad}", zorder=3))
    ax.annotate("", xy=(5.45, 0.9), xytext=(-0.45, 0.9), arrowprops=dict(arrowstyle="-|>", color="#224488", lw=2))
    ax.text(3.5, 0.97, "the pipeline: scene -> capture -> prefilter -> probe set -> runtime -> dynamic -> evaluate -> viewer",
            ha="center", fontsize=10, color="#224488")
    ax.set_xlim(-0.6, 8.0)
    ax.set_ylim(-2.7, 1.05)
    ax.axis("off")
    ax.set_title(f"envcap packages ({len(g.modules)} modules, {len(g.cycles())} import cycles). Grey arrow: "
                 f"'imports from'; drawn {len(drawn)} of {len(edges)} package edges (every package may use "
                 f"core/, gpu/, outputs/; cli/ and benchmarks/ use the stages)", fontsize=10, pad=22)
    out = Path(__file__).with_name("architecture.png")
    fig.savefig(out, dpi=110, bbox_inches="tight")
    return out


if __name__ == "__main__":
    print(main())
