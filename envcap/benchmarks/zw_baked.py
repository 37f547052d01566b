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
``w <= 16``) as in ``bench zw``.  Also the bytes per probe of each mode and of ``probes.ktx2``, and
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
from envcap.runtime.sampling import composite, sample_sky
from envcap.scene import load_scene

SPACING = 400.0
"""Probe spacing of the canyon bakes (m): one probe, at (0, 2, 0)."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (zw_baked.json)")
    p.add_argument("--size", type=int, default=64, help="face size N of the bakes (default 64)")
    p.add_argument("--dirs", type=int, default=1024, help="random directions (default 1024)")
    p.add_argument("--powers", type=int, default=33, help="w values log-spaced in [1, 1e4] (default 33)")
    p.add_argument("--modes", default="paper,half_octave", help="ladder modes, comma-separated (default paper,half_octave)")
    p.add_argument("--quality", default="composed", help="prefilter quality of the bakes (default composed, as envcap capture)")
    p.add_argument("--rung-errors", action="store_true",
                   help="also each half_octave rung against the float64 exact lobe (key rung_error)")


def baked_lookups(ps: Any) -> tuple[Any, Any]:
    """``(street(d, w), sky(d, w))`` of the probe at (0, 2, 0) of a read-back set ``ps``: the
    runtime twin's street RGBA over the sky, and the sky alone."""
    chains = ProbeChains.from_probe_set(ps)
    sky = SkyChain(ps.sky_levels) if chains.ladder is None else SkyChain(ps.sky_rungs, chains.ladder)
    layer = [p.layer for st in ps.manifest.streets for p in st.probes if abs(p.position[0]) < 1e-6][0]

    def street(d: NDArray, w: NDArray) -> NDArray:
        return composite(chains.fetch(d, np.full(len(d), layer), w), sample_sky(sky, d, w, chains.xk))

    def sky_only(d: NDArray, w: NDArray) -> NDArray:
        return sample_sky(sky, d, w, chains.xk)[..., :3]

    return street, sky_only


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
    ws = np.logspace(0, 4, int(args.powers))
    inputs, capture, sky0 = zw_inputs(n, ctx)
    truth = {name: [luminance(convolve_exact_dirs(env, w, dirs)) for w in ws] for name, env in inputs.items()}
    scene = load_scene("canyon")
    result: dict[str, Any] = {"size": n, "directions": int(args.dirs), "w": ws.tolist(), "quality": args.quality,
                              "bytes_per_probe": {m: {str(s): ladder_bytes_per_probe(m, s) for s in (64, 128, 256)}
                                                  for m in ("paper", "half_octave", "octave")},
                              "file_bytes_per_probe": {}, "bake_s": {}, "bake_cpu_s": {}, "inputs": {}, "summary": {}}
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
            street, sky_only = baked_lookups(back)
            names = {"street": street, "sky": sky_only} if not sun else {"sky_sun": sky_only}
            for name, look in names.items():
                errs = []
                for w, ye in zip(ws, truth[name]):
                    got = luminance(look(dirs, np.full(len(dirs), w))[..., :3])
                    errs.append(float(np.sqrt(np.mean((got - ye) ** 2) / np.mean(ye ** 2))))
                result["inputs"].setdefault(name, {})[mode] = errs
                result["summary"].setdefault(name, {})[mode] = summary(ws, errs)
            print(mode, "sun" if sun else "no sun", f"{time.perf_counter() - t0:.1f} s",
                  {k: {m: {a: round(b, 4) for a, b in s.items()} for m, s in v.items() if m == mode}
                   for k, v in result["summary"].items()}, flush=True)
    if args.rung_errors:
        result["rung_error"] = rung_errors(capture, sky0, args.quality, ctx)
        for row in result["rung_error"]:
            print(" ".join(f"{k} {v:.4g}" for k, v in row.items()), flush=True)
    ctx.release()
    with atomic_output_dir(args.out) as tmp:
        (Path(tmp) / "zw_baked.json").write_text(json.dumps(result, indent=2))
    return 0
