"""Where a ladder lookup's error comes from: blending two lobes, and interpolating one level.

The two error terms of ``docs/lobes.md`` ("Why the paper's chain is off between levels"), measured
separately on the canyon street (probe at (0, 2, 0) over its sky without the sun) and that sky,
relative RMSE of luminance at 1024 random uniform directions:

* ``blend``: ``(1 - t) E_wa + t E_wb`` against ``E_w`` with exact lobes (no texels), for nodes
  ``w_a = 3 .. 1022`` and ``w_b`` a variance ratio ``rho = 2^octaves`` wider (4, 2, sqrt 2),
  ``t = 1/4, 1/2, 3/4``; ``w`` from the log rule (``log2(1 + w)`` linear in ``t``, the runtime's)
  or the variance rule (``1 / (w + 2)`` linear in ``t``: the mixture's mean cosine exact);
* ``interp``: the GL filter's ``cos^w`` level stored on ``M^2`` faces, looked up bilinearly,
  against the exact convolution, for ``M = 4 .. 2N`` (``sigma_texels``: the lobe's RMS angle in
  face-centre texels of the input's ``N``).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from envcap.benchmarks.zw import zw_inputs
from envcap.core.color import luminance
from envcap.core.cube_sampling import sample_cube
from envcap.gpu.context import create_context
from envcap.outputs import atomic_output_dir
from envcap.prefilter import convolve_exact_dirs, prefilter_level


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (JSON)")
    p.add_argument("--size", type=int, default=64, help="face size of the inputs (default 64)")


def run(args: argparse.Namespace) -> int:
    n = int(args.size)
    if n < 8:
        raise ValueError(f"--size must be >= 8, got {n}")
    ctx = create_context()
    rng = np.random.default_rng(0)
    d = rng.normal(size=(1024, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    inputs, _, _ = zw_inputs(n, ctx)
    result: dict = {"size": n, "blend": {}, "interp": {}}
    for name in ("street", "sky"):
        env = inputs[name]
        cache: dict[float, np.ndarray] = {}

        def exact(w: float) -> np.ndarray:
            if w not in cache:
                cache[w] = luminance(convolve_exact_dirs(env, w, d))
            return cache[w]

        def rel(a: np.ndarray, b: np.ndarray) -> float:
            return float(np.sqrt(np.mean((a - b) ** 2) / np.mean(b ** 2)))

        for octaves in (2.0, 1.0, 0.5):
            res: dict[str, list[float]] = {"log": [], "var": []}
            for wa in (3, 14, 62, 254, 1022):
                va = 1.0 / (wa + 2)
                vb = va * 2 ** octaves
                wb = 1.0 / vb - 2
                if wb < 0.5:
                    continue
                xa, xb = np.log2(1 + wa), np.log2(1 + wb)
                for t in (0.25, 0.5, 0.75):
                    mix = (1 - t) * exact(wa) + t * exact(wb)
                    res["log"].append(rel(mix, exact(2 ** (xa + t * (xb - xa)) - 1)))
                    res["var"].append(rel(mix, exact(1.0 / (va + t * (vb - va)) - 2)))
            result["blend"][f"{name}_rho_2^{octaves:g}"] = {
                k: {"median": float(np.median(v)), "max": float(np.max(v))} for k, v in res.items()}
            print(name, "blend", octaves, result["blend"][f"{name}_rho_2^{octaves:g}"], flush=True)
        rows = []
        for w in (1, 4, 16, 64, 256, 1000, 3000, 1e4):
            row = {"w": float(w), "sigma_texels": float(1 / np.sqrt(w + 2) / (2 / n))}
            for m in (4, 8, 16, 32, 64, 128, 256, 512):
                if m <= 2 * n:
                    yl = luminance(sample_cube([prefilter_level(env, w, m, ctx=ctx)], d, 0.0))
                    row[f"M{m}"] = rel(yl, exact(float(w)))
            rows.append(row)
            print(name, "interp", {k: round(v, 4) for k, v in row.items()}, flush=True)
        result["interp"][name] = rows
    ctx.release()
    with atomic_output_dir(args.out) as tmp:
        (tmp / "lobe_blend.json").write_text(json.dumps(result, indent=2))
    return 0
