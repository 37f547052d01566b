"""The top-down map of detected streets (``envcap streets``: ``streets_map.png``).

+X right, +Z down (the view from +Y).  Grey: walls (their plan segments); blue: each street's two
facade lines and its centre line, labelled with name, direction and width; dots: probe positions
every ``spacing`` m along the centre lines; red crosses: intersections (a probe at each centre).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from envcap.scene.street_detect import DetectedStreet, intersections, wall_triangles


def probe_positions(street: DetectedStreet, spacing: float) -> NDArray[np.float64]:
    """Plan positions (K, 2) every ``spacing`` m along the centre line, half a spacing from each end."""
    if not (np.isfinite(spacing) and spacing > 0):
        raise ValueError(f"probe spacing must be a positive number of meters, got {spacing!r}")
    count = max(1, int(street.length // spacing))
    d = (np.arange(count) + 0.5) * street.length / count
    p0, p1 = np.array(street.p0), np.array(street.p1)
    return p0 + d[:, None] * (p1 - p0) / street.length


def save_street_map(triangles: NDArray[np.float64], streets: list[DetectedStreet], path: Path, spacing: float = 10.0) -> None:
    """Write the map PNG of ``streets`` found in ``triangles`` (T, 3, 3) world meters to ``path``."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    walls, _, _ = wall_triangles(triangles)
    plan = walls[:, :, [0, 2]]
    fig, ax = plt.subplots(figsize=(11, 8), dpi=100)
    ends = [seg[np.argsort(seg[:, 0] + 1e-3 * seg[:, 1])][[0, -1]] for seg in plan]   # a wall's plan segment
    ax.add_collection(LineCollection(ends, colors="0.55", linewidths=0.6))
    for s in streets:
        a = np.radians(s.angle_deg)
        n = np.array([-np.sin(a), np.cos(a)])
        p0, p1 = np.array(s.p0), np.array(s.p1)
        for off in s.facade_offsets:
            ax.plot(*np.stack([p0 + off * n, p1 + off * n]).T, color="tab:blue", linewidth=1.2)
        ax.plot(*np.stack([p0, p1]).T, color="tab:blue", linewidth=0.6, linestyle="--")
        probes = probe_positions(s, spacing)
        ax.plot(probes[:, 0], probes[:, 1], ".", color="tab:orange", markersize=3)
        mid = p0 + 0.3 * (p1 - p0)   # not the middle: crossings are often there
        ax.annotate(f"{s.name}\n{s.angle_deg:.1f}°, {s.width:.1f} m", mid, fontsize=7, color="navy", ha="center", va="center",
                    bbox=dict(boxstyle="round,pad=0.15", fc="white", alpha=0.75, lw=0))
    crossings = np.array(intersections(streets)).reshape(-1, 2)
    ax.plot(crossings[:, 0], crossings[:, 1], "x", color="tab:red", markersize=6, linestyle="none")
    lo, hi = plan.reshape(-1, 2).min(axis=0) - 10, plan.reshape(-1, 2).max(axis=0) + 10
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(hi[1], lo[1])
    ax.set_aspect("equal")
    ax.set_xlabel("world x (m)")
    ax.set_ylabel("world z (m), +Z down")
    ax.set_title(f"{len(streets)} streets found (blue: facades and centre line; orange: probes every {spacing:g} m; "
                 "red: intersections)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
