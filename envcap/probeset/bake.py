"""Bake a probe set: place probes along every street of a scene, capture, fit planes, filter.

This is the main job of envcap (``envcap capture SCENE --out DIR``):

1. the scene's sky (:func:`envcap.sky.sky.sky_from_spec`) and its float32 cube (the sun included);
2. probes along each street's center line (:func:`envcap.probeset.placement.place_probes`);
3. HDR cube captures of all probes (:class:`envcap.capture.renderer.CubeCapture`), running only the
   passes the scene's effects call for;
4. the three planes fitted per probe from its distance channel (:func:`envcap.probeset.placement.fit_planes`),
   recorded beside the nominal planes of the street description;
5. cosine-lobe mip chains for the probes and the sky (:func:`envcap.prefilter.filters.prefilter_chain`);
6. a :class:`envcap.probeset.store.ProbeSet` with its manifest, written by
   :func:`envcap.probeset.store.write_probe_set`.
"""

from __future__ import annotations

import sys
import time
from typing import Any

import numpy as np

from envcap.probeset.placement import fit_planes, place_probes
from envcap.probeset.store import ProbeSet, new_manifest
from envcap.scene.model import Scene


def _log(msg: str, verbose: bool) -> None:
    if verbose:
        print(msg, file=sys.stderr, flush=True)


def bake_probe_set(
    scene: Scene,
    *,
    resolution: int = 256,
    spacing: float = 5.0,
    height: float = 2.0,
    quality: str = "default",
    filter_levels: bool = True,
    sun_in_sky: bool = False,
    ctx: Any = None,
    progress: bool | None = None,
    verbose: bool = False,
) -> ProbeSet:
    """Capture and filter the probes of every street of ``scene``.

    ``resolution``: face size N of each probe cube (texels); ``spacing``, ``height``: probe
    spacing along the street and height above its ground (m); ``quality``: prefilter quality
    (see :data:`envcap.prefilter.filters.QUALITY`); ``filter_levels=False`` stores level 0 only.
    ``sun_in_sky``: splat the sun's disk into the sky map (float32, energy-conserving).  By
    default the sky map holds the sky dome only and the sun is an analytic light in the manifest
    (``sky.sun``: direction, disk radiance, illuminance): an engine lights with it (with its own
    shadows) and uses the maps for the rest, so the sun is neither counted twice nor leaked
    through the filtered alpha of facade edges at wide lobes (see docs/evaluation.md).
    ``ctx``: a moderngl context (one is made when ``None``).  Returns the probe set in memory;
    the layers of ``levels`` are the probes of all streets, in street order.

    A probe that stands inside a building (most of its sphere sees back faces) is kept and
    flagged ``"inside_geometry": true`` in the manifest, with a warning on stderr.
    """
    from envcap.capture.renderer import CubeCapture, probe_inside_geometry
    from envcap.prefilter.filters import prefilter_chain, prefilter_many
    from envcap.sky.sky import sky_from_spec

    if not scene.streets:
        raise ValueError(f"scene '{scene.name}' has no streets: nothing to place probes along")
    placements = [place_probes(st, spacing=spacing, height=height) for st in scene.streets]  # validates first
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    sky = sky_from_spec(scene.sky, scene.base_dir)
    sky_rgb = sky.cube(resolution, include_sun=sun_in_sky)
    sky_rgba = np.concatenate([sky_rgb, np.ones(sky_rgb.shape[:-1] + (1,), np.float32)], axis=-1)
    timings["sky_s"] = time.perf_counter() - t0

    positions = np.array([p.position for street in placements for p in street], dtype=np.float64)
    _log(f"{scene.name}: {len(positions)} probes on {len(scene.streets)} street(s), {resolution}^2 per face", verbose)

    own_ctx = ctx is None
    if own_ctx:
        from envcap.gpu.gl import create_context

        ctx = create_context()
    try:
        t0 = time.perf_counter()
        cap = CubeCapture.from_scene(scene, resolution, sky=sky, ctx=ctx)
        try:
            captured = cap.capture_many(positions, progress=bool(progress) if progress is not None else True)
        finally:
            cap.release()
        timings["capture_s"] = time.perf_counter() - t0
        timings.update({f"pass_{k}_s": float(v) for k, v in captured.pass_times_s.items()})

        t0 = time.perf_counter()
        if filter_levels:
            from envcap.core.lobes import lobe_ladder

            ladder = lobe_ladder(resolution)
            levels = [lv.astype(np.float32, copy=False)
                      for lv in prefilter_many(captured.rgba, ladder, quality=quality, ctx=ctx, progress=progress)]
            sky_levels = [lv.astype(np.float32) for lv in prefilter_chain(sky_rgba, ladder, quality=quality, ctx=ctx, progress=False)]
            lobes = ladder.to_manifest()
            powers: list[float | None] = [float(w) for w in ladder.powers]
        else:
            levels, sky_levels, lobes, powers = [captured.rgba.astype(np.float32)], [sky_rgba], {}, [None]
        timings["prefilter_s"] = time.perf_counter() - t0
    finally:
        if own_ctx:
            ctx.release()

    streets = []
    layer = 0
    inside = []
    for st, probes in zip(scene.streets, placements):
        entries = []
        for p in probes:
            fitted = fit_planes(p.position, captured.distance[layer], captured.rgba[layer, ..., 3], st.axis)
            inside_flag = probe_inside_geometry(captured.backfacing[layer])
            if inside_flag:
                inside.append((st.name, p.index, p.position))
            entries.append({
                "layer": layer,
                "index": p.index,
                "position": [float(x) for x in p.position],
                "planes": p.planes.as_dict(),
                "fitted_planes": fitted.as_dict(),
                "inside_geometry": inside_flag,
            })
            layer += 1
        streets.append({
            "name": st.name,
            "axis": st.axis,
            "start": float(st.start),
            "end": float(st.end),
            "center": float(st.center_line),
            "planes": {"facade_min": float(st.facade_min), "facade_max": float(st.facade_max), "ground": float(st.ground)},
            "probes": entries,
        })
    for name, idx, pos in inside:
        print(f"envcap: warning: probe {idx} of street '{name}' at {pos} stands inside geometry", file=sys.stderr)

    manifest = new_manifest(
        resolution,
        len(levels),
        probe_height=float(height),
        probe_spacing=float(spacing),
        streets=streets,
        effects=sorted(scene.effects),
        passes_run=list(captured.passes_run),
        sky={"spec": sky.spec(), "format": "RGBA32F", "sun": (sky.sun.spec() if sky.sun is not None else None),
             "sun_in_map": bool(sun_in_sky and sky.sun is not None)},
        timings={k: round(v, 4) for k, v in timings.items()},
        scene={"name": scene.name, "description": scene.description, "triangles": scene.mesh.triangle_count},
        lobes=lobes,
    )
    for k, w in enumerate(powers):
        manifest["levels"][k]["lobe_power"] = w
    return ProbeSet(manifest=manifest, levels=levels, distance=captured.distance, sky_levels=sky_levels)
