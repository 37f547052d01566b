"""End-to-end bake: probes/s and the time of each stage, before (default filter, every file) and after (the fast path).

Per face size (``--sizes``, default 64 and 256) on the bundled scene (``--scene canyon``,
``--spacing 5``), in one run, each bake written to its own directory under ``--out``:

* ``before``: today's defaults before issue 11: ``quality="default"``, then every default writer
  one after the other (``ktx2``, per-probe ``exr``, ``previews``);
* ``after``: the fast path: ``quality`` ``--fast-quality`` (``composed``), ``probes.ktx2`` and
  ``sky.ktx2`` only (what ``envcap capture`` writes now);
* ``after_files`` (unless ``--no-files-run``): the fast path with ``--exr --previews``: the
  per-probe files written on threads while the bake runs.

Stages (wall and CPU seconds, ``time.process_time``, which counts llvmpipe's threads): ``sky``,
``capture``, ``prefilter`` (probes and the sky), ``write files`` (waiting for the threads),
``write <writer>``; ``other`` = end to end minus the stages (plane fits, checks, manifest).
Prefilter error: for ``--error-probes`` probes of the set, the relative RMSE of luminance per
level against the exact float64 reference (:func:`envcap.prefilter.convolve_exact_dirs`) on
``--samples`` random texels per level (every texel when a level has fewer), for both filters;
the exact method's time on those texels, scaled to the whole set, gives the ratio against it.
cmft is not built here: its time enters only as a conversion through the known point
``--cmft-seconds`` (one 256^2 cube in and out, 9 levels, 2 threads, ``../shared/PLATFORM.md``).

``sky_visibility`` (per size, unless ``--sky-visibility-reps 0``): the fast path without and with
``--sky-visibility``, interleaved pairs, their ratio and the moments' error against the exact
reference (:mod:`envcap.benchmarks.bake_sky_visibility`).

``floor`` (per size, unless ``--floor-filter-probes 0``): what a bake of those probes cannot do
without, each part timed alone, per probe: the capture (the scene's effects, fresh output arrays
as in the bake; render and readback), the capture without shading (``geometry_only``), and the
composed filter per level on ``--floor-filter-probes`` captured probes; beside the budget of
:data:`GOAL_PROBES_PER_S` on this machine's cores (wall and CPU ms per probe).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from envcap.capture.renderer import CubeCapture
from envcap.benchmarks import bake_sky_visibility
from envcap.core import cube as cm
from envcap.core.color import luminance
from envcap.core.lobes import lobe_ladder
from envcap.formats.registry import default_writer_names
from envcap.gpu.context import create_context
from envcap.outputs import atomic_output_dir
from envcap.prefilter import QUALITIES, convolve_exact_dirs
from envcap.prefilter.composed import prefilter_many_composed
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.bake_output import bake_to_directory
from envcap.probeset.probe_set import ProbeSet
from envcap.probeset.progress import BakeProgress
from envcap.probeset.shadow_fit import shadow_effect_parameters
from envcap.probeset.store import fill_probe_set_dir
from envcap.scene import load_scene

CMFT_SIZE = 256


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (bake.json, bake.md and the probe sets)")
    p.add_argument("--scene", default="canyon", help="bundled scene (default canyon)")
    p.add_argument("--sizes", default="64,256", help="face sizes, comma-separated (default 64,256)")
    p.add_argument("--spacing", type=float, default=5.0, help="probe spacing in meters (default 5)")
    p.add_argument("--fast-quality", default="composed", choices=list(QUALITIES),
                   help="filter quality of the fast path (default composed)")
    p.add_argument("--no-files-run", action="store_true", help="skip the fast path with --exr --previews")
    p.add_argument("--error-probes", type=int, default=2, help="probes whose levels are checked against exact (default 2)")
    p.add_argument("--samples", type=int, default=64, help="texels per level checked against exact (default 64)")
    p.add_argument("--floor-filter-probes", type=int, default=8,
                   help="probes of the set filtered alone for the per-level floor (default 8; 0: no floor)")
    bake_sky_visibility.add_sky_visibility_arguments(p)
    p.add_argument("--cmft-seconds", type=float, default=4.8,
                   help="cmft's wall time for one 256^2 cube, 9 levels, 2 threads, on this machine (default 4.8, "
                        "PLATFORM.md); used only to convert")


def _stages(rep: BakeProgress, total_wall: float, total_cpu: float) -> dict[str, Any]:
    stages = {name: {"seconds": round(rep.seconds[name], 4), "cpu_seconds": round(rep.cpu_seconds[name], 4)}
              for name in rep.seconds}
    stages["other"] = {"seconds": round(total_wall - sum(rep.seconds.values()), 4),
                       "cpu_seconds": round(total_cpu - sum(rep.cpu_seconds.values()), 4)}
    return stages


def _before(scene: Any, out: Path, size: int, spacing: float, ctx: Any) -> tuple[ProbeSet, dict[str, Any]]:
    """Bake with the default filter, then every default writer in turn (the flow before issue 11)."""
    rep = BakeProgress("lines")
    t0, c0 = time.perf_counter(), time.process_time()
    ps = bake_probe_set(scene, resolution=size, spacing=spacing, quality="default", ctx=ctx, report=rep)
    with atomic_output_dir(out, kind="probe-set") as tmp:
        fill_probe_set_dir(tmp, ps, default_writer_names(), report=rep)
    return ps, {"wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0, "report": rep}


def _after(scene: Any, out: Path, size: int, spacing: float, quality: str, ctx: Any,
           files: bool) -> tuple[ProbeSet, dict[str, Any]]:
    rep = BakeProgress("lines")
    t0, c0 = time.perf_counter(), time.process_time()
    _, ps = bake_to_directory(scene, out, exr=files, previews=files, report=rep, resolution=size, spacing=spacing,
                              quality=quality, ctx=ctx)
    return ps, {"wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0, "report": rep}


def _errors(sets: dict[str, ProbeSet], probes: int, samples: int, rng: np.random.Generator) -> dict[str, Any]:
    """Per filter, the relative RMSE of luminance per level against exact, over ``probes`` probes."""
    first = next(iter(sets.values()))
    n, layers = first.resolution, first.layer_count
    lad = lobe_ladder(n)
    picks = np.unique(np.linspace(0, layers - 1, max(1, min(probes, layers))).round().astype(int))
    err: dict[str, list[list[float]]] = {name: [] for name in sets}
    exact_s = exact_cpu = 0.0
    texels = 0
    for layer in picks:
        env = np.asarray(first.levels[0][layer], np.float64)
        for k in range(1, lad.levels):
            nk = lad.sizes[k]
            m = min(samples, 6 * nk * nk)
            idx = rng.choice(6 * nk * nk, m, replace=False)
            dirs = cm.texel_directions(nk).reshape(-1, 3)[idx]
            t, c = time.perf_counter(), time.process_time()
            ref = luminance(convolve_exact_dirs(env, lad.powers[k], dirs))
            exact_s += (time.perf_counter() - t) * (6 * nk * nk) / m
            exact_cpu += (time.process_time() - c) * (6 * nk * nk) / m
            om = cm.texel_solid_angles(nk).reshape(-1)[idx]
            for name, ps in sets.items():
                got = luminance(np.asarray(ps.levels[k][layer], np.float64).reshape(-1, 4)[idx])
                e = float(math.sqrt((om * (got - ref) ** 2).sum() / max((om * ref ** 2).sum(), 1e-300)))
                if len(err[name]) < k:
                    err[name].append([])
                err[name][k - 1].append(e)
        texels += 1
    return {"probes": picks.tolist(), "samples_per_level": samples,
            "exact_seconds_per_probe_extrapolated": exact_s / max(texels, 1),
            "exact_cpu_seconds_per_probe_extrapolated": exact_cpu / max(texels, 1),
            "rel_rmse_per_level": {name: [max(v) for v in lv] for name, lv in err.items()}}


def _gil_probe(ps: ProbeSet, tmp: Path, reps: int = 3) -> dict[str, Any]:
    """Whether the EXR and PNG writers release the GIL: CPU seconds of a pure-Python thread that
    spins while the writer thread writes ``reps`` files of probe 0 (a writer that held the GIL
    throughout would leave it ~0), beside the writer thread's own CPU seconds."""
    from envcap.formats.exr_writer import write_probe_exr
    from envcap.formats.preview_writer import write_probe_preview

    rgba = np.asarray(ps.levels[0][0])
    dist = None if ps.distance is None else np.asarray(ps.distance[0])
    (tmp / "exr").mkdir(parents=True)
    (tmp / "previews").mkdir()
    out: dict[str, Any] = {}
    jobs = {"exr": lambda i: write_probe_exr(tmp, i, rgba, dist), "preview": lambda i: write_probe_preview(tmp, i, rgba)}
    for name, job in jobs.items():
        stop, spun = threading.Event(), [0.0]

        def spin() -> None:
            t = time.thread_time()
            while not stop.is_set():
                pass
            spun[0] = time.thread_time() - t

        th = threading.Thread(target=spin)
        th.start()
        t0, w0 = time.thread_time(), time.perf_counter()
        for i in range(reps):
            job(i)
        work, wall = time.thread_time() - t0, time.perf_counter() - w0
        stop.set()
        th.join()
        out[name] = {"files": reps, "writer_thread_cpu_s": round(work, 3), "spinning_thread_cpu_s": round(spun[0], 3),
                     "wall_s": round(wall, 3)}
    return out


