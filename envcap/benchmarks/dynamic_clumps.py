"""Tight clumps of spheres: the union of their caps by the overlap rule and by the rings rule against
float64 quadrature, and what the rings cost (numpy and GLSL).

    envcap bench dynamic_clumps --out DIR [--clumps 100] [--gl-size 256] [--nodes 8]

**Family** (:func:`clump`, seeded): 2-8 spheres of radius 0.2-0.35 m whose centers lie within
0.25 m of the clump's center (so within 0.5 m of each other), the clump's center 1-3 m from the
shading point (the origin) in a random direction; the lobe aimed at the clump (its axis within the
clump's angular radius ``atan(0.25 m / distance)`` of the center, uniform in the disk), each clump
at every power of ``POWERS``.  Two named cases (:func:`named_cases`): two spheres of radius 0.28 m
at ``(1.5, +-0.175, 0)`` m, lobe ``+x``, ``w = 100`` (issue 21); a stacked body column, five spheres
of radius 0.25 m 0.3 m apart (centers ``(2, -0.6..0.6, 0)`` m), lobe ``+x``, ``w = 100``.

**Error**: ``|U - U_true|`` of the lobe's blocked fraction (fractions of the lobe's light), ``U`` from
the runtime's per-sphere fractions (envcap's form, :func:`envcap.dynamic.cap_lobe.occlusion`) and
:func:`envcap.dynamic.spheres.combine` per rule, ``U_true`` from
:func:`envcap.dynamic.quadrature.union_lobe_fraction` (float64, exact arcs on 32768 rings).

**Cost**: numpy, :func:`envcap.dynamic.terms.dynamic_terms` for a two-lobe material at points
around a clump, per rule, against the ``"overlap"`` rule in the same run; GLSL (llvmpipe here: a
CPU rasterizer), ``envcap_sphere_shares`` alone for one lobe aimed at a clump of 8 spheres (every
slot live: the rule's worst case) per ``ENVCAP_DYNAMIC_COMBINE`` (``sum``: the per-sphere
fractions and nothing more), and the full-screen pass of
:func:`envcap.benchmarks.dynamic_street_cost.gl_cost` (Eq. 3 + ``envcap_dynamic_terms``, 8 spheres
per point) with the overlap and the rings rule, as multiples of a plain Eq. 3.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.dynamic.cap_lobe import occlusion
from envcap.dynamic.quadrature import union_lobe_fraction
from envcap.dynamic.spheres import SphereBuffer, combine, select_spheres
from envcap.dynamic.terms import dynamic_terms
from envcap.dynamic.union import UNION_NODES
from envcap.outputs import atomic_output_dir
from envcap.runtime.lafortune import Lafortune

POWERS = (1.0, 10.0, 100.0, 1000.0)
RULES = ("overlap", "rings", "independent")
SEED = 21
CLUMP_SPREAD = 0.25
"""Sphere centers lie within this distance (m) of the clump's center."""


def clump(rng: np.random.Generator) -> tuple[SphereBuffer, NDArray[np.float64]]:
    """One tight clump around the origin and a unit lobe axis aimed at it (module docstring)."""
    n = int(rng.integers(2, 9))
    d = rng.normal(size=3)
    d /= np.linalg.norm(d)
    dist = rng.uniform(1.0, 3.0)
    off = rng.normal(size=(n, 3))
    off *= CLUMP_SPREAD * rng.uniform(0, 1, (n, 1)) ** (1 / 3) / np.linalg.norm(off, axis=1, keepdims=True)
    r = rng.uniform(0.2, 0.35, n)
    p = rng.normal(size=3)
    p -= (p @ d) * d
    p /= np.linalg.norm(p)
    a = math.atan(CLUMP_SPREAD / dist) * math.sqrt(rng.uniform())
    return SphereBuffer(d * dist + off, r, np.full((n, 3), 0.5)), math.cos(a) * d + math.sin(a) * p


def named_cases() -> list[tuple[str, SphereBuffer, NDArray[np.float64], float]]:
    """``(name, spheres, lobe axis, w)`` of the two named cases (module docstring)."""
    x = np.array([1.0, 0.0, 0.0])
    pair = SphereBuffer([[1.5, 0.175, 0.0], [1.5, -0.175, 0.0]], [0.28, 0.28], np.full((2, 3), 0.5))
    ys = 0.3 * (np.arange(5) - 2)
    column = SphereBuffer(np.c_[np.full(5, 2.0), ys, np.zeros(5)], np.full(5, 0.25), np.full((5, 3), 0.5))
    return [("two spheres r 0.28 m at (1.5, ±0.175, 0) m, w 100", pair, x, 100.0),
            ("body column: 5 spheres r 0.25 m, 0.3 m apart, 2 m away, w 100", column, x, 100.0)]


