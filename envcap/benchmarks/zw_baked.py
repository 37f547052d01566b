"""z(w) lookup error of *baked* probe sets, read back from disk: the paper's chain against the rung
ladders that ``envcap capture --ladder MODE`` stores (``docs/lobes.md``, "Ladder modes").

``envcap bench zw`` measures ladders rebuilt in memory from one capture; this benchmark bakes the
``canyon`` (one probe, at (0, 2, 0): the probe of ``bench zw``) with each mode,
writes the set (``probes.ktx2`` RGBA16F, ``sky.ktx2`` RGBA32F, ``manifest.json``), reads it back
with :func:`envcap.probeset.store.read_probe_set` and looks it up as the runtime's numpy twin does:
:class:`envcap.runtime.chains.ProbeChains` (a rung ladder: two rungs,
:func:`envcap.runtime.rungs.rung_fetch`) composited over :func:`envcap.runtime.sampling.sample_sky`
(the baked sky; with the sky-weighted alpha the bake stores).  Truth: the exact normalized
``cos^w`` convolution (float64, :func:`envcap.prefilter.exact.convolve_exact_dirs`) of the float
capture composited over the sky (``envcap.benchmarks.zw.zw_inputs``): ``street``, ``sky`` (no
sun) and ``sky_sun`` (a second bake with ``sun_in_sky``).  Relative RMSE of luminance at random
uniform directions, ``w`` log-spaced in [1, 1e4]; median, p95 and the floor (largest error at
``w <= 16``) as in ``bench zw``.  The top of the ladder (``docs/lobes.md``): the grid runs on,
as densely in ``log w``, to ``--w-max`` (1e7) and the mirror ``w = inf`` (truth: the limit of the
exact filter, the nearest texel centre); ``summary_to_mirror`` is median / p95 / max over all of
it, with ``MODE_before`` for a rung mode: the same baked set looked up as before
(:func:`previous_rung_fetch`: rung 0 read bilinearly, the rung position clamped at 0), and the
command prints a table of them.  Also the bytes per probe of each mode and of ``probes.ktx2``, and
each bake's (no sun) wall and CPU seconds (``bake_s``, ``bake_cpu_s``: ``time.process_time``, which
counts llvmpipe's threads; the one to compare on a shared machine).  ``--rung-errors``: each rung of
the half_octave filter against the float64 exact lobe (:func:`rung_errors`, key ``rung_error``).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.benchmarks.zw import summary, zw_inputs
from envcap.core import cube_sampling
from envcap.core.color import luminance
from envcap.core.cube import texel_directions
from envcap.core.rungs import ladder_bytes_per_probe
from envcap.gpu.context import create_context
from envcap.outputs import atomic_output_dir
from envcap.prefilter import convolve_exact_dirs
from envcap.prefilter.rungs import rung_textures
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.store import read_probe_set, write_probe_set
from envcap.runtime.chains import ProbeChains, SkyChain
from envcap.runtime.rungs import rung_position
from envcap.runtime.sampling import composite, sample_sky
from envcap.scene import load_scene

SPACING = 400.0
"""Probe spacing of the canyon bakes (m): one probe, at (0, 2, 0)."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (zw_baked.json)")
    p.add_argument("--size", type=int, default=64, help="face size N of the bakes (default 64)")
    p.add_argument("--dirs", type=int, default=1024, help="random directions (default 1024)")
    p.add_argument("--powers", type=int, default=33, help="w values log-spaced in [1, 1e4] (default 33)")
    p.add_argument("--w-max", type=float, default=1e7,
                   help="the grid runs on, as densely, to this w and the mirror (default 1e7; <= 1e4: [1, 1e4] only)")
    p.add_argument("--modes", default="paper,half_octave", help="ladder modes, comma-separated (default paper,half_octave)")
    p.add_argument("--quality", default="composed", help="prefilter quality of the bakes (default composed, as envcap capture)")
    p.add_argument("--rung-errors", action="store_true",
                   help="also each half_octave rung against the float64 exact lobe (key rung_error)")


