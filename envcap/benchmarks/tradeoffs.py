"""tradeoffs: what accuracy costs - error vs time or memory for each knob (Pareto plot).

On a short street segment of each scene (default: 40 m of ``canyon`` and of ``asymmetric``), measured on this machine
in one run, every knob is varied with the others at a fixed reference setting:

* ``spacing`` (2.5, 5, 10, 20 m; probes 32^2; nearest, planes_mip, blend): error vs memory and
  bake time per 100 m of street;
* ``resolution`` (16, 32, 64, 128; spacing 5 m): error vs capture (+ prefilter) time per probe;
* ``quality`` (fast, default, high; 64^2, spacing 5 m): error vs prefilter time per probe;
* ``method`` (every :data:`envcap.runtime.methods.METHODS`; 32^2, spacing 5 m): error vs cost per lookup
  as a ratio to a plain lookup (``textureLod`` twin: one cube-array fetch at ``d``, level
  ``z(w)``), timed on the numpy twin in the same run (GLSL ratios: ``envcap bench runtime``).

Error: :func:`envcap.evaluate.run.evaluate_scene` (fresh captures, 32^2 truth, ``--positions``
positions, fixed seed), mean over positions and lobe powers (mirror, 256, 64, 16) of the
solid-angle weighted relative RMSE of luminance, sun taken out of the sky (an analytic sun light;
docs/evaluation.md explains why), method ``planes_mip`` unless the knob is the method.  Writes
``tradeoffs.json`` and ``tradeoffs.png`` to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from envcap.core import cube, cube_sampling
from envcap.evaluate.predict import Predictor
from envcap.evaluate.result import EvaluationResult, lobe_power_label
from envcap.evaluate.run import evaluate_scene
from envcap.evaluate.sweep import Sweep
from envcap.gpu.context import create_context
from envcap.outputs import atomic_output_dir
from envcap.probeset.bake import bake_probe_set
from envcap.runtime.methods import METHODS
from envcap.scene import load_scene
from envcap.scene.segment import street_segment

LOBES = (math.inf, 256.0, 64.0, 16.0)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", required=True, type=Path, help="output directory (written atomically)")
    parser.add_argument("--scenes", default="canyon,asymmetric",
                        help="bundled scenes, comma-separated (default canyon,asymmetric: planar facades / ragged low side with gaps)")
    parser.add_argument("--length", type=float, default=40.0, metavar="M", help="street segment length (default 40 m)")
    parser.add_argument("--positions", type=int, default=8, metavar="K", help="evaluation positions per street (default 8)")
    parser.add_argument("--spacings", default="2.5,5,10,20", help="probe spacings in m (default 2.5,5,10,20)")
    parser.add_argument("--resolutions", default="16,32,64,128", help="capture resolutions (default 16,32,64,128)")
    parser.add_argument("--repeats", type=int, default=7, help="timing repeats of the lookup costs (median)")


def _floats(text: str, what: str) -> list[float]:
    try:
        vals = [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise ValueError(f"{what}: expected comma-separated numbers, got {text!r}") from None
    if not vals or any(not (math.isfinite(v) and v > 0) for v in vals):
        raise ValueError(f"{what}: values must be positive, got {text!r}")
    return vals


def _probe_bytes(ps: Any) -> int:
    """Bytes of the probe textures as stored (RGBA16F levels) + the distance channel (float16)."""
    n = sum(int(np.prod(lv.shape)) * 2 for lv in ps.levels)
    if ps.distance is not None:
        n += int(np.prod(ps.distance.shape)) * 2
    return n


def _error(res: EvaluationResult, method: str) -> dict[str, float]:
    per = {lobe_power_label(lp): res.error(method, lp, sun=False) for lp in res.meta["lobe_powers"]}
    return {"error": float(np.mean(list(per.values()))), **{f"error_{k}": v for k, v in per.items()}}


def _lookup_costs(ps: Any, scene_street: str, repeats: int) -> dict[str, float]:
    """Seconds per lookup of each method on the numpy twin, and of a plain cube-array fetch."""
    pr = Predictor(ps)
    d = cube.texel_directions(32).reshape(-1, 3)
    rng = np.random.default_rng(0)
    w = np.exp(rng.uniform(0, 8, d.shape[0]))
    x = np.array(ps.manifest.streets[0].probes[0].position, float) + np.array([1.3, -0.7, 0.0])
    x[2 - pr.streets[scene_street].along] += 2.0
    layer = np.zeros(d.shape[0])
    out: dict[str, float] = {}

    def timed(fn: Any) -> float:
        ts = []
        for _ in range(max(1, repeats)):
            t0 = time.perf_counter()
            fn()
            ts.append(time.perf_counter() - t0)
        return float(np.median(ts)) / d.shape[0]

    out["plain"] = timed(lambda: cube_sampling.sample_cube_array(pr.chains.levels, d, layer, pr.chains.level(w)))
    for m in METHODS:
        out[m] = timed(lambda m=m: pr.predict(m, scene_street, x, d, w))
    return out


def _pareto(points: list[tuple[float, float]]) -> list[bool]:
    """True for points not dominated (lower cost and lower error) by another point."""
    flags = []
    for i, (c, e) in enumerate(points):
        flags.append(not any((c2 <= c and e2 <= e) and (c2 < c or e2 < e) for j, (c2, e2) in enumerate(points) if j != i))
    return flags


def run(args: argparse.Namespace) -> int:
    spacings = _floats(args.spacings, "--spacings")
    resolutions = [int(v) for v in _floats(args.resolutions, "--resolutions")]
    if args.positions < 1:
        raise ValueError(f"--positions must be >= 1, got {args.positions}")
    t_start = time.perf_counter()
    names = [t.strip() for t in args.scenes.split(",") if t.strip()]
    if not names:
        raise ValueError("--scenes: no scene given")
    sweep = Sweep(per_street=args.positions, seed=7)
    ctx = create_context()
    rows: list[dict[str, Any]] = []
    eval_kw = dict(sweep=sweep, lobe_powers=LOBES, resolution=32, ctx=ctx, materials=(), keep_worst=0,
                   floor_probes=0, sun_variants=(False,), progress=False)
    n_pos = 0
    try:
        for name in names:
            scene = street_segment(load_scene(name), args.length)
            street_len = sum(st.length for st in scene.streets)

            def bake(res: int, spacing: float, quality: str = "default") -> tuple[Any, float]:
                t0 = time.perf_counter()
                ps = bake_probe_set(scene, resolution=res, spacing=spacing, quality=quality, ctx=ctx, progress=False)
                return ps, time.perf_counter() - t0

            for sp in spacings:
                ps, tb = bake(32, sp)
                res = evaluate_scene(scene, ps, methods=("nearest", "planes_mip", "blend"), **eval_kw)
                for m in ("nearest", "planes_mip", "blend"):
                    rows.append({"scene": name, "knob": "spacing", "value": sp, "method": m, "probes": ps.layer_count,
                                 "memory_mb_per_100m": _probe_bytes(ps) / 1e6 * 100.0 / street_len,
                                 "bake_s_per_100m": tb * 100.0 / street_len, **_error(res, m)})
            for r in resolutions:
                ps, tb = bake(r, 5.0)
                res = evaluate_scene(scene, ps, methods=("planes_mip",), **eval_kw)
                t = ps.manifest.timings
                rows.append({"scene": name, "knob": "resolution", "value": r, "method": "planes_mip", "probes": ps.layer_count,
                             "capture_s_per_probe": t.capture_s / ps.layer_count,
                             "prefilter_s_per_probe": t.prefilter_s / ps.layer_count,
                             "bake_s_per_probe": tb / ps.layer_count,
                             "memory_mb_per_100m": _probe_bytes(ps) / 1e6 * 100.0 / street_len, **_error(res, "planes_mip")})
            for q in ("fast", "default", "high"):
                ps, tb = bake(64, 5.0, q)
                res = evaluate_scene(scene, ps, methods=("planes_mip",), **eval_kw)
                rows.append({"scene": name, "knob": "quality", "value": q, "method": "planes_mip", "probes": ps.layer_count,
                             "prefilter_s_per_probe": ps.manifest.timings.prefilter_s / ps.layer_count,
                             **_error(res, "planes_mip")})
            ps, _ = bake(32, 5.0)
            res = evaluate_scene(scene, ps, methods=METHODS, **eval_kw)
            n_pos = len(res.positions)
            costs = _lookup_costs(ps, scene.streets[0].name, args.repeats)
            for m in METHODS:
                rows.append({"scene": name, "knob": "method", "value": m, "method": m, "lookup_us": costs[m] * 1e6,
                             "cost_ratio": costs[m] / costs["plain"], **_error(res, m)})
    finally:
        ctx.release()
    total = time.perf_counter() - t_start
    doc = {"benchmark": "tradeoffs", "scenes": names, "street_length_m": args.length, "positions_per_street": n_pos,
           "lobe_powers": ["mirror" if math.isinf(w) else w for w in LOBES], "truth_resolution": 32,
           "error": "mean rel. RMSE of luminance over positions and lobe powers, sun out of the sky",
           "lookup_timing": "numpy twin (envcap.runtime.methods via envcap.evaluate.predict.Predictor), 6144 directions, median of repeats; "
                            "plain = one cube-array fetch at d, z(w)",
           "rows": rows, "total_s": total}
    with atomic_output_dir(args.out) as tmp:
        (tmp / "tradeoffs.json").write_text(json.dumps(doc, indent=1) + "\n")
        _plot(rows, tmp / "tradeoffs.png")
    for r in rows:
        cost = {"spacing": "memory_mb_per_100m", "resolution": "capture_s_per_probe", "quality": "prefilter_s_per_probe",
                "method": "cost_ratio"}[r["knob"]]
        cost = "bake_s_per_probe" if r["knob"] == "resolution" else cost
        print(f"{r['scene']:>10} {r['knob']:>10} {str(r['value']):>18} {r['method']:>18}  error {r['error']:.4f}  "
              f"{cost} {r[cost]:.4g}")
    print(f"total {total:.1f} s; wrote {Path(args.out) / 'tradeoffs.json'} and tradeoffs.png")
    return 0


def _plot(rows: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    panels = [("spacing", "memory_mb_per_100m", "probe memory per 100 m of street (MB, RGBA16F + depth)", "{:g} m"),
              ("resolution", "bake_s_per_probe", "capture + prefilter time per probe (s)", "{}²"),
              ("quality", "prefilter_s_per_probe", "prefilter time per probe (s, 64²)", "{}"),
              ("method", "cost_ratio", "cost per lookup / plain lookup (numpy twin)", "{}")]
    fig, axes = plt.subplots(1, 4, figsize=(20, 4.6), dpi=100)
    for ax, (knob, cost, xlabel, fmt) in zip(axes, panels):
        rr = [r for r in rows if r["knob"] == knob]
        groups = sorted({(r["scene"], r["method"]) for r in rr}) if knob != "method" else sorted({(r["scene"], None) for r in rr})
        for gi, (sc, m) in enumerate(groups):
            sub = [r for r in rr if r["scene"] == sc and (m is None or r["method"] == m)]
            pts = [(r[cost], r["error"]) for r in sub]
            front = _pareto(pts)
            if knob == "method":
                ax.plot([p[0] for p in pts], [p[1] for p in pts], "s^o"[gi % 3], ms=6, ls="none", label=sc)
            else:
                ax.plot([p[0] for p in pts], [p[1] for p in pts], "-o", ms=5, label=f"{sc}: {m}")
            for r, (c, e), f in zip(sub, pts, front):
                ax.annotate(fmt.format(r["value"]) + ("" if f else " (dominated)"), (c, e), fontsize=6,
                            xytext=(4, 4), textcoords="offset points")
        ax.legend(fontsize=6)
        ax.set_xscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("mean relative RMSE (no sun)")
        ax.set_title(knob)
        ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
