"""Cosine-lobe chain filters: time and error against the exact float64 reference, per level.

Filters (``quality``): ``fast``, ``default``, ``high`` (coarse sources, :mod:`envcap.prefilter.fast`),
``composed`` (difference lobes, :mod:`envcap.prefilter.composed`), and solid-angle box mips.  At
``--full-size`` also ``composed_direct`` (the composed mode's GL passes with every level filtered
directly from level 0: what composing adds is the difference) and ``composition_float64`` (each
composed level from the *exact* source level, float64 brute force: the error of the method alone).
Times: best of ``--repeats`` runs after a warm-up, wall and CPU (``time.process_time``, which
counts llvmpipe's threads), with the load average.  cmft is not built here: its time enters only as
a conversion through the known point ``--cmft-seconds`` (256^2 in and out, 9 levels, 2 threads, on
this machine: ``../shared/PLATFORM.md``).  Inputs: :func:`envcap.benchmarks.inputs.real_inputs`.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from typing import Any, Callable

import numpy as np
from numpy.typing import NDArray

from envcap.benchmarks.inputs import real_inputs
from envcap.core import cube as cm
from envcap.core.color import luminance
from envcap.core.lobes import LobeLadder, lobe_ladder
from envcap.gpu.context import create_context
from envcap.outputs import atomic_output_dir
from envcap.prefilter import (QUALITIES, composition_plan, convolve_exact, convolve_exact_dirs, omega_box_pyramid,
                              prefilter_chain)
from envcap.prefilter.composed import prefilter_many_composed
from envcap.prefilter.composition import COMPOSED_EPS, TAYLOR_MAX_THETA, TAYLOR_MIN_SIZE, LevelStep
from envcap.prefilter.footprint import LOOP_BUDGET, footprint_theta, loop_estimate
from envcap.prefilter.hot import hot_texels, luminance_weight

CMFT_SIZE = 256


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (JSON + PNG)")
    p.add_argument("--size", type=int, default=256, help="face size of the inputs (default 256)")
    p.add_argument("--samples", type=int, default=96,
                   help="output texels per level evaluated with the exact method (time extrapolated to the full chain)")
    p.add_argument("--full-size", type=int, default=64,
                   help="face size at which the exact method runs on every output texel (measured, not extrapolated)")
    p.add_argument("--repeats", type=int, default=3, help="timed runs per filter; the best is reported (default 3)")
    p.add_argument("--cmft-seconds", type=float, default=4.8,
                   help="cmft's wall time for 256^2 in and out, 9 levels, 2 threads, on this machine (default 4.8, "
                        "PLATFORM.md); used only to convert the 256^2 times")


def _timed(fn: Callable[[], Any], repeats: int) -> tuple[Any, float, float]:
    """``(result, best wall seconds, best CPU seconds)`` of ``fn`` after one warm-up call."""
    out = fn()
    walls, cpus = [], []
    for _ in range(max(1, repeats)):
        c0, t0 = time.process_time(), time.perf_counter()
        out = fn()
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    return out, min(walls), min(cpus)


def _direct_plan(ladder: LobeLadder) -> list[LevelStep] | None:
    """Every level filtered from level 0 with the composed mode's passes (``composed_direct``), or
    ``None`` where a footprint would exceed the GL loop budget."""
    plan = []
    for k in range(1, ladder.levels):
        theta = footprint_theta(float(ladder.powers[k]), COMPOSED_EPS)
        if loop_estimate(theta, ladder.sizes[0]) > LOOP_BUDGET:
            return None
        plan.append(LevelStep(k, 0, float(ladder.powers[k]), ladder.sizes[0] >= TAYLOR_MIN_SIZE and theta <= TAYLOR_MAX_THETA))
    return plan


def composition_float64(env: NDArray[np.float64], ladder: LobeLadder) -> list[NDArray[np.float64]]:
    """The composed plan evaluated in float64 from *exact* source levels (brute force), hot texels
    split off and added exactly as the GL mode does: each level's error is the method's own
    (difference-lobe shape, sampling of the source level), free of truncation and float32."""
    hot, _ = hot_texels(luminance_weight(env))
    hot_cube = np.zeros_like(env)
    lum = 3 if env.shape[-1] >= 3 else env.shape[-1]
    hot_cube.reshape(-1, env.shape[-1])[hot, :lum] = env.reshape(-1, env.shape[-1])[hot, :lum]
    cold = env - hot_cube
    exact_cold = [cold] + [convolve_exact(cold, ladder.powers[k], ladder.sizes[k]) for k in range(1, ladder.levels)]
    out = [env]
    for s in composition_plan(ladder):
        k = s.level
        hot_k = convolve_exact(hot_cube, ladder.powers[k], ladder.sizes[k]) if hot.size else 0.0
        src = convolve_exact(exact_cold[s.source], s.lobe, ladder.sizes[k]) if s.source else exact_cold[k]
        out.append(src + hot_k)
    return out


def _run_size(size: int, samples: int | None, ctx: Any, rng: np.random.Generator, repeats: int,
              cmft_seconds: float) -> dict:
    lad = lobe_ladder(size)
    run_rec: dict = {"size": size, "exact": "sampled" if samples else "full", "ladder": lad.to_manifest(),
                     "composed_plan": [[s.level, s.source, s.lobe, s.taylor] for s in composition_plan(lad)], "inputs": {}}
    total_out = sum(6 * s * s for s in lad.sizes[1:])
    for name, env in real_inputs(size, ctx).items():
        rec: dict = {}
        picks, exact, t_exact = [], [], 0.0
        for k in range(1, lad.levels):
            nk = lad.sizes[k]
            m = 6 * nk * nk if samples is None else min(samples, 6 * nk * nk)
            idx = np.arange(m) if samples is None else rng.choice(6 * nk * nk, m, replace=False)
            dirs = cm.texel_directions(nk).reshape(-1, 3)[idx]
            t = time.perf_counter()
            exact.append(convolve_exact_dirs(env, lad.powers[k], dirs))
            t_exact += (time.perf_counter() - t) * (6 * nk * nk) / idx.size
            picks.append(idx)
        rec["exact"] = {"seconds" if samples is None else "seconds_extrapolated": t_exact,
                        "note": "every output texel" if samples is None else
                        f"{samples} texels per level timed, scaled to all {total_out}"}

        def err(chain: list[NDArray]) -> list[float]:
            out = []
            for k in range(1, lad.levels):
                om = cm.texel_solid_angles(lad.sizes[k]).reshape(-1)[picks[k - 1]]
                yf = luminance(chain[k].reshape(-1, chain[k].shape[-1])[picks[k - 1]])
                ye = luminance(exact[k - 1])
                out.append(float(math.sqrt((om * (yf - ye) ** 2).sum() / (om * ye**2).sum())))
            return out

        runs: dict[str, Callable[[], Any]] = {
            q: (lambda q=q: prefilter_chain(env, lad, quality=q, ctx=ctx, progress=False)) for q in QUALITIES}
        runs["box_mips"] = lambda: omega_box_pyramid(env, lad.levels)
        direct = _direct_plan(lad) if samples is None else None
        if direct is not None:
            runs["composed_direct"] = lambda: [lv[0] for lv in prefilter_many_composed(env[None], lad, ctx, False,
                                                                                      plan=direct)]
        for method, fn in runs.items():
            chain, wall, cpu = _timed(fn, repeats)
            rec[method] = {"seconds": wall, "cpu_seconds": cpu, "speedup_vs_exact": t_exact / wall,
                           "rel_rmse_per_level": err(chain)}
            if size == CMFT_SIZE:   # a conversion through the known point, not a measurement of cmft
                rec[method]["speedup_vs_cmft_converted"] = cmft_seconds / wall
        if samples is None:
            rec["composition_float64"] = {"rel_rmse_per_level": err(composition_float64(env, lad)),
                                          "note": "float64 brute force from exact sources: the method's error alone"}
        rec["load_average"] = list(os.getloadavg())
        run_rec["inputs"][name] = rec
        print(size, name, {m: (round(v.get("seconds", v.get("seconds_extrapolated", 0)), 3),
                               f"{max(v.get('rel_rmse_per_level', [0])):.2g}") for m, v in rec.items() if isinstance(v, dict)},
              flush=True)
    return run_rec


def run(args: argparse.Namespace) -> int:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = int(args.size)
    if n < 2:
        raise ValueError(f"--size must be >= 2, got {n}")
    ctx = create_context()
    rng = np.random.default_rng(0)
    result: dict = {"cmft": {"seconds": float(args.cmft_seconds), "size": CMFT_SIZE, "levels": 9, "threads": 2,
                             "note": "not run here: the known point of PLATFORM.md; ratios against it are conversions"},
                    "runs": []}
    try:
        for size, samples in ((n, int(args.samples)), (int(args.full_size), None)):
            result["runs"].append(_run_size(size, samples, ctx, rng, int(args.repeats), float(args.cmft_seconds)))
    finally:
        ctx.release()
    with atomic_output_dir(args.out) as tmp:
        (tmp / "prefilter.json").write_text(json.dumps(result, indent=2))
        fig, axes = plt.subplots(2, 2, figsize=(12, 8.5))
        for row, run_rec in zip(axes, result["runs"]):
            lv = range(1, len(run_rec["ladder"]["sizes"]))
            for ax, (name, rec) in zip(row, run_rec["inputs"].items()):
                for m in ("fast", "default", "high", "composed", "composed_direct", "composition_float64", "box_mips"):
                    if m not in rec:
                        continue
                    label = m if "cpu_seconds" not in rec[m] else \
                        f"{m}: {rec[m]['seconds']:.3g} s, {rec[m]['speedup_vs_exact']:.0f}x faster than exact"
                    ax.semilogy(lv, np.maximum(rec[m]["rel_rmse_per_level"], 1e-9), "o-", label=label)
                ax.axhline(5e-3, color="k", ls=":", label="0.5% target")
                ex = rec["exact"]
                how = f"{ex['seconds']:.0f} s" if "seconds" in ex else f"{ex['seconds_extrapolated']:.0f} s extrapolated"
                ax.set_title(f"{name}, 6x{run_rec['size']}^2, exact: {how}", fontsize=9)
                ax.set_xlabel("level k")
                ax.set_ylabel("relative RMSE of luminance vs exact")
                ax.legend(fontsize=6)
        fig.tight_layout()
        fig.savefig(tmp / "prefilter_cost.png", dpi=110)
    return 0
