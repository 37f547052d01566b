"""z(w) lookup error of the ladder modes (paper's chain vs rung ladders), McGuire et al. 2013 box
mips and a cmft-style ladder; Eq. 3 shading from each mode; the composite-after-filtering error.

For cosine powers ``w`` log-spaced in [1, 1e4] (a log-uniform sample of the range), each method
builds its chain the way it is meant to be built and is looked up at its own continuous level for
``w`` (GL-style trilinear, seamless bilinear: :func:`envcap.core.cube_sampling.sample_cube`; a
rung ladder blends its two rungs: :func:`envcap.runtime.rungs.rung_fetch`); the error is against
the exact normalized ``cos^w`` convolution (:func:`envcap.prefilter.exact.convolve_exact_dirs`)
at random uniform directions (relative RMSE of luminance):

* ``paper``: :func:`envcap.core.lobes.lobe_ladder` + :func:`envcap.prefilter.fast.prefilter_chain`
  (the bake's default, "before"); ``half_octave``, ``octave``: :func:`envcap.core.rungs.rung_ladder`
  + :func:`envcap.prefilter.rungs.prefilter_rungs` ("after");
* ``paper_sigma1``: ``lobe_ladder(N, sigma_texels=1)``; ``mcguire2013``: solid-angle box mips,
  ``m = log2(N sqrt 3) - 0.5 log2(w + 1)``; ``cmft``: exact ``cos^w_k`` levels,
  ``w_k = 2^(10 g_k + 1)``, ``g_k = 1 - k / (L - 1)``.

Inputs (one capture of the ``canyon`` probe at (0, 2, 0), the probe's own position: no
parallax): ``street`` (composited over the sky without its sun, as a bake stores it; the sun is
behind a facade from there, so with the sun it is the same cube), ``sky`` (no sun) and ``sky_sun``.

Also: Eq. 3 (:func:`envcap.evaluate.shading.shade`, three materials, the evaluator's frames) lit
by each mode's lookups of ``street`` against the exact lobe integrals (relative RMS error over the
frames); and ``composite``: ``filter(alpha sky) - filter(alpha) filter(sky)`` per ``w`` (the
runtime composites after filtering; sky without its sun), relative to the composited truth and to
the sky term ``filter((1 - alpha) sky)``; ``sky_change``: the same composite lit by the baked sky
and by another one, with the sky-visibility corrections (:func:`sky_change_errors`).
Derivations and the tables: ``docs/lobes.md``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import replace
from typing import Any, Callable

import numpy as np
from numpy.typing import NDArray

from envcap.capture.renderer import CubeCapture
from envcap.core.color import luminance
from envcap.core.cube_sampling import sample_cube
from envcap.core.lobes import lobe_ladder
from envcap.core.rungs import ladder_bytes_per_probe, rung_ladder
from envcap.evaluate.shading import MATERIALS, exact_environment, shade, shading_frames
from envcap.gpu.context import create_context
from envcap.outputs import atomic_output_dir
from envcap.prefilter import convolve_exact_dirs, omega_box_pyramid, prefilter_chain, prefilter_level
from envcap.prefilter.rungs import prefilter_rungs
from envcap.runtime.rungs import RungChains
from envcap.scene import load_scene

Lookup = Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]]
"""``lookup(dirs (M, 3), w (M,)) -> (M, C)``: a method's cos^w-convolved environment."""

MODES = ("paper", "half_octave", "octave")
COMPARE = ("paper_sigma1", "mcguire2013", "cmft")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (JSON + PNG)")
    p.add_argument("--size", type=int, default=64, help="face size of the inputs (default 64)")
    p.add_argument("--dirs", type=int, default=1024, help="random directions per w (default 1024)")
    p.add_argument("--powers", type=int, default=33, help="number of log-spaced w in [1, 1e4] (default 33)")


def mcguire_level(w: np.ndarray, n: int, levels: int) -> np.ndarray:
    """McGuire et al. 2013: ``m = log2(N sqrt 3) - 0.5 log2(w + 1)``, clamped to the chain."""
    return np.clip(math.log2(n * math.sqrt(3.0)) - 0.5 * np.log2(np.asarray(w, float) + 1.0), 0, levels - 1)


def cmft_powers(levels: int, scale: float = 10.0, bias: float = 1.0) -> np.ndarray:
    g = 1.0 - np.arange(levels) / max(levels - 1, 1)
    return 2.0 ** (scale * g + bias)


