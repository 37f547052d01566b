"""z(w) lookup error: envcap's lobe ladder vs McGuire et al. 2013 box mips vs a cmft-style ladder.

For cosine powers ``w`` log-spaced in [1, 1e4], each method builds its chain the way it is meant
to be built and is looked up at its own continuous level for ``w`` (GL-style trilinear between
the two nearest levels, seamless bilinear within a level: :func:`envcap.core.cube_sampling.sample_cube`);
the error is against the exact normalized ``cos^w`` convolution
(:func:`envcap.prefilter.exact.convolve_exact_dirs`) at random uniform directions:

* ``envcap``: :func:`envcap.core.lobes.lobe_ladder` + :func:`envcap.prefilter.fast.prefilter_chain`,
  level ``z(w)`` from the ladder table;
* ``envcap_sigma1``: the same with ``lobe_ladder(N, sigma_texels=1)`` (each level's lobe spans
  one texel RMS instead of half a texel);
* ``mcguire2013``: solid-angle box mips, ``m = log2(N sqrt 3) - 0.5 log2(w + 1)``;
* ``cmft``: level ``k`` holds an (exactly filtered) ``cos^w_k`` lobe with
  ``w_k = 2^(scale g_k + bias)``, ``g_k = 1 - k / (L - 1)``, cmft's defaults ``scale = 10``,
  ``bias = 1``; lookup ``g = (log2 w - bias) / scale``, level ``(1 - g)(L - 1)``.

Error: relative RMSE of luminance over the directions (uniform on the sphere, so solid-angle
weighted).  Inputs: a captured ``canyon`` probe at (0, 2, 0) composited over its sky, and the
Preetham sky with its sun (:mod:`envcap.benchmarks.inputs`).
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from envcap.benchmarks.inputs import real_inputs
from envcap.core.color import luminance
from envcap.core.cube_sampling import sample_cube
from envcap.core.lobes import lobe_ladder
from envcap.gpu.context import create_context
from envcap.outputs import atomic_output_dir
from envcap.prefilter import convolve_exact_dirs, omega_box_pyramid, prefilter_chain, prefilter_level


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (JSON + PNG)")
    p.add_argument("--size", type=int, default=64, help="face size of the inputs (default 64)")
    p.add_argument("--dirs", type=int, default=1024, help="random directions per w (default 1024)")
    p.add_argument("--powers", type=int, default=17, help="number of log-spaced w in [1, 1e4] (default 17)")


def mcguire_level(w: np.ndarray, n: int, levels: int) -> np.ndarray:
    """McGuire et al. 2013: ``m = log2(N sqrt 3) - 0.5 log2(w + 1)``, clamped to the chain."""
    return np.clip(math.log2(n * math.sqrt(3.0)) - 0.5 * np.log2(np.asarray(w, float) + 1.0), 0, levels - 1)


def cmft_powers(levels: int, scale: float = 10.0, bias: float = 1.0) -> np.ndarray:
    g = 1.0 - np.arange(levels) / max(levels - 1, 1)
    return 2.0 ** (scale * g + bias)


def cmft_level(w: np.ndarray, levels: int, scale: float = 10.0, bias: float = 1.0) -> np.ndarray:
    g = (np.log2(np.maximum(np.asarray(w, float), 1e-30)) - bias) / scale
    return np.clip((1.0 - g) * (levels - 1), 0, levels - 1)


def run(args: argparse.Namespace) -> int:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = int(args.size)
    if n < 4:
        raise ValueError(f"--size must be >= 4, got {n}")
    ctx = create_context()
    rng = np.random.default_rng(0)
    dirs = rng.normal(size=(int(args.dirs), 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    ws = np.logspace(0, 4, int(args.powers))
    lad = lobe_ladder(n)
    lad1 = lobe_ladder(n, sigma_texels=1.0)  # the same rule with lobes of 1 texel RMS (better resolved, fewer sharp levels)
    levels = lad.levels
    result = {"size": n, "directions": int(args.dirs), "w": ws.tolist(), "ladder": lad.to_manifest(),
              "cmft_powers": cmft_powers(levels).tolist(), "inputs": {}}
    for name, env in real_inputs(n, ctx).items():
        t0 = time.perf_counter()
        chains = {
            "envcap": (prefilter_chain(env, lad, ctx=ctx, progress=False), lad.z(ws)),
            "envcap_sigma1": (prefilter_chain(env, lad1, ctx=ctx, progress=False), lad1.z(ws)),
            "mcguire2013": (omega_box_pyramid(env, levels), mcguire_level(ws, n, levels)),
            "cmft": ([prefilter_level(env, wk, lad.sizes[k], ctx=ctx) for k, wk in enumerate(cmft_powers(levels))],
                     cmft_level(ws, levels)),
        }
        rec = {m: [] for m in chains}
        for i, w in enumerate(ws):
            ye = luminance(convolve_exact_dirs(env, w, dirs))
            for m, (chain, lod) in chains.items():
                yl = luminance(sample_cube(chain, dirs, np.full(len(dirs), lod[i])))
                rec[m].append(float(np.sqrt(np.mean((yl - ye) ** 2) / np.mean(ye ** 2))))
        result["inputs"][name] = rec
        print(name, f"{time.perf_counter() - t0:.1f} s", {m: f"max {max(v):.3g} median {np.median(v):.3g}" for m, v in rec.items()}, flush=True)
    ctx.release()
    with atomic_output_dir(args.out) as tmp:
        (tmp / "zw.json").write_text(json.dumps(result, indent=2))
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        for ax, (name, rec) in zip(axes, result["inputs"].items()):
            for m, style in (("envcap", "o-"), ("envcap_sigma1", "d-"), ("mcguire2013", "s--"), ("cmft", "^:")):
                ax.loglog(ws, np.maximum(rec[m], 1e-7), style, label=m)
            for wk in lad.powers:
                if 1 <= wk <= 1e4:
                    ax.axvline(wk, color="0.85", lw=0.8, zorder=0)
            ax.axhline(5e-3, color="k", ls=":", lw=0.8)
            ax.set_title(f"{name}, 6x{n}^2: lookup at level(w) vs exact cos^w")
            ax.set_xlabel("cosine power w (grey: envcap ladder nodes)")
            ax.set_ylabel("relative RMSE of luminance")
            ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(tmp / "prefilter_zw_error.png", dpi=110)
    return 0
