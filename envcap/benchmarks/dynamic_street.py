"""dynamic_street: the dynamic terms (spheres) in a bundled street, against fresh captures.

The bundled ``canyon`` is baked (``--probe-resolution``, ``--spacing``); at ``--positions``
crowd positions on its street (1.5 m above the ground: at a probe, between probes, off the center line) each
ring of :data:`envcap.evaluate.dynamic_occluders.DEFAULT_RINGS` is placed around the point, the
scene with the spheres is captured there as truth, and Eq. 3 shading of the evaluator's materials
is compared with the probes without (``static``) and with the dynamic terms of each model
(:data:`envcap.evaluate.dynamic_occluders.MODELS`), and with a sphere-free fresh capture as the
static part (``oracle``).  Also the cost per shading point, numpy and GLSL, as ratios to a plain
Eq. 3 (:mod:`envcap.benchmarks.dynamic_street_cost`).

Writes ``dynamic_street.json`` (rows, summaries, terms, cost), ``dynamic_street.md`` (tables) and
``dynamic_street.png`` (error against sky coverage) to ``--out``.  Sun: the analytic variant (the
sun out of the sky maps, as the evaluator's primary), ``--sun-in-sky`` adds the other.
``--avatars also|only``: walker avatars around the positions as well / instead
(:mod:`envcap.benchmarks.dynamic_street_avatars`, ``dynamic_street_avatars.*``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from envcap.benchmarks.dynamic_street_avatars import avatar_section, write_avatar_files
from envcap.benchmarks.dynamic_street_cost import gl_cost, numpy_cost
from envcap.benchmarks.dynamic_street_plot import plot_error_vs_hidden
from envcap.core.street_frame import frame_to_world, world_to_frame
from envcap.evaluate.dynamic_occluders import (
    DEFAULT_MODELS,
    DEFAULT_RINGS,
    MODELS,
    Ring,
    evaluate_rings,
    markdown_table,
    summarize_by_coverage,
)
from envcap.evaluate.dynamic_terms import sphere_buffer
from envcap.evaluate.predict import Predictor
from envcap.evaluate.sweep import StreetExtent
from envcap.gpu.context import create_context
from envcap.outputs import atomic_output_dir
from envcap.probeset.bake import bake_probe_set
from envcap.scene import load_scene

SCENE = "canyon"
HEIGHT_M = 1.5
"""Height of the shading points above the ground (m)."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (JSON, Markdown, PNG)")
    p.add_argument("--resolution", type=int, default=32, help="face size of the fresh captures (default 32)")
    p.add_argument("--probe-resolution", type=int, default=32, help="face size of the baked probes (default 32)")
    p.add_argument("--spacing", type=float, default=20.0, help="probe spacing in m (default 20)")
    p.add_argument("--positions", type=int, default=3, help="crowd positions, 1-6 (default 3)")
    p.add_argument("--models", nargs="+", default=list(DEFAULT_MODELS), help=f"dynamic models ({', '.join(MODELS)})")
    p.add_argument("--sun-in-sky", action="store_true", help="also evaluate with the sun splatted into the sky maps")
    p.add_argument("--gl-size", type=int, default=256, help="framebuffer side of the GLSL cost pass (0: skip)")
    p.add_argument("--spheres", type=int, default=8, help="spheres per shading point in the cost passes, 0-16 (default 8)")
    p.add_argument("--avatars", choices=("off", "also", "only"), default="off",
                   help="walkers around the positions instead of spheres: also (a second table), only (just them)")


