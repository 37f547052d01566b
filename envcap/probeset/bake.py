"""Bake a probe set: place probes along every street of a scene, capture, fit planes, filter.

This is the main job of envcap (``envcap capture SCENE --out DIR``):

0. bounds before work (:mod:`envcap.probeset.bake_bounds`): the probe count, peak memory and
   rough time estimated and refused past their limits, the mesh and the probes checked against
   float32 range, the capture's face atlas against the GL limits (estimate printed on big jobs);
1. the scene's sky (``scene.sky.build()``, see :class:`envcap.sky.SkySpec`) and its float32 cube;
2. probes along each street's center line (:func:`envcap.probeset.placement.place_probes`, or at
   the coordinates a placement strategy chose, ``along=``: :mod:`envcap.placement`; a
   street at an angle places them in its own frame, :mod:`envcap.core.street_frame`, and its
   probes' cubes are captured with their faces along that frame's axes, planes fitted there);
3. HDR cube captures of all probes (:class:`envcap.capture.renderer.CubeCapture`), running only the
   passes the scene's effects call for, checked against the half-float range of ``probes.ktx2``
   (:func:`envcap.probeset.half_range.check_half_range`: one line naming the probe and the cause);
4. the three planes fitted per probe from its distance channel (:func:`envcap.probeset.planes.fit_planes`),
   recorded beside the nominal planes of the street description;
5. cosine-lobe mip chains for the probes and the sky (:func:`envcap.prefilter.fast.prefilter_chain`);
6. a :class:`envcap.probeset.probe_set.ProbeSet` with its typed manifest
   (:class:`envcap.probeset.manifest.Manifest`), written by
   :func:`envcap.probeset.store.write_probe_set`.
"""

from __future__ import annotations

import itertools
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from envcap.capture.outputs import CaptureSet, probe_inside_geometry
from envcap.capture.renderer import CubeCapture
from envcap.core.checks import positive_int
from envcap.core.lobes import Z_OF_W_RULE, lobe_ladder
from envcap.core.rungs import LADDER_MODES, RUNGS_PER_LEVEL
from envcap.gpu.context import create_context
from envcap.prefilter import prefilter_chain, prefilter_many
from envcap.prefilter.rungs import rung_textures
from envcap.probeset.bake_bounds import check_bake_cost, check_geometry, check_gl_limits, estimate_bake
from envcap.probeset.crossings import Meeting, corridor, crossing_alongs, detect_crossings
from envcap.probeset.half_range import check_half_range
from envcap.probeset.ladder_table import LadderTable
from envcap.probeset.manifest import Crossing, LobeTable, Manifest, Probe, SceneInfo, SkyInfo, Street, SunInfo, Timings, level_table
from envcap.probeset.placement import MAX_PROBES, ProbePlacement, check_along, place_probes, place_probes_at, probe_count
from envcap.probeset.placement_table import PlacementTable
from envcap.probeset.planes import Planes, fit_planes
from envcap.probeset.probe_set import ProbeSet
from envcap.probeset.progress import BakeProgress
from envcap.probeset.shadow_fit import cascade_texels, shadow_effect_parameters, shadow_summary
from envcap.probeset.street_checks import (inside_geometry_warning, plane_fit_warnings,
                                          street_setup_warnings)
from envcap.scene.ground_height import GroundHeights
from envcap.scene.model import Scene


CAPTURE_CHUNK = 8
"""Probes captured between two ``on_captured`` calls (no effect on the result)."""
PREFILTER_BATCH_BYTES = 64 << 20
"""Level-0 float32 RGBA bytes per prefilter batch (the filters' own default).  The bake filters
whole batches at a time, so its chunks are the batches the filter would make of the whole set:
the result is bit-identical to one call (the coarse-source qualities' footprint truncation
follows a batch's dynamic range, so the batches must not move)."""

PREFILTER_CHUNK_PROBES = 16
"""At least this many probes per prefilter call of the bake (rounded up to whole batches)."""

CapturedFn = Callable[[int, np.ndarray, np.ndarray], None]
"""``on_captured(first_layer, rgba, distance)``: level 0 ``(P, 6, N, N, 4)`` float32 and its
distances ``(P, 6, N, N)`` (m) of layers ``first_layer ..`` as soon as they are captured (e.g.
for :class:`envcap.formats.probe_files.ProbeFileWriter`); the arrays are the bake's own: read only."""


