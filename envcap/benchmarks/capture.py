"""Probe capture throughput (probes/s at 6 x N^2): per-face chunk culling against drawing everything.

The scene is the bundled ``canyon`` street (48,942 triangles) with its sky.  Measured in the
same run, interleaved probe by probe so that load from other processes hits both alike:

* ``culled``: :class:`~envcap.capture.renderer.CubeCapture` as shipped (chunks culled per face, near
  first), for every effect subset;
* ``unculled``: the simplest correct method, ``cull_chunks=False`` (every triangle drawn for
  every face, one draw call per face), all effects; its output must be bit-identical;
* ``naive``: a fresh capture per probe (mesh upload, shader compile, shadow map, sky SH), all
  effects, for the cost of the per-set setup.

Every timed capture set is preceded by an untimed one of the same size (shader JIT, and the
first touch of fresh memory, slow on this VM).  Reports probes/s (1 / median wall time per
probe), the end-to-end ``capture_many`` rate, ratios, per-probe pass costs (``cull``: CPU
choosing chunks, ``render``: the six faces drawn and finished, ``readback``: read into
(6, N, N, 4)), triangles and draw calls per probe, and the load average seen.  Writes
``capture.json`` and ``capture.png`` to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

from envcap.capture.effects import BUILTIN_EFFECTS
from envcap.capture.outputs import CaptureSet
from envcap.capture.renderer import CubeCapture
from envcap.gpu.context import create_context
from envcap.outputs import atomic_output_dir
from envcap.scene import load_scene


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", required=True, help="output directory (JSON + PNG)")
    parser.add_argument("--size", type=int, default=256, help="face resolution N")
    parser.add_argument("--probes", type=int, default=20, help="probes per timed round")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds (culled / unculled)")
    parser.add_argument("--baseline-probes", type=int, default=3, help="probes for the naive baseline")


def _timed(cap: CubeCapture, pos: np.ndarray) -> tuple[float, dict[str, float], CaptureSet]:
    """Wall seconds for ``capture_many(pos)``, per-probe pass means, and the set."""
    t0 = time.perf_counter()
    s = cap.capture_many(pos, progress=False)
    dt = time.perf_counter() - t0
    per = {k: s.pass_times_s[k] / len(pos) for k in ("render", "readback")}
    return dt, per, s


def run(args: argparse.Namespace) -> int:
    if args.size < 1 or args.probes < 1 or args.baseline_probes < 1 or args.rounds < 1:
        raise ValueError("--size, --probes, --rounds and --baseline-probes must be >= 1")
    load_before = os.getloadavg()
    name = "canyon"
    sc = load_scene(name)
    mesh, sky = sc.mesh, sc.sky.build()
    ctx = create_context()
    rng = np.random.default_rng(0)
    x_lo, x_hi = -290.0, 290.0  # along the canyon street (x), inside its ends
    pos = np.stack([rng.uniform(x_lo, x_hi, args.probes), np.full(args.probes, 1.7),
                    rng.uniform(-3.0, 3.0, args.probes)], axis=1)
    all_eff = {e.name for e in BUILTIN_EFFECTS}
    subsets = {"geometry only": set(), "emissive_windows": {"emissive_windows"}, "sky_light": {"sky_light"},
               "sun_light": {"sun_light"}, "sun_light+sun_shadows": {"sun_light", "sun_shadows"}, "all": all_eff}

    # Culled vs unculled, all effects, interleaved probe by probe (both see the same load); every
    # output compared bit by bit.  Per-probe wall = cull + render + readback + unpacking.
    fast = CubeCapture(mesh, args.size, sky=sky, effects=all_eff, ctx=ctx)
    full = CubeCapture(mesh, args.size, sky=sky, effects=all_eff, ctx=ctx, cull_chunks=False)
    # Warm-up: shader JIT, and first touch of output memory (on this VM the first use of fresh
    # guest memory costs up to ~13 ms per 6 x 256^2 probe; reused memory 0.6 ms).
    fast.capture_many(pos, progress=False), full.capture_many(pos, progress=False)
    rec: dict[str, dict[str, list[float]]] = {
        k: {m: [] for m in ("wall", "render", "readback", "cull", "triangles", "draw_calls")}
        for k in ("culled", "unculled")}
    identical = True
    for _ in range(args.rounds):
        for p in pos:
            got = {}
            for key, cap in (("culled", fast), ("unculled", full)):
                t0 = time.perf_counter()
                c = cap.capture(p)
                r = rec[key]
                r["wall"].append(time.perf_counter() - t0)
                r["render"].append(c.pass_times_s["render"])
                r["readback"].append(c.pass_times_s["readback"])
                r["cull"].append(c.draw_stats["cull_s"])
                r["triangles"].append(c.draw_stats["triangles"])
                r["draw_calls"].append(c.draw_stats["draw_calls"])
                got[key] = c
            a, b = got["culled"], got["unculled"]
            identical &= bool(np.array_equal(a.rgba, b.rgba) and np.array_equal(a.distance, b.distance)
                              and np.array_equal(a.backfacing, b.backfacing))
    compare = {}
    for key, r in rec.items():
        med = {m: float(np.median(v)) for m, v in r.items()}
        compare[key] = {"probes_per_s": 1.0 / med["wall"], "probes_per_s_mean": 1.0 / float(np.mean(r["wall"])),
                        "wall_per_probe_s_median": med["wall"],
                        "wall_per_probe_s_p10_p90": [float(np.quantile(r["wall"], q)) for q in (0.1, 0.9)],
                        "per_probe_s": {"cull": med["cull"], "render": med["render"], "readback": med["readback"]},
                        "triangles_per_probe": float(np.mean(r["triangles"])),
                        "draw_calls_per_probe": float(np.mean(r["draw_calls"]))}
    # End to end, as envcap capture calls it: one capture_many (culled), after the warm-up above.
    dt, _, _ = _timed(fast, pos)
    compare["culled"]["capture_many_probes_per_s"] = args.probes / dt
    ratio = compare["culled"]["probes_per_s"] / compare["unculled"]["probes_per_s"]
    per_set = dict(fast.pass_times_s)
    fast.release()
    full.release()
    print(f"all effects (median per probe): culled {compare['culled']['probes_per_s']:.1f} probes/s, unculled "
          f"{compare['unculled']['probes_per_s']:.1f} probes/s, ratio {ratio:.2f}x, identical={identical}; "
          f"capture_many culled {compare['culled']['capture_many_probes_per_s']:.1f} probes/s")

    # Per effect subset (culled path only).
    results: dict[str, dict] = {}
    for label, eff in subsets.items():
        t0 = time.perf_counter()
        cap = CubeCapture(mesh, args.size, sky=sky, effects=eff, ctx=ctx)
        setup = time.perf_counter() - t0
        cap.capture_many(pos, progress=False)  # warm-up (JIT, output memory)
        dt, per, _ = _timed(cap, pos)
        results[label] = {"probes_per_s": args.probes / dt, "setup_s": setup,
                          "per_set_passes_s": dict(cap.pass_times_s), "per_probe_s": per}
        cap.release()
        print(f"{label:24s} {results[label]['probes_per_s']:7.1f} probes/s  setup {setup * 1e3:7.1f} ms")

    # Naive baseline: everything re-done per probe (all effects, culled).
    t0 = time.perf_counter()
    for i in range(args.baseline_probes):
        c = CubeCapture(mesh, args.size, sky=sky, effects=all_eff, ctx=ctx)
        c.capture(pos[i % len(pos)])
        c.release()
    naive = args.baseline_probes / (time.perf_counter() - t0)
    load_after = os.getloadavg()
    out = {
        "scene": name, "triangles": mesh.triangle_count, "size": args.size, "probes": args.probes,
        "rounds": args.rounds, "cpu_count": os.cpu_count(), "LP_NUM_THREADS": os.environ.get("LP_NUM_THREADS"),
        "load_average_1_5_15_before": list(load_before), "load_average_1_5_15_after": list(load_after),
        "all_effects": compare, "culled_over_unculled": ratio, "culled_output_identical": identical,
        "per_set_passes_s": per_set, "subsets": results, "naive_all_probes_per_s": naive,
        "speedup_vs_naive": compare["culled"]["probes_per_s"] / naive,
    }
    print(f"naive (re-create per probe) {naive:.2f} probes/s; load {load_before[0]:.2f} -> {load_after[0]:.2f}")
    with atomic_output_dir(args.out) as d:
        (Path(d) / "capture.json").write_text(json.dumps(out, indent=2))
        _plot(Path(d) / "capture.png", out, mesh.triangle_count, args.size)
    ctx.release()
    return 0 if identical else 1


def _plot(path: Path, out: dict, tris: int, size: int) -> None:
    import matplotlib  # heavy, needed only for the figure

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cmp_ = out["all_effects"]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 4.0), gridspec_kw={"width_ratios": [3, 2]})
    labels = [f"{k} (culled, capture_many)" for k in out["subsets"]] + [
        "all, culled (median, alternating)", "all, unculled (median, alternating)", "all, naive (re-create)"]
    vals = [v["probes_per_s"] for v in out["subsets"].values()] + [
        cmp_["culled"]["probes_per_s"], cmp_["unculled"]["probes_per_s"], out["naive_all_probes_per_s"]]
    ax.barh(labels, vals, color=["C0"] * len(out["subsets"]) + ["C2", "C1", "C3"])
    ax.axvline(20, color="k", ls="--", lw=0.8, label="goal 20 probes/s")
    ax.set_xlabel(f"probes/s at 6x{size}^2, {tris} triangles")
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title(f"load avg {out['load_average_1_5_15_before'][0]:.1f}, {out['cpu_count']} cores", fontsize=9)
    keys = ["culled", "unculled"]
    bottom = np.zeros(2)
    for part, col in (("cull", "C2"), ("render", "C0"), ("readback", "C4")):
        v = np.array([cmp_[k]["per_probe_s"].get(part, 0.0) * 1e3 for k in keys])
        bx.bar(keys, v, bottom=bottom, color=col, label=part)
        bottom += v
    for i, k in enumerate(keys):
        bx.text(i, bottom[i], f"{cmp_[k]['triangles_per_probe'] / 1e3:.0f}k tris\n{cmp_[k]['draw_calls_per_probe']:.0f} index ranges",
                ha="center", va="bottom", fontsize=8)
    bx.set_ylabel("ms per probe (all effects)")
    bx.set_ylim(0, bottom.max() * 1.3)
    bx.set_title(f"culled / unculled = {out['culled_over_unculled']:.2f}x", fontsize=9)
    bx.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
