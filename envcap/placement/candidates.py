"""Candidate probes and the evaluator's error of each: what the error-driven strategies measure.

A strategy that asks the evaluator (``density``, ``min_error``) bakes a probe at every candidate
position of a street at a low resolution (:func:`bake_candidates`: the street alone, the same
capture and filter as ``envcap capture``), then runs one evaluator pass (:func:`error_matrix`):
at each evaluation point a fresh capture (:class:`envcap.evaluate.truth.TruthRenderer`, filtered
at exactly each lobe power ``w``, sun out of the sky: the evaluator's primary variant,
docs/evaluation.md) against the prediction of a parallax method reading *one* candidate probe,
for every candidate within reach.  The result ``E[k, j]`` is the mean over the powers of the
solid-angle weighted relative RMSE of luminance (:func:`envcap.evaluate.metrics.relative_rmse`):
what a lookup at point ``j`` costs when candidate ``k`` is the probe the runtime picks.

Conventions: meters; along-street coordinates in the street's frame; points as
:class:`envcap.evaluate.sweep.EvalPosition` (world positions).
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core.street_frame import world_to_frame
from envcap.evaluate.metrics import relative_rmse
from envcap.evaluate.predict import Predictor
from envcap.evaluate.run import PositionEvaluator, check_settings
from envcap.evaluate.sweep import EvalPosition
from envcap.evaluate.truth import TruthRenderer
from envcap.placement.registry import PlacementContext
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.placement_table import PlacementTable
from envcap.probeset.probe_set import ProbeSet
from envcap.runtime import methods
from envcap.runtime.sampling import composite
from envcap.runtime.street import StreetProbes
from envcap.scene.model import Street

MAX_CANDIDATES = 512
"""Most candidate probes of one street (each is a pre-capture and a row of evaluator passes).  A
long street gets candidates farther apart than a strategy's ``step_m``."""

PREDICTION_S = 0.006
"""Seconds of one prediction (one candidate, one point, one lobe power, ``depth_refine``, 64^2
truth) on this machine's llvmpipe-era CPU (2 cores): the unit of :func:`pass_seconds`."""

NOTE_SECONDS = 60.0
"""A placement estimated to take longer than this (s) says so first."""

CAPTURE_S = 0.25
"""Seconds per candidate or evaluation point of capture, filter and truth filtering at 64^2."""


def grid_cells(street: Street, step: float, counts: Sequence[int], extra: int, strategy: str) -> int:
    """How many equal cells the candidate grid of ``street`` has: one per ``step`` m, at least two
    per probe of the largest of ``counts``, at most :data:`MAX_CANDIDATES` less ``extra`` (the
    candidates a strategy adds beside the grid; ``ValueError`` naming the street when even two per
    probe do not fit)."""
    least, most = 2 * max(counts), MAX_CANDIDATES - int(extra)
    if least > most:
        raise ValueError(f"placement {strategy}: {max(counts)} probes on street '{street.name}' need at least {least + extra} "
                         f"candidate probes, more than the limit of {MAX_CANDIDATES}; ask for fewer probes per street "
                         "or use --placement uniform")
    return int(np.clip(round(street.length / step), least, most))


def candidate_grid(street: Street, cells: int, extra: ArrayLike = ()) -> NDArray[np.float64]:
    """Candidate coordinates (m, ascending, distinct): the centres of ``cells`` equal cells of the
    street, and the coordinates ``extra`` (e.g. the uniform placements the strategy must be able
    to choose), rounded to 1 nm."""
    grid = street.start + (np.arange(cells) + 0.5) * street.length / cells
    both = np.concatenate([grid, np.asarray(extra, np.float64).reshape(-1)])
    return np.unique(np.round(both, 9))


def note_cost(context: PlacementContext, street: Street, strategy: str, seconds: float) -> None:
    """Say on stderr what a long placement will cost (over :data:`NOTE_SECONDS`, when
    ``context.verbose``): the street, its length and the estimate."""
    if context.verbose and seconds > NOTE_SECONDS:
        print(f"envcap: note: placement {strategy}: street '{street.name}' ({street.length:g} m): roughly "
              f"{seconds / 60:.0f} min of pre-captures and evaluator passes at llvmpipe rates", file=sys.stderr, flush=True)