def runtime_union(sb: SphereBuffer, C: NDArray, w: float, rule: str, nodes: int = UNION_NODES) -> float:
    """The runtime's blocked fraction of the lobe ``(C, w)`` at the origin by ``rule``."""
    sel = select_spheres(np.zeros(3), sb)
    f = np.where(sel.index >= 0, occlusion(sel.D, C, sel.t, w).integral * (1 + w) / (2 * np.pi), 0.0)
    return float(combine(f, rule, sel.overlap, lobe=(sel.D, sel.t, C, w), nodes=nodes)[0])  # type: ignore[arg-type]


def true_union(sb: SphereBuffer, C: NDArray, w: float) -> float:
    """Float64 reference: :func:`envcap.dynamic.quadrature.union_lobe_fraction` over all spheres."""
    ell = np.linalg.norm(sb.centers, axis=1)
    return union_lobe_fraction(sb.centers / ell[:, None], np.arcsin(sb.radii / ell), C, w)


def stats(errs: list[float]) -> dict[str, float]:
    e = np.asarray(errs)
    return {"mean": float(e.mean()), "p95": float(np.percentile(e, 95)), "max": float(e.max())}


def clump_errors(count: int = 100, seed: int = SEED, nodes: int = UNION_NODES) -> dict[str, Any]:
    """Per power and over all: mean / p95 / max ``|U - U_true|`` per rule of :data:`RULES`; and
    the named cases."""
    rng = np.random.default_rng(seed)
    per: dict[float, dict[str, list[float]]] = {w: {r: [] for r in RULES} | {"truth": []} for w in POWERS}
    for _ in range(count):
        sb, C = clump(rng)
        for w in POWERS:
            truth = true_union(sb, C, w)
            per[w]["truth"].append(truth)
            for rule in RULES:
                per[w][rule].append(abs(runtime_union(sb, C, w, rule, nodes) - truth))
    rows = [{"w": w, "mean_U_true": float(np.mean(v["truth"])), **{r: stats(v[r]) for r in RULES}}
            for w, v in per.items()]
    rows.append({"w": "all", "mean_U_true": float(np.mean([t for v in per.values() for t in v["truth"]])),
                 **{r: stats([e for v in per.values() for e in v[r]]) for r in RULES}})
    named = []
    for name, sb, C, w in named_cases():
        truth = true_union(sb, C, w)
        named.append({"case": name, "U_true": truth, **{r: runtime_union(sb, C, w, r, nodes) for r in RULES}})
    return {"count": count, "seed": seed, "nodes": nodes, "rows": rows, "named": named}


def numpy_cost(points: int = 2048, repeats: int = 5, seed: int = SEED) -> dict[str, Any]:
    """Median seconds of :func:`envcap.dynamic.terms.dynamic_terms` (two lobes, 8 spheres of a
    clump around every point) per rule, and ratios to ``"overlap"``."""
    rng = np.random.default_rng(seed)
    sb = SphereBuffer(rng.normal(size=(8, 3)) * 0.25 + (2.0, 0.0, 0.0), rng.uniform(0.2, 0.35, 8), np.full((8, 3), 0.5))
    x = rng.normal(size=(points, 3)) * 0.2
    frame = np.broadcast_to(np.eye(3)[[1, 2, 0]], (points, 3, 3))     # rows T, B, N: N = +x, towards the clump
    v = np.tile([0.3, 0.1, 0.95], (points, 1)) / np.linalg.norm([0.3, 0.1, 0.95])
    mat = Lafortune((0.5, 0.5, 0.5), ((-1.0, -1.0, 1.0),), (20.0,), ((0.3, 0.3, 0.3),))
    env = lambda d, w: np.ones(d.shape[:-1] + (3,))  # noqa: E731
    med = {}
    for rule in RULES:
        ts = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            dynamic_terms(x, frame, v, mat, sb, env, rule=rule)  # type: ignore[arg-type]
            ts.append(time.perf_counter() - t0)
        med[rule] = float(np.median(ts))
    return {"points": points, "median_s": med, "ratio_to_overlap": {k: t / med["overlap"] for k, t in med.items()}}


