"""``envcap capture SCENE --out DIR``: bake a probe set for a bundled scene or a scene file."""

from __future__ import annotations

import argparse
import time
from pathlib import Path


def add_bake_arguments(p: argparse.ArgumentParser, resolution: int) -> None:
    """Options shared by ``capture`` and ``demo``."""
    p.add_argument("--resolution", type=int, default=resolution, metavar="N", help=f"face size in texels (default {resolution})")
    p.add_argument("--spacing", type=float, default=5.0, metavar="M", help="probe spacing along the street in meters (default 5)")
    p.add_argument("--height", type=float, default=2.0, metavar="M", help="probe height above the ground in meters (default 2)")
    p.add_argument("--quality", default="default", choices=["fast", "default", "high"], help="cosine-lobe filter quality")
    p.add_argument("--sun-in-sky", action="store_true",
                   help="splat the sun into sky.ktx2 (float32) instead of keeping it only as an analytic light")
    p.add_argument("--no-exr", action="store_true", help="skip the per-probe OpenEXR files")
    p.add_argument("--no-previews", action="store_true", help="skip the PNG previews")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("capture", help="capture HDR probes along the streets of a scene")
    p.add_argument("scene", help="bundled scene name (see 'envcap scenes') or path to a scene .toml")
    p.add_argument("--out", required=True, type=Path, help="output directory (written atomically)")
    add_bake_arguments(p, 256)
    p.set_defaults(func=run)


def bake_to_dir(args: argparse.Namespace, scene_name: str, out: Path) -> Path:
    from envcap.probeset.bake import bake_probe_set
    from envcap.probeset.store import write_probe_set
    from envcap.scene import load_scene

    if args.resolution < 1:
        raise ValueError(f"--resolution must be a positive number of texels, got {args.resolution}")
    t0 = time.perf_counter()
    scene = load_scene(scene_name)
    ps = bake_probe_set(scene, resolution=args.resolution, spacing=args.spacing, height=args.height,
                        quality=args.quality, sun_in_sky=args.sun_in_sky, verbose=True)
    ps.manifest["timings"]["total_s"] = round(time.perf_counter() - t0, 3)
    path = write_probe_set(out, ps, exr=not args.no_exr, previews=not args.no_previews)
    n = ps.layer_count
    print(f"wrote {n} probes ({args.resolution}^2 x 6, {len(ps.levels)} levels) of '{scene.name}' to {path}"
          f" in {time.perf_counter() - t0:.1f} s")
    return path


def run(args: argparse.Namespace) -> int:
    bake_to_dir(args, args.scene, args.out)
    return 0