def pass_seconds(candidates: int, points: int, pairs: int, powers: int) -> float:
    """Rough wall time (s) of :func:`bake_candidates` + :func:`error_matrix` on this machine:
    captures of candidates and points, and ``pairs`` predictions at each of ``powers``."""
    return CAPTURE_S * (candidates + points) + PREDICTION_S * pairs * powers


def bake_candidates(context: PlacementContext, street: Street, along: ArrayLike, resolution: int,
                    strategy: str) -> ProbeSet:
    """The street alone with a probe at every coordinate of ``along`` (m), ``resolution``^2
    faces, filtered like ``envcap capture`` (``quality="composed"``); its manifest says it was
    placed by ``strategy`` (so that evaluation points sweep the whole street)."""
    one = dataclasses.replace(context.scene, streets=[street])
    return bake_probe_set(one, resolution=resolution, height=context.height, quality="composed", ctx=context.gl,
                          along={street.name: along}, placement=PlacementTable(f"{strategy}_candidates"),
                          progress=False)


def error_matrix(context: PlacementContext, candidates: ProbeSet, points: Sequence[EvalPosition], method: str,
                 powers: Sequence[float], resolution: int, reach: float = math.inf) -> NDArray[np.float64]:
    """``E`` ``(K, J)``: the error at point ``j`` of ``method`` reading only candidate ``k``
    (module docstring), mean over ``powers``; ``inf`` where the candidate is more than ``reach``
    m along the street from the point (not evaluated).  Truth captures of ``resolution``^2,
    filtered as :func:`envcap.evaluate.run.evaluate_scene` filters them: where candidate ``k`` is
    the one the runtime picks at point ``j``, ``E[k, j]`` is the evaluator's own error there."""
    scene = dataclasses.replace(context.scene, streets=[s for s in context.scene.streets
                                                        if s.name == candidates.manifest.streets[0].name])
    settings = check_settings(scene, candidates, [method], powers, (False,), resolution)
    meth = methods.get(method)
    truth = TruthRenderer(scene, settings.resolution, context.gl, quality=settings.quality)   # the evaluator's
    try:
        pred = Predictor(candidates, sky=truth.sky, ctx=context.gl, quality=settings.quality)
        ev = PositionEvaluator(settings, truth, pred)
        probes = pred.streets[candidates.manifest.streets[0].name]
        s = probes.positions[:, probes.along]
        out = np.full((s.size, len(points)), np.inf)
        for j, ep in enumerate(points):
            x = np.asarray(ep.position, np.float64)
            xs = float(world_to_frame(x, probes.yaw_deg, probes.origin_xz)[probes.along])
            near = np.flatnonzero(np.abs(s - xs) <= reach)
            if near.size == 0:
                continue
            at = ev.truth_at(ep)
            total = np.zeros(near.size)
            for w, part in at.parts.items():
                m = part["street"].shape[1]
                truth_rgb = composite(part["street"], part["sky_nosun"])
                d = ev.directions(m, ep.yaw_deg)
                sky = ev.predicted_sky(m, w, False, ep.yaw_deg).reshape(6, m, m, -1)
                ww = np.full(d.shape[0], w)
                for i, k in enumerate(near):
                    street = probes.runtime_street(meth.planes, [k])
                    rgba = meth(pred.chains, street, x, d, ww).reshape(6, m, m, 4)
                    total[i] += relative_rmse(composite(rgba, sky), truth_rgb)
            out[near, j] = total / len(at.parts)
    finally:
        truth.release()
    return out


def along_of(candidates: ProbeSet) -> NDArray[np.float64]:
    """The candidates' along-street coordinates (m, the street's frame), ascending: the rows of
    :func:`error_matrix`."""
    probes = StreetProbes.from_manifest(candidates.manifest.streets[0])
    return probes.positions[:, probes.along]


def point_along(street: Street, points: Sequence[EvalPosition]) -> NDArray[np.float64]:
    """Along-street coordinates (m, the street's frame) of evaluation points (world positions)."""
    x = np.array([p.position for p in points], np.float64).reshape(-1, 3)
    return street.to_frame(x)[:, street.along_index]


def notes_number(x: Any) -> Any:
    """A float rounded for the manifest's notes (5 significant digits; ``inf`` -> ``None``)."""
    x = float(x)
    return float(f"{x:.5g}") if math.isfinite(x) else None