def shares_gl_cost(points: int = 1 << 16, repeats: int = 3, seed: int = SEED,
                   nodes: int = UNION_NODES) -> dict[str, Any]:
    """Seconds per ``points`` lobes of ``envcap_sphere_shares`` (8 spheres of a clump, all live;
    ``nodes`` rings) per rule (``ENVCAP_DYNAMIC_COMBINE``), less a run of ``points / 16`` (after
    one to compile), best of ``repeats``; ratios to the overlap rule, of the whole call and of the combining step alone
    (less the ``sum`` rule's time: the per-sphere fractions)."""
    from envcap.gpu.context import create_context
    from envcap.gpu.glsl_harness import run_glsl

    rng = np.random.default_rng(seed)
    sb = SphereBuffer(rng.normal(size=(8, 3)) * 0.15 + (2.0, 0.0, 0.0), rng.uniform(0.25, 0.35, 8), np.full((8, 3), 0.5))
    body = """EnvcapSphereSet s = envcap_select_spheres(vec3(0.0), vec3(0.0));
vec4 occ[ENVCAP_SPHERE_CAP];
o[i] = vec4(envcap_sphere_shares(s, c[i].xyz, c[i].w, occ), occ[0].w, occ[7].w, 0.0);"""
    uni = {"envcap_spheres": np.c_[sb.centers, sb.radii], "envcap_sphere_albedo": sb.albedo, "envcap_sphere_count": 8}
    ctx = create_context()
    secs = {}
    try:
        for name, mode in (("sum", 2), ("overlap", 0), ("rings", 4)):
            best = math.inf
            for _ in range(repeats):
                t = []
                for n in (points // 16, points // 16, points):             # the first: compile (cached after)
                    C = np.array([1.0, 0.0, 0.0]) + rng.normal(size=(n, 3)) * 0.1
                    w = np.exp(rng.uniform(0.0, math.log(1000.0), n))
                    t0 = time.perf_counter()
                    run_glsl(ctx, body, {"c": np.c_[C, w]}, {"o": 3}, includes=("runtime/envcap_dynamic_spheres.glsl",),
                             defines={"ENVCAP_DYNAMIC_COMBINE": mode, "ENVCAP_UNION_NODES": nodes}, uniforms=uni)
                    t.append(time.perf_counter() - t0)
                best = min(best, t[2] - t[1])
            secs[name] = best * points / (points - points // 16)
        device = ctx.info.get("GL_RENDERER", "?")
    finally:
        ctx.release()
    step = {k: secs[k] - secs["sum"] for k in ("overlap", "rings")}
    return {"device": device, "points": points, "seconds": secs, "ratio_to_overlap": secs["rings"] / secs["overlap"],
            "combine_step_ratio": step["rings"] / step["overlap"] if step["overlap"] > 0 else math.nan}


def markdown(res: dict[str, Any]) -> str:
    er = res["errors"]
    cells = lambda r: " | ".join(f"{r[k]['mean']:.4f} / {r[k]['p95']:.4f} / {r[k]['max']:.4f}" for k in RULES)  # noqa: E731
    out = [f"{er['count']} clumps (seed {er['seed']}) x {len(POWERS)} powers; rings rule: {er['nodes']} rings.", "",
           "| w | true U (mean) | " + " | ".join(f"{r} mean / p95 / max" for r in RULES) + " |",
           "| --- | --- | " + "--- | " * len(RULES)]
    out += [f"| {r['w'] if r['w'] == 'all' else format(r['w'], 'g')} | {r['mean_U_true']:.3f} | {cells(r)} |"
            for r in er["rows"]]
    out += ["", "| case | true U | " + " | ".join(RULES) + " |", "| --- | --- | " + "--- | " * len(RULES)]
    out += [f"| {c['case']} | {c['U_true']:.4f} | " + " | ".join(f"{c[r]:.4f}" for r in RULES) + " |" for c in er["named"]]
    nc = res["numpy_cost"]
    out += ["", f"numpy `dynamic_terms` ({nc['points']} points, 2 lobes, 8 spheres), time / the overlap rule's: "
            + ", ".join(f"{k} {v:.2f}" for k, v in nc["ratio_to_overlap"].items())]
    sc = res.get("shares_gl_cost")
    if sc:
        out += ["", f"GLSL `envcap_sphere_shares` ({sc['device']}, one lobe, 8 live spheres), ns per lobe: "
                + ", ".join(f"{k} {1e9 * v / sc['points']:.0f}" for k, v in sc["seconds"].items())
                + f"; rings / overlap {sc['ratio_to_overlap']:.2f} (the combining step alone: {sc['combine_step_ratio']:.2f})"]
    gc = res.get("gl_cost")
    if gc:
        ratio = gc["ratio_to_plain"]
        out += ["", f"GLSL pass ({gc['device']}, {gc['pixels']} points, 8 spheres), multiples of a plain Eq. 3: "
                + ", ".join(f"{k} {v:.1f}" for k, v in ratio.items() if k != "plain")
                + f"; rings / overlap (envcap form): {ratio['envcap'] / ratio['envcap_overlap']:.2f}"]
    return "\n".join(out) + "\n"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (dynamic_clumps.json, dynamic_clumps.md)")
    p.add_argument("--clumps", type=int, default=100, help="random clumps, each at every power (default 100)")
    p.add_argument("--nodes", type=int, default=UNION_NODES, help=f"rings of the rings rule, 1-8 (default {UNION_NODES})")
    p.add_argument("--gl-size", type=int, default=256, help="side of the GLSL cost pass (0: skip; default 256)")


def run(args: argparse.Namespace) -> int:
    res: dict[str, Any] = {"errors": clump_errors(args.clumps, nodes=args.nodes), "numpy_cost": numpy_cost()}
    if args.gl_size > 0:
        from envcap.benchmarks.dynamic_street_cost import gl_cost
        res["shares_gl_cost"] = shares_gl_cost(nodes=args.nodes)
        res["gl_cost"] = gl_cost(size=args.gl_size, spheres=8)
    table = markdown(res)
    print(table)
    with atomic_output_dir(args.out) as d:
        (d / "dynamic_clumps.json").write_text(json.dumps(res, indent=1))
        (d / "dynamic_clumps.md").write_text(table)
    return 0
