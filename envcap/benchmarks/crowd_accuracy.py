"""crowd_accuracy: the lit crowd per term, per material and per crowd density, against fresh captures.

The bundled ``canyon`` is baked (``--probe-resolution``, ``--spacing``); at ``--sites`` sites on
its street (at the middle probe, then half a spacing along and 2 m across either way) walkers are
placed at each ``--densities`` (walkers per m^2 within 4 m:
:mod:`envcap.evaluate.crowd_placement`) around a host walker, and Eq. 3 shading of the evaluator's
materials at points on the host (``self``) and among the crowd (``free``) is compared with fresh
captures with the posed crowd: the probes alone, ``+self`` (the host's own blocker bones),
``+self+neighbours`` / ``+neighbours`` (every other walker's spheres by the crowd LOD rule), and the
same with a crowd-free capture as the static part (``oracle``)
(:mod:`envcap.evaluate.crowd_accuracy`).  ``--configs``: the runtime's choices (sphere cap, union
rule, the self spheres' scale and clamp, :class:`envcap.evaluate.crowd_accuracy.TermConfig`), the
first for every term, the others for the last; default :data:`DEFAULT_CONFIGS`.

Writes ``crowd_accuracy.json`` (rows, summary, goal lines), ``crowd_accuracy.md`` (tables, PASS /
FAIL lines) and ``crowd_accuracy.png`` (error against density per term, one panel per material)
to ``--out``, and prints the goal lines.  ``--quick``: a small run for tests (8^2 probes, 16^2
captures, two densities, one site, one point of each kind).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from envcap.core.street_frame import frame_to_world, world_to_frame
from envcap.dynamic.spheres import COMBINE_RULES
from envcap.evaluate.crowd_accuracy import (
    STATICS,
    TERMS,
    TermConfig,
    evaluate_crowd_accuracy,
    goal_lines,
    summarize,
    summary_table,
)
from envcap.evaluate.crowd_placement import DENSITIES, check_density, street_inside
from envcap.evaluate.shading import MATERIALS
from envcap.evaluate.sweep import StreetExtent
from envcap.gpu.context import create_context
from envcap.outputs import atomic_output_dir
from envcap.probeset.bake import bake_probe_set
from envcap.scene import load_scene

SCENE = "canyon"
SITE_OFFSETS = ((0.0, 0.0), (0.5, 2.0), (0.25, -2.0), (0.75, 0.0))
"""Sites: (fraction of the probe spacing along, m across) from the street's middle probe."""
DEFAULT_CONFIGS = ("8:rings", "8:rings:1:0.7")
"""The runtime's terms (cap 8, the rings union), and the same with the self spheres' radii at
most 0.7 times their distance from the point."""


