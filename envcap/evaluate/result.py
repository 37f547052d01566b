"""What an evaluation returns: :class:`EvaluationResult`, the per-position rows aggregated by
:func:`summarize`, and how lobe powers are keyed and labelled in rows and reports.

Lobe powers: ``inf`` (the mirror) is keyed ``None`` in rows and JSON, labelled ``"mirror"``;
a power ``w`` is keyed ``float(w)`` and labelled ``"w=<w>"``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from envcap.evaluate.sweep import EvalPosition


def lobe_power_key(w: float | None) -> float | None:
    """The row key of lobe power ``w``: ``None`` for the mirror (``inf`` or ``None``), else ``float(w)``."""
    return None if w is None or (isinstance(w, float) and math.isinf(w)) else float(w)


def lobe_power_label(w: float | None) -> str:
    """``"mirror"`` for the mirror, else ``"w=<w>"`` (``%g``)."""
    return "mirror" if lobe_power_key(w) is None else f"w={w:g}"


def summarize(scene: str, rows: Sequence[Mapping[str, Any]],
              by: Sequence[str] = ("method", "lobe_power", "sun")) -> list[dict[str, Any]]:
    """Aggregate per-position rows into ``{scene, <by...>, rel_rmse (mean), median, p90, max, n_positions}``."""
    groups: dict[tuple, list[float]] = {}
    for r in rows:
        groups.setdefault(tuple(r.get(k) for k in by), []).append(float(r["rel_rmse"]))
    out = []
    for k, v in groups.items():
        a = np.array(v)
        out.append({"scene": scene, **dict(zip(by, k)), "rel_rmse": float(a.mean()), "median": float(np.median(a)),
                    "p90": float(np.percentile(a, 90)), "max": float(a.max()), "n_positions": int(a.size)})
    return out


@dataclass
class EvaluationResult:
    """Outcome of :func:`envcap.evaluate.run.evaluate_scene`.

    ``rows``: one dict per (position, method, lobe power, sun variant): ``scene, street,
    position_index, method, lobe_power`` (``None`` = mirror), ``sun``, ``rel_rmse``, offsets,
    ``plane_misfit``.  ``summary``: one dict per (method, lobe power, sun variant):
    ``rel_rmse`` (mean over positions), ``median``, ``p90``, ``max``, ``n_positions``.
    ``shading``: one dict per (position, method, sun variant, material): ``rel_err`` of Eq. 3
    luminance.  ``timings``: seconds (setup, captures, filtering, predictions, shading, total).
    ``floor``: the summary at the probes' own positions (evaluator and filter floor).  ``meta``:
    resolution, sweep, probe set facts.  ``strips``: truth and predictions of the worst positions.
    """

    scene: str
    positions: list[EvalPosition]
    rows: list[dict[str, Any]]
    summary: list[dict[str, Any]]
    shading: list[dict[str, Any]]
    timings: dict[str, float]
    meta: dict[str, Any]
    floor: list[dict[str, Any]] = field(default_factory=list)
    strips: dict[str, Any] = field(default_factory=dict)

    def error(self, method: str, lobe_power: float | None, stat: str = "rel_rmse", sun: bool = True) -> float:
        """Summary statistic of ``method`` at ``lobe_power`` (``None``/``inf`` = mirror) with or
        without the sun in the sky; NaN if absent."""
        lp = lobe_power_key(lobe_power)
        for r in self.summary:
            if r["method"] == method and r["lobe_power"] == lp and r.get("sun", True) == sun:
                return float(r[stat])
        return float("nan")