GOAL_PROBES_PER_S = 10.0
"""Issue 11's goal: probes per second end to end at 6 x 256^2 on this machine's cores."""


def _timed(fn: Any) -> tuple[Any, float, float]:
    t, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - t, time.process_time() - c


def _floor(scene_name: str, ps: ProbeSet, size: int, ctx: Any, filter_probes: int) -> dict[str, Any]:
    """The least a bake of ``ps``'s probes must do here, per probe: the capture alone (the scene's
    effects and shadow map, fresh output arrays as in the bake), the same without shading
    (``geometry_only``: no effects), and the composed filter per level on ``filter_probes`` of the
    captured probes (each level's dispatches timed alone, the rest of the call as ``outside``);
    with the budget of :data:`GOAL_PROBES_PER_S` on this machine's cores."""
    scene = load_scene(scene_name)
    sky = scene.sky.build()
    pos = np.array([p.position for st in ps.manifest.streets for p in st.probes], np.float64)
    count = len(pos)
    rec: dict[str, Any] = {"probes": count}
    rgba = None
    for name in ("capture", "geometry_only"):
        if name == "capture":
            cap, setup_s, setup_cpu = _timed(lambda: CubeCapture.from_scene(
                scene, size, sky=sky, ctx=ctx, effect_parameters=shadow_effect_parameters(scene)))
        else:
            cap, setup_s, setup_cpu = _timed(lambda: CubeCapture(scene.mesh, size, ctx=ctx))
        try:
            cap.capture_many(pos[:1], progress=False)   # compiles, warms
            cs, wall, cpu = _timed(lambda: cap.capture_many(pos, progress=False))
        finally:
            cap.release()
        t = cs.pass_times_s
        rec[name] = {"setup_s": round(setup_s, 4), "setup_cpu_s": round(setup_cpu, 4),
                     "ms_per_probe": round(1e3 * wall / count, 2), "cpu_ms_per_probe": round(1e3 * cpu / count, 2),
                     "render_ms_per_probe": round(1e3 * t.get("render", 0.0) / count, 2),
                     "readback_ms_per_probe": round(1e3 * t.get("readback", 0.0) / count, 2),
                     "set_passes_s": {k: round(v, 4) for k, v in t.items() if k not in ("render", "readback")},
                     "probes_per_s": round(count / wall, 2), "probes_per_cpu_s": round(count / cpu, 2)}
        if name == "capture":
            rgba = np.ascontiguousarray(cs.rgba[:max(1, filter_probes)])
        del cs
    assert rgba is not None
    lad = lobe_ladder(size)
    prefilter_many_composed(rgba[:1], lad, ctx)   # compiles the variants
    sec: dict[int, list[float]] = {}
    _, wall, cpu = _timed(lambda: prefilter_many_composed(rgba, lad, ctx, level_seconds=sec))
    k = len(rgba)
    rec["prefilter"] = {
        "probes": k, "ms_per_probe": round(1e3 * wall / k, 2), "cpu_ms_per_probe": round(1e3 * cpu / k, 2),
        "levels": {str(lv): {"ms_per_probe": round(1e3 * v[0] / k, 2), "cpu_ms_per_probe": round(1e3 * v[1] / k, 2)}
                   for lv, v in sorted(sec.items())},
        "outside_dispatches_cpu_ms_per_probe": round(1e3 * (cpu - sum(v[1] for v in sec.values())) / k, 2)}
    cores = os.cpu_count() or 1
    rec["goal"] = {"probes_per_s": GOAL_PROBES_PER_S, "cores": cores, "wall_ms_per_probe": 1e3 / GOAL_PROBES_PER_S,
                   "cpu_ms_per_probe_all_cores_busy": 1e3 * cores / GOAL_PROBES_PER_S,
                   "capture_alone_share_of_wall_budget": round(rec["capture"]["ms_per_probe"] * GOAL_PROBES_PER_S / 1e3, 3),
                   "capture_and_filter_cpu_share_of_cpu_budget": round(
                       (rec["capture"]["cpu_ms_per_probe"] + rec["prefilter"]["cpu_ms_per_probe"]) * GOAL_PROBES_PER_S
                       / (1e3 * cores), 3)}
    return rec



