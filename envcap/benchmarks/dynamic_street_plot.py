"""The figure of ``envcap bench dynamic_street``: Eq. 3 error against the share of visible sky the
occluders hide, one panel per static part (the probes, or a fresh occluder-free capture), one
colour per variant (helper module: no benchmark of its own)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

VARIANT_COLORS = ("#d62728", "#ff7f0e", "#9467bd", "#2ca02c", "#1f77b4", "#8c564b")


def plot_error_vs_hidden(rows: Sequence[dict[str, Any]], models: Sequence[str], path: Path, occluders: str,
                         title: str, with_sun: bool = True) -> None:
    """Scatter of ``rel_err`` (%) against ``sky_hidden`` (%) for the variants ``static``,
    ``static+MODEL``, ``oracle``, ``oracle+MODEL`` of ``rows``; ``with_sun = False`` leaves out
    the rows with ``sun`` set; ``occluders`` names them on the axis ("spheres", "avatars")."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for ax, src in zip(axes, ("static", "oracle")):
        for j, v in enumerate([src] + [f"{src}+{m}" for m in models]):
            sel = [r for r in rows if r["variant"] == v and (with_sun or not r.get("sun"))]
            if not sel:
                continue
            cov = np.array([r["sky_hidden"] for r in sel]) * 100
            err = np.array([r["rel_err"] for r in sel]) * 100
            ax.scatter(cov, err, s=13, alpha=0.6, color="#444" if j == 0 else VARIANT_COLORS[(j - 1) % len(VARIANT_COLORS)],
                       marker="x" if j == 0 else "o", label=v)
        ax.axvline(10, color="k", ls=":", lw=1)
        ax.set_xlabel(f"visible sky hidden by the {occluders} (%)")
        ax.set_title("probes as the static part" if src == "static"
                     else f"fresh {occluders.rstrip('s')}-free capture as the static part", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    axes[0].set_ylabel("Eq. 3 luminance error, relative RMS over frames (%)")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
