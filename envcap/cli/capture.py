"""``envcap capture SCENE --out DIR``: bake a probe set for a bundled scene or a scene file."""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from envcap.cli.output_options import add_force_argument, scene_input_files
from envcap.outputs import claim_output_dir
from envcap.prefilter import QUALITIES
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.store import write_probe_set
from envcap.scene import load_scene


def add_bake_arguments(p: argparse.ArgumentParser, resolution: int) -> None:
    """Options shared by ``capture`` and ``demo``."""
    p.add_argument("--resolution", type=int, default=resolution, metavar="N", help=f"face size in texels (default {resolution})")
    p.add_argument("--spacing", type=float, default=5.0, metavar="M", help="probe spacing along the street in meters (default 5)")
    p.add_argument("--height", type=float, default=2.0, metavar="M", help="probe height above the ground in meters (default 2)")
    p.add_argument("--quality", default="default", choices=list(QUALITIES), help="cosine-lobe filter quality")
    p.add_argument("--sun-in-sky", action="store_true",
                   help="splat the sun into sky.ktx2 (float32) instead of keeping it only as an analytic light")
    p.add_argument("--no-exr", action="store_true", help="skip the per-probe OpenEXR files")
    p.add_argument("--no-previews", action="store_true", help="skip the PNG previews")
    add_force_argument(p)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("capture", help="capture HDR probes along the streets of a scene")
    p.add_argument("scene", help="bundled scene name (see 'envcap scenes') or path to a scene .toml")
    p.add_argument("--out", required=True, type=Path, help="output directory (written atomically)")
    add_bake_arguments(p, 256)
    p.set_defaults(func=run)


def check_bake_arguments(args: argparse.Namespace) -> None:
    """Refuse bad bake options before any output is claimed (``ValueError``)."""
    if args.resolution < 1:
        raise ValueError(f"--resolution must be a positive number of texels, got {args.resolution}")


def bake_to_dir(args: argparse.Namespace, scene_name: str, out: str | os.PathLike[str]) -> Path:
    """Bake ``scene_name`` with the options in ``args`` and write the probe set to ``out`` (a path,
    or an output claimed with :func:`envcap.outputs.claim_output_dir`); return its path."""
    check_bake_arguments(args)
    t0 = time.perf_counter()
    scene = load_scene(scene_name)
    ps = bake_probe_set(scene, resolution=args.resolution, spacing=args.spacing, height=args.height,
                        quality=args.quality, sun_in_sky=args.sun_in_sky, verbose=True)
    ps.manifest = ps.manifest.with_timings(total_s=round(time.perf_counter() - t0, 3))
    path = write_probe_set(out, ps, exr=not args.no_exr, previews=not args.no_previews)
    n = ps.layer_count
    print(f"wrote {n} probes ({args.resolution}^2 x 6, {len(ps.levels)} levels) of '{scene.name}' to {path}"
          f" in {time.perf_counter() - t0:.1f} s")
    return path


def run(args: argparse.Namespace) -> int:
    check_bake_arguments(args)
    with claim_output_dir(args.out, kind="probe-set", inputs=scene_input_files(args.scene), force=args.force) as out:
        bake_to_dir(args, args.scene, out)
    return 0