def _run_size(scene_name: str, size: int, args: argparse.Namespace, tmp: Path, ctx: Any,
              rng: np.random.Generator) -> dict[str, Any]:
    scene = load_scene(scene_name)
    runs: dict[str, tuple[ProbeSet, dict[str, Any]]] = {}
    runs["before"] = _before(scene, tmp / f"before_{size}", size, args.spacing, ctx)
    runs["after"] = _after(scene, tmp / f"after_{size}", size, args.spacing, args.fast_quality, ctx, False)
    if not args.no_files_run:
        runs["after_files"] = _after(scene, tmp / f"after_files_{size}", size, args.spacing, args.fast_quality, ctx, True)
    layers = runs["before"][0].layer_count
    rec: dict[str, Any] = {"size": size, "probes": layers, "load_average_start": list(os.getloadavg()), "runs": {}}
    for name, (ps, t) in runs.items():
        rec["runs"][name] = {
            "quality": "default" if name == "before" else args.fast_quality,
            "files": "ktx2, exr, previews (in turn)" if name == "before" else
                     ("ktx2 + exr, previews on threads" if name == "after_files" else "ktx2"),
            "wall_s": round(t["wall_s"], 3), "cpu_s": round(t["cpu_s"], 3),
            "probes_per_s": round(layers / t["wall_s"], 3), "probes_per_cpu_s": round(layers / t["cpu_s"], 3),
            "stages": _stages(t["report"], t["wall_s"], t["cpu_s"])}
    sets = {"default": runs["before"][0], args.fast_quality: runs["after"][0]}
    rec["prefilter_error"] = _errors(sets, args.error_probes, args.samples, rng)
    rec["gil"] = _gil_probe(runs["after"][0], tmp / f"gil_{size}")
    pre = {n: rec["runs"][n]["stages"]["prefilter"] for n in ("before", "after")}
    exact_total = rec["prefilter_error"]["exact_seconds_per_probe_extrapolated"] * layers
    exact_cpu = rec["prefilter_error"]["exact_cpu_seconds_per_probe_extrapolated"] * layers
    rec["prefilter_ratio"] = {
        "previous_over_fast_wall": pre["before"]["seconds"] / pre["after"]["seconds"],
        "previous_over_fast_cpu": pre["before"]["cpu_seconds"] / pre["after"]["cpu_seconds"],
        "exact_over_fast_wall": exact_total / pre["after"]["seconds"],
        "exact_over_fast_cpu": exact_cpu / pre["after"]["cpu_seconds"],
        "exact_over_previous_cpu": exact_cpu / pre["before"]["cpu_seconds"]}
    if size == CMFT_SIZE:
        # cmft ran 2 threads for --cmft-seconds (wall): ~2x that in CPU; the probes and the sky
        rec["prefilter_ratio"]["cmft_converted_over_fast_wall"] = args.cmft_seconds * (layers + 1) / pre["after"]["seconds"]
        rec["prefilter_ratio"]["cmft_converted_over_fast_cpu"] = 2 * args.cmft_seconds * (layers + 1) / pre["after"]["cpu_seconds"]
        rec["prefilter_ratio"]["cmft_converted_over_previous_cpu"] = 2 * args.cmft_seconds * (layers + 1) / pre["before"]["cpu_seconds"]
    if args.floor_filter_probes > 0:
        rec["floor"] = _floor(scene_name, runs["after"][0], size, ctx, args.floor_filter_probes)
    if args.sky_visibility_reps > 0:
        rec["sky_visibility"] = bake_sky_visibility.sky_visibility_record(scene, size, args, tmp, ctx, runs["after"][0],
                                                                          np.random.default_rng(size))
    rec["load_average_end"] = list(os.getloadavg())
    return rec


