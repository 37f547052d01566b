"""Parallax error evaluation against fresh captures (``envcap evaluate``).

At sampled positions in the street volume (:mod:`envcap.evaluate.sweep`) a fresh HDR cube is
captured, composited with the sky the way the runtime does and filtered at exactly each evaluated
lobe power ``w`` (:mod:`envcap.evaluate.truth`).  The same environment is predicted from the probe
set by each parallax method (:mod:`envcap.runtime.methods`, through
:class:`envcap.evaluate.predict.Predictor`) for every texel direction of the truth cube, and the
two are compared with the solid-angle weighted relative RMSE of luminance
(:func:`envcap.evaluate.metrics.relative_rmse`) and with Eq. 3 shading of a few Lafortune
materials (:mod:`envcap.evaluate.shading`).  Definitions, assumptions and measured figures:
``docs/evaluation.md``.

Conventions: world meters, +Y up (``envcap/core/cube.py``); cubes ``(6, M, M, C)``; colors linear
HDR.  ``w = inf`` is the mirror (level 0, unfiltered).  A street at any angle is evaluated in its
frame: the truth cubes (street and sky) have their axes along it (``EvalPosition.yaw_deg``), the
predictions are looked up along the same texel directions turned back into the world.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray
from tqdm import tqdm

from envcap.core import cube as cubemod
from envcap.core.street_frame import from_frame
from envcap.evaluate.bounds import MAX_POSITIONS, check_evaluation, estimate_evaluation
from envcap.evaluate.metrics import plane_misfit, relative_error_map, relative_rmse
from envcap.evaluate.predict import Predictor
from envcap.evaluate.report import write_report
from envcap.evaluate.result import EvaluationResult, lobe_power_key, lobe_power_label, summarize
from envcap.evaluate.shading import MATERIALS, Material, shading_errors
from envcap.evaluate.sweep import DEFAULT_SWEEP, QUICK_SWEEP, EvalPosition, Sweep, positions_from_array, sample_positions
from envcap.evaluate.truth import TruthRenderer, truth_grid_size
from envcap.gpu.context import create_context
from envcap.probeset.bake_bounds import check_gl_limits
from envcap.probeset.manifest import Manifest
from envcap.probeset.probe_set import ProbeSet
from envcap.probeset.progress import BakeProgress
from envcap.probeset.store import read_probe_set
from envcap.runtime import methods as runtime_methods
from envcap.runtime.methods import METHODS
from envcap.runtime.sampling import composite

DEFAULT_LOBE_POWERS: tuple[float, ...] = (math.inf, 1024.0, 256.0, 64.0, 16.0, 4.0, 1.0)
"""Evaluated lobe powers: the mirror (``inf``, level 0) and normalized cos^w lobes."""


@dataclass(frozen=True)
class EvaluationSettings:
    """Checked inputs of one evaluation: ``methods`` (registered names, no duplicates),
    ``lobe_powers`` (``inf`` or >= 0), ``suns`` (sky variants: ``True`` = sun splatted into the sky
    map), ``primary`` (the variant of the image strips and worst-position picks: without the sun
    when evaluated), ``resolution`` (face size of the truth captures) and ``quality`` (filter)."""

    methods: tuple[str, ...]
    lobe_powers: tuple[float, ...]
    suns: tuple[bool, ...]
    primary: bool
    resolution: int
    quality: str


def check_settings(scene: Any, probe_set: ProbeSet, methods: Sequence[str], lobe_powers: Sequence[float],
                   sun_variants: Sequence[bool], resolution: int | None) -> EvaluationSettings:
    """Validate the inputs of :func:`evaluate_scene` (``ValueError`` with the reason).  A method
    that needs the distance channel of a probe set without one is skipped with a warning."""
    ps_scene = None if probe_set.manifest.scene is None else probe_set.manifest.scene.name
    if ps_scene is not None and ps_scene != scene.name:
        raise ValueError(f"probe set was baked from scene {ps_scene!r}, not {scene.name!r}")
    names = list(dict.fromkeys(methods))
    known = runtime_methods.registered()
    bad = [m for m in names if m not in known]
    if bad or not names:
        raise ValueError(f"unknown or no method(s) {bad}; known: {', '.join(known)}")
    for m in list(names):
        if runtime_methods.get(m).needs_distance and probe_set.distance is None:
            print(f"envcap: warning: probe set has no distance channel: skipping {m}", file=sys.stderr)
            names.remove(m)
    lps = []
    for w in lobe_powers:
        w = float(w)
        if math.isnan(w) or w < 0:
            raise ValueError(f"lobe powers must be >= 0 or inf, got {w}")
        lps.append(w)
    if not lps:
        raise ValueError("no lobe powers to evaluate")
    suns = tuple(dict.fromkeys(bool(v) for v in sun_variants))
    if not suns:
        raise ValueError("sun_variants must hold True and/or False")
    n = int(resolution) if resolution is not None else min(int(probe_set.resolution), 64)
    if n < 4:
        raise ValueError(f"evaluation resolution (--resolution) must be >= 4 texels per face, got {n}")
    # The manifest does not record the bake's prefilter quality: the truth is filtered at the default one.
    return EvaluationSettings(tuple(names), tuple(lps), suns, False if False in suns else True, n, "default")


@dataclass
class TruthAt:
    """The truth at one position: the capture (``rgba`` (6, N, N, 4), ``distance`` (6, N, N) m) and
    ``parts[w]``: street and skies filtered at ``w`` (see :meth:`TruthRenderer.filtered`)."""

    position: EvalPosition
    capture: Any
    parts: dict[float, dict[str, NDArray[np.float64]]]


class PositionEvaluator:
    """The per-position steps of an evaluation: capture the truth, compare every method with it
    (rows), shade (Eq. 3 rows), measure the sky composite, keep cubes for image strips.

    ``timings`` accumulates ``predictions_s`` and ``shading_s`` (seconds)."""

    def __init__(self, settings: EvaluationSettings, truth: TruthRenderer, predictor: Predictor) -> None:
        self.settings = settings
        self.truth = truth
        self.predictor = predictor
        self.timings = {"predictions_s": 0.0, "shading_s": 0.0}
        self._dirs: dict[tuple[int, float], NDArray[np.float64]] = {}
        self._sky: dict[tuple[int, float, bool, float], NDArray[np.float64]] = {}

    def directions(self, m: int, yaw_deg: float = 0.0) -> NDArray[np.float64]:
        """World directions ``(6 m^2, 3)`` of the texel centers of an ``m`` cube whose axes are the
        frame of a street at ``yaw_deg`` (0: the world's)."""
        if (m, yaw_deg) not in self._dirs:
            d = cubemod.texel_directions(m).reshape(-1, 3)
            self._dirs[(m, yaw_deg)] = from_frame(d, yaw_deg) if yaw_deg else d
        return self._dirs[(m, yaw_deg)]

    def predicted_sky(self, m: int, w: float, sun: bool, yaw_deg: float = 0.0) -> NDArray[np.float64]:
        """The predicted sky ``(6 m^2, 4)`` at lobe power ``w`` on the texels of :meth:`directions`
        (the same at every position of a street)."""
        if (m, w, sun, yaw_deg) not in self._sky:
            d = self.directions(m, yaw_deg)
            self._sky[(m, w, sun, yaw_deg)] = self.predictor.sky_rgb(d, np.full(d.shape[0], w), sun)
        return self._sky[(m, w, sun, yaw_deg)]

    def truth_at(self, ep: EvalPosition) -> TruthAt:
        """Capture at ``ep`` (cube axes along its street's frame) and filter at every lobe power."""
        cap = self.truth.capture(np.array(ep.position), ep.yaw_deg)
        return TruthAt(ep, cap, self.truth.filtered(cap.rgba, self.settings.lobe_powers, ep.yaw_deg))

    def _truth_composites(self, part: Mapping[str, NDArray]) -> dict[bool, NDArray[np.float64]]:
        return {sun: composite(part["street"], part["sky" if sun else "sky_nosun"]) for sun in self.settings.suns}

    def _street(self, method: str, ep: EvalPosition, m: int, w: float) -> NDArray[np.float64]:
        d = self.directions(m, ep.yaw_deg)
        st = self.predictor.street_rgba(method, ep.street, np.array(ep.position), d, np.full(d.shape[0], w))
        st = st.reshape(6, m, m, 4)
        if not np.all(np.isfinite(st)):
            raise ValueError(f"method {method} produced NaN/Inf at {ep.position}")
        return st

    def _prediction(self, street_rgba: NDArray, m: int, w: float, sun: bool, yaw_deg: float = 0.0) -> NDArray[np.float64]:
        return composite(street_rgba, self.predicted_sky(m, w, sun, yaw_deg).reshape(6, m, m, -1))

    def error_rows(self, at: TruthAt) -> list[dict[str, Any]]:
        """One row per (lobe power, method, sun variant): the relative RMSE of the prediction."""
        ep = at.position
        x = np.array(ep.position)
        misfit = plane_misfit(x, at.capture.distance, at.capture.rgba[..., 3], self.predictor.local_street(ep.street, x))
        in_crossing = self.predictor.crossing_at(x) >= 0
        t0 = time.perf_counter()
        rows = []
        for w, part in at.parts.items():
            m = part["street"].shape[1]
            truth = self._truth_composites(part)
            for meth in self.settings.methods:
                st = self._street(meth, ep, m, w)
                for sun in self.settings.suns:
                    rows.append({"street": ep.street, "position_index": ep.index, "method": meth,
                                 "lobe_power": lobe_power_key(w), "sun": sun,
                                 "rel_rmse": relative_rmse(self._prediction(st, m, w, sun, ep.yaw_deg), truth[sun]),
                                 "lateral_m": ep.lateral, "along_m": ep.along, "height_m": ep.height,
                                 "near_crossing": ep.near_crossing, "in_crossing": in_crossing, "plane_misfit": misfit,
                                 "position": list(ep.position)})
        self.timings["predictions_s"] += time.perf_counter() - t0
        return rows

    def composite_rows(self, at: TruthAt) -> list[dict[str, Any]]:
        """One row per lobe power: the relative RMSE of the runtime's composite (street and sky
        filtered separately) against the filtered composite (the radiance that really arrives),
        with the sun in the sky; NaN when that variant is not evaluated."""
        t0 = time.perf_counter()
        rows = []
        for w, part in at.parts.items():
            err = float("nan")
            if True in self.settings.suns:
                err = relative_rmse(composite(part["street"], part["sky"]),
                                    self.truth.physical(at.capture.rgba, w, True, at.position.yaw_deg))
            rows.append({"position_index": at.position.index, "lobe_power": lobe_power_key(w), "rel_rmse": err})
        self.timings["predictions_s"] += time.perf_counter() - t0
        return rows

    def shading_rows(self, at: TruthAt, materials: Sequence[Material]) -> list[dict[str, Any]]:
        """Eq. 3 shading errors (:func:`envcap.evaluate.shading.shading_errors`); none without materials."""
        if not materials:
            return []
        t0 = time.perf_counter()
        sky = {s: self.truth.sky_cube(s, at.position.yaw_deg) for s in (True, False)}
        rows = shading_errors(self.predictor, at.position, at.capture.rgba, sky, self.settings.methods,
                              materials, self.settings.suns)
        self.timings["shading_s"] += time.perf_counter() - t0
        return rows

    def strip(self, at: TruthAt) -> dict[str, Any]:
        """Truth and predictions of the primary sky variant for image strips: ``{"truth": {w: cube},
        "pred": {(method, w): cube}, "maps": {(method, w): relative error map}}``."""
        primary = self.settings.primary
        store: dict[str, Any] = {"truth": {}, "pred": {}}
        for w, part in at.parts.items():
            m = part["street"].shape[1]
            store["truth"][w] = self._truth_composites(part)[primary]
            for meth in self.settings.methods:
                store["pred"][(meth, w)] = self._prediction(self._street(meth, at.position, m, w), m, w, primary,
                                                            at.position.yaw_deg)
        store["maps"] = {k: relative_error_map(v, store["truth"][k[1]]) for k, v in store["pred"].items()}
        return store


def floor_positions(manifest: Manifest, count: int) -> list[list[float]]:
    """Positions (m) of the first ``count`` probes of the manifest's first street."""
    return [list(q.position) for st in manifest.streets[:1] for q in st.probes[: max(0, count)]]


def worst_positions(rows: Sequence[Mapping[str, Any]], method: str, lobe_power: float, sun: bool, count: int) -> list[int]:
    """Indices of the ``count`` positions with the largest error of ``method`` at ``lobe_power``, worst first."""
    cand = [(r["rel_rmse"], r["position_index"]) for r in rows
            if r["method"] == method and r["lobe_power"] == lobe_power_key(lobe_power) and r["sun"] == sun]
    return [idx for _, idx in sorted(cand, reverse=True)[: max(0, count)]]


def evaluate_scene(
    scene: Any,
    probe_set: ProbeSet,
    *,
    positions: ArrayLike | None = None,
    sweep: Sweep = DEFAULT_SWEEP,
    methods: Sequence[str] = METHODS,
    lobe_powers: Sequence[float] = DEFAULT_LOBE_POWERS,
    resolution: int | None = None,
    ctx: Any = None,
    materials: Sequence[Material] = MATERIALS,
    keep_worst: int = 3,
    floor_probes: int = 2,
    sun_variants: Sequence[bool] = (True, False),
    progress: bool | None = None,
    max_positions: int = MAX_POSITIONS,
    report: BakeProgress | None = None,
    crossings: bool | str = True,
) -> EvaluationResult:
    """Evaluate the probe set ``probe_set`` of ``scene`` against fresh captures.

    ``positions``: explicit world positions ``(P, 3)`` (m), else :func:`sample_positions` with
    ``sweep``.  ``methods``: registered parallax methods (default :data:`METHODS`, the built-in
    ones).  ``lobe_powers``: ``inf`` (mirror) and/or powers ``w >= 0``.  ``resolution``: face size
    of the truth captures (default: the probe set's, at most 64).  ``sun_variants``: ``True``
    evaluates with the sun splatted into the sky map (of truth and prediction), ``False`` with the
    sun taken out of the sky of both (an engine that draws the sun as an analytic light).
    ``materials``: Eq. 3 shading metric (empty: skipped).  ``keep_worst``: keep truth and
    predictions of the worst positions (by ``planes_mip`` at w = 64, primary sky variant) for image
    strips.  ``floor_probes``: also evaluate at this many probe positions (the evaluator's own
    floor) and measure there what compositing the sky after filtering costs.  ``max_positions``:
    the most positions (:data:`envcap.evaluate.bounds.MAX_POSITIONS`); the position count, the
    truth face size and the memory are checked before any work (:mod:`envcap.evaluate.bounds`).
    ``report``: stages ``positions``, ``floor``, ``strips`` with positions done and positions/s
    (:class:`envcap.probeset.progress.BakeProgress`, as ``envcap evaluate`` prints them); without
    it a tqdm bar on a terminal, as ``progress`` says.  ``crossings``: positions inside a crossing of a
    set that records them are looked up through the crossing probe (:class:`Predictor`); ``False``:
    per street.
    """
    t_all = time.perf_counter()
    settings = check_settings(scene, probe_set, methods, lobe_powers, sun_variants, resolution)
    manifest = probe_set.manifest
    explicit = None if positions is None else positions_from_array(manifest, positions)
    count = sweep.per_street * len(manifest.streets) if explicit is None else len(explicit)
    check_evaluation(estimate_evaluation(count, settings.resolution, len(settings.lobe_powers), len(settings.methods),
                                         len(settings.suns)), max_positions=max_positions)
    pos_list = sample_positions(manifest, sweep) if explicit is None else explicit
    own = ctx is None
    if own:
        ctx = create_context()
    try:
        check_gl_limits(ctx, settings.resolution, 0)
        truth = TruthRenderer(scene, settings.resolution, ctx, quality=settings.quality)
    except BaseException:
        if own:
            ctx.release()
        raise
    t0 = time.perf_counter()
    predictor = Predictor(probe_set, sky=truth.sky if False in settings.suns else None, ctx=ctx, quality=settings.quality,
                          crossings=crossings)
    t_setup = time.perf_counter() - t0
    ev = PositionEvaluator(settings, truth, predictor)
    rows: list[dict[str, Any]] = []
    shading: list[dict[str, Any]] = []
    floor_rows: list[dict[str, Any]] = []
    composite_rows: list[dict[str, Any]] = []
    key = "planes_mip" if "planes_mip" in settings.methods else settings.methods[0]
    wkey = 64.0 if 64.0 in settings.lobe_powers else settings.lobe_powers[0]
    kept: dict[int, dict[str, Any]] = {}
    stages = BakeProgress("off") if report is None else report
    try:
        stages.start("positions", len(pos_list))
        bar = tqdm(pos_list, desc=f"evaluate {scene.name}", unit="pos",
                   disable=report is not None or (None if progress is None else not progress))
        for ep in bar:
            at = ev.truth_at(ep)
            rows += ev.error_rows(at)
            shading += ev.shading_rows(at, materials)
            stages.advance()
        # the evaluator's own floor: the probes' own positions (every method must match the truth)
        fl_pos = floor_positions(manifest, floor_probes)
        stages.start("floor", len(fl_pos))
        for ep in positions_from_array(manifest, np.array(fl_pos)) if fl_pos else []:
            at = ev.truth_at(ep)
            composite_rows += ev.composite_rows(at)
            floor_rows += ev.error_rows(at)
            stages.advance()
        # the worst positions, captured again with their cubes kept for the image strips
        worst = worst_positions(rows, key, wkey, settings.primary, keep_worst)
        stages.start("strips", len(worst))
        for idx in worst:
            kept[idx] = ev.strip(ev.truth_at(pos_list[idx]))
            stages.advance()
        stages.finish()
    finally:
        truth.release()
        if own:
            ctx.release()
    times = {"captures_s": truth.times["capture_s"], "filtering_s": truth.times["filter_s"], **ev.timings,
             "setup_s": t_setup, "total_s": time.perf_counter() - t_all}
    for r in rows + floor_rows + shading + composite_rows:
        r["scene"] = scene.name
    meta = _meta(scene.name, probe_set, settings, sweep if positions is None else None, len(pos_list), materials,
                 composite_rows)
    meta["crossings"] = [c.name for c in probe_set.manifest.crossings or ()]
    meta["crossing_lookup"] = predictor.crossing_mode if meta["crossings"] else None
    return EvaluationResult(scene.name, pos_list, rows, summarize(scene.name, rows), shading, times, meta,
                            floor=summarize(scene.name, floor_rows),
                            strips={"positions": kept, "key_method": key, "key_power": wkey})


def _meta(scene: str, probe_set: ProbeSet, settings: EvaluationSettings, sweep: Sweep | None, n_positions: int,
          materials: Sequence[Material], composite_rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """``EvaluationResult.meta``: resolution, probe set facts, settings, sweep, grid sizes, composite error."""
    manifest = probe_set.manifest
    lps = settings.lobe_powers
    return {"resolution": settings.resolution, "probe_resolution": int(probe_set.resolution),
            "probe_spacing": manifest.probe_spacing, "probe_count": int(probe_set.layer_count),
            "placement": None if manifest.placement is None else manifest.placement.strategy,
            "methods": list(settings.methods), "lobe_powers": [lobe_power_key(w) for w in lps],
            "sun_variants": list(settings.suns), "primary_sun": settings.primary, "quality": settings.quality,
            "sweep": "explicit" if sweep is None else {
                "per_street": sweep.per_street, "margin_m": sweep.margin, "end_margin_m": sweep.end_margin,
                "heights_m": list(sweep.heights), "seed": sweep.seed},
            "n_positions": n_positions, "grid_sizes": {lobe_power_label(w): truth_grid_size(w, settings.resolution) for w in lps},
            "materials": [m.name for m in materials],
            "composite_error": summarize(scene, [{**r, "method": "composite_after_filtering", "sun": True}
                                                 for r in composite_rows])}


def quick_evaluation(scene: Any, probe_set_dir: str | Path, out_dir: str | Path, ctx: Any = None,
                     report: BakeProgress | None = None) -> Path:
    """A short evaluation (6 positions per street, mirror + w in {256, 64, 16}, <~30 s) of the
    probe set in ``probe_set_dir``; writes the report into ``out_dir`` (atomically), prints
    where the report and pictures are and returns the path of ``report.md``.  ``report``: as
    :func:`evaluate_scene`'s."""
    ps = read_probe_set(probe_set_dir)
    res = evaluate_scene(scene, ps, sweep=QUICK_SWEEP, lobe_powers=(math.inf, 256.0, 64.0, 16.0),
                         resolution=min(ps.resolution, 32), ctx=ctx, keep_worst=2, report=report)
    out = write_report([res], out_dir)
    report = Path(out) / "report.md"
    print(f"evaluation: {report} (plots and worst-position strips in {Path(out)})")
    return report
