"""narrow: where the parallax error of narrow streets comes from (an error budget at w >= 64).

For each scene (default ``canyon``, ``crossing``, ``asymmetric``: the narrow ones, and ``avenue``
for contrast) 60 m are baked in memory (64^2, 5 m, as the default sweep), ``--positions``
positions per street are drawn like the default sweep, and at each the truth (a fresh capture,
filtered at exactly ``w``, sun out of the sky: docs/evaluation.md) is compared with a ladder of
predictions, each removing one more source of error:

* ``nearest``, ``planes_mip`` (the paper), ``planes_mip_footprint`` (traced footprint shift),
  ``planes_mip_aniso`` (its 2 taps), ``planes_mip_sigma`` (4 taps where the sigma rays land),
  ``blend``, ``planes_mip_oblique`` (the oblique closed-form shift), ``fitted_planes_mip``,
  ``fitted_planes_oblique`` (the oblique shift on the fitted planes) and ``depth_refine`` (the
  fitted planes' hit checked against the probe's distance and refined where wrong, oblique
  shift): the runtime methods;
* ``exact_lobe``: the footprint shift with a perfect ladder: the nearest probe's level 0 filtered
  with the exact normalized cos^w' lobe around ``r`` for every direction (float64 sum over its
  texels; ``w'`` the traced footprint's power).  Minus ``planes_mip_footprint``: what the ladder
  costs (interpolation between levels, the chain's texels);
* ``exact_lobe_taps8``: the same perfect ladder read with 8 taps along the footprint's long axis
  (``planes_mip_aniso``'s rule): what the footprint's anisotropy is worth with a perfect ladder;
* ``planes_then_filter``: the nearest probe's level 0 reprojected through its three planes to the
  shading point for every texel of a 64^2 cube, then filtered at exactly ``w`` like the truth: no
  mip shift at all (the footprint is exact).  Minus ``exact_lobe``: what one isotropic lobe per
  direction costs (anisotropy, footprint shape);
* ``depth_then_filter``: the same reprojection through the probe's distance channel
  (``depth_reproject``) instead of three planes.  ``planes_then_filter`` minus it: what the plane
  model costs (set-backs, gaps, street ends); what is left is what the probe cannot see from
  where it stands (disocclusion), its resolution and the depth march's own error.

Errors: mean over positions of the solid-angle weighted relative RMSE of luminance (the
evaluator's metric) at each ``--powers``.  Writes ``narrow.json`` to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.core import cube as cubemod
from envcap.evaluate.metrics import relative_rmse
from envcap.evaluate.predict import Predictor
from envcap.evaluate.sweep import Sweep, sample_positions
from envcap.evaluate.truth import TruthRenderer, filter_truth, truth_grid_size
from envcap.gpu.context import create_context
from envcap.outputs import atomic_output_dir
from envcap.probeset.bake import bake_probe_set
from envcap.runtime.footprint import sigma_footprint, tap_offsets
from envcap.runtime.sampling import composite
from envcap.scene import load_scene
from envcap.scene.segment import street_segment

METHODS = ("nearest", "planes_mip", "planes_mip_footprint", "planes_mip_aniso", "planes_mip_sigma", "blend",
           "planes_mip_oblique", "fitted_planes_mip", "fitted_planes_oblique", "depth_refine")
CHEAP = ("planes_mip", "planes_mip_footprint", "planes_mip_aniso", "blend", "planes_mip_oblique", "fitted_planes_mip",
         "fitted_planes_oblique", "depth_refine")
"""The runtime methods costing <= 3x a plain lookup (docs/runtime.md, "Cost"; all but ``planes_mip_sigma``)."""
STAGES = METHODS + ("exact_lobe", "exact_lobe_taps8", "planes_then_filter", "depth_then_filter")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", required=True, type=Path, help="output directory (written atomically)")
    parser.add_argument("--scenes", default="canyon,crossing,asymmetric,avenue", help="bundled scenes, comma-separated")
    parser.add_argument("--positions", type=int, default=6, metavar="K", help="positions per street (default 6)")
    parser.add_argument("--powers", default="64,256", help="lobe powers (default 64,256)")
    parser.add_argument("--stages", default=",".join(STAGES),
                        help="stages to compute, comma-separated, 'nearest' among them (default: all; e.g. "
                             "nearest,planes_mip_oblique,fitted_planes_mip,depth_refine for a short run)")


def exact_lobe(level0: NDArray, r: NDArray, w: NDArray) -> NDArray[np.float64]:
    """``(M, 4)``: the cube ``level0`` ``(6, N, N, 4)`` filtered with the normalized cos^w lobe
    around each unit ``r`` ``(M, 3)`` (float64 sum over texels, weights renormalized; ``w`` clamped
    to the texel power ``~3 N^2`` so that the sum resolves the lobe)."""
    n = level0.shape[1]
    s = cubemod.texel_directions(n).reshape(-1, 3)
    om = cubemod.texel_solid_angles(n).reshape(-1)
    vals = level0.reshape(-1, level0.shape[-1]).astype(np.float64)
    w = np.minimum(np.asarray(w, np.float64), 3.0 * n * n)
    out = np.zeros((r.shape[0], vals.shape[1]))
    for a in range(0, r.shape[0], 256):
        c = np.clip(r[a:a + 256] @ s.T, 0.0, 1.0)
        with np.errstate(divide="ignore"):
            k = np.exp(w[a:a + 256, None] * np.log(np.where(c > 0, c, 1e-300))) * om
        out[a:a + 256] = (k @ vals) / k.sum(axis=1, keepdims=True)
    return out


def run(args: argparse.Namespace) -> int:
    powers = [float(v) for v in args.powers.split(",") if v.strip()]
    if args.positions < 1 or not powers or any(not (w > 0 and math.isfinite(w)) for w in powers):
        raise ValueError("--positions must be >= 1 and --powers positive finite numbers")
    stages = tuple(s for s in STAGES if s in {v.strip() for v in args.stages.split(",")})
    unknown = {v.strip() for v in args.stages.split(",") if v.strip()} - set(STAGES)
    if unknown or "nearest" not in stages:
        raise ValueError(f"--stages must name 'nearest' and stages of {', '.join(STAGES)}; unknown: {sorted(unknown)}")
    t0 = time.perf_counter()
    ctx = create_context()
    result: dict[str, Any] = {}
    try:
        for name in [t.strip() for t in args.scenes.split(",") if t.strip()]:
            scene = street_segment(load_scene(name), 60.0)
            ps = bake_probe_set(scene, resolution=64, spacing=5.0, ctx=ctx, progress=False)
            truth = TruthRenderer(scene, 64, ctx)
            pred = Predictor(ps, sky=truth.sky, ctx=ctx)
            errs: dict[str, dict[float, list[float]]] = {s: {w: [] for w in powers} for s in stages}
            for ep in sample_positions(ps.manifest, Sweep(per_street=args.positions, seed=5)):
                x = np.array(ep.position)
                parts = truth.filtered(truth.capture(x).rgba, powers)
                dfull = cubemod.texel_directions(64).reshape(-1, 3)
                inf = np.full(dfull.shape[0], math.inf)
                cubes = {st: pred.street_rgba(meth, ep.street, x, dfull, inf) for st, meth in
                         (("planes_then_filter", "planes"), ("depth_then_filter", "depth_reproject")) if st in stages}
                local = pred.local_street(ep.street, x)
                xf = local.to_frame(x)            # the probes, planes and cubes are in the street's frame
                i = local.nearest(xf)
                level0 = pred.chains.levels[0][local.layers[i]]
                for w in powers:
                    m = truth_grid_size(w, 64)
                    d = cubemod.texel_directions(m).reshape(-1, 3)
                    sky = truth.sky_at(w, False)
                    t = composite(parts[w]["street"], sky)
                    skyp = pred.sky_rgb(d, np.full(d.shape[0], w), sun=False)
                    for meth in (m for m in METHODS if m in stages):
                        p = pred.predict(meth, ep.street, x, d, np.full(d.shape[0], w), sun=False)
                        errs[meth][w].append(relative_rmse(p.reshape(t.shape), t))
                    if "exact_lobe" not in stages and "exact_lobe_taps8" not in stages:
                        continue
                    sf = sigma_footprint(xf, local.direction_to_frame(d), w, local.positions[i], local.lookup_planes[i],
                                         local.along)
                    if "exact_lobe" in stages:
                        p = composite(exact_lobe(level0, sf.r, sf.power()), skyp)
                        errs["exact_lobe"][w].append(relative_rmse(p.reshape(t.shape), t))
                    if "exact_lobe_taps8" not in stages:
                        continue
                    v_tap = np.maximum(sf.var_minor, sf.var_major / 22.0)       # 8 taps: 1 + (8^2 - 1) / 3
                    spread = np.sqrt(np.maximum(sf.var_major - v_tap, 0.0))
                    acc = np.zeros((d.shape[0], 4))
                    for c in tap_offsets(8):
                        u = sf.r + (c * spread)[:, None] * sf.major
                        acc += exact_lobe(level0, u / np.linalg.norm(u, axis=1, keepdims=True), np.maximum(1 / v_tap - 3, 0))
                    errs["exact_lobe_taps8"][w].append(relative_rmse(composite(acc / 8, skyp).reshape(t.shape), t))
                for w in powers:
                    sky = truth.sky_at(w, False)
                    t = composite(parts[w]["street"], sky)
                    for stage, rgba in cubes.items():
                        f = filter_truth(rgba.reshape(6, 64, 64, 4).astype(np.float32), w, ctx=ctx).astype(np.float64)
                        errs[stage][w].append(relative_rmse(composite(f, sky), t))
            truth.release()
            result[name] = {s: {str(int(w)): float(np.mean(v[w])) for w in powers} for s, v in errs.items()}
            result[name]["positions"] = len(errs["nearest"][powers[0]])
            print(name, json.dumps(result[name]))
    finally:
        ctx.release()
    doc = {"benchmark": "narrow", "powers": powers, "error": "mean rel. RMSE of luminance, sun out of the sky",
           "stages": list(stages), "scenes": result, "total_s": time.perf_counter() - t0}
    with atomic_output_dir(args.out) as tmp:
        (Path(tmp) / "narrow.json").write_text(json.dumps(doc, indent=1) + "\n")
    for w in powers:
        print(f"w = {w:g}: " + " | ".join(stages) + "   (then nearest / each)")
        for name, r in result.items():
            e = {s: r[s][str(int(w))] for s in stages}
            cheap = [s for s in CHEAP if s in e]
            best = f", best <= 3x: {min(cheap, key=lambda s: e[s])}" if cheap else ""
            print(f"  {name:>11}: " + " ".join(f"{e[s]:.3f}" for s in stages) + "   "
                  + " ".join(f"{e['nearest'] / e[s]:.2f}" for s in stages) + best)
    print(f"total {doc['total_s']:.1f} s; wrote {Path(args.out) / 'narrow.json'}")
    return 0