def _table(result: dict[str, Any]) -> str:
    names = ["sky", "capture", "prefilter", "planes", "write files", "write ktx2", "write exr", "write previews", "other"]
    lines = ["| size | run | probes/s | wall s | CPU s | " + " | ".join(names) + " |",
             "| --- | --- | --- | --- | --- | " + " | ".join("---" for _ in names) + " |"]
    for rec in result["sizes"]:
        for run, r in rec["runs"].items():
            cells = [f"{r['stages'][s]['seconds']:.2f} / {r['stages'][s]['cpu_seconds']:.2f}" if s in r["stages"] else ""
                     for s in names]
            lines.append(f"| 6x{rec['size']}^2, {rec['probes']} probes | {run} ({r['quality']}) | {r['probes_per_s']:.2f} | "
                         f"{r['wall_s']:.1f} | {r['cpu_s']:.1f} | " + " | ".join(cells) + " |")
    lines += ["", "Stage cells: wall s / CPU s.", "", "| size | filter | rel. RMSE per level (max over checked probes) |",
              "| --- | --- | --- |"]
    for rec in result["sizes"]:
        for q, lv in rec["prefilter_error"]["rel_rmse_per_level"].items():
            lines.append(f"| {rec['size']} | {q} | " + " ".join(f"{e:.1e}" for e in lv) + " |")
    lines += ["", "| size | writer | files | writer thread CPU s | spinning Python thread CPU s | wall s |",
              "| --- | --- | --- | --- | --- | --- |"]
    for rec in result["sizes"]:
        for w, g in rec.get("gil", {}).items():
            lines.append(f"| {rec['size']} | {w} | {g['files']} | {g['writer_thread_cpu_s']} | "
                         f"{g['spinning_thread_cpu_s']} | {g['wall_s']} |")
    lines += ["", "| size | floor (per probe, alone) | wall ms | CPU ms | render ms | readback ms | probes/s |",
              "| --- | --- | --- | --- | --- | --- | --- |"]
    for rec in result["sizes"]:
        fl = rec.get("floor")
        if fl is None:
            continue
        for what in ("capture", "geometry_only"):
            f = fl[what]
            lines.append(f"| {rec['size']} | {what} ({fl['probes']} probes) | {f['ms_per_probe']} | {f['cpu_ms_per_probe']} | "
                         f"{f['render_ms_per_probe']} | {f['readback_ms_per_probe']} | {f['probes_per_s']} |")
        pf = fl["prefilter"]
        lines.append(f"| {rec['size']} | composed filter ({pf['probes']} probes) | {pf['ms_per_probe']} | {pf['cpu_ms_per_probe']} "
                     f"| levels: " + ", ".join(f"{k}: {v['cpu_ms_per_probe']}" for k, v in pf["levels"].items())
                     + f"; outside the dispatches {pf['outside_dispatches_cpu_ms_per_probe']} (CPU ms) | | |")
        g = fl["goal"]
        lines.append(f"| {rec['size']} | goal {g['probes_per_s']:g} probes/s on {g['cores']} cores | {g['wall_ms_per_probe']:g} "
                     f"| {g['cpu_ms_per_probe_all_cores_busy']:g} | capture alone: {g['capture_alone_share_of_wall_budget']} "
                     f"of the wall budget | capture + filter: {g['capture_and_filter_cpu_share_of_cpu_budget']} of the CPU "
                     f"budget | |")
    lines += bake_sky_visibility.table_lines(result)
    lines += ["", "| size | ratio | value |", "| --- | --- | --- |"]
    for rec in result["sizes"]:
        for k, v in rec["prefilter_ratio"].items():
            lines.append(f"| {rec['size']} | {k} | {v:.1f} |")
    return "\n".join(lines) + "\n"


def run(args: argparse.Namespace) -> int:
    sizes = [int(s) for s in str(args.sizes).split(",") if s.strip()]
    if not sizes or min(sizes) < 2:
        raise ValueError(f"--sizes must list face sizes >= 2, got {args.sizes!r}")
    if args.error_probes < 1 or args.samples < 1:
        raise ValueError("--error-probes and --samples must be >= 1")
    rng = np.random.default_rng(0)
    result: dict[str, Any] = {"scene": args.scene, "spacing": args.spacing, "cpu_count": os.cpu_count(),
                              "cmft": {"seconds_per_cube": args.cmft_seconds, "size": CMFT_SIZE,
                                       "note": "not run here: the known point of PLATFORM.md; ratios are conversions"},
                              "sizes": []}
    ctx = create_context()
    try:
        with atomic_output_dir(args.out) as tmp:
            for size in sizes:
                result["sizes"].append(_run_size(args.scene, size, args, tmp, ctx, rng))
                print(json.dumps({k: v for k, v in result["sizes"][-1].items() if k != "runs"}), flush=True)
            (tmp / "bake.json").write_text(json.dumps(result, indent=2))
            (tmp / "bake.md").write_text(_table(result))
            print(_table(result))
    finally:
        ctx.release()
    return 0
