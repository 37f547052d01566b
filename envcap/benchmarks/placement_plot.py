"""The figures of ``envcap bench placement`` (helper module: no benchmark of its own).

* :func:`pareto_figure`: mean error of one method against the probes per street, one panel per
  scene and one for the mean over scenes, one colour per strategy (solid: the first lobe power,
  dashed: the last); the legend gives each strategy's placing time.
* :func:`street_figure`: one street in plan (its facades, the other streets' roadways that cross
  it) with the probes each strategy placed on it, the error at each evaluation position along it
  and the error rate ``density`` measured.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

COLORS = {"uniform": "#7f7f7f", "density": "#1f77b4", "min_error": "#d62728"}
OTHER_COLORS = ("#2ca02c", "#9467bd", "#8c564b", "#ff7f0e")


def _color(strategy: str, order: Sequence[str]) -> str:
    return COLORS.get(strategy) or OTHER_COLORS[list(order).index(strategy) % len(OTHER_COLORS)]


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def pareto_figure(rows: Sequence[dict[str, Any]], path: Path, method: str, scenes: dict[str, Any]) -> None:
    """Error of ``method`` vs probes per street (module docstring) from the bench's ``rows``."""
    plt = _pyplot()
    names = list(dict.fromkeys(r["scene"] for r in rows))
    strategies = list(dict.fromkeys(r["strategy"] for r in rows))
    powers = list(dict.fromkeys(r["power"] for r in rows))
    counts = sorted({r["count"] for r in rows})
    panels = names + (["mean over scenes"] if len(names) > 1 else [])
    fig, axes = plt.subplots(1, len(panels), figsize=(3.6 * len(panels), 3.6), squeeze=False)
    for ax, panel in zip(axes[0], panels):
        for s in strategies:
            for w, style in zip(powers, ("-", "--", ":", "-.")):
                sel = [r for r in rows if r["strategy"] == s and r["power"] == w and r["method"] == method
                       and (r["scene"] == panel or panel not in names)]
                err = [np.mean([r["error"] for r in sel if r["count"] == n]) for n in counts]
                cost = "" if panel not in names else f", {scenes[panel]['placed'][s]['seconds']:.0f} s"
                ax.plot(counts, err, style, marker="o", color=_color(s, strategies),
                        label=f"{s} w={w:g}{cost}" if style == "-" or panel not in names else None)
        ax.set_xscale("log", base=2)
        ax.set_xticks(counts, [str(n) for n in counts])
        ax.set_xlabel("probes per street")
        ax.set_title(panel, fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6)
    axes[0][0].set_ylabel(f"mean rel. RMSE ({method}, sun out of the sky)")
    fig.suptitle("error vs probe count\n(solid: first power, dashed: last)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def street_figure(figure: dict[str, Any], path: Path, method: str, power: float) -> None:
    """One street's probes as each strategy placed them (module docstring).  ``figure``: the
    bench's ``{"scene": Scene, "street": name, "placed": {strategy: {"along": {count: {street:
    [...]}}, "notes": ...}}, "errors": {(count, strategy): [(world position, error), ...]}}``."""
    scene = figure["scene"]
    street = next((st for st in scene.streets if st.name == figure["street"]), None)
    if street is None or not figure["errors"]:
        return
    plt = _pyplot()
    counts = sorted({n for n, _ in figure["errors"]})
    n = counts[len(counts) // 2]
    strategies = [s for s in figure["placed"] if (n, s) in figure["errors"]]
    fig, axes = plt.subplots(3, 1, figsize=(9, 7.5), sharex=True, gridspec_kw={"height_ratios": [1.3, 1.2, 0.9]})
    ax = axes[0]
    for other in scene.streets:          # the other streets' roadways, in this street's frame
        if other.name == street.name:
            continue
        xz = other.plan_corners()
        f = street.to_frame(np.c_[xz[:, 0], np.zeros(4), xz[:, 1]])
        ax.fill(f[:, street.along_index], f[:, street.cross_index], color="#dddddd", zorder=0)
    for y in (street.facade_min, street.facade_max):
        ax.plot([street.start, street.end], [y, y], color="k", lw=2)
    rows = np.linspace(street.facade_min, street.facade_max, len(strategies) + 2)[1:-1]
    for s, y in zip(strategies, rows):
        a = np.asarray(figure["placed"][s]["along"][n][street.name])
        ax.plot(a, np.full(a.size, y), "o", color=_color(s, strategies), ms=7, label=s)
    ax.set_ylabel("across (m)")
    ax.set_title(f"{scene.name}: street '{street.name}', {n} probes placed by each strategy "
                 f"(grey: the crossing streets; black: the facades)", fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    ax = axes[1]
    for s in strategies:
        pts = figure["errors"][(n, s)]
        if pts:
            x = street.to_frame(np.array([p for p, _ in pts]))[:, street.along_index]
            e = np.array([v for _, v in pts])
            order = np.argsort(x)
            ax.plot(x[order], e[order], "o-", color=_color(s, strategies), ms=3, lw=0.8,
                    label=f"{s}: mean {e.mean():.4f}")
    ax.set_ylabel(f"rel. RMSE ({method}, w={power:g})")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    ax = axes[2]
    notes = figure["placed"].get("density", {}).get("notes", {}).get(n, {}).get(street.name, {})
    rate = notes.get("rate_per_m")
    if rate:
        step = float(notes["step_m"])
        ax.step(street.start + (np.arange(len(rate)) + 0.5) * step, [0.0 if v is None else v for v in rate],
                where="mid", color=_color("density", strategies))
    ax.set_ylabel("error rate g (1/m)")
    ax.set_xlabel("along the street (m)")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
