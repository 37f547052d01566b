"""``min_error``: the placement with the least evaluated error on the street's own training points.

Candidates every ``step_m`` m along the street (at least two per asked probe, at most
:data:`envcap.placement.candidates.MAX_CANDIDATES` in all), plus the uniform
placement of every asked count (so that uniform is always one of the choices), are baked at
``resolution``^2 (:func:`envcap.placement.candidates.bake_candidates`).  Training points are drawn
like the evaluator's default sweep over the whole street (jittered strata along it, lateral within
the facades less 1 m, 0.3-3 m above the ground) but with their own ``seed`` (101; the evaluator's
is 5, so a bench never scores a placement on the points it was chosen on), ``points_per_m`` per
meter of street (at least ``min_points``).  One evaluator pass measures ``E[k, j]``, the error of
``method`` at point ``j`` reading only candidate ``k`` (mean over ``powers``; a candidate farther
than ``reach`` mean spacings ``length / count`` from a point never serves it, and is not evaluated
there beyond the reach of the smallest count), and the exact dynamic programme of
:func:`envcap.placement.partition.best_subset` picks the ``count`` candidates whose nearest-probe
service of the training points has the least mean error (docs/placement.md).  Its training error
is never above uniform's (uniform is a candidate subset).

Needs: a GL context (captures).  Parameters: ``method`` (``"depth_refine"``, any registered
parallax method), ``powers`` (``(64.0, 256.0)``), ``step_m`` (1.5), ``resolution`` (64, at most
the bake's), ``points_per_m`` (0.5), ``min_points`` (16), ``seed`` (101), ``reach`` (3.0 mean
spacings).  Notes per street: ``training_error``, ``uniform_training_error``,
``floor_training_error`` (each training point served by its best candidate: no placement on the
candidates does better, whatever its count), ``candidates``, ``training_points``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from envcap.evaluate.sweep import Sweep, sample_positions
from envcap.placement.candidates import (bake_candidates, candidate_grid, error_matrix, grid_cells, note_cost,
                                         notes_number, pass_seconds, point_along)
from envcap.placement.partition import best_subset, served_error
from envcap.placement.registry import PlacementContext, PlacementStrategy, StreetPlacement
from envcap.probeset.placement import uniform_along
from envcap.scene.model import Street

MAX_POINTS = 512
"""Most training points of one street."""


def place(context: PlacementContext, street: Street, counts: Sequence[int], method: str = "depth_refine",
          powers: Sequence[float] = (64.0, 256.0), step_m: float = 1.5, resolution: int = 64,
          points_per_m: float = 0.5, min_points: int = 16, seed: int = 101, reach: float = 3.0) -> list[StreetPlacement]:
    """The least-error placement of each of ``counts`` probes on ``street`` (module docstring)."""
    length = street.length
    uniforms = {n: np.round(uniform_along(street, n), 9) for n in counts}
    cells = grid_cells(street, float(step_m), counts, sum(counts), "min_error")
    s = candidate_grid(street, cells, np.concatenate(list(uniforms.values())))
    n_points = min(MAX_POINTS, max(int(min_points), math.ceil(points_per_m * length)))
    pairs = int(sum(min(s.size, 2 * reach * s.size / min(counts) + 1) for _ in range(n_points)))
    note_cost(context, street, "min_error", pass_seconds(s.size, n_points, pairs, len(powers)))
    res = min(int(resolution), int(context.resolution))
    cand = bake_candidates(context, street, s, res, "min_error")
    points = sample_positions(cand.manifest, Sweep(per_street=n_points, seed=seed))
    errors = error_matrix(context, cand, points, method, powers, res, reach=reach * length / min(counts) + 1e-9)
    xs = point_along(street, points)
    floor = notes_number(np.mean(np.min(errors, axis=0)))   # every point served by its best candidate
    out = []
    for n in counts:
        served = np.abs(xs[None, :] - s[:, None]) <= reach * length / n    # no probe serves a point farther
        chosen, err = best_subset(s, xs, np.where(served, errors, np.inf), n)
        uniform = np.searchsorted(s, uniforms[n])
        notes = {"training_error": notes_number(err), "uniform_training_error": notes_number(served_error(uniform, s, xs, errors)),
                 "floor_training_error": floor, "candidates": int(s.size), "training_points": len(points)}
        out.append(StreetPlacement(s[chosen], notes))
    return out


STRATEGY = PlacementStrategy(
    "min_error", place, "least evaluated error on training points (candidates baked, one evaluator pass, exact DP)",
    parameters={"method": "depth_refine", "powers": (64.0, 256.0), "step_m": 1.5, "resolution": 64, "points_per_m": 0.5,
                "min_points": 16, "seed": 101, "reach": 3.0},
    needs_gl=True)