def _log(msg: str, verbose: bool) -> None:
    if verbose:
        print(msg, file=sys.stderr, flush=True)


def _capture(cap: CubeCapture, positions: np.ndarray, yaws: np.ndarray, report: BakeProgress, progress: bool,
             on_captured: CapturedFn | None) -> CaptureSet:
    """``cap.capture_many(positions)`` with each probe's cube turned by its street's ``yaws``
    (P,) degrees (one call per run of equal yaws, copied into one set when there are several),
    reporting each probe in the current stage and handing every :data:`CAPTURE_CHUNK` probes to
    ``on_captured``."""
    done = [0]
    cuts = [0, *(np.flatnonzero(np.diff(yaws)) + 1).tolist(), len(positions)]
    whole: list[CaptureSet] = []

    def on_probe(first: int, i: int, out: CaptureSet) -> None:
        if whole:
            for name in ("rgba", "distance", "backfacing"):
                getattr(whole[0], name)[first + i] = getattr(out, name)[i]
        whole_set = whole[0] if whole else out
        report.advance()
        if on_captured is not None and (first + i + 1 - done[0] >= CAPTURE_CHUNK or first + i + 1 == len(positions)):
            on_captured(done[0], whole_set.rgba[done[0]:first + i + 1], whole_set.distance[done[0]:first + i + 1])
            done[0] = first + i + 1

    if len(cuts) > 2:  # several yaws: one set for all, filled as each run's probes come
        n, p = cap.size, len(positions)
        whole.append(CaptureSet(np.asarray(positions, np.float64), np.empty((p, 6, n, n, 4), np.float32),
                                np.empty((p, 6, n, n), np.float32), np.empty((p, 6, n, n), bool), [], {}))
    parts = []
    for a, b in itertools.pairwise(cuts):
        parts.append(cap.capture_many(positions[a:b], progress=progress and report.mode == "off",
                                      on_probe=lambda i, out, a=a: on_probe(a, i, out), yaw_deg=float(yaws[a])))
    if not whole:
        return parts[0]
    out = whole[0]
    out.passes_run = parts[0].passes_run
    out.pass_times_s = merged_pass_times(cap.pass_times_s, [part.pass_times_s for part in parts])
    return out


def merged_pass_times(per_set: Mapping[str, float], parts: Sequence[Mapping[str, float]]) -> dict[str, float]:
    """Pass seconds of one capture set captured in ``parts`` (the ``pass_times_s`` of sets of one
    :class:`CubeCapture`, e.g. one per yaw group): each part holds the capture's per-set passes
    ``per_set`` (run once, before any probe) plus its own per-probe seconds (``render``,
    ``readback``, and the effects' per-probe passes, e.g. shadow cascades redrawn under
    ``shadow_map``); the sum counts ``per_set`` once and every part's per-probe seconds."""
    out = dict(parts[0])
    for part in parts[1:]:
        for k, v in part.items():
            out[k] = out.get(k, 0.0) + (v - per_set.get(k, 0.0))
    return out


