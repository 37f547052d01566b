"""``envcap bench bake``'s ``sky_visibility`` record: what ``envcap capture --sky-visibility`` adds to
the bake (``docs/lobes.md``, "Visibility moments by Funk-Hecke").

* ``pairs``: ``--sky-visibility-reps`` pairs of the fast-path bake (:func:`envcap.probeset.bake_output.
  bake_to_directory`, ``probes.ktx2`` and ``sky.ktx2``) without and with the ``sky_visibility``
  writer, interleaved in one process (the machine is shared: only ratios from the same run count);
  per pair wall and CPU seconds (``time.process_time``: llvmpipe's and BLAS's threads too), the
  writer's own stage, and the ratio with / without.  The goal (issue 19): at most 2x.
* ``error``: the moments ``V_lm`` of ``--error-probes`` probes of the set (what the writer stores,
  before RGBA16F) against the exact float64 reference (:func:`envcap.prefilter.exact.
  convolve_exact_dirs` of ``alpha Y_lm``) on ``--samples`` random texels per stored rung (every texel
  of a smaller rung): max and RMS absolute error per rung, for ``quality="harmonics"`` (the bake's)
  and, with ``--sky-visibility-gl-probes K > 0``, the GL filter it replaced (``quality="default"``)
  on the first ``K`` of those probes, with its seconds per probe (scaled to the set: the ``before``
  of the docs' table).
"""

from __future__ import annotations

import argparse
import math
import shutil
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np

from envcap.core import cube as cm
from envcap.core.rungs import rung_ladder
from envcap.prefilter import convolve_exact_dirs
from envcap.prefilter.sky_visibility import prefilter_sky_visibility, sh_basis
from envcap.probeset.bake_output import bake_to_directory
from envcap.probeset.probe_set import ProbeSet
from envcap.probeset.progress import BakeProgress

__all__ = ["GOAL_RATIO", "add_sky_visibility_arguments", "sky_visibility_record", "table_lines"]

GOAL_RATIO = 2.0
"""Issue 19: a bake with ``--sky-visibility`` takes at most this times the same bake without it."""
ORDER = 1
"""The writer's SH order (:data:`envcap.formats.sky_visibility_writer.ORDER`)."""


def add_sky_visibility_arguments(p: argparse.ArgumentParser) -> None:
    """The options of this record (a helper of `bench bake`: no `add_arguments`, so no benchmark of its own)."""
    p.add_argument("--sky-visibility-reps", type=int, default=2,
                   help="pairs of bakes without / with --sky-visibility, interleaved (default 2; 0: none)")
    p.add_argument("--sky-visibility-gl-probes", type=int, default=0,
                   help="probes whose moments the previous GL filter also makes, timed and checked (default 0)")


def _bake(scene: Any, out: Path, size: int, spacing: float, quality: str, ctx: Any, with_moments: bool) -> dict[str, Any]:
    rep = BakeProgress("off")
    shutil.rmtree(out, ignore_errors=True)
    t0, c0 = time.perf_counter(), time.process_time()
    bake_to_directory(scene, out, report=rep, resolution=size, spacing=spacing, quality=quality, ctx=ctx,
                      writers=["sky_visibility"] if with_moments else [])
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    shutil.rmtree(out, ignore_errors=True)
    stage = "write sky_visibility"
    return {"wall_s": round(wall, 3), "cpu_s": round(cpu, 3),
            "writer_s": round(rep.seconds.get(stage, 0.0), 3), "writer_cpu_s": round(rep.cpu_seconds.get(stage, 0.0), 3)}


def _errors(alpha: np.ndarray, vis: Any, rng: np.random.Generator, samples: int) -> list[dict[str, float]]:
    """Max and RMS absolute error of ``vis`` (a :class:`SkyVisibility` of the cubes ``alpha``) per stored rung."""
    lad, r_per, n = vis.ladder, vis.ladder.per_level, alpha.shape[2]
    basis = sh_basis(cm.texel_directions(n), ORDER)
    rows = []
    for i in range(vis.first_rung, lad.rungs):
        j, r = divmod(i, r_per)
        s = lad.sizes[j]
        idx = rng.choice(6 * s * s, min(samples, 6 * s * s), replace=False)
        dirs = cm.texel_directions(s).reshape(-1, 3)[idx]
        worst, sq, count = 0.0, 0.0, 0
        for p in range(alpha.shape[0]):
            ref = convolve_exact_dirs(alpha[p][..., None] * basis, lad.powers[i], dirs) if i else \
                (alpha[p][..., None] * basis).reshape(-1, basis.shape[-1])[idx]
            got = vis.levels[j - vis.first_level][p * r_per + r].reshape(-1, basis.shape[-1])[idx]
            err = np.abs(got - ref)
            worst, sq, count = max(worst, float(err.max())), sq + float((err ** 2).sum()), count + err.size
        rows.append({"rung": i, "w": round(float(lad.powers[i]), 3), "face": s, "max_abs": worst,
                     "rms": math.sqrt(sq / count)})
    return rows