def cmft_level(w: np.ndarray, levels: int, scale: float = 10.0, bias: float = 1.0) -> np.ndarray:
    g = (np.log2(np.maximum(np.asarray(w, float), 1e-30)) - bias) / scale
    return np.clip((1.0 - g) * (levels - 1), 0, levels - 1)


def zw_inputs(n: int, ctx: Any) -> tuple[dict[str, NDArray[np.float64]], NDArray[np.float64], NDArray[np.float64]]:
    """``(inputs, capture, sky)``: the three input cubes ``(6, n, n, 4)`` float64 (module docstring),
    the canyon capture at (0, 2, 0) (premultiplied RGBA) and the sky without its sun (alpha 1)."""
    scene = load_scene("canyon")
    sky = scene.sky.build()

    def rgba(include_sun: bool) -> NDArray[np.float64]:
        rgb = np.asarray(sky.cube(n, include_sun=include_sun), np.float64)
        return np.concatenate([rgb, np.ones(rgb.shape[:-1] + (1,))], -1)

    sky0, sky1 = rgba(False), rgba(True)
    cap = CubeCapture.from_scene(scene, n, sky=sky, ctx=ctx)
    try:
        street = np.asarray(cap.capture((0.0, 2.0, 0.0)).rgba, np.float64)
    finally:
        cap.release()

    def over(s: NDArray[np.float64]) -> NDArray[np.float64]:
        env = street + (1.0 - street[..., 3:4]) * s
        env[..., 3] = street[..., 3]
        return env

    return {"street": over(sky0), "sky": sky0, "sky_sun": sky1}, street, sky0


def other_sky(n: int) -> NDArray[np.float64]:
    """The canyon's Preetham sky at another time (sun at 15 deg elevation, azimuth 250 deg, turbidity
    5), without its sun, ``(6, n, n, 4)`` float64: a sky change after the bake."""
    spec = load_scene("canyon").sky
    params = replace(spec.params, sun_elevation_deg=15.0, sun_azimuth_deg=250.0, turbidity=5.0)
    rgb = np.asarray(replace(spec, params=params).build().cube(n, include_sun=False), np.float64)
    return np.concatenate([rgb, np.ones(rgb.shape[:-1] + (1,))], -1)


def _lookups(env: NDArray[np.float64], n: int, ctx: Any, compare: bool) -> dict[str, Lookup]:
    lad = lobe_ladder(n)

    def chain_lookup(chain: list, level_fn: Callable[[NDArray], NDArray]) -> Lookup:
        return lambda d, w: sample_cube(chain, d, level_fn(w))

    out: dict[str, Lookup] = {"paper": chain_lookup(prefilter_chain(env, lad, ctx=ctx, progress=False), lad.z)}
    for mode in ("half_octave", "octave"):
        rl = rung_ladder(n, mode)
        rc = RungChains(prefilter_rungs(env, rl, ctx=ctx, progress=False), rl)
        out[mode] = lambda d, w, rc=rc: rc.fetch(d, 0.0, w)
    if compare:
        lad1 = lobe_ladder(n, sigma_texels=1.0)
        levels = lad.levels
        out["paper_sigma1"] = chain_lookup(prefilter_chain(env, lad1, ctx=ctx, progress=False), lad1.z)
        out["mcguire2013"] = chain_lookup(omega_box_pyramid(env, levels), lambda w: mcguire_level(w, n, levels))
        cm = [prefilter_level(env, wk, lad.sizes[k], ctx=ctx) for k, wk in enumerate(cmft_powers(levels))]
        out["cmft"] = chain_lookup(cm, lambda w: cmft_level(w, levels))
    return out


def _rel(pred: NDArray, truth: NDArray) -> float:
    return float(np.sqrt(np.mean((pred - truth) ** 2) / np.mean(truth ** 2)))


def summary(ws: NDArray[np.float64], errs: list[float]) -> dict[str, float]:
    """Median and p95 over the (log-uniform) w grid, and the largest error at ``w <= 16`` (the floor)."""
    e = np.asarray(errs)
    return {"median": float(np.median(e)), "p95": float(np.percentile(e, 95)), "max": float(e.max()),
            "floor_w_le_16": float(e[ws <= 16.0].max())}