def parse_config(text: str) -> TermConfig:
    """``CAP[:RULE[:SCALE[:CLAMP[:EXCLUDE]]]]`` (``CAP`` 0: every sphere) as a :class:`TermConfig`;
    ``ValueError`` naming the problem otherwise."""
    parts = text.split(":")
    try:
        if len(parts) > 5:
            raise ValueError
        cap = int(parts[0])
        rule = parts[1] if len(parts) > 1 and parts[1] else TermConfig.rule
        scale = float(parts[2]) if len(parts) > 2 and parts[2] else 1.0
        clamp = float(parts[3]) if len(parts) > 3 and parts[3] else 0.0
        exclude = float(parts[4]) if len(parts) > 4 and parts[4] else 0.0
    except ValueError:
        raise ValueError(f"--configs entry {text!r} must be CAP[:RULE[:SCALE[:CLAMP[:EXCLUDE]]]], e.g. 16:rings:1:0.7") from None
    if rule not in COMBINE_RULES:
        raise ValueError(f"--configs entry {text!r}: rule must be one of {', '.join(COMBINE_RULES)}")
    return TermConfig(cap, rule, scale, clamp, exclude)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (JSON, Markdown, PNG)")
    p.add_argument("--densities", type=float, nargs="+", default=list(DENSITIES),
                   help="crowd densities, walkers per m^2 (default 0.05 0.2 0.5 1)")
    p.add_argument("--sites", type=int, default=4, help=f"evaluation sites, 1-{len(SITE_OFFSETS)} (default 4)")
    p.add_argument("--self-points", type=int, default=5, help="points on the host walker per site (default 5)")
    p.add_argument("--free-points", type=int, default=2, help="points among the crowd per site (default 2)")
    p.add_argument("--configs", nargs="+", default=list(DEFAULT_CONFIGS),
                   help="term configurations CAP[:RULE[:SCALE[:CLAMP[:EXCLUDE]]]]: the sphere cap (0: every sphere), "
                        "the union rule, a factor on the self spheres' radii, those radii at most CLAMP x their "
                        "distance (0: no clamp), the self blockers' exclude weight; the first the main one, the others "
                        "measured for the last term (default: %(default)s, the runtime's and the self spheres clamped)")
    p.add_argument("--seed", type=int, default=0, help="placement seed (site i uses seed + i)")
    p.add_argument("--resolution", type=int, default=32, help="face size of the fresh captures (default 32)")
    p.add_argument("--probe-resolution", type=int, default=32, help="face size of the baked probes (default 32)")
    p.add_argument("--spacing", type=float, default=20.0, help="probe spacing in m (default 20)")
    p.add_argument("--quick", action="store_true", help="a small run (tests)")