def sky_visibility_record(scene: Any, size: int, args: argparse.Namespace, tmp: Path, ctx: Any, ps: ProbeSet,
                          rng: np.random.Generator) -> dict[str, Any]:
    """The ``sky_visibility`` record of one face size (module docstring); ``ps``: the fast path's set."""
    rec: dict[str, Any] = {"goal_ratio": GOAL_RATIO, "pairs": []}
    for k in range(max(0, args.sky_visibility_reps)):
        without = _bake(scene, tmp / f"skyvis_without_{size}", size, args.spacing, args.fast_quality, ctx, False)
        with_ = _bake(scene, tmp / f"skyvis_with_{size}", size, args.spacing, args.fast_quality, ctx, True)
        rec["pairs"].append({"without": without, "with": with_, "ratio_wall": round(with_["wall_s"] / without["wall_s"], 3),
                             "ratio_cpu": round(with_["cpu_s"] / without["cpu_s"], 3)})
    if rec["pairs"]:
        for key in ("ratio_wall", "ratio_cpu"):
            vals = [p[key] for p in rec["pairs"]]
            rec[f"{key}_median"], rec[f"{key}_max"] = statistics.median(vals), max(vals)
    layers = ps.layer_count
    picks = np.unique(np.linspace(0, layers - 1, max(1, min(args.error_probes, layers))).round().astype(int))
    alpha = np.asarray(ps.levels[0][picks], np.float64)[..., 3]
    lad = rung_ladder(ps.resolution, "half_octave")
    vis = prefilter_sky_visibility(alpha, lad, ORDER)
    rec["error"] = {"probes": picks.tolist(), "samples_per_rung": args.samples,
                    "harmonics": _errors(alpha, vis, rng, args.samples)}
    k = min(max(0, args.sky_visibility_gl_probes), len(picks))
    if k:
        t0, c0 = time.perf_counter(), time.process_time()
        old = prefilter_sky_visibility(alpha[:k], lad, ORDER, quality="default", ctx=ctx)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        rec["error"]["gl_default"] = _errors(alpha[:k], old, rng, args.samples)
        rec["gl_default"] = {"probes": k, "seconds_per_probe": round(wall / k, 3), "cpu_seconds_per_probe": round(cpu / k, 3),
                             "set_seconds_extrapolated": round(wall / k * layers, 1)}
        if rec["pairs"]:
            base = statistics.median(p["without"]["wall_s"] for p in rec["pairs"])
            rec["gl_default"]["ratio_wall_extrapolated"] = round((base + wall / k * layers) / base, 1)
    return rec


def table_lines(result: dict[str, Any]) -> list[str]:
    """The markdown rows of ``bench bake``'s ``sky_visibility`` records."""
    lines = ["", "| size | probes | bake s (without / with --sky-visibility, each pair) | writer s | ratio wall (median, max) "
             "| ratio CPU (median) | moments max abs error (harmonics; GL) |", "| --- | --- | --- | --- | --- | --- | --- |"]
    for rec in result["sizes"]:
        sv = rec.get("sky_visibility")
        if not sv or not sv["pairs"]:
            continue
        pairs = ", ".join(f"{p['without']['wall_s']:.1f} / {p['with']['wall_s']:.1f}" for p in sv["pairs"])
        writer = ", ".join(f"{p['with']['writer_s']:.2f}" for p in sv["pairs"])
        err = f"{max(e['max_abs'] for e in sv['error']['harmonics']):.1e}"
        if "gl_default" in sv["error"]:
            err += f"; {max(e['max_abs'] for e in sv['error']['gl_default']):.1e} (GL: {sv['gl_default']['seconds_per_probe']} s "\
                   f"per probe, ~{sv['gl_default'].get('ratio_wall_extrapolated', '?')}x)"
        lines.append(f"| {rec['size']} | {rec['probes']} | {pairs} | {writer} | {sv['ratio_wall_median']:.2f}, "
                     f"{sv['ratio_wall_max']:.2f} | {sv['ratio_cpu_median']:.2f} | {err} |")
    return lines
