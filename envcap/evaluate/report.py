"""Reports of :func:`envcap.evaluate.run.evaluate_scene`: ``report.json``, ``report.md``, plots and
image strips of the worst positions, written atomically into one directory.

``report.json``: ``results`` (rows ``{scene, method, lobe_power, rel_rmse, median, p90, max,
n_positions}``; ``lobe_power`` null = mirror; ``rel_rmse`` is the mean over positions of the
per-position solid-angle weighted relative RMSE of luminance), ``positions`` (per-position rows),
``shading`` (per scene/method/material mean relative error of Eq. 3 luminance), ``floor`` (the
same metrics at probe positions), ``ratios`` (nearest / method per scene and lobe power),
``by_offset`` (binned by lateral, along and height offset), ``timings`` and ``meta`` per scene.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from envcap.core.cube import horizontal_cross
from envcap.evaluate.result import EvaluationResult, lobe_power_label, summarize
from envcap.formats.png_preview import contact_sheet_png, heatmap_png
from envcap.outputs import atomic_output_dir


def best_method(res: EvaluationResult, candidates: Sequence[str] | None = None) -> str:
    """Method (other than ``nearest``) with the lowest mean error over all lobe powers (primary sky variant)."""
    methods = [m for m in res.meta["methods"] if m != "nearest"] if candidates is None else list(candidates)
    if not methods:
        return res.meta["methods"][0]
    prim = res.meta.get("primary_sun", True)
    score = {m: np.mean([r["rel_rmse"] for r in res.summary if r["method"] == m and r.get("sun", True) == prim])
             for m in methods}
    return min(score, key=lambda m: score[m])


def ratios(res: EvaluationResult, base: str = "nearest") -> list[dict[str, Any]]:
    """``error(base) / error(method)`` of the summary means per lobe power (> 1: method is better)."""
    out = []
    for r in res.summary:
        b = res.error(base, r["lobe_power"], sun=r.get("sun", True))
        if r["method"] == base or not math.isfinite(b):
            continue
        out.append({"scene": res.scene, "method": r["method"], "lobe_power": r["lobe_power"], "sun": r.get("sun", True),
                    "ratio": b / r["rel_rmse"] if r["rel_rmse"] > 0 else math.inf})
    return out


def _bins(values: np.ndarray, edges: Sequence[float]) -> np.ndarray:
    return np.clip(np.digitize(values, edges[1:-1]), 0, len(edges) - 2)


def by_offset(res: EvaluationResult) -> list[dict[str, Any]]:
    """Mean error per method and lobe power in bins of |lateral|, along (to the nearest probe) and height."""
    out = []
    specs = {"lateral_m": ("abs", [0, 1.5, 3, 5, 8, 1e9]), "along_m": ("", [0, 0.75, 1.5, 2.5, 5, 1e9]),
             "height_m": ("", [0, 1.0, 2.0, 1e9]), "plane_misfit": ("", [0, 0.05, 0.15, 0.3, 1e9])}
    for key, (mode, edges) in specs.items():
        groups: dict[tuple, list[float]] = {}
        for r in res.rows:
            if key not in r:
                continue
            v = abs(r[key]) if mode == "abs" else r[key]
            b = int(_bins(np.array([v]), edges)[0])
            groups.setdefault((r["method"], r["lobe_power"], r.get("sun", True), b), []).append(r["rel_rmse"])
        for (m, lp, sun, b), v in sorted(groups.items(), key=lambda kv: (kv[0][0], -1 if kv[0][1] is None else -kv[0][1],
                                                                          not kv[0][2], kv[0][3])):
            hi = edges[b + 1]
            out.append({"scene": res.scene, "offset": key, "bin": f"{edges[b]:g}-{'' if hi > 1e8 else f'{hi:g}'}",
                        "method": m, "lobe_power": lp, "sun": sun, "rel_rmse": float(np.mean(v)), "n": len(v)})
    return out


def _fmt(x: float) -> str:
    return "–" if x is None or not math.isfinite(x) else (f"{x:.3f}" if x >= 0.001 else f"{x:.1e}")


def _md_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(" --- " for _ in header) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def _spacing_words(meta: dict) -> str:
    """How the probes stand: ``every 5.0 m``, or ``placed by min_error (mean spacing 10 m)``."""
    placed = meta.get("placement")
    if placed is None:
        return f"every {meta['probe_spacing']} m"
    return f"placed by {placed} (mean spacing {meta['probe_spacing']:.3g} m)"


def _markdown(results: Sequence[EvaluationResult]) -> str:
    parts = ["# envcap parallax evaluation", "",
             "Error = solid-angle weighted relative RMSE of luminance between the prediction from the probe set "
             "and a fresh capture at the same position, filtered at exactly the lobe power (mean over positions; "
             "p90 in report.json). Definitions: docs/evaluation.md.", ""]
    for res in results:
        lps = res.meta["lobe_powers"]
        best = best_method(res)
        parts += [f"## {res.scene}", "",
                  f"{res.meta['n_positions']} positions, truth {res.meta['resolution']}² per face, probes "
                  f"{res.meta['probe_resolution']}² {_spacing_words(res.meta)} ({res.meta['probe_count']} probes). "
                  f"Best method: **{best}**.", ""]
        rat = ratios(res)
        variants = sorted(res.meta.get("sun_variants", [True]), key=lambda v: v != res.meta.get("primary_sun", True))
        for sun in variants:   # the primary variant first
            label = "sun splatted into the sky map" if sun else "sun taken out of the sky (analytic sun light; primary)"
            rows = [[m] + [_fmt(res.error(m, lp, sun=sun)) for lp in lps] for m in res.meta["methods"]]
            parts += [f"### Mean relative RMSE by method and lobe power: {label}", "",
                      _md_table(["method"] + [lobe_power_label(lp) for lp in lps], rows), ""]
            rrows = []
            for m in res.meta["methods"]:
                if m == "nearest":
                    continue
                rrows.append([m] + [_fmt(next((r["ratio"] for r in rat if r["method"] == m and r["lobe_power"] == lp
                                               and r["sun"] == sun), math.nan)) for lp in lps])
            parts += [f"Error of `nearest` / error of method (higher is better), {label}:", "",
                      _md_table(["method"] + [lobe_power_label(lp) for lp in lps], rrows), ""]
        bo = by_offset(res)
        sun_b = False if False in res.meta.get("sun_variants", [True]) else True
        lp_b = 64.0 if 64.0 in lps else lps[0]
        meths = [m for m in ("nearest", "planes_mip", best) if m in res.meta["methods"]]
        meths = list(dict.fromkeys(meths))
        brows = []
        for key in ("lateral_m", "along_m", "height_m", "plane_misfit"):
            bins = list(dict.fromkeys(r["bin"] for r in bo if r["offset"] == key))
            for b in bins:
                vals = [next((r for r in bo if r["offset"] == key and r["bin"] == b and r["method"] == m
                              and r["lobe_power"] == lp_b and r["sun"] == sun_b), None) for m in meths]
                if vals[0] is None:
                    continue
                label = {"lateral_m": "|lateral| (m)", "along_m": "along to nearest probe (m)", "height_m": "height (m)",
                         "plane_misfit": "plane misfit"}[key]
                brows.append([label, b, str(vals[0]["n"])]
                             + [_fmt(v["rel_rmse"]) if v else "–" for v in vals])
        parts += [f"### By offset ({lobe_power_label(lp_b)}, {'sun out of the sky' if not sun_b else 'sun in the sky'}); "
                  "plane_misfit = share of the sphere where the three planes are the wrong model", "",
                  _md_table(["offset", "bin", "positions"] + meths, brows), ""]
        inside = [r for r in res.rows if r.get("in_crossing")]
        if inside:
            nc = summarize(res.scene, inside)
            crows = [[r["method"], lobe_power_label(r["lobe_power"]), "yes" if r["sun"] else "no", _fmt(r["rel_rmse"]),
                      str(r["n_positions"])] for r in nc if r["lobe_power"] in (None, 64.0, 256.0)]
            parts += [f"### Positions inside a crossing ({', '.join(res.meta.get('crossings') or [])}; lookup "
                      f"`{res.meta.get('crossing_lookup')}`, docs/crossings.md)", "",
                      _md_table(["method", "lobe", "sun", "mean rel. RMSE", "positions"], crows), ""]
        cr = [r for r in res.rows if r["near_crossing"]]
        if cr:
            nc = summarize(res.scene, cr)
            crows = [[r["method"], lobe_power_label(r["lobe_power"]), "yes" if r["sun"] else "no", _fmt(r["rel_rmse"]),
                      str(r["n_positions"])] for r in nc if r["lobe_power"] in (None, 64.0)]
            parts += ["### Positions inside the other street's roadway (three planes are wrong there)", "",
                      _md_table(["method", "lobe", "sun", "mean rel. RMSE", "positions"], crows), ""]
        if res.floor:
            lps_f = sorted({r["lobe_power"] for r in res.floor}, key=lambda v: -math.inf if v is None else -v)
            frows = []
            for sun in res.meta.get("sun_variants", [True]):
                for m in list(dict.fromkeys(("nearest", "planes_mip", best))):
                    frows.append([f"{m} ({'sun' if sun else 'no sun'})"] + [
                        _fmt(next((r["rel_rmse"] for r in res.floor if r["method"] == m and r["lobe_power"] == lp
                                   and r["sun"] == sun), math.nan)) for lp in lps_f])
            ce = res.meta.get("composite_error") or []
            frows.append(["sky composited after filtering vs filtered composite"] +
                         [_fmt(next((r["rel_rmse"] for r in ce if r["lobe_power"] == lp), math.nan)) for lp in lps_f])
            parts += ["### Floor: evaluated at probe positions (chain interpolation and filtering only)", "",
                      _md_table(["method"] + [lobe_power_label(lp) for lp in lps_f], frows), ""]
        if res.shading:
            mats = sorted({r["material"] for r in res.shading})
            srows = []
            suns = res.meta.get("sun_variants", [True])
            for m in res.meta["methods"]:
                srows.append([m] + [_fmt(float(np.mean([r["rel_err"] for r in res.shading if r["method"] == m and
                                                        r["material"] == mat and r["sun"] == sun] or [math.nan])))
                                    for sun in suns for mat in mats])
            parts += ["### Eq. 3 shading: relative RMS error of luminance (10 normal/view pairs per position)", "",
                      _md_table(["method"] + [f"{mat}{'' if sun else ' (no sun)'}" for sun in suns for mat in mats], srows), ""]
        t = res.timings
        parts += ["### Time", "", _md_table(["captures", "filtering", "predictions", "shading", "total"],
                                            [[f"{t.get(k, 0):.1f} s" for k in ("captures_s", "filtering_s", "predictions_s",
                                                                               "shading_s", "total_s")]]), ""]
    parts += ["Plots: `error_vs_lateral.png`, `error_vs_lobe.png`; worst positions: `worst_*.png` "
              "(truth | nearest | planes_mip | best, one exposure, primary sky variant) and `worst_*_error.png` (relative error maps); `error_vs_misfit.png`.", ""]
    return "\n".join(parts)


def _plots(results: Sequence[EvaluationResult], out: Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    files = []
    methods = list(dict.fromkeys(m for r in results for m in r.meta["methods"]))
    colors = {m: plt.get_cmap("tab10")(i) for i, m in enumerate(methods)}
    # error vs lateral offset, mirror and w = 64
    powers = [None, 64.0]
    fig, axes = plt.subplots(1, len(powers), figsize=(6 * len(powers), 4.2), dpi=100, squeeze=False)
    for ax, lp in zip(axes[0], powers):
        for m in methods:
            rr = [r for res in results for r in res.rows if r["method"] == m and r["lobe_power"] == lp
                  and r.get("sun", True) == res.meta.get("primary_sun", True)]
            if not rr:
                continue
            lat = np.array([r["lateral_m"] for r in rr])
            err = np.array([r["rel_rmse"] for r in rr])
            ax.scatter(np.abs(lat), err, s=8, color=colors[m], alpha=0.35)
            edges = np.array([0, 1, 2, 3, 4, 6, 9, 15, 40])
            b = _bins(np.abs(lat), edges)
            xs, ys = [], []
            for k in range(len(edges) - 1):
                if np.any(b == k):
                    xs.append(np.mean(np.abs(lat)[b == k]))
                    ys.append(np.mean(err[b == k]))
            ax.plot(xs, ys, "-o", color=colors[m], label=m, ms=3)
        ax.set_xlabel("|lateral offset| from the probe line (m)")
        ax.set_ylabel("relative RMSE of luminance")
        ax.set_yscale("log")
        ax.set_title(f"{lobe_power_label(lp)}, all scenes")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=7)
    files.append(_save_figure(plt, fig, out, "error_vs_lateral.png"))
    # error vs plane misfit (where three planes are the wrong model), w = 64, sun out of the sky if evaluated
    fig, ax = plt.subplots(figsize=(6.5, 4.2), dpi=100)
    for m in [m for m in ("nearest", "planes_mip", "fitted_planes_mip", "depth_reproject", "blend") if m in methods]:
        rr = [r for res in results for r in res.rows if r["method"] == m and r["lobe_power"] == 64.0
              and r.get("sun", True) == (False not in res.meta.get("sun_variants", [True])) and "plane_misfit" in r]
        if rr:
            ax.scatter([r["plane_misfit"] for r in rr], [r["rel_rmse"] for r in rr], s=9, color=colors[m], alpha=0.6, label=m)
    ax.set_xlabel("plane misfit: share of the sphere where three planes are wrong")
    ax.set_ylabel("relative RMSE (w=64)")
    ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    files.append(_save_figure(plt, fig, out, "error_vs_misfit.png"))
    # error vs lobe power, one panel per scene
    ncol = min(3, len(results))
    nrow = math.ceil(len(results) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.6 * ncol, 3.8 * nrow), dpi=100, squeeze=False)
    for ax in axes.ravel()[len(results):]:
        ax.axis("off")
    for ax, res in zip(axes.ravel(), results):
        lps = [lp for lp in res.meta["lobe_powers"]]
        xs = [4 * max(lp for lp in lps if lp is not None) if lp is None else lp for lp in lps] if any(lps) else [1]
        for m in res.meta["methods"]:
            if False in res.meta.get("sun_variants", []):
                ax.plot(xs, [res.error(m, lp, sun=False) for lp in lps], "-o", ms=3, color=colors[m], label=m)
            if True in res.meta.get("sun_variants", [True]):
                ax.plot(xs, [res.error(m, lp) for lp in lps], ":", color=colors[m], lw=1,
                        label=None if False in res.meta.get("sun_variants", []) else m)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("lobe power w (rightmost: mirror)")
        ax.set_ylabel("mean relative RMSE")
        ax.set_title(f"{res.scene} (solid: no sun; dotted: sun in sky)", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=7)
    files.append(_save_figure(plt, fig, out, "error_vs_lobe.png"))
    return files


def _save_figure(plt: Any, fig: Any, out: Path, name: str) -> str:
    """Lay out ``fig``, write it as ``out/name``, close it; returns ``name`` (for the file list)."""
    fig.tight_layout()
    fig.savefig(out / name)
    plt.close(fig)
    return name


def _strips(res: EvaluationResult, out: Path) -> list[str]:
    files = []
    kept = res.strips.get("positions") or {}
    best = best_method(res, [m for m in res.meta["methods"] if m not in ("nearest", "planes_mip")] or None)
    show = [m for m in ("nearest", "planes_mip", best) if m in res.meta["methods"]]
    show = list(dict.fromkeys(show))
    for rank, (idx, store) in enumerate(kept.items()):
        ep = res.positions[idx]
        for w in [w for w in store["truth"] if math.isinf(w) or w == res.strips.get("key_power")]:
            cubes = [store["truth"][w]] + [store["pred"][(m, w)] for m in show]
            up = max(1, 48 // cubes[0].shape[1])   # blow small grids up (nearest) so they can be seen
            cubes = [np.repeat(np.repeat(c, up, axis=1), up, axis=2) for c in cubes]
            sun0 = res.meta.get("primary_sun", True)
            errs = {m: next(r["rel_rmse"] for r in res.rows if r["position_index"] == idx and r["method"] == m
                            and r["lobe_power"] == (None if math.isinf(w) else w) and r.get("sun", True) == sun0) for m in show}
            labels = [f"truth {lobe_power_label(w)}"] + [f"{m}: {errs[m]:.3f}" for m in show]
            tag = "mirror" if math.isinf(w) else f"w{w:g}"
            name = f"worst_{res.scene}_{rank}_{tag}.png"
            contact_sheet_png(out / name, cubes, labels, cols=len(cubes))
            files.append(name)
            maps = [horizontal_cross(np.repeat(np.repeat(store["maps"][(m, w)], up, axis=1), up, axis=2)[..., None],
                                     inside=True, fill=np.nan)[..., 0] for m in show]
            gap = np.full((maps[0].shape[0], max(2, maps[0].shape[1] // 16)), np.nan)
            row = np.concatenate(sum([[mp, gap] for mp in maps], [])[:-1], axis=1)
            name = f"worst_{res.scene}_{rank}_{tag}_error.png"
            heatmap_png(out / name, np.minimum(row, 1.0), 0.0, 1.0, "relative luminance error (clipped at 1)",
                        title=f"{res.scene} pos {idx} {ep.street} lat {ep.lateral:+.1f} m h {ep.height:.1f} m, "
                              f"{lobe_power_label(w)}: " + " | ".join(show))
            files.append(name)
    return files


def report_dict(results: Sequence[EvaluationResult]) -> dict[str, Any]:
    """The JSON document of :func:`write_report` (see the module docstring)."""
    def shade_summary(res: EvaluationResult) -> list[dict[str, Any]]:
        g: dict[tuple, list[float]] = {}
        for r in res.shading:
            g.setdefault((r["method"], r["material"], r["sun"]), []).append(r["rel_err"])
        return [{"scene": res.scene, "method": m, "material": mat, "sun": sun, "rel_err": float(np.mean(v)),
                 "p90": float(np.percentile(v, 90)), "n_positions": len(v)} for (m, mat, sun), v in g.items()]

    return {
        "results": [r for res in results for r in res.summary],
        "ratios": [r for res in results for r in ratios(res)],
        "best_method": {res.scene: best_method(res) for res in results},
        "shading": [r for res in results for r in shade_summary(res)],
        "floor": [r for res in results for r in res.floor],
        "by_offset": [r for res in results for r in by_offset(res)],
        "timings": {res.scene: {k: round(v, 3) for k, v in res.timings.items()} for res in results},
        "meta": {res.scene: res.meta for res in results},
        "positions": [r for res in results for r in res.rows],
        "shading_positions": [r for res in results for r in res.shading],
    }


def _clean(o: Any) -> Any:
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    if isinstance(o, dict):
        return {str(k): _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if isinstance(o, (np.floating, np.integer, np.bool_)):
        return _clean(o.item())
    return o


def write_report(results: Sequence[EvaluationResult], out_dir: str | Path, *, images: bool = True) -> Path:
    """Write ``report.json``, ``report.md``, the plots and the worst-position strips of ``results``
    (one per scene) into ``out_dir`` atomically; returns the directory."""
    if not results:
        raise ValueError("no evaluation results to report")
    with atomic_output_dir(out_dir) as tmp:
        doc = _clean(report_dict(results))
        files = []
        if images:
            files += _plots(results, tmp)
            for res in results:
                files += _strips(res, tmp)
        doc["files"] = files
        (tmp / "report.json").write_text(json.dumps(doc, indent=1, allow_nan=False) + "\n")
        (tmp / "report.md").write_text(_markdown(results))
    return Path(out_dir).resolve()