def crowd_positions(manifest: Any, count: int, spacing: float) -> list[list[float]]:
    """``count`` (1-6) positions :data:`HEIGHT_M` above the ground under them
    (:meth:`envcap.evaluate.sweep.StreetExtent.ground_at`: a street that follows the terrain stands
    on its probes' grounds) near the middle of the first street: at a probe, half a spacing along
    and 3 m across, a quarter along and 4 m the other way, ..."""
    st = manifest.streets[0]
    extent = StreetExtent.from_manifest(st)
    yaw, oxz = st.frame_yaw_deg, st.frame_origin_xz     # offsets along and across the street, in its frame
    probe = world_to_frame(st.probes[len(st.probes) // 2].position, yaw, oxz)
    along = 0 if st.axis == "x" else 2
    cross = 2 - along
    offsets = ((0.0, 0.0), (0.5, 3.0), (0.25, -4.0), (0.75, -2.0), (0.5, 0.0), (0.1, 5.0))
    out = []
    for fa, dc in offsets[:count]:
        p = probe.copy()
        p[along] += fa * spacing
        p[cross] += dc
        p[1] = extent.ground_at(float(p[along])) + HEIGHT_M
        out.append([float(v) for v in frame_to_world(p, yaw, oxz)])
    return out


def goal_check(summary: Sequence[dict[str, Any]], statics: Sequence[str], models: Sequence[str]) -> list[dict[str, Any]]:
    """Per static source and model: over the bins at or above 10 % visible sky hidden, the ratio of
    the error with the dynamic terms to the error without (RMS over bins and materials); the goal
    is <= 0.5."""
    out = []
    hi = [r for r in summary if r["bin_lo"] >= 0.1 - 1e-9]
    for s in statics:
        base = [r["rms_rel_err"] for r in hi if r["variant"] == s]
        for m in models:
            dyn = [r["rms_rel_err"] for r in hi if r["variant"] == f"{s}+{m}"]
            if base and dyn:
                b, d = float(np.sqrt(np.mean(np.square(base)))), float(np.sqrt(np.mean(np.square(dyn))))
                out.append({"static": s, "model": m, "err_without": b, "err_with": d, "ratio": d / b if b > 0 else float("nan")})
    return out


def plot(rows: Sequence[dict[str, Any]], models: Sequence[str], path: Path) -> None:
    """The rings' figure (:func:`plot_error_vs_hidden`, rows without the sun in the sky)."""
    plot_error_vs_hidden(rows, models, path, "spheres", "canyon: ring of spheres around a point; error against a fresh "
                         "capture with the spheres (3 materials, analytic sun)", with_sun=False)


def run(args: argparse.Namespace) -> int:
    if not 1 <= args.positions <= 6 or args.resolution < 8 or args.probe_resolution < 8 or not args.spacing > 0 \
            or not 0 <= args.spheres <= 16 or args.gl_size < 0:
        raise ValueError("--positions must be 1-6, --resolution and --probe-resolution >= 8, --spacing > 0, "
                         "--spheres 0-16, --gl-size >= 0")
    bad = [m for m in args.models if m not in MODELS]
    if bad:
        raise ValueError(f"unknown model(s) {bad}; known: {', '.join(MODELS)}")
    t_all = time.perf_counter()
    scene = load_scene(SCENE)
    ctx = create_context()
    try:
        ps = bake_probe_set(scene, resolution=args.probe_resolution, spacing=args.spacing, ctx=ctx, progress=False)
        suns = (False, True) if args.sun_in_sky else (False,)
        sky = scene.sky.build()
        predictor = Predictor(ps, sky=sky, ctx=ctx)
        positions = crowd_positions(ps.manifest, args.positions, args.spacing)
        if args.avatars != "off":
            avatars = avatar_section(scene, predictor, ps.manifest.streets[0].name, positions, ctx=ctx,
                                     resolution=args.resolution, models=args.models)
            if args.avatars == "only":
                with atomic_output_dir(args.out) as tmp:
                    write_avatar_files(Path(tmp), avatars)
                print(avatars["md"])
                return 0
        rows, terms = evaluate_rings(scene, predictor, ps.manifest.streets[0].name, positions, rings=DEFAULT_RINGS,
                                     ctx=ctx, resolution=args.resolution, suns=suns, models=args.models)
        x = np.array(positions[0])
        sset = sphere_buffer(Ring(max(args.spheres, 1), 1.5, 0.45, 30.0).spheres(x)[: args.spheres])
        street = ps.manifest.streets[0].name

        def probes(d: np.ndarray, w: np.ndarray) -> np.ndarray:
            return predictor.predict("planes_mip", street, x, d.reshape(-1, 3), np.ravel(w), False).reshape(d.shape[:-1] + (3,))
        def light(d: np.ndarray, w: np.ndarray) -> np.ndarray:   # a sky-chain lookup, as a runtime makes it
            return predictor.sky_rgb(d.reshape(-1, 3), np.ravel(w), False)[:, :3].reshape(d.shape[:-1] + (3,))
        cost = {"numpy": numpy_cost(probes, light, x, sset)}
    finally:
        ctx.release()
    if args.gl_size > 0:
        cost["glsl"] = gl_cost(size=args.gl_size, spheres=args.spheres)
    by_hidden = summarize_by_coverage(rows, "sky_hidden")
    by_dome = summarize_by_coverage(rows, "coverage")
    variants = [f"{s}{'' if m is None else '+' + m}" for s in ("static", "oracle") for m in [None, *args.models]]
    goal = goal_check(by_hidden, ("static", "oracle"), args.models)
    result = {"scene": SCENE, "resolution": args.resolution, "probe_resolution": args.probe_resolution,
              "spacing_m": args.spacing, "positions": positions, "rings": [r.label for r in DEFAULT_RINGS],
              "models": {m: vars(MODELS[m]) for m in args.models}, "rows": rows, "terms": terms,
              "summary_sky_hidden": by_hidden, "summary_dome": by_dome, "goal": goal, "cost": cost,
              "total_s": time.perf_counter() - t_all}
    md = ("## Error by visible sky hidden (RMS of relative errors, %)\n\n" + markdown_table(by_hidden, variants)
          + "\n## Error by upper-hemisphere coverage (RMS of relative errors, %)\n\n" + markdown_table(by_dome, variants)
          + "\n## Goal: error with / without, where >= 10 % of the visible sky is hidden\n\n"
          + "| static | model | without (%) | with (%) | ratio |\n| --- | --- | --- | --- | --- |\n"
          + "".join(f"| {g['static']} | {g['model']} | {100 * g['err_without']:.1f} | {100 * g['err_with']:.1f} | "
                    f"{g['ratio']:.2f} |\n" for g in goal)
          + "\n## Cost per shading point (ratio to plain Eq. 3, same run)\n\n"
          + "| pass | spheres | variant | ratio | per point |\n| --- | --- | --- | --- | --- |\n"
          + "".join(f"| {k} | {c['spheres']} | {v} | {r:.2f} | "
                    + (f"{c['us_per_point'][v]:.2f} us" if k == "numpy" else f"{c['ns_per_point'][v]:.0f} ns") + " |\n"
                    for k, c in cost.items() for v, r in c["ratio_to_plain"].items()))
    with atomic_output_dir(args.out) as tmp:
        if args.avatars != "off":
            write_avatar_files(Path(tmp), avatars)
            md += "\n" + avatars["md"]
        (Path(tmp) / "dynamic_street.json").write_text(json.dumps(result, indent=1))
        (Path(tmp) / "dynamic_street.md").write_text(md)
        plot(rows, args.models, Path(tmp) / "dynamic_street.png")
    print(md)
    return 0
