"""Cosine-lobe chain filters: time and error against the exact float64 reference, per level."""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from envcap.benchmarks.inputs import real_inputs
from envcap.core import cube as cm
from envcap.core.color import luminance
from envcap.core.lobes import lobe_ladder
from envcap.gpu.context import create_context
from envcap.outputs import atomic_output_dir
from envcap.prefilter import convolve_exact_dirs, omega_box_pyramid, prefilter_chain


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (JSON + PNG)")
    p.add_argument("--size", type=int, default=256, help="face size of the inputs (default 256)")
    p.add_argument("--samples", type=int, default=96,
                   help="output texels per level evaluated with the exact method (time extrapolated to the full chain)")
    p.add_argument("--full-size", type=int, default=64,
                   help="face size at which the exact method runs on every output texel (measured, not extrapolated)")


def run(args: argparse.Namespace) -> int:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = int(args.size)
    if n < 2:
        raise ValueError(f"--size must be >= 2, got {n}")
    ctx = create_context()
    rng = np.random.default_rng(0)
    result: dict = {"runs": []}
    for size, samples in ((n, int(args.samples)), (int(args.full_size), None)):
        lad = lobe_ladder(size)
        run_rec: dict = {"size": size, "exact": "sampled" if samples else "full", "ladder": lad.to_manifest(), "inputs": {}}
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

            def err(chain):
                out = []
                for k in range(1, lad.levels):
                    om = cm.texel_solid_angles(lad.sizes[k]).reshape(-1)[picks[k - 1]]
                    yf = luminance(chain[k].reshape(-1, chain[k].shape[-1])[picks[k - 1]])
                    ye = luminance(exact[k - 1])
                    out.append(float(math.sqrt((om * (yf - ye) ** 2).sum() / (om * ye**2).sum())))
                return out

            for q in ("fast", "default", "high"):
                prefilter_chain(env, lad, quality=q, ctx=ctx, progress=False)  # warm-up (shader compile)
                t = time.perf_counter()
                chain = prefilter_chain(env, lad, quality=q, ctx=ctx, progress=False)
                dt = time.perf_counter() - t
                rec[q] = {"seconds": dt, "speedup_vs_exact": t_exact / dt, "rel_rmse_per_level": err(chain)}
            t = time.perf_counter()
            box = omega_box_pyramid(env, lad.levels)
            dt = time.perf_counter() - t
            rec["box_mips"] = {"seconds": dt, "speedup_vs_exact": t_exact / dt, "rel_rmse_per_level": err(box)}
            run_rec["inputs"][name] = rec
            print(size, name, {m: (round(v.get("seconds", v.get("seconds_extrapolated", 0)), 3),
                                   f"{max(v.get('rel_rmse_per_level', [0])):.2g}") for m, v in rec.items()}, flush=True)
        result["runs"].append(run_rec)
    ctx.release()
    with atomic_output_dir(args.out) as tmp:
        (tmp / "prefilter.json").write_text(json.dumps(result, indent=2))
        fig, axes = plt.subplots(2, 2, figsize=(11, 8))
        for row, run_rec in zip(axes, result["runs"]):
            lv = range(1, len(run_rec["ladder"]["sizes"]))
            for ax, (name, rec) in zip(row, run_rec["inputs"].items()):
                for m in ("fast", "default", "high", "box_mips"):
                    ax.semilogy(lv, np.maximum(rec[m]["rel_rmse_per_level"], 1e-9), "o-",
                                label=f"{m}: {rec[m]['seconds']:.3g} s, {rec[m]['speedup_vs_exact']:.0f}x faster than exact")
                ax.axhline(5e-3, color="k", ls=":", label="0.5% target")
                ex = rec["exact"]
                how = f"{ex['seconds']:.0f} s" if "seconds" in ex else f"{ex['seconds_extrapolated']:.0f} s extrapolated"
                ax.set_title(f"{name}, 6x{run_rec['size']}^2, exact: {how}", fontsize=9)
                ax.set_xlabel("level k")
                ax.set_ylabel("relative RMSE of luminance vs exact")
                ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(tmp / "prefilter_cost.png", dpi=110)
    return 0
