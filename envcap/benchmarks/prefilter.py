"""Cosine-lobe chain filters: time and error against the exact float64 reference, per level."""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from envcap import cube as cm
from envcap.atomic import atomic_output_dir
from envcap.lobes import lobe_ladder
from envcap.prefilter import convolve_exact_dirs, omega_box_pyramid, prefilter_chain

LUMA = np.array([0.2126, 0.7152, 0.0722])


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (JSON + PNG)")
    p.add_argument("--size", type=int, default=256, help="face size of the inputs (default 256)")
    p.add_argument("--samples", type=int, default=96,
                   help="output texels per level evaluated with the exact method (time extrapolated to the full chain)")


def inputs(n: int) -> dict[str, np.ndarray]:
    """Synthetic street probe (premultiplied RGBA, sharp edges, alpha-0 sky) composited over a sky, and a sky with a sun."""
    d = cm.texel_directions(n)
    az = np.arctan2(d[..., 0], d[..., 2])
    geo = (d[..., 1] < 0.35 + 0.2 * (np.sin(7 * az) > 0)).astype(np.float64)
    rgb = np.stack([0.3 + 0.2 * (d[..., 0] > 0.2), 0.25 + 0.1 * (d[..., 2] > 0), 0.2 + 0 * d[..., 0]], -1) * 500
    street = np.concatenate([rgb * geo[..., None], geo[..., None]], -1)
    sky = np.stack([4e3 + 3e3 * np.clip(d[..., 1], 0, 1), 5e3 + 3e3 * np.clip(d[..., 1], 0, 1), 8e3 + 4e3 * np.clip(d[..., 1], 0, 1),
                    np.ones_like(az)], -1) * (d[..., 1:2] > -0.05)
    sun_dir = np.array([0.6, 0.55, 0.58]) / np.linalg.norm([0.6, 0.55, 0.58])
    sun = (d @ sun_dir > math.cos(2.0 / n)) * np.float32(1e9)
    sky_sun = sky.copy()
    sky_sun[..., :3] += sun[..., None]
    return {"street": street + (1 - street[..., 3:4]) * sky, "sky_sun": sky_sun.astype(np.float32).astype(np.float64)}


def run(args: argparse.Namespace) -> int:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from envcap.gl import create_context

    n = int(args.size)
    if n < 2:
        raise ValueError(f"--size must be >= 2, got {n}")
    lad = lobe_ladder(n)
    ctx = create_context()
    rng = np.random.default_rng(0)
    result: dict = {"size": n, "ladder": lad.to_manifest(), "inputs": {}}
    total_out = sum(6 * s * s for s in lad.sizes[1:])
    for name, env in inputs(n).items():
        rec: dict = {}
        picks, exact, t_exact = [], [], 0.0
        for k in range(1, lad.levels):
            nk = lad.sizes[k]
            idx = rng.choice(6 * nk * nk, min(args.samples, 6 * nk * nk), replace=False)
            dirs = cm.texel_directions(nk).reshape(-1, 3)[idx]
            t = time.perf_counter()
            exact.append(convolve_exact_dirs(env, lad.powers[k], dirs))
            t_exact += (time.perf_counter() - t) * (6 * nk * nk) / idx.size
            picks.append(idx)
        rec["exact"] = {"seconds_extrapolated": t_exact, "note": f"{args.samples} texels per level timed, scaled to all {total_out}"}

        def err(chain):
            out = []
            for k in range(1, lad.levels):
                om = cm.texel_solid_angles(lad.sizes[k]).reshape(-1)[picks[k - 1]]
                yf = chain[k].reshape(-1, chain[k].shape[-1])[picks[k - 1], :3] @ LUMA
                ye = exact[k - 1][:, :3] @ LUMA
                out.append(float(math.sqrt((om * (yf - ye) ** 2).sum() / (om * ye**2).sum())))
            return out

        for q in ("fast", "default", "high"):
            t = time.perf_counter()
            chain = prefilter_chain(env, lad, quality=q, ctx=ctx, progress=False)
            dt = time.perf_counter() - t
            rec[q] = {"seconds": dt, "speedup_vs_exact": t_exact / dt, "rel_rmse_per_level": err(chain)}
        t = time.perf_counter()
        box = omega_box_pyramid(env, lad.levels)
        dt = time.perf_counter() - t
        rec["box_mips"] = {"seconds": dt, "speedup_vs_exact": t_exact / dt, "rel_rmse_per_level": err(box)}
        result["inputs"][name] = rec
        print(name, {m: (round(v.get("seconds", v.get("seconds_extrapolated")), 3),
                         max(v.get("rel_rmse_per_level", [0]))) for m, v in rec.items()}, flush=True)
    ctx.release()
    with atomic_output_dir(args.out) as tmp:
        (tmp / "prefilter.json").write_text(json.dumps(result, indent=2))
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        for ax, (name, rec) in zip(axes, result["inputs"].items()):
            for m in ("fast", "default", "high", "box_mips"):
                ax.semilogy(range(1, lad.levels), np.maximum(rec[m]["rel_rmse_per_level"], 1e-9), "o-",
                            label=f"{m} ({rec[m]['speedup_vs_exact']:.0f}x faster than exact)")
            ax.axhline(5e-3, color="k", ls=":", label="0.5% target")
            ax.set_title(f"{name}, 6x{n}^2, exact: {rec['exact']['seconds_extrapolated']:.0f} s (extrapolated)")
            ax.set_xlabel("level k")
            ax.set_ylabel("relative RMSE of luminance vs exact")
            ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(tmp / "prefilter_cost.png", dpi=110)
    return 0