def site_centers(manifest: Any, count: int, spacing: float) -> list[list[float]]:
    """``count`` site centres (world m, on the ground) of :data:`SITE_OFFSETS` from the middle
    probe of the first street."""
    st = manifest.streets[0]
    extent = StreetExtent.from_manifest(st)
    yaw, oxz = st.frame_yaw_deg, st.frame_origin_xz
    probe = world_to_frame(st.probes[len(st.probes) // 2].position, yaw, oxz)
    out = []
    for fa, dc in SITE_OFFSETS[:count]:
        p = probe.copy()
        p[extent.along] += fa * spacing
        p[extent.cross] += dc
        p[1] = extent.ground_at(float(p[extent.along]))
        out.append([float(v) for v in frame_to_world(p, yaw, oxz)])
    return out


def plot(summary: Sequence[dict[str, Any]], configs: Sequence[str], path: Path) -> None:
    """Error (%) against density, one panel per material, one line per kind x term of the first of
    ``configs`` and per other configuration the self points' last term (solid: probes as the
    static part, dotted: oracle)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    mats = list(dict.fromkeys(s["material"] for s in summary))
    fig, axes = plt.subplots(1, len(mats), figsize=(4.2 * len(mats), 3.8), sharey=True, squeeze=False)
    lines = [("self", "probes", configs[0], "0.3"), ("self", "+self", configs[0], "tab:orange"),
             ("self", "+self+neighbours", configs[0], "tab:red"), ("free", "probes", configs[0], "0.6"),
             ("free", "+neighbours", configs[0], "tab:blue")]
    lines += [("self", "+self+neighbours", c, color) for c, color in zip(configs[1:], ("tab:purple", "tab:green", "tab:brown"))]
    for ax, mat in zip(axes[0], mats):
        for kind, term, config, color in lines:
            for static, style in (("probes", "-"), ("oracle", ":")):
                pts = sorted((s["density"], 100 * s["rms"]) for s in summary if s["material"] == mat and s["kind"] == kind
                             and s["term"] == term and s["static"] == static and (s["config"] == config or term == "probes"))
                label = f"{kind}: {term}" + (f" ({config})" if config != configs[0] else "")
                if pts:
                    ax.plot(*zip(*pts), style, marker="o", ms=3, color=color, label=label if static == "probes" else None)
        ax.set_title(mat)
        ax.set_xlabel("crowd density (walkers / m²)")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("Eq. 3 error vs fresh capture (%, RMS over points)")
    axes[0][-1].legend(fontsize=6, loc="upper right")
    fig.suptitle(f"canyon: the lit crowd per term and density ({configs[0]}; solid: probes, dotted: oracle as the "
                 "static part)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(args: argparse.Namespace) -> int:
    if args.quick:
        args.densities, args.sites, args.self_points, args.free_points = [0.0, 0.5], 1, 1, 1
        args.resolution, args.probe_resolution, args.spacing = 16, 8, 100.0
        args.configs = args.configs[:1]
    configs = [parse_config(c) for c in args.configs]
    args.densities = [check_density(d) for d in args.densities]
    if not 1 <= args.sites <= len(SITE_OFFSETS) or args.resolution < 8 or args.probe_resolution < 8 \
            or not args.spacing > 0 or args.self_points < 0 or args.free_points < 0 \
            or args.self_points + args.free_points < 1 or not args.densities:
        raise ValueError(f"--sites must be 1-{len(SITE_OFFSETS)}, --resolution and --probe-resolution >= 8, --spacing > 0, "
                         "--self-points and --free-points >= 0 (not both 0), at least one density")
    t0 = time.perf_counter()
    scene = load_scene(SCENE)
    ctx = create_context()
    try:
        ps = bake_probe_set(scene, resolution=args.probe_resolution, spacing=args.spacing, ctx=ctx, progress=False)
        from envcap.evaluate.predict import Predictor

        predictor = Predictor(ps, sky=scene.sky.build(), ctx=ctx)
        street = ps.manifest.streets[0].name
        extent = StreetExtent.from_manifest(ps.manifest.streets[0])
        centers = site_centers(ps.manifest, args.sites, args.spacing)
        rows = evaluate_crowd_accuracy(scene, predictor, street, centers, ctx=ctx, densities=args.densities,
                                       resolution=args.resolution, seed=args.seed, self_count=args.self_points,
                                       free_count=args.free_points, configs=configs, inside=street_inside(extent))
    finally:
        ctx.release()
    summary = summarize(rows)
    main = configs[0].label
    mats = [m.name for m in MATERIALS]
    goals = [line for cfg in configs for st in STATICS for line in goal_lines(summary, cfg.label, st)]
    md = f"# crowd_accuracy ({SCENE}; {main})\n\n"
    for static in STATICS:
        md += (f"## Error per density, term and material, static part `{static}` (RMS over points, %; ratio to "
               f"`{static}` alone)\n\n" + summary_table(summary, main, static, mats) + "\n")
    if len(configs) > 1:
        md += "## Every term, per configuration (RMS over points, %; ratio)\n\n"
        for cfg in configs:
            md += f"### {cfg.label}\n\n" + summary_table(
                [s for s in summary if s["term"] in ("probes",) + tuple(t[-1] for t in TERMS.values())],
                cfg.label, "probes", mats) + "\n"
    md += "## Goal (every term <= 0.5x the static part alone)\n\n```\n" + "\n".join(goals) + "\n```\n"
    result = {"scene": SCENE, "densities": list(args.densities), "sites": centers, "configs": [c.label for c in configs],
              "resolution": args.resolution, "probe_resolution": args.probe_resolution, "spacing": args.spacing,
              "seed": args.seed, "rows": rows, "summary": summary, "goal": goals, "total_s": time.perf_counter() - t0}
    with atomic_output_dir(args.out) as tmp:
        (Path(tmp) / "crowd_accuracy.json").write_text(json.dumps(result, indent=1))
        (Path(tmp) / "crowd_accuracy.md").write_text(md)
        plot(summary, [c.label for c in configs], Path(tmp) / "crowd_accuracy.png")
    print("\n".join(goals))
    print(f"crowd_accuracy: {len(rows)} rows in {time.perf_counter() - t0:.0f} s -> {getattr(args.out, 'path', args.out)}")
    return 0
