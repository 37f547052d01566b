"""Probe capture throughput (probes/s at 6 x N^2) per effect subset, against a naive re-upload path.

The scene is the bundled ``canyon`` street when ``envcap.scene.load_scene`` exists, else a
synthetic street of ~50k triangles (``envcap.capture_synthetic.street_canyon``).  The baseline is
the simplest correct method: a fresh :class:`~envcap.capture.CubeCapture` per probe (mesh
re-upload, shader compile, shadow map and sky SH recomputed for every probe).  Its output is
checked equal to the fast path's.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from envcap.atomic import atomic_output_dir


class _Sun:
    def __init__(self) -> None:
        d = np.array([0.35, 0.8, 0.25])
        self.direction = d / np.linalg.norm(d)
        self.illuminance = np.array([9e4, 8.5e4, 8e4])
        self.angular_radius = 0.00465
        self.radiance = self.illuminance / (np.pi * self.angular_radius ** 2)


class _Sky:
    """Uniform stand-in used only when envcap.sky is missing."""

    def __init__(self) -> None:
        self.sun = _Sun()

    def radiance(self, dirs: np.ndarray) -> np.ndarray:
        return np.broadcast_to(np.array([4000.0, 5000.0, 7000.0]), np.shape(dirs)).copy()


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", required=True, help="output directory (JSON + PNG)")
    parser.add_argument("--size", type=int, default=256, help="face resolution N")
    parser.add_argument("--probes", type=int, default=20, help="probes per timed run")
    parser.add_argument("--baseline-probes", type=int, default=3, help="probes for the naive baseline")


def _scene():
    try:
        from envcap.scene import load_scene  # type: ignore[attr-defined]

        sc = load_scene("canyon")
        return sc.mesh, "canyon", sc
    except Exception:
        from envcap.capture_synthetic import street_canyon

        return street_canyon(), "synthetic street_canyon", None


def run(args: argparse.Namespace) -> int:
    from envcap.capture import CubeCapture
    from envcap.gl import create_context

    if args.size < 1 or args.probes < 1 or args.baseline_probes < 1:
        raise ValueError("--size, --probes and --baseline-probes must be >= 1")
    mesh, name, sc = _scene()
    sky = _Sky()
    if sc is not None:
        from envcap.sky import sky_from_spec

        sky = sky_from_spec(sc.sky, sc.base_dir)
    ctx = create_context()
    lo, hi = mesh.positions.min(0), mesh.positions.max(0)
    rng = np.random.default_rng(0)
    pos = np.stack([rng.uniform(lo[0] + 0.3 * (hi[0] - lo[0]), lo[0] + 0.7 * (hi[0] - lo[0]), args.probes),
                    np.full(args.probes, 1.7), np.zeros(args.probes)], axis=1)
    subsets = {"geometry only": set(), "emissive_windows": {"emissive_windows"}, "sky_light": {"sky_light"},
               "sun_light": {"sun_light"}, "sun_light+sun_shadows": {"sun_light", "sun_shadows"},
               "all": {"sun_light", "sun_shadows", "sky_light", "emissive_windows"}}
    results: dict[str, dict] = {}
    for label, eff in subsets.items():
        t0 = time.perf_counter()
        cap = CubeCapture(mesh, args.size, sky=sky, effects=eff, ctx=ctx)
        setup = time.perf_counter() - t0
        cap.capture(pos[0])  # warm-up
        t0 = time.perf_counter()
        s = cap.capture_many(pos, progress=False)
        dt = time.perf_counter() - t0
        results[label] = {"probes_per_s": args.probes / dt, "setup_s": setup,
                          "per_set_passes_s": {k: v for k, v in cap.pass_times_s.items()},
                          "per_probe_s": {k: s.pass_times_s[k] / args.probes for k in ("render", "readback")}}
        last = cap.capture(pos[0])
        cap.release()
        print(f"{label:24s} {results[label]['probes_per_s']:7.1f} probes/s  setup {setup * 1e3:7.1f} ms")
    # Naive baseline: everything re-done per probe (all effects).
    t0 = time.perf_counter()
    for i in range(args.baseline_probes):
        c = CubeCapture(mesh, args.size, sky=sky, effects=subsets["all"], ctx=ctx)
        b = c.capture(pos[0])
        c.release()
    naive = args.baseline_probes / (time.perf_counter() - t0)
    same = bool(np.array_equal(b.rgba, last.rgba) and np.array_equal(b.distance, last.distance))
    out = {"scene": name, "triangles": mesh.triangle_count, "size": args.size, "probes": args.probes,
           "subsets": results, "naive_all_probes_per_s": naive,
           "speedup_vs_naive": results["all"]["probes_per_s"] / naive, "naive_output_identical": same}
    print(f"naive (re-upload per probe) {naive:.2f} probes/s; speedup {out['speedup_vs_naive']:.1f}x; identical={same}")
    with atomic_output_dir(args.out) as d:
        (Path(d) / "capture.json").write_text(json.dumps(out, indent=2))
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        labels = list(results) + ["naive (all)"]
        vals = [results[k]["probes_per_s"] for k in results] + [naive]
        fig, ax = plt.subplots(figsize=(7, 3.2))
        ax.barh(labels, vals, color=["C0"] * len(results) + ["C3"])
        ax.axvline(20, color="k", ls="--", lw=0.8, label="goal 20 probes/s")
        ax.set_xlabel(f"probes/s at 6x{args.size}^2, {mesh.triangle_count} triangles")
        ax.legend(loc="lower right")
        fig.tight_layout()
        fig.savefig(Path(d) / "capture.png", dpi=100)
        plt.close(fig)
    ctx.release()
    return 0 if same else 1
