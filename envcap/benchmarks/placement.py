"""placement: error vs probe count of each placement strategy (the Pareto curve), and what placing costs.

For each scene (``--scenes``, default the bundled ``canyon``, ``asymmetric``, ``crossing`` and the
generated city ``generated_city``) ``--length`` m of every street are cut around its middle
(:func:`envcap.scene.segment.street_segment`, default 60).  Each strategy (``--strategies``,
default every registered one: ``uniform``, ``density``, ``min_error``) places ``--counts`` probes
per street (default 3,6,12), all counts from one analysis per street (its wall time is the cost
of placing); each placement is baked (``--resolution``, 64^2, ``quality="composed"`` as ``envcap
capture``) and evaluated by :func:`envcap.evaluate.run.evaluate_scene` on the *same* positions for
every strategy and count: ``--positions`` per street drawn like the default sweep over the whole
street (``--seed``, default 5, the evaluator's; ``min_error`` trains on seed 101; each position is
evaluated on the street it was drawn on, as ``envcap evaluate`` does), truth at 64^2, the methods
``--methods`` (default ``nearest``, ``blend``, ``depth_refine``) at ``--powers`` (64, 256), sun
out of the sky (docs/evaluation.md).

Writes to ``--out``: ``placement.json`` (every number, the placements, the costs),
``placement.csv`` (one row per scene, strategy, count, method, power: mean error and its ratio to
uniform's), ``placement_pareto.png`` (error vs probes per street, one panel per scene and the
mean) and ``placement_street.png`` (``--figure-street``'s probes as each strategy placed them,
the measured error rate and the error at each position).  Prints the table and the goal line:
the mean over scenes and powers of each strategy's error over uniform's at equal count
(``--goal-method``, default ``depth_refine``).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from envcap.benchmarks.placement_plot import pareto_figure, street_figure
from envcap.evaluate.run import evaluate_scene
from envcap.evaluate.sweep import Sweep
from envcap.gpu.context import create_context
from envcap.outputs import atomic_output_dir
from envcap.placement import get, registered
from envcap.placement.place import plain_json
from envcap.placement.registry import PlacementContext
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.placement_table import PlacementTable
from envcap.runtime import methods as runtime_methods
from envcap.scene import load_scene
from envcap.scene.segment import street_segment

SCENES = ("canyon", "asymmetric", "crossing", "generated_city")


def _names(text: str) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", required=True, type=Path, help="output directory (written atomically)")
    parser.add_argument("--scenes", default=",".join(SCENES), help=f"scenes, comma-separated (default {','.join(SCENES)})")
    parser.add_argument("--strategies", default=None, help="placement strategies, comma-separated (default: all registered)")
    parser.add_argument("--counts", default="3,6,12", help="probes per street, comma-separated (default 3,6,12)")
    parser.add_argument("--length", type=float, default=60.0, metavar="M", help="meters of every street (default 60)")
    parser.add_argument("--positions", type=int, default=16, metavar="K", help="evaluation positions per street (default 16)")
    parser.add_argument("--seed", type=int, default=5, help="seed of the evaluation positions (default 5, the evaluator's)")
    parser.add_argument("--resolution", type=int, default=64, metavar="N", help="face size of the bakes (default 64)")
    parser.add_argument("--methods", default="nearest,blend,depth_refine", help="parallax methods (default nearest,blend,depth_refine)")
    parser.add_argument("--powers", default="64,256", help="lobe powers (default 64,256)")
    parser.add_argument("--goal-method", default="depth_refine", help="method of the goal line (default depth_refine)")
    parser.add_argument("--set", action="append", default=[], metavar="STRATEGY.KEY=VALUE",
                        help="a strategy's parameter (JSON value), e.g. min_error.points_per_m=1.0; repeatable")
    parser.add_argument("--figure-street", default="crossing:east_west", metavar="SCENE:STREET",
                        help="the street of placement_street.png (default crossing:east_west)")


def check_args(args: argparse.Namespace) -> dict[str, Any]:
    """The checked options (``ValueError``, one line, before any work)."""
    counts = []
    for v in _names(args.counts):
        if not v.isdigit() or int(v) < 1:
            raise ValueError(f"--counts must be whole numbers >= 1, got {v!r}")
        counts.append(int(v))
    powers = [float(v) for v in _names(args.powers)]
    if not counts or not powers or any(not (w > 0 and math.isfinite(w)) for w in powers):
        raise ValueError("--counts and --powers must be non-empty; powers positive finite numbers")
    if args.positions < 1 or args.resolution < 1 or not (math.isfinite(args.length) and args.length > 0) or args.seed < 0:
        raise ValueError("--positions and --resolution must be >= 1, --length a positive number of meters, --seed >= 0")
    strategies = _names(args.strategies) if args.strategies else list(registered())
    for s in strategies:
        get(s)                                   # unknown: the known names
    if "uniform" not in strategies:
        raise ValueError("--strategies must include uniform (every ratio is against it)")
    meths = _names(args.methods)
    for m in meths + [args.goal_method]:
        runtime_methods.get(m)
    if args.goal_method not in meths:
        raise ValueError(f"--goal-method {args.goal_method} must be one of --methods")
    scene, _, street = args.figure_street.partition(":")
    params: dict[str, dict[str, Any]] = {s: {} for s in strategies}
    for item in args.set:
        key, eq, text = item.partition("=")
        strat, dot, name = key.partition(".")
        if not (eq and dot and strat in params):
            raise ValueError(f"--set must be STRATEGY.KEY=VALUE for one of --strategies, got {item!r}")
        try:
            params[strat][name] = json.loads(text)
        except json.JSONDecodeError:
            params[strat][name] = text
        get(strat).settings(params[strat])        # unknown parameter: the known ones
    return {"params": params, "counts": sorted(set(counts)), "powers": powers, "strategies": strategies, "methods": meths,
            "scenes": _names(args.scenes), "figure": (scene, street)}


def place_all(scene: Any, strategies: list[str], counts: list[int], resolution: int, ctx: Any,
              params: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """``{strategy: {"seconds": s, "along": {count: {street: [m, ...]}}, "notes": {count: {street: notes}},
    "parameters": {...}}}``, each strategy with its ``params``."""
    out: dict[str, Any] = {}
    context = PlacementContext(scene, 2.0, resolution, ctx)
    for name in strategies:
        strat = get(name)
        t0 = time.perf_counter()
        along: dict[int, dict[str, list[float]]] = {n: {} for n in counts}
        notes: dict[int, dict[str, Any]] = {n: {} for n in counts}
        for st in scene.streets:
            for n, placed in zip(counts, strat(context, st, counts, **params[name])):
                along[n][st.name] = [float(v) for v in placed.along]
                notes[n][st.name] = plain_json(placed.notes)
        out[name] = {"seconds": time.perf_counter() - t0, "along": along, "notes": notes,
                     "parameters": plain_json(strat.settings(params[name]))}
        print(f"{scene.name}: placed by {name} in {out[name]['seconds']:.1f} s", flush=True)
    return out


def run(args: argparse.Namespace) -> int:
    opts = check_args(args)
    counts, powers, strategies, meths = opts["counts"], opts["powers"], opts["strategies"], opts["methods"]
    t_all = time.perf_counter()
    ctx = create_context()
    rows: list[dict[str, Any]] = []
    scenes: dict[str, Any] = {}
    figure: dict[str, Any] | None = None
    try:
        for name in opts["scenes"]:
            scene = street_segment(load_scene(name), args.length)
            placed = place_all(scene, strategies, counts, args.resolution, ctx, opts["params"])
            sweep = Sweep(per_street=args.positions, seed=args.seed)
            for n in counts:
                for strat in strategies:
                    table = PlacementTable(strat, n, {}, round(placed[strat]["seconds"], 3), {})
                    ps = bake_probe_set(scene, resolution=args.resolution, quality="composed", ctx=ctx,
                                        along=placed[strat]["along"][n], placement=table, progress=False)
                    # a placed set's sweep covers each whole street: the same positions (and streets) for every placement
                    res = evaluate_scene(scene, ps, sweep=sweep, methods=meths, lobe_powers=powers, resolution=64,
                                         ctx=ctx, materials=(), keep_worst=0, floor_probes=0, sun_variants=(False,),
                                         progress=False)
                    for m in meths:
                        for w in powers:
                            each = [r["rel_rmse"] for r in sorted(res.rows, key=lambda r: r["position_index"])
                                    if r["method"] == m and r["lobe_power"] == w]
                            rows.append({"scene": name, "strategy": strat, "count": n, "method": m, "power": w,
                                         "error": res.error(m, w, sun=False), "per_position": each})
                    if name == opts["figure"][0]:
                        figure = figure or {"scene": scene, "street": opts["figure"][1], "placed": placed, "errors": {}}
                        figure["errors"][(n, strat)] = [(r["position"], r["rel_rmse"]) for r in res.rows
                                                        if r["street"] == opts["figure"][1] and r["method"] == args.goal_method
                                                        and r["lobe_power"] == powers[0]]
                    print(f"{name} n={n} {strat}: " + " ".join(
                        f"{m} {res.error(m, powers[0], sun=False):.4f}/{res.error(m, powers[-1], sun=False):.4f}" for m in meths),
                        flush=True)
            scenes[name] = {"streets": [st.name for st in scene.streets], "placed": placed,
                            "positions_per_street": args.positions}
    finally:
        ctx.release()
    for r in rows:      # the ratio to uniform, and its 95 % interval from the paired per-position differences
        base = next(u for u in rows if u["scene"] == r["scene"] and u["strategy"] == "uniform"
                    and u["count"] == r["count"] and u["method"] == r["method"] and u["power"] == r["power"])
        diff = np.asarray(r["per_position"]) - np.asarray(base["per_position"])
        half = 1.96 * float(np.std(diff, ddof=1)) / math.sqrt(diff.size) if diff.size > 1 else math.inf
        r["ratio_to_uniform"] = r["error"] / base["error"]
        r["ratio_ci95"] = half / base["error"]
    per_position = [r.pop("per_position") for r in rows]
    goal = {s: float(np.mean([r["ratio_to_uniform"] for r in rows if r["strategy"] == s and r["method"] == args.goal_method]))
            for s in strategies}
    goal_by_count = {s: {n: float(np.mean([r["ratio_to_uniform"] for r in rows if r["strategy"] == s and r["count"] == n
                                           and r["method"] == args.goal_method])) for n in counts} for s in strategies}
    doc = {"benchmark": "placement", "error": "mean rel. RMSE of luminance, sun out of the sky", "counts": counts,
           "powers": powers, "methods": meths, "strategies": strategies, "length_m": args.length,
           "resolution": args.resolution, "positions_per_street": args.positions, "goal_method": args.goal_method,
           "goal_ratio": goal, "goal_ratio_by_count": goal_by_count, "floor_ratio": floor_ratio(scenes, counts), "rows": rows,
           "per_position": per_position, "seed": args.seed,
           "scenes": {k: {**v, "placed": {s: {**p, "along": {str(n): a for n, a in p["along"].items()},
                                               "notes": {str(n): a for n, a in p["notes"].items()}}
                                          for s, p in v["placed"].items()}} for k, v in scenes.items()},
           "total_s": time.perf_counter() - t_all}
    with atomic_output_dir(args.out) as tmp:
        (Path(tmp) / "placement.json").write_text(json.dumps(doc, indent=1) + "\n")
        with open(Path(tmp) / "placement.csv", "w", newline="") as f:
            wr = csv.DictWriter(f, fieldnames=list(rows[0]))
            wr.writeheader()
            wr.writerows(rows)
        pareto_figure(rows, Path(tmp) / "placement_pareto.png", args.goal_method, doc["scenes"])
        if figure is not None:
            street_figure(figure, Path(tmp) / "placement_street.png", args.goal_method, powers[0])
    _print_table(rows, strategies, counts, powers, args.goal_method, scenes)
    print("goal (mean over scenes and powers of error / uniform's, " + args.goal_method + "): "
          + ", ".join(f"{s} {goal[s]:.3f} ({' / '.join(f'{goal_by_count[s][n]:.3f}' for n in counts)} at "
                      f"{'/'.join(str(n) for n in counts)})" for s in strategies if s != "uniform")
          + "; the goal is <= 0.70")
    if doc["floor_ratio"]:
        print("floor on min_error's training points (each served by its best candidate) / uniform's: " + ", ".join(
            f"{name} {' / '.join(f'{v:.3f}' for v in by.values())}" for name, by in doc["floor_ratio"].items())
              + f" at {'/'.join(str(n) for n in counts)} probes per street")
    print(f"total {doc['total_s']:.0f} s; wrote {Path(args.out)}")
    return 0


def floor_ratio(scenes: dict[str, Any], counts: list[int]) -> dict[str, dict[int, float]]:
    """Per scene and count, the mean over streets of ``min_error``'s floor on its training points
    (each point served by its best candidate) over uniform's training error: how much of the
    error any placement on the probe line could remove at all (empty without ``min_error``)."""
    out: dict[str, dict[int, float]] = {}
    for name, v in scenes.items():
        notes = v["placed"].get("min_error", {}).get("notes", {})
        by = {n: [s["floor_training_error"] / s["uniform_training_error"] for s in notes.get(n, {}).values()
                  if s.get("floor_training_error") and s.get("uniform_training_error")] for n in counts}
        if all(by.values()):
            out[name] = {n: float(np.mean(r)) for n, r in by.items()}
    return out


def _print_table(rows: list[dict[str, Any]], strategies: list[str], counts: list[int], powers: list[float],
                 method: str, scenes: dict[str, Any]) -> None:
    """Error of ``method`` per scene, count and power, each strategy's beside uniform's, and the cost."""
    print(f"{method}: error per scene, probes per street, power (ratio to uniform ± its 95 % interval from the "
          "paired per-position differences); placing cost in s")
    for name in scenes:
        cost = ", ".join(f"{s} {scenes[name]['placed'][s]['seconds']:.0f} s" for s in strategies)
        print(f"  {name} ({cost})")
        for n in counts:
            for w in powers:
                e = {r["strategy"]: r for r in rows if r["scene"] == name and r["count"] == n and r["power"] == w
                     and r["method"] == method}
                print(f"    n={n:>3} w={w:>5g}: " + "  ".join(
                    f"{s} {e[s]['error']:.4f}" + ("" if s == "uniform" else
                                                  f" ({e[s]['ratio_to_uniform']:.3f} ± {e[s]['ratio_ci95']:.3f})")
                    for s in strategies))
