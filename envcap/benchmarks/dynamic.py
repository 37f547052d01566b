"""Eq. 7 (a sphere blocking a BRDF lobe) against float64 quadrature of the spherical cap.

For caps of half-angle ``theta`` (``sin theta = r / l``: size and distance enter only through
their ratio), lobe powers ``w`` and angles ``gamma = m theta`` between the sphere's direction and
the lobe axis, the blocked fraction of the lobe ``f = I / (2 pi / (1 + w))`` is computed by
:func:`envcap.dynamic.quadrature.cap_lobe_integral` (truth) and by Eq. 7
(:func:`envcap.dynamic.lobe_product.lobe_product`) with

* ``paper``: the solid-angle power ``t`` (:func:`envcap.dynamic.sphere_lobe.sphere_lobe`) and
  exponent 0.7;
* ``k=0.5``, ``k=1``: the same with another exponent;
* ``matched``: exponent 0.7 and the per-lobe power ``t_w``
  (:func:`envcap.dynamic.sphere_lobe.lobe_power_matched`, exact at ``gamma = 0``);
* ``envcap``: envcap's ring integral (:func:`envcap.dynamic.cap_lobe.cap_lobe_product`, 4 nodes).

The error is ``|f_eq7 - f_true|`` (fraction of the lobe's light, what a shader gets wrong); the
table gives, per ``(theta, w)``, ``f_true`` at ``gamma = 0`` and the largest error over the
``gamma`` grid; a second table bins the errors of ``paper`` and ``envcap`` by ``w theta^2`` (where
the paper's 0.7 exponents hold).  Then many spheres (:mod:`envcap.benchmarks.dynamic_union`): the
union of caps per form and combine rule, and the blocked / bounced radiance.  Writes
``dynamic.json`` and ``dynamic.md`` to ``--out``.  No GPU; about a minute.  ``--paper-threshold``
instead scans, per power, the smallest ``theta`` where the paper's error passes 0.01
(:func:`paper_threshold`; ``paper_threshold.json`` / ``.md``).
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np

from envcap.benchmarks.dynamic_union import radiance_errors, union_errors
from envcap.dynamic.cap_lobe import cap_lobe_product
from envcap.dynamic.lobe_product import lobe_product
from envcap.dynamic.quadrature import cap_lobe_integral
from envcap.dynamic.sphere_lobe import lobe_power_matched, sphere_lobe
from envcap.outputs import atomic_output_dir

THETAS_DEG = (2.0, 5.0, 10.0, 20.0, 40.0, 60.0, 85.0)
POWERS = (1.0, 10.0, 100.0, 1000.0)
GAMMA_MULTIPLES = (0.0, 0.5, 1.0, 1.5, 2.0, 3.0)
VARIANTS = ("paper", "k=0.5", "k=1", "matched", "envcap")
BINS = (0.0, 0.1, 0.3, 1.0, 3.0, 10.0, 100.0, math.inf)
"""Edges of the ``w theta^2`` bins (theta in rad)."""
THRESHOLD_POWERS = (0.0, 0.5, 1.0, 2.0, 3.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0)
"""Powers of the ``--paper-threshold`` scan."""
THRESHOLD_ERROR = 0.01
"""The error (fraction of the lobe's light) whose first crossing ``--paper-threshold`` finds."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (JSON + Markdown table)")
    p.add_argument("--cost", action="store_true",
                   help="also time the GLSL forms on the GL driver at hand (llvmpipe here: a CPU proxy)")
    p.add_argument("--paper-threshold", action="store_true",
                   help="only scan, per power w, the smallest cap angle theta at which the paper's Eq. 4-7 "
                        f"errs by more than {THRESHOLD_ERROR} (paper_threshold.json / .md; ~3 min)")


def glsl_cost(nodes_list: tuple[int, ...] = (2, 3, 4, 8), n: int = 200_000, repeats: int = 3) -> list[dict]:
    """Seconds per 32 n evaluations of ``envcap_lobe_product`` (paper) and
    ``envcap_cap_lobe_product`` (envcap, per node count), less an empty loop, best of ``repeats``."""
    import time

    from envcap.gpu.context import create_context
    from envcap.gpu.glsl_harness import run_glsl

    ctx = create_context()
    rng = np.random.default_rng(0)
    D, C = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    t, w = np.exp(rng.uniform(0, 8, n)), np.exp(rng.uniform(0, 8, n))
    body = ("vec4 acc = vec4(0.0); vec3 dd = d[i].xyz, cc = c[i].xyz;\n"
            "for (int r = 0; r < 32; ++r) { acc += FN(dd, cc, d[i].w * (1.0 + 0.01 * float(r)), c[i].w);"
            " dd = dd.yzx + 0.01 * acc.xyz; }\no[i] = acc;")
    cases = [("empty", 0, {"FN(a, b, x, y)": "vec4(a + b, x + y)"}), ("paper", 0, {"FN": "envcap_lobe_product"})]
    cases += [("envcap", k, {"FN": "envcap_cap_lobe_product", "ENVCAP_CAP_NODES": k}) for k in nodes_list]
    out = []
    for name, k, defs in cases:
        best = math.inf
        for _ in range(repeats):
            t0 = time.perf_counter()
            run_glsl(ctx, body, {"d": np.c_[D, t], "c": np.c_[C, w]}, {"o": 4}, includes=("runtime/envcap_dynamic.glsl",),
                     defines=defs)
            best = min(best, time.perf_counter() - t0)
        out.append({"form": name, "nodes": k, "seconds": best})
    empty = out[0]["seconds"]
    paper = out[1]["seconds"] - empty
    for r in out:
        r["relative_to_paper"] = (r["seconds"] - empty) / paper
    ctx.release()
    return out[1:]


def node_errors(rows: list[dict], nodes_list: tuple[int, ...] = (2, 3, 4, 8)) -> dict[int, float]:
    """Largest error of the envcap form per node count over the table's grid."""
    from envcap.dynamic.cap_lobe import cap_lobe_fraction

    out = {}
    for k in nodes_list:
        err = 0.0
        for r in rows:
            th = math.radians(r["theta_deg"])
            g = np.minimum(np.array(GAMMA_MULTIPLES) * th, math.pi)
            f, _, _ = cap_lobe_fraction(th, g, r["w"], nodes=k)
            err = max(err, float(np.max(np.abs(f - np.array(r["f_true"])))))
        out[k] = err
    return out


def eq7_fraction(theta: float, gamma: float, w: float, variant: str) -> float:
    """Blocked fraction of the lobe by Eq. 7 for one configuration and variant."""
    s = math.sin(theta)
    D, t = sphere_lobe(np.zeros(3), np.array([0.0, 0.0, 1.0]), s)
    if variant == "matched":
        t = lobe_power_matched(s, w)
    C = np.array([math.sin(gamma), 0.0, math.cos(gamma)])
    if variant == "envcap":
        return float(cap_lobe_product(D, C, t, w).integral) * (1 + w) / (2 * math.pi)
    k = {"k=0.5": 0.5, "k=1": 1.0}.get(variant, 0.7)
    return float(lobe_product(D, C, t, w, exponent=k).integral) * (1 + w) / (2 * math.pi)


def measure() -> list[dict]:
    """One row per (theta, w): truth at gamma = 0, and per variant the largest error over gamma."""
    rows = []
    for theta_deg in THETAS_DEG:
        theta = math.radians(theta_deg)
        for w in POWERS:
            gammas = [min(m * theta, math.pi) for m in GAMMA_MULTIPLES]
            truth = [cap_lobe_integral(theta, g, w) * (1 + w) / (2 * math.pi) for g in gammas]
            row = {"theta_deg": theta_deg, "w": w, "f_true_gamma0": truth[0], "f_true": truth}
            for v in VARIANTS:
                f = [eq7_fraction(theta, g, w, v) for g in gammas]
                row[v] = f
                row[f"max_err_{v}"] = max(abs(a - b) for a, b in zip(f, truth))
            rows.append(row)
    return rows


def binned(rows: list[dict]) -> list[dict]:
    """Largest and mean error (over gamma) of ``paper`` and ``envcap`` per ``w theta^2`` bin."""
    out = []
    for lo, hi in zip(BINS[:-1], BINS[1:]):
        sel = [r for r in rows if lo <= r["w"] * math.radians(r["theta_deg"]) ** 2 < hi]
        if not sel:
            continue
        b = {"lo": lo, "hi": hi, "n": len(sel)}
        for v in ("paper", "envcap"):
            errs = [abs(a - t) for r in sel for a, t in zip(r[v], r["f_true"])]
            b[v] = {"max": max(errs), "mean": float(np.mean(errs))}
        out.append(b)
    return out


def paper_max_error(theta: float, w: float, gammas: int = 91) -> tuple[float, float]:
    """``(err, gamma)``: the paper's largest ``|f_Eq7 - f_true|`` over ``gammas`` angles in
    ``[0, min(theta + pi/2, pi)]`` (beyond, neither blocks anything) and where it is (rad)."""
    best = (0.0, 0.0)
    for g in np.linspace(0.0, min(theta + math.pi / 2, math.pi), gammas):
        e = abs(eq7_fraction(theta, float(g), w, "paper") - cap_lobe_integral(theta, float(g), w) * (1 + w) / (2 * math.pi))
        best = max(best, (e, float(g)))
    return best


def paper_threshold(powers: tuple[float, ...] = THRESHOLD_POWERS, tol: float = THRESHOLD_ERROR,
                    step_deg: float = 0.5, refine_deg: float = 0.05) -> list[dict]:
    """Per power ``w``: the smallest cap half-angle ``theta`` (deg) at which the paper's form errs by
    more than ``tol`` at some ``gamma`` (``theta`` up in ``step_deg`` steps from ``step_deg``, then
    bisection to ``refine_deg``), with ``w theta^2`` (rad) there: below it the paper holds."""
    out = []
    for w in powers:
        ok, bad = 0.0, step_deg
        while bad < 89.5 and paper_max_error(math.radians(bad), w)[0] <= tol:
            ok, bad = bad, bad + step_deg
        while bad - ok > refine_deg:
            mid = 0.5 * (ok + bad)
            ok, bad = (mid, bad) if paper_max_error(math.radians(mid), w)[0] <= tol else (ok, mid)
        err, g = paper_max_error(math.radians(bad), w)
        out.append({"w": w, "theta_deg": bad, "w_theta2": w * math.radians(bad) ** 2, "err": err,
                    "gamma_deg": math.degrees(g)})
    return out


def threshold_markdown(rows: list[dict]) -> str:
    return ("| w | theta where the paper first errs > 0.01 | w theta^2 there | error | at gamma |\n"
            "| --- | --- | --- | --- | --- |\n" + "".join(
                f"| {r['w']:g} | {r['theta_deg']:.2f}° | {r['w_theta2']:.3f} | {r['err']:.4f} | {r['gamma_deg']:.1f}° |\n"
                for r in rows))


def union_markdown(rows: list[dict], keys: list[str]) -> str:
    head = "| scene | w | " + " | ".join(keys) + " |\n" + "| --- " * (2 + len(keys)) + "|\n"
    return head + "".join(f"| {r['scene']} | {r['w']:g} | " + " | ".join(
        f"{r[k]['mean']:.4f} / {r[k]['max']:.3f}" for k in keys) + " |\n" for r in rows)


def markdown(rows: list[dict]) -> str:
    head = ("| theta | w | f true (gamma=0) | f paper (gamma=0) | " + " | ".join(f"max err {v}" for v in VARIANTS) + " |\n"
            + "| --- " * (4 + len(VARIANTS)) + "|\n")
    body = "".join(f"| {r['theta_deg']:g}° | {r['w']:g} | {r['f_true_gamma0']:.3f} | {r['paper'][0]:.3f} | "
                   + " | ".join(f"{r[f'max_err_{v}']:.4f}" for v in VARIANTS) + " |\n" for r in rows)
    return head + body


def run(args: argparse.Namespace) -> int:
    if getattr(args, "paper_threshold", False):
        th = paper_threshold()
        table = threshold_markdown(th)
        print(table)
        with atomic_output_dir(args.out) as tmp:
            (tmp / "paper_threshold.json").write_text(json.dumps(th, indent=2))
            (tmp / "paper_threshold.md").write_text(table)
        return 0
    rows = measure()
    bins = binned(rows)
    table = markdown(rows) + "\n| w theta^2 | rows | paper max / mean | envcap max / mean |\n| --- | --- | --- | --- |\n" + "".join(
        f"| [{b['lo']:g}, {b['hi']:g}) | {b['n']} | {b['paper']['max']:.3f} / {b['paper']['mean']:.4f} | "
        f"{b['envcap']['max']:.4f} / {b['envcap']['mean']:.5f} |\n" for b in bins)
    rng = np.random.default_rng(14)
    union = union_errors(rng)
    radiance = radiance_errors(rng)
    table += "\nUnion of caps, |U - U_true| mean / max (true mean U in the last column):\n\n" + union_markdown(
        [dict(r, truth={"mean": r["mean_U_true"], "max": r["mean_U_true"]}) for r in union],
        [f"{f}/{rule}" for f in ("paper", "envcap", "exact") for rule in ("rings", "overlap", "independent", "sum", "max")] + ["truth"])
    table += "\nBlocked and bounced radiance, error mean / max (fraction of the lobe's unblocked light):\n\n" + union_markdown(
        radiance, ["blocked/paper", "blocked/envcap", "bounced paper/paper", "bounced paper/envcap",
                   "bounced facing/paper", "bounced facing/envcap", "blocked_true", "bounced_true"])
    errs = node_errors(rows)
    cost = glsl_cost() if getattr(args, "cost", False) else []
    table += "\n| form | nodes | max err (table grid) | GLSL time / paper's |\n| --- | --- | --- | --- |\n"
    table += f"| paper | - | {max(r['max_err_paper'] for r in rows):.4f} | 1 |\n" + "".join(
        f"| envcap | {k} | {e:.4f} | " + "".join(f"{c['relative_to_paper']:.2f}" for c in cost if c["nodes"] == k)
        + (" |\n" if cost else "(--cost) |\n") for k, e in errs.items())
    print(table)
    with atomic_output_dir(args.out) as tmp:
        (tmp / "dynamic.json").write_text(json.dumps({"gamma_multiples": GAMMA_MULTIPLES, "rows": rows, "bins": bins,
                                                      "union": union, "radiance": radiance, "node_errors": errs,
                                                      "cost": cost}, indent=2))
        (tmp / "dynamic.md").write_text(table)
    return 0
