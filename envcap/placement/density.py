"""``density``: probes spread as the square root of a measured error rate along the street.

The cheap error-driven strategy of docs/placement.md.  Candidates every ``step_m`` m on the probe
line (at least two per asked probe, at most :data:`envcap.placement.candidates.MAX_CANDIDATES`) are baked at ``resolution``^2 and each is evaluated at its neighbours' positions only (one
evaluator pass, :func:`envcap.placement.candidates.error_matrix`, with the points on the probe
line: no training points off it).  The error rate between candidates ``k`` and ``k + m``, ``m``
candidates apart (``m step`` ~ a quarter of the mean spacing of the asked count, the mean distance
from a shading point to its probe under uniform placement), is

    g = max(0, (E[k, k+m] + E[k+m, k] - E[k, k] - E[k+m, k+m]) / 2) / (m step)    (per meter)

at their midpoint: the error a probe adds per meter a lookup moves away from it, less the
evaluator's floor at the probe itself.  With the error of a lookup modelled as a floor plus
``g(s) |s - p|``, the mean error is smallest when the probe density is proportional to
``sqrt(g)`` (docs/placement.md, the derivation); the probes stand at the quantiles ``(i + 1/2) / N``
of the density ``(g + floor * mean(g)) ^ exponent`` (:func:`envcap.placement.partition.density_positions`;
a constant rate gives the uniform placement exactly).

Needs: a GL context (captures).  Parameters: ``method`` (``"depth_refine"``), ``powers``
(``(64.0, 256.0)``), ``step_m`` (1.0), ``resolution`` (32, at most the bake's), ``exponent``
(0.5), ``floor`` (0.1: the least density, as a fraction of the mean rate).  Notes per street:
``rate_per_m`` (g on the candidate cells), ``step_m``, ``offset_m`` (``m step``),
``predicted_ratio`` (the model's error of this placement over uniform's, reducible part only:
``(sum sqrt g)^2 / (K sum g)`` for exponent 1/2).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from envcap.evaluate.sweep import positions_from_array
from envcap.placement.candidates import (bake_candidates, candidate_grid, error_matrix, grid_cells, note_cost,
                                         notes_number, pass_seconds)
from envcap.placement.partition import density_positions
from envcap.placement.registry import PlacementContext, PlacementStrategy, StreetPlacement
from envcap.probeset.placement import uniform_along
from envcap.scene.model import Street


def error_rate(errors: np.ndarray, s: np.ndarray, offset: int) -> np.ndarray:
    """The error rate ``g`` (per meter, >= 0) on the candidates' cells from ``errors[k, k']``
    (candidate ``k`` evaluated at candidate ``k'``'s position, ``s`` (K,) their coordinates):
    the symmetric rate of each pair ``offset`` apart at its midpoint (module docstring),
    interpolated linearly to the cell centres ``s`` (constant beyond the outermost midpoints)."""
    k = s.size - offset
    if k < 1:
        return np.zeros(s.size)
    i = np.arange(k)
    cross = 0.5 * (errors[i, i + offset] + errors[i + offset, i])
    own = 0.5 * (errors[i, i] + errors[i + offset, i + offset])
    rate = np.maximum(cross - own, 0.0) / (s[i + offset] - s[i])
    return np.interp(s, 0.5 * (s[i] + s[i + offset]), rate)


def place(context: PlacementContext, street: Street, counts: Sequence[int], method: str = "depth_refine",
          powers: Sequence[float] = (64.0, 256.0), step_m: float = 1.0, resolution: int = 32,
          exponent: float = 0.5, floor: float = 0.1) -> list[StreetPlacement]:
    """Probes at the quantiles of ``g^exponent`` for each of ``counts`` (module docstring)."""
    length = street.length
    s = candidate_grid(street, grid_cells(street, float(step_m), counts, 0, "density"))
    cell = length / s.size
    offsets = {n: max(1, int(round(length / (4 * n * cell)))) for n in counts}
    reach = (max(offsets.values()) + 0.5) * cell
    note_cost(context, street, "density", pass_seconds(s.size, s.size, s.size * (2 * max(offsets.values()) + 1), len(powers)))
    res = min(int(resolution), int(context.resolution))
    cand = bake_candidates(context, street, s, res, "density")
    at_candidates = positions_from_array(cand.manifest, [p.position for p in cand.manifest.streets[0].probes])
    errors = error_matrix(context, cand, at_candidates, method, powers, res, reach=reach)
    edges = street.start + np.arange(s.size + 1) * cell
    out = []
    for n in counts:
        g = error_rate(errors, s, offsets[n])
        notes = {"rate_per_m": [notes_number(v) for v in g], "step_m": notes_number(cell),
                 "offset_m": notes_number(offsets[n] * cell), "candidates": int(s.size)}
        if not g.sum() > 0:      # nothing measured (one candidate, or no error anywhere): uniform
            out.append(StreetPlacement(uniform_along(street, n), {**notes, "predicted_ratio": 1.0}))
            continue
        rho = (g + float(floor) * g.mean()) ** float(exponent)
        notes["predicted_ratio"] = notes_number(float(np.sqrt(g).sum()) ** 2 / (s.size * float(g.sum())))
        out.append(StreetPlacement(density_positions(edges, rho, n), notes))
    return out


STRATEGY = PlacementStrategy(
    "density", place, "probe density ~ sqrt(measured error rate) (candidates on the probe line, one evaluator pass)",
    parameters={"method": "depth_refine", "powers": (64.0, 256.0), "step_m": 1.0, "resolution": 32, "exponent": 0.5,
                "floor": 0.1},
    needs_gl=True)