def _prefilter_chunks(rgba: np.ndarray, ladder: Any, quality: str, ctx: Any, report: BakeProgress,
                      progress: bool | None) -> list[np.ndarray]:
    """``prefilter_many(rgba)`` a few of its own batches at a time (bit-identical), reporting each
    in the current stage."""
    n = rgba.shape[2]
    per = max(1, int(PREFILTER_BATCH_BYTES // (6 * n * n * 16)))
    step = per * max(1, -(-PREFILTER_CHUNK_PROBES // per)) if report.mode != "off" else len(rgba)
    # level 0 is the capture itself; the filter writes the other levels in place (no copies)
    levels = [rgba] + [np.empty((rgba.shape[0], 6, s, s, 4), np.float32) for s in ladder.sizes[1:]]
    for i0 in range(0, len(rgba), step):
        chunk = rgba[i0:i0 + step]
        prefilter_many(chunk, ladder, quality=quality, ctx=ctx, progress=progress if report.mode == "off" else False,
                       batch_bytes=PREFILTER_BATCH_BYTES, out=[chunk] + [lv[i0:i0 + step] for lv in levels[1:]])
        report.advance(len(chunk))
    return levels


def bake_probe_set(
    scene: Scene,
    *,
    resolution: int = 256,
    spacing: float = 5.0,
    height: float = 2.0,
    quality: str = "default",
    filter_levels: bool = True,
    sun_in_sky: bool = False,
    ladder_mode: str = "paper",
    ctx: Any = None,
    progress: bool | None = None,
    verbose: bool = False,
    max_probes: int = MAX_PROBES,
    report: BakeProgress | None = None,
    on_captured: CapturedFn | None = None,
    writers: Sequence[str] = (),
    along: Mapping[str, Sequence[float]] | None = None,
    placement: PlacementTable | None = None,
    crossings: bool = False,
) -> ProbeSet:
    """Capture and filter the probes of every street of ``scene``.

    ``resolution``: face size N of each probe cube (texels); ``spacing``, ``height``: probe
    spacing along the street and height above its ground (m); ``quality``: prefilter quality
    (see :data:`envcap.prefilter.fast.QUALITY`); ``filter_levels=False`` stores level 0 only.
    ``ladder_mode``: ``"paper"`` (the single chain) or a rung ladder (``"half_octave"``,
    ``"octave"``: :func:`envcap.prefilter.rungs.rung_textures`, ``ProbeSet.rungs``, ``manifest.ladder``).
    ``sun_in_sky``: splat the sun's disk into the sky map (float32, energy-conserving).  By
    default the sky map holds the sky dome only and the sun is an analytic light in the manifest
    (``sky.sun``: direction, disk radiance, illuminance): an engine lights with it (with its own
    shadows) and uses the maps for the rest, so the sun is neither counted twice nor leaked
    through the filtered alpha of facade edges at wide lobes (see docs/evaluation.md).
    ``ctx``: a moderngl context (one is made when ``None``).  Returns the probe set in memory;
    the layers of ``levels`` are the probes of all streets, in street order.
    ``writers``: names of the writers that will run on the result (their memory is in the estimate).
    ``along``: the probes' along-street coordinates (m, each street's frame) per street name, as a
    placement strategy chose them (:mod:`envcap.placement`; every street of the scene, each
    strictly increasing within the street: :func:`envcap.probeset.placement.place_probes_at`)
    instead of ``spacing``; the manifest's ``probe_spacing`` is then their mean spacing.
    ``placement``: how they were placed, recorded as the manifest's ``placement`` (``None``: omitted).
    ``crossings``: where streets meet (:func:`envcap.probeset.crossings.detect_crossings`), add a
    probe at each crossing's centre to its first street (none added where one already stands
    within :data:`CROSSING_REUSE_M`) and record the crossings as the manifest's ``crossings``
    (docs/crossings.md); ``False``: neither (the key is omitted).

    ``report``: stages and probes/s (:class:`envcap.probeset.progress.BakeProgress`: sky,
    capture, prefilter); without one the capture and filter show their own tqdm bars as
    ``progress`` says.  ``on_captured``: see :data:`CapturedFn` (called per chunk of
    :data:`CAPTURE_CHUNK` probes, in layer order, from this thread).  Capture and filtering run
    in chunks; the result does not depend on them (tested).

    A probe that stands inside a building (most of its sphere sees back faces) is kept and
    flagged ``inside_geometry`` in the manifest, with a warning on stderr.

    Bounds before work (docs/reliability.md, Limits): more than ``max_probes`` probes, a peak
    memory past :func:`envcap.core.budget.memory_limit`, a face atlas (3N x 2N) past the GL
    limits, or a mesh or probe past float32 distance range raise ``ValueError`` (one line) before
    the sky is built or anything is captured; big jobs print their estimate when ``verbose``.
    """
    if not scene.streets:
        raise ValueError(f"scene '{scene.name}' has no streets: nothing to place probes along")
    resolution = positive_int(resolution, "probe resolution (--resolution)")
    if ladder_mode not in LADDER_MODES or (ladder_mode != "paper" and not filter_levels):
        raise ValueError(f"ladder mode (--ladder) must be one of {list(LADDER_MODES)} (a rung ladder needs filtered levels), got {ladder_mode!r}")
    if along is not None:
        missing = [st.name for st in scene.streets if st.name not in along]
        if missing or len(along) != len(scene.streets):
            raise ValueError(f"probe positions (along) must name every street of scene '{scene.name}' once; "
                             f"missing {missing}, unknown {sorted(set(along) - {st.name for st in scene.streets})}")
        along = {st.name: check_along(st, along[st.name]) for st in scene.streets}
        count = sum(a.size for a in along.values())
        spacing = sum(st.length for st in scene.streets) / count
    else:
        count = sum(probe_count(st, spacing) for st in scene.streets)  # validates the spacing
    estimate = estimate_bake(count, resolution, filter_levels=filter_levels, quality=quality,
                             rungs_per_level=RUNGS_PER_LEVEL.get(ladder_mode, 0), writers=writers)
    check_bake_cost(estimate, sum(st.length for st in scene.streets), spacing, max_probes)
    terrain = GroundHeights(scene.mesh) if any(st.follow_terrain for st in scene.streets) else None
    placements = [place_probes(st, spacing=spacing, height=height, max_probes=max_probes, ground_at=terrain)
                  if along is None else place_probes_at(st, along[st.name], height, ground_at=terrain)
                  for st in scene.streets]
    positions = np.array([p.position for street in placements for p in street], dtype=np.float64)
    yaws = np.array([st.yaw_deg for st, street in zip(scene.streets, placements) for _ in street], dtype=np.float64)
    cross_table: list[tuple[Meeting, int, int]] = []
    if crossings:
        placements, cross_table = _crossing_placements(scene, placements, height, spacing, terrain)
        positions = np.array([p.position for street in placements for p in street], dtype=np.float64)
        yaws = np.array([st.yaw_deg for st, street in zip(scene.streets, placements) for _ in street], dtype=np.float64)
    check_geometry(scene, positions)
    for line in street_setup_warnings(scene):
        print(f"envcap: warning: {line}", file=sys.stderr)
    if estimate.big:
        _log(f"{scene.name}: estimate: {estimate.describe()}", verbose)
    _log(f"{scene.name}: {len(positions)} probes on {len(scene.streets)} street(s), {resolution}^2 per face", verbose)

    timings: dict[str, float] = {}
    report = BakeProgress("off") if report is None else report
    own_ctx = ctx is None
    if own_ctx:
        ctx = create_context()
    try:
        note = check_gl_limits(ctx, resolution, len(positions))
        if note is not None:
            _log(f"envcap: note: {note}", verbose)
        t0 = time.perf_counter()
        report.start("sky", 0)
        sky = scene.sky.build()
        sky_rgb = sky.cube(resolution, include_sun=sun_in_sky)
        sky_rgba = np.concatenate([sky_rgb, np.ones(sky_rgb.shape[:-1] + (1,), np.float32)], axis=-1)
        timings["sky_s"] = time.perf_counter() - t0
        report.finish()

        t0 = time.perf_counter()
        report.start("capture", len(positions))
        cap = CubeCapture.from_scene(scene, resolution, sky=sky, ctx=ctx,
                                     effect_parameters=shadow_effect_parameters(scene))
        shadow_texel = cap.effect_facts.get("sun_shadows.texel_m")
        shadow_cascades = cascade_texels(cap.effect_facts)
        if shadow_cascades is not None:
            _log(f"{scene.name}: {shadow_summary(cap.effect_facts)}", verbose)
        try:
            captured = _capture(cap, positions, yaws, report, bool(progress) if progress is not None else True, on_captured)
        finally:
            cap.release()
        timings["capture_s"] = time.perf_counter() - t0
        report.finish()
        timings.update({f"pass_{k}_s": float(v) for k, v in captured.pass_times_s.items()})
        check_half_range(captured.rgba, [(p.street, p.index) for street in placements for p in street], positions,
                         scene, sky)

        t0 = time.perf_counter()
        report.start("prefilter", len(positions))
        rungs = sky_rungs = ladder_table = None
        if filter_levels and ladder_mode != "paper":
            lad, rungs, sky_rungs = rung_textures(captured.rgba, sky_rgba, ladder_mode, quality, ctx, progress)
            levels, sky_levels = [lv[0::lad.per_level] for lv in rungs], [lv[0] for lv in sky_rungs]
            powers = [float(w) for w in lad.powers[0::lad.per_level]]
            lobes = LobeTable(lad.sizes, tuple(powers), Z_OF_W_RULE)   # layer r = 0 of each level
            ladder_table = LadderTable.of(ladder_mode, lad)
            report.advance(len(positions))
        elif filter_levels:
            ladder = lobe_ladder(resolution)
            levels = _prefilter_chunks(captured.rgba, ladder, quality, ctx, report, progress)
            sky_levels = [lv.astype(np.float32) for lv in prefilter_chain(sky_rgba, ladder, quality=quality, ctx=ctx, progress=False)]
            lobes: LobeTable | None = LobeTable.from_json(ladder.to_manifest())
            powers: list[float | None] = [float(w) for w in ladder.powers]
        else:
            levels, sky_levels, lobes, powers = [captured.rgba.astype(np.float32)], [sky_rgba], None, [None]
        timings["prefilter_s"] = time.perf_counter() - t0
        report.finish()
    finally:
        if own_ctx:
            ctx.release()

    streets = []
    layer = 0
    warnings = []
    report.start("planes", len(positions))
    for st, probes in zip(scene.streets, placements):
        entries = []
        for p in probes:  # a framed street's cubes and planes are in its frame: fit at the probe's frame position
            fitted = fit_planes(st.to_frame(p.position), captured.distance[layer], captured.rgba[layer, ..., 3], st.axis,
                                fit_slope=st.follow_terrain)
            inside_flag = probe_inside_geometry(captured.backfacing[layer])
            if inside_flag:
                warnings.append(inside_geometry_warning(st.name, p.index, p.position, captured.backfacing[layer]))
            entries.append(Probe(layer, p.index, p.position, p.planes, fitted, bool(inside_flag)))
            layer += 1
            report.advance()
        fits = [(e.index, e.planes, e.fitted_planes) for e in entries if e.fitted_planes is not None]
        warnings += plane_fit_warnings(st.name, st.facade_max - st.facade_min, fits)
        frame = (st.yaw_deg, st.origin_xz) if st.framed else (None, None)
        streets.append(Street(st.name, st.axis, float(st.start), float(st.end), float(st.center_line),
                              Planes(float(st.facade_min), float(st.facade_max), float(st.ground)), tuple(entries), *frame))
    report.finish()
    for line in warnings:
        print(f"envcap: warning: {line}", file=sys.stderr)

    sun = None if sky.sun is None else SunInfo.from_json(sky.sun.spec())
    manifest = Manifest(
        resolution=resolution,
        levels=level_table(resolution, len(levels), powers),
        lobes=lobes,
        ladder=ladder_table,
        prefilter_quality=quality if filter_levels else None,
        shadow_texel_m=None if shadow_texel is None else round(float(shadow_texel), 6),
        shadow_cascade_texels_m=shadow_cascades,
        probe_height=float(height),
        probe_spacing=float(spacing),
        placement=placement,
        streets=tuple(streets),
        crossings=None if not crossings else tuple(
            Crossing("+".join(scene.streets[i].name for i in m.streets), streets[si].probes[pi].position,
                     tuple(scene.streets[i].name for i in m.streets), streets[si].probes[pi].layer)
            for m, si, pi in cross_table),
        effects=tuple(sorted(scene.effects)),
        passes_run=tuple(captured.passes_run),
        sky=SkyInfo(sky.spec(), sun=sun, sun_in_map=bool(sun_in_sky and sky.sun is not None)),
        timings=Timings.from_json({k: round(v, 4) for k, v in timings.items()}),
        scene=SceneInfo(scene.name, scene.description, scene.mesh.triangle_count),
    )
    return ProbeSet(manifest=manifest, levels=levels, distance=captured.distance, sky_levels=sky_levels,
                    rungs=rungs, sky_rungs=sky_rungs)


CROSSING_REUSE_M = 0.05
"""A probe of the owning street this close (m, along it) to a crossing's centre is the crossing probe."""


def _crossing_placements(scene: Scene, placements: list[list[ProbePlacement]], height: float, spacing: float,
                         terrain: Any) -> tuple[list[list[ProbePlacement]], list[tuple[Meeting, int, int]]]:
    """``placements`` with a probe at each crossing's centre on its first street, and per crossing
    ``(meeting, street index, probe index in the street)``."""
    meetings = detect_crossings(scene.streets)
    cors = [corridor(st) for st in scene.streets]
    adds = crossing_alongs(cors, meetings)
    out = list(placements)
    for i, extra in adds.items():
        st = scene.streets[i]
        have = np.array([st.to_frame(np.array(p.position))[st.along_index] for p in placements[i]])
        new = [a for a in extra if not np.any(np.abs(have - a) <= CROSSING_REUSE_M)]
        if new:
            out[i] = place_probes_at(st, np.sort(np.concatenate([have, new])), height, ground_at=terrain,
                                     slope_spacing=spacing)
    table = []
    for m in meetings:
        i = m.streets[0]
        st = scene.streets[i]
        s = np.array([st.to_frame(np.array(p.position))[st.along_index] for p in out[i]])
        a = cors[i].frame_of(np.array(m.centre))[0]
        table.append((m, i, int(np.argmin(np.abs(s - a)))))
    return out, table