def random_frames(count: int, seed: int = 1) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``count`` shading frames ``(F, 3, 3)`` (rows T, B, N) with uniform random normals and local
    views ``(F, 3)`` at polar angles uniform in [0, 80] degrees (the evaluator's frames have
    axis-aligned normals only: face centres, where a 1^2 level is exact)."""
    rng = np.random.default_rng(seed)
    nrm = rng.normal(size=(count, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    helper = np.where(np.abs(nrm[:, 1:2]) < 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    t = np.cross(helper, nrm)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    th, ph = np.radians(rng.uniform(0, 80, count)), rng.uniform(0, 2 * np.pi, count)
    views = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], 1)
    return np.stack([t, np.cross(nrm, t), nrm], 1), views


def shading_errors(env: NDArray[np.float64], lookups: dict[str, Lookup]) -> dict[str, dict[str, float]]:
    """Relative RMS error of Eq. 3 luminance per mode and material (keys ``material``: the
    evaluator's frames; ``material_random``: 64 random frames, :func:`random_frames`)."""
    sets = {"": shading_frames(0), "_random": random_frames(64)}
    truth_env = exact_environment(env[..., :3])
    out: dict[str, dict[str, float]] = {}
    for mode, look in lookups.items():
        def lit(d: NDArray, w: NDArray, look: Lookup = look) -> NDArray:
            return look(d.reshape(-1, 3), np.ravel(np.broadcast_to(w, d.shape[:-1])))[:, :3].reshape(d.shape)
        out[mode] = {}
        for suffix, (frames, views) in sets.items():
            for mat in MATERIALS:
                lt = luminance(shade(truth_env, mat, frames, views))
                lp = luminance(shade(lit, mat, frames, views))
                out[mode][mat.name + suffix] = _rel(lp, lt)
    return out


def composite_errors(capture: NDArray[np.float64], sky: NDArray[np.float64], sky2: NDArray[np.float64],
                     ws: NDArray[np.float64], dirs: NDArray[np.float64], ctx: Any) -> dict[str, list[float]]:
    """Per ``w``, luminance, relative RMS of the composited truth ``T = filter(street + (1 - alpha) sky)``:

    * ``exact``: the runtime's composite ``street_w + (1 - alpha_w) sky_w`` with exact filters, i.e.
      ``filter(alpha sky) - filter(alpha) filter(sky)`` over ``T`` (``exact_of_sky_term``: over the
      sky term ``filter((1 - alpha) sky)`` instead);
    * ``half_octave``: the same composite from half-octave rung lookups;
    * ``half_octave_sky_alpha``: with the rungs' alpha sky-weighted for ``sky``
      (:func:`envcap.prefilter.rungs.sky_weighted_alpha`);
    * ``*_sky2``: the runtime lit by another sky ``sky2`` (same bake: plain or ``sky``-weighted alpha)
      against ``filter(street + (1 - alpha) sky2)``.
    """
    a = capture[..., 3:4]
    lad = rung_ladder(capture.shape[1], "half_octave")
    st_r, sta_r, sky_r, sky2_r = (RungChains(prefilter_rungs(c, lad, ctx=ctx, sky=k), lad)
                                  for c, k in ((capture, None), (capture, sky), (sky, None), (sky2, None)))
    keys = ("exact", "exact_of_sky_term", "half_octave", "half_octave_sky_alpha", "half_octave_sky2",
            "half_octave_sky_alpha_sky2")
    rows: dict[str, list[float]] = {k: [] for k in keys}
    for w in ws:
        f_st = luminance(convolve_exact_dirs(capture[..., :3], w, dirs))
        f_a = convolve_exact_dirs(a, w, dirs)[..., 0]
        truth = {}
        for name, s in (("", sky), ("_sky2", sky2)):
            f_sky = luminance(convolve_exact_dirs(s[..., :3], w, dirs))
            f_asky = luminance(convolve_exact_dirs(a * s[..., :3], w, dirs))
            truth[name] = f_st + f_sky - f_asky
            if not name:
                diff = f_asky - f_a * f_sky
                rows["exact"].append(_rel(truth[name] + diff, truth[name]))
                rows["exact_of_sky_term"].append(float(np.sqrt(np.mean(diff ** 2) / np.mean((f_sky - f_asky) ** 2))))
        ww = np.full(len(dirs), w)
        look = {k: c.fetch(dirs, 0.0, ww) for k, c in (("st", st_r), ("sta", sta_r), ("sky", sky_r), ("sky2", sky2_r))}
        for key, stk in (("half_octave", "st"), ("half_octave_sky_alpha", "sta")):
            st = look[stk]
            for name, skk in (("", "sky"), ("_sky2", "sky2")):
                comp = st[:, :3] + (1.0 - np.clip(st[:, 3:], 0, 1)) * look[skk][:, :3]
                rows[key + name].append(_rel(luminance(comp), truth[name]))
    return rows


def sky_change_errors(capture: NDArray[np.float64], skies: dict[str, NDArray[np.float64]], ws: NDArray[np.float64],
                      dirs: NDArray[np.float64], ctx: Any, orders: tuple[int, ...] = (1, 2, 3, 4)) -> dict[str, Any]:
    """The composite after filtering lit by each sky of ``skies`` (the first: the baked one) with the
    sky-visibility correction (:mod:`envcap.runtime.sky_visibility`, ``docs/lobes.md``), per ``w``:
    relative RMS of luminance against ``filter(street + (1 - alpha) sky)``.  Rows ``[SKY][METHOD]``:
    ``plain`` / ``sky_alpha``: today's composite (rungs' alpha plain / sky-weighted for the baked
    sky); with ``V`` of SH order ``L`` (sky-weighted alpha where none is stored): ``sh2`` (pure SH),
    ``shL_residual`` (SH + residual, no base), ``deltaL`` (the baked sky as base, SH of the
    difference), ``local1`` (``V`` of l <= 1, the new sky's local gradient, no SH, no base),
    ``delta_local1`` (the same on the difference from the baked sky), ``delta2_local`` (SH l <= 2
    of the difference + its gradient); ``_f16``: ``V`` rounded to float16, as RGBA16F stores it."""
    from envcap.prefilter.sky_visibility import SkyVisibility, prefilter_sky_visibility, sh_count
    from envcap.runtime.sky_visibility import sh_projection_error, sky_delta, sky_sh_coefficients, sky_visible

    a = capture[..., 3:4]
    lad = rung_ladder(capture.shape[1], "half_octave")
    base = next(iter(skies.values()))
    st = {k: RungChains(prefilter_rungs(capture, lad, ctx=ctx, sky=s), lad) for k, s in (("plain", None), ("sky_alpha", base))}
    v4 = prefilter_sky_visibility(a[..., 0], lad, max(orders), ctx=ctx)
    vis = {o: SkyVisibility([lv[..., :sh_count(o)] for lv in v4.levels], lad, o, v4.first_level) for o in orders}
    vis16 = {o: SkyVisibility([lv.astype(np.float16).astype(np.float32) for lv in v.levels], lad, o, v.first_level)
             for o, v in vis.items()}
    sky_r = {k: RungChains(prefilter_rungs(s, lad, ctx=ctx), lad) for k, s in skies.items()}
    kb = {o: sky_sh_coefficients(base, o) for o in orders}
    out: dict[str, Any] = {"rows": {}, "sh_projection_error": {}, "delta_projection_error": {}, "scale": {},
                           "first_stored_power": lad.powers[v4.first_rung],
                           "bytes_per_probe": {o: v.bytes_per_probe() for o, v in vis.items()}}
    for name, sky in skies.items():
        ks = {o: sky_sh_coefficients(sky, o) for o in orders}
        dl = {o: sky_delta(ks[o], kb[o], o) for o in orders}
        sc = dl[orders[0]][0]
        out["scale"][name] = sc.tolist()
        out["sh_projection_error"][name] = {o: sh_projection_error(sky, k, o) for o, k in ks.items()}
        out["delta_projection_error"][name] = {o: sh_projection_error(sky[..., :3] - dl[o][0] * base[..., :3], dl[o][1], o)
                                               for o in orders}
        rows: dict[str, list[float]] = {}
        for w in ws:
            truth = luminance(convolve_exact_dirs(capture[..., :3] + (1.0 - a) * sky[..., :3], w, dirs))
            ww = np.full(len(dirs), w)
            k_w = sky_r[name].fetch(dirs, 0.0, ww)[:, :3]
            b_w = sky_r[next(iter(skies))].fetch(dirs, 0.0, ww)[:, :3]
            look = {k: c.fetch(dirs, 0.0, ww) for k, c in st.items()}
            pred = {k: s[:, :3] + (1.0 - np.clip(s[:, 3:], 0, 1)) * k_w for k, s in look.items()}
            s_a, a_w = look["sky_alpha"], np.clip(look["sky_alpha"][:, 3], 0, 1)
            sc = dl[2][0]

            def new_sky(dd: NDArray, ww: NDArray = ww, name: str = name) -> NDArray:
                return sky_r[name].fetch(dd, 0.0, ww)[:, :3]

            def diff_sky(dd: NDArray, ww: NDArray = ww, sc: NDArray = sc, name: str = name) -> NDArray:
                return new_sky(dd, ww, name) - sc * sky_r[next(iter(skies))].fetch(dd, 0.0, ww)[:, :3]

            runs = [(f"sh{o}", vis[o], ks[o], None, "sh", None) for o in orders if o == 2]
            runs += [(f"sh{o}_residual", vis[o], ks[o], None, "sh_residual", None) for o in orders]
            runs += [(f"delta{o}", vis[o], dl[o][1], dl[o][0] * b_w, "sh_residual", None) for o in orders]
            z1 = np.zeros((4, 3))
            runs += [("local1", vis[1], z1, None, "sh_residual", new_sky), ("local1_f16", vis16[1], z1, None, "sh_residual", new_sky),
                     ("delta_local1", vis[1], z1, sc * b_w, "sh_residual", diff_sky),
                     ("delta_local1_f16", vis16[1], z1, sc * b_w, "sh_residual", diff_sky),
                     ("delta2_local", vis[2], dl[2][1], sc * b_w, "sh_residual", diff_sky)]
            for key, vv, kk, bw, corr, grad in runs:
                pred[key] = s_a[:, :3] + k_w - sky_visible(vv, dirs, 0, ww, kk, a_w, k_w, corr, bw, grad)  # type: ignore[arg-type]
            for key, p in pred.items():
                rows.setdefault(key, []).append(_rel(luminance(p), truth))
        out["rows"][name] = rows
    return out


def run(args: argparse.Namespace) -> int:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = int(args.size)
    if n < 8:
        raise ValueError(f"--size must be >= 8, got {n}")
    ctx = create_context()
    rng = np.random.default_rng(0)
    dirs = rng.normal(size=(int(args.dirs), 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    ws = np.logspace(0, 4, int(args.powers))
    result: dict[str, Any] = {
        "size": n, "directions": int(args.dirs), "w": ws.tolist(), "ladder": lobe_ladder(n).to_manifest(),
        "rungs": {m: rung_ladder(n, m).to_manifest() for m in ("half_octave", "octave")},
        "bytes_per_probe": {m: {str(s): ladder_bytes_per_probe(m, s) for s in (64, 128, 256)} for m in MODES},
        "cmft_powers": cmft_powers(lobe_ladder(n).levels).tolist(), "inputs": {}, "summary": {}}
    inputs, capture, sky = zw_inputs(n, ctx)
    for name, env in inputs.items():
        t0 = time.perf_counter()
        lookups = _lookups(env, n, ctx, compare=True)
        rec: dict[str, list[float]] = {m: [] for m in lookups}
        for w in ws:
            ye = luminance(convolve_exact_dirs(env, w, dirs))
            for m, look in lookups.items():
                rec[m].append(_rel(luminance(look(dirs, np.full(len(dirs), w))), ye))
        result["inputs"][name] = rec
        result["summary"][name] = {m: summary(ws, v) for m, v in rec.items()}
        if name == "street":
            result["shading"] = shading_errors(env, {m: lookups[m] for m in MODES})
        print(name, f"{time.perf_counter() - t0:.1f} s",
              {m: {k: round(v, 4) for k, v in s.items()} for m, s in result["summary"][name].items()}, flush=True)
    print("shading", result["shading"], flush=True)
    result["composite"] = composite_errors(capture, sky, other_sky(n), ws, dirs, ctx)
    print("composite", {k: f"max {max(v):.3g} median {np.median(v):.3g}" for k, v in result["composite"].items()}, flush=True)
    result["sky_change"] = sky_change_errors(capture, {"sky": sky, "sky2": other_sky(n)}, ws, dirs, ctx)
    ctx.release()
    with atomic_output_dir(args.out) as tmp:
        (tmp / "zw.json").write_text(json.dumps(result, indent=2))
        fig, axes = plt.subplots(1, 3, figsize=(16, 4.5))
        for ax, (name, rec) in zip(axes.ravel(), result["inputs"].items()):
            for m, style in (("paper", "o-"), ("half_octave", "*-"), ("octave", "v-"), ("paper_sigma1", "d:"),
                             ("mcguire2013", "s--"), ("cmft", "^:")):
                ax.loglog(ws, np.maximum(rec[m], 1e-7), style, label=m, ms=4)
            ax.axhline(0.015, color="k", ls=":", lw=0.8)
            ax.set_title(f"{name}, 6x{n}^2: lookup vs exact cos^w")
            ax.set_xlabel("cosine power w")
            ax.set_ylabel("relative RMSE of luminance")
            ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(tmp / "prefilter_zw_error.png", dpi=110)
    return 0