def previous_rung_fetch(levels: Any, d: NDArray, base: NDArray, w: NDArray, xr: NDArray, per_level: int) -> NDArray:
    """The rung lookup before the top of the ladder: rungs ``floor(u)`` and the next at the rung
    position ``u`` (clamped at 0: every ``w`` past rung 0's power reads rung 0), each one bilinear
    fetch, blended linearly in ``u``."""
    u = rung_position(w, xr)
    n = np.asarray(xr).size
    i0 = np.floor(u).astype(np.int64)
    i1 = np.minimum(i0 + 1, n - 1)
    t = (u - i0)[..., None]
    a = cube_sampling.sample_cube_array(levels, d, base + i0 % per_level, (i0 // per_level).astype(np.float64))
    c = cube_sampling.sample_cube_array(levels, d, base + i1 % per_level, (i1 // per_level).astype(np.float64))
    return a + t * (c - a)


def baked_lookups(ps: Any, before: bool = False) -> tuple[Any, Any]:
    """``(street(d, w), sky(d, w))`` of the probe at (0, 2, 0) of a read-back set ``ps``: the
    runtime twin's street RGBA over the sky, and the sky alone (``before``: a rung ladder looked
    up with :func:`previous_rung_fetch`)."""
    chains = ProbeChains.from_probe_set(ps)
    sky = SkyChain(ps.sky_levels) if chains.ladder is None else SkyChain(ps.sky_rungs, chains.ladder)
    layer = [p.layer for st in ps.manifest.streets for p in st.probes if abs(p.position[0]) < 1e-6][0]

    def street_rgba(d: NDArray, w: NDArray) -> NDArray:
        if before and chains.ladder is not None:
            per = chains.ladder.per_level
            return previous_rung_fetch(chains.levels, d, np.full(len(d), float(layer * per)), w, chains.xk, per)
        return chains.fetch(d, np.full(len(d), layer), w)

    def sky_rgba(d: NDArray, w: NDArray) -> NDArray:
        if before and chains.ladder is not None:
            return previous_rung_fetch(sky.levels, d, np.zeros(len(d)), w, chains.xk, chains.ladder.per_level)
        return sample_sky(sky, d, w, chains.xk)

    def street(d: NDArray, w: NDArray) -> NDArray:
        return composite(street_rgba(d, w), sky_rgba(d, w))

    def sky_only(d: NDArray, w: NDArray) -> NDArray:
        return sky_rgba(d, w)[..., :3]

    return street, sky_only


def power_grid(powers: int, w_max: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(ws, main)``: ``powers`` w log-spaced in [1, 1e4], continued as densely to ``w_max`` and
    then ``+inf`` (the mirror) when ``w_max > 1e4``; ``main``: the mask of the [1, 1e4] part."""
    main = np.logspace(0, 4, int(powers))
    if not w_max > 1e4:
        return main, np.ones(main.size, bool)
    per_decade = max(int(powers) - 1, 1) / 4.0
    top = np.logspace(4, np.log10(w_max), max(int(round(per_decade * np.log10(w_max / 1e4))), 1) + 1)[1:]
    ws = np.concatenate([main, top, [np.inf]])
    return ws, np.arange(ws.size) < main.size


def _table(result: dict[str, Any]) -> str:
    s = result["summary_to_mirror"]
    modes = list(next(iter(s.values())))
    ws = result["w"]
    lines = [f"p95 (median, max) over {len(ws)} w log-uniform in [1, {ws[-2]:.3g}] and the mirror, "
             f"{result['size']}^2, {result['directions']} directions:", "input    " + "".join(f"{m:>28}" for m in modes)]
    for name, row in s.items():
        lines.append(f"{name:<9}" + "".join(f"{100 * v['p95']:>9.2f} % ({100 * v['median']:.2f}, {100 * v['max']:.3g})"
                                             .rjust(28) for v in row.values()))
    return "\n".join(lines)


def rung_errors(street: NDArray, sky: NDArray, quality: str, ctx: Any, samples: int = 1200) -> list[dict[str, Any]]:
    """Each rung of ``rung_textures(street, sky, "half_octave", quality)`` against the float64 exact
    lobe at ``samples`` random texel centres: relative RMS of the street's luminance, of the sky's,
    of the composite ``street + (1 - alpha) sky`` (against the exact filter of the composited cube),
    and the RMS of alpha against ``exact(alpha Y) / exact(Y)``."""
    lad, probes, sky_r = rung_textures(street[None].astype(np.float32), sky.astype(np.float32), "half_octave",
                                       quality, ctx)  # type: ignore[arg-type]
    y = luminance(sky[..., :3])
    every = np.concatenate([street, street[..., 3:4] * y[..., None], y[..., None], sky,
                            street[..., :3] + (1.0 - street[..., 3:4]) * sky[..., :3]], -1)
    rng = np.random.default_rng(0)

    def rel(a: NDArray, b: NDArray) -> float:
        return float(np.sqrt(np.mean((a - b) ** 2) / np.mean(b ** 2)))

    rows = []
    for i in range(1, lad.rungs):
        j, r = divmod(i, lad.per_level)
        d = texel_directions(lad.sizes[j]).reshape(-1, 3)
        idx = rng.choice(len(d), min(samples, len(d)), replace=False)
        ex = convolve_exact_dirs(every, lad.powers[i], d[idx])
        got = probes[j][r].reshape(-1, 4)[idx].astype(np.float64)
        got_sky = sky_r[j][r].reshape(-1, 4)[idx].astype(np.float64)
        comp = got[:, :3] + (1.0 - got[:, 3:4]) * got_sky[:, :3]
        rows.append({"rung": i, "w": float(lad.powers[i]), "size": int(lad.sizes[j]),
                     "street": rel(luminance(got[:, :3]), luminance(ex[:, :3])),
                     "alpha": float(np.sqrt(np.mean((got[:, 3] - ex[:, 4] / ex[:, 5]) ** 2))),
                     "sky": rel(luminance(got_sky[:, :3]), luminance(ex[:, 6:9])),
                     "composite": rel(luminance(comp), luminance(ex[:, 10:13]))})
    return rows


def run(args: argparse.Namespace) -> int:
    n = int(args.size)
    modes = [m.strip() for m in str(args.modes).split(",") if m.strip()]
    ctx = create_context()
    rng = np.random.default_rng(0)
    dirs = rng.normal(size=(int(args.dirs), 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    ws, main = power_grid(int(args.powers), float(args.w_max))
    inputs, capture, sky0 = zw_inputs(n, ctx)
    truth = {name: [luminance(convolve_exact_dirs(env, min(w, 1e300), dirs)) for w in ws] for name, env in inputs.items()}
    scene = load_scene("canyon")
    result: dict[str, Any] = {"size": n, "directions": int(args.dirs), "w": [float(w) for w in ws], "quality": args.quality,
                              "w_main": [float(w) for w in ws[main]],
                              "bytes_per_probe": {m: {str(s): ladder_bytes_per_probe(m, s) for s in (64, 128, 256)}
                                                  for m in ("paper", "half_octave", "octave")},
                              "file_bytes_per_probe": {}, "bake_s": {}, "bake_cpu_s": {}, "inputs": {}, "summary": {},
                              "summary_to_mirror": {}}
    for mode in modes:
        for sun in (False, True):
            t0, c0 = time.perf_counter(), time.process_time()
            ps = bake_probe_set(scene, resolution=n, spacing=SPACING, quality=args.quality, sun_in_sky=sun,
                                ladder_mode=mode, ctx=ctx, progress=False)
            with tempfile.TemporaryDirectory() as tmp:
                path = write_probe_set(Path(tmp) / "set", ps, exr=False, previews=False)
                if not sun:
                    result["file_bytes_per_probe"][mode] = (path / "probes.ktx2").stat().st_size / ps.layer_count
                    result["bake_s"][mode] = round(time.perf_counter() - t0, 2)
                    result["bake_cpu_s"][mode] = round(time.process_time() - c0, 2)
                back = read_probe_set(path)
            variants = [(mode, False)] + ([(f"{mode}_before", True)] if back.manifest.ladder is not None else [])
            for key, before in variants:
                street, sky_only = baked_lookups(back, before)
                names = {"street": street, "sky": sky_only} if not sun else {"sky_sun": sky_only}
                for name, look in names.items():
                    errs = []
                    for w, ye in zip(ws, truth[name]):
                        got = luminance(look(dirs, np.full(len(dirs), w))[..., :3])
                        errs.append(float(np.sqrt(np.mean((got - ye) ** 2) / np.mean(ye ** 2))))
                    result["inputs"].setdefault(name, {})[key] = errs
                    if not before:
                        result["summary"].setdefault(name, {})[key] = summary(ws[main], list(np.asarray(errs)[main]))
                    e = np.asarray(errs)
                    result["summary_to_mirror"].setdefault(name, {})[key] = {
                        "median": float(np.median(e)), "p95": float(np.percentile(e, 95)), "max": float(e.max())}
            print(mode, "sun" if sun else "no sun", f"{time.perf_counter() - t0:.1f} s",
                  {k: {m: {a: round(b, 4) for a, b in s.items()} for m, s in v.items() if m == mode}
                   for k, v in result["summary"].items()}, flush=True)
    if not main.all():
        print(_table(result), flush=True)
    if args.rung_errors:
        result["rung_error"] = rung_errors(capture, sky0, args.quality, ctx)
        for row in result["rung_error"]:
            print(" ".join(f"{k} {v:.4g}" for k, v in row.items()), flush=True)
    ctx.release()
    with atomic_output_dir(args.out) as tmp:
        (Path(tmp) / "zw_baked.json").write_text(json.dumps(result, indent=2))
    return 0
