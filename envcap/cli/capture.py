"""``envcap capture SCENE --out DIR``: bake a probe set for a bundled scene or a scene file."""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from envcap.cli.capture_city import add_city_arguments, city_requested, run_city
from envcap.cli.output_options import add_force_argument, scene_input_files
from envcap.core.rungs import LADDER_MODES
from envcap.formats.registry import default_writer_names
from envcap.formats.scene_gltf_writer import registered_scene_writer
from envcap.outputs import claim_output_dir
from envcap.placement import get as get_placement, registered as placement_names
from envcap.placement.place import check_probes_per_street, place_scene
from envcap.prefilter import QUALITIES
from envcap.probeset.bake_output import bake_to_directory
from envcap.probeset.progress import BakeProgress
from envcap.scene import load_scene


BAKE_QUALITY = "composed"
"""The filter of ``capture`` and ``demo`` (issue 11): levels composed with difference lobes, 4-6x
less CPU than ``"default"`` and within 0.5 % of the exact reference at every level (docs/bake.md).
The library's :func:`envcap.probeset.bake.bake_probe_set` keeps ``"default"``."""


class _Given(argparse.Action):
    """Store the value and note that the option was given (``args.<dest>_given``): ``--spacing``
    and ``--probes-per-street`` exclude each other only when both are typed."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: object,
                 option_string: str | None = None) -> None:
        setattr(namespace, self.dest, values)
        setattr(namespace, f"{self.dest}_given", True)


def add_bake_arguments(p: argparse.ArgumentParser, resolution: int, *, files: bool = False, spacing: float = 5.0) -> None:
    """Options shared by ``capture`` and ``demo``; ``files``: whether the per-probe EXRs and the
    previews are written unless ``--no-exr`` / ``--no-previews`` (``demo``) or only with
    ``--exr`` / ``--previews`` (``capture``: the probe set needs neither); ``resolution`` and
    ``spacing`` (m): the defaults, as the help says them."""
    p.add_argument("--resolution", type=int, default=resolution, metavar="N", help=f"face size in texels (default {resolution})")
    p.add_argument("--spacing", type=float, default=spacing, metavar="M", action=_Given,
                   help=f"probe spacing along the street in meters (default {spacing:g})")
    p.add_argument("--height", type=float, default=2.0, metavar="M", help="probe height above the ground in meters (default 2)")
    p.add_argument("--quality", default=BAKE_QUALITY, choices=list(QUALITIES),
                   help=f"cosine-lobe filter quality (default {BAKE_QUALITY}: <= 0.2%% error per level, docs/bake.md)")
    p.add_argument("--sun-in-sky", action="store_true",
                   help="splat the sun into sky.ktx2 (float32) instead of keeping it only as an analytic light")
    on_off = "default: on; --no-{0} to skip" if files else "default: off; --{0} to write"
    p.add_argument("--exr", action=argparse.BooleanOptionalAction, default=files,
                   help=f"per-probe OpenEXR cubes exr/probe_NNN.exr, level 0 and distance ({on_off.format('exr')})")
    p.add_argument("--previews", action=argparse.BooleanOptionalAction, default=files,
                   help=f"PNG previews: a cross per probe, the sky, a contact sheet ({on_off.format('previews')})")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr (warnings and errors still)")
    p.add_argument("--webgl2", action="store_true",
                   help="also write probes_atlas.ktx2: the probes as face atlases for WebGL2 / three.js (docs/engines.md)")
    p.add_argument("--latlong", action="store_true",
                   help="also write latlong/*.exr: lat-long maps of the sky and of each probe over it (docs/engines.md)")
    p.add_argument("--latlong-hdr", action="store_true",
                   help="also write latlong/*.hdr: the same lat-long maps as Radiance .hdr, for Unreal (docs/engines.md)")
    p.add_argument("--sky-visibility", action="store_true",
                   help="also write sky_visibility.ktx2: visibility moments that keep the composite right when the sky "
                        "changes after the bake (docs/lobes.md)")
    p.add_argument("--inverse-distance", action=argparse.BooleanOptionalAction, default=None,
                   help="inverse_distance.ktx2: each probe's 1/distance (R16F), the texture the depth_refine "
                        "method reads and the distance channel 'envcap evaluate' needs for the depth-aware "
                        "methods (docs/engines.md; default: on for a probe set, off for a city bake; "
                        "--no-inverse-distance to skip)")
    p.add_argument("--scene-gltf", action="store_true",
                   help="also write scene.glb: the scene mesh near the streets as binary glTF, drawn by 'envcap view' (docs/viewer.md)")
    add_force_argument(p)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("capture", help="capture HDR probes along the streets of a scene")
    p.add_argument("scene", help="bundled scene name (see 'envcap scenes') or path to a scene .toml")
    p.add_argument("--out", required=True, type=Path, help="output directory (written atomically)")
    add_bake_arguments(p, 256)
    p.add_argument("--ladder", choices=list(LADDER_MODES), default="paper",
                   help="lobe ladder: paper (default: one chain), half_octave (4 rungs per level, ~4x the texels: "
                        "holds cos^w between levels and at wide lobes) or octave (2 rungs, ~2x); docs/lobes.md")
    p.add_argument("--placement", default=None, metavar="NAME",
                   help=f"how the probes are placed along each street: {', '.join(placement_names())} "
                        "(default uniform, at --spacing; docs/placement.md)")
    p.add_argument("--probes-per-street", default=None, metavar="N",
                   help="place N probes on every street, whatever its length (instead of --spacing)")
    p.add_argument("--crossings", action=argparse.BooleanOptionalAction, default=True,
                   help="where streets meet, add a probe at the crossing's centre shared by them and record the "
                        "crossings in the manifest (default on; docs/crossings.md)")
    add_city_arguments(p)
    p.set_defaults(func=run)


def check_bake_arguments(args: argparse.Namespace) -> None:
    """Refuse bad bake options before any output is claimed (``ValueError``)."""
    if args.resolution < 1:
        raise ValueError(f"--resolution must be a positive number of texels, got {args.resolution}")
    if getattr(args, "placement", None) is not None:
        get_placement(args.placement)                    # unknown: one line with the known names
    if getattr(args, "probes_per_street", None) is not None:
        check_probes_per_street(args.probes_per_street)
        if getattr(args, "spacing_given", False):
            raise ValueError("--spacing and --probes-per-street both given: give one (--probes-per-street N puts N probes "
                             "on every street whatever its length, --spacing M one every M meters)")


def placement_requested(args: argparse.Namespace) -> bool:
    """Whether the probes are placed by a strategy (``--placement`` or ``--probes-per-street``)."""
    return getattr(args, "placement", None) is not None or getattr(args, "probes_per_street", None) is not None


def bake_to_dir(args: argparse.Namespace, scene_name: str, out: str | os.PathLike[str]) -> Path:
    """Bake ``scene_name`` with the options in ``args`` and write the probe set to ``out`` (a path,
    or an output claimed with :func:`envcap.outputs.claim_output_dir`); return its path."""
    check_bake_arguments(args)
    t0 = time.perf_counter()
    scene = load_scene(scene_name)
    writers = ([n for n in default_writer_names() if n not in ("exr", "previews")]   # those two: --exr, --previews
               + [w for w in ("webgl2", "latlong", "latlong_hdr", "sky_visibility") if getattr(args, w, False)]
               + ([] if getattr(args, "inverse_distance", None) is False else ["inverse_distance"]))
    quiet = bool(getattr(args, "quiet", False))
    report = BakeProgress("off" if quiet else "auto")
    placed = {}
    if placement_requested(args):
        n = args.probes_per_street
        sp = place_scene(scene, args.placement or "uniform", probes_per_street=None if n is None else check_probes_per_street(n),
                         spacing=args.spacing, height=args.height, resolution=args.resolution, verbose=not quiet)
        placed = {"along": sp.along, "placement": sp.table}
        if not quiet:
            print(f"placed {sum(a.size for a in sp.along.values())} probes on {len(sp.along)} street(s) by "
                  f"{sp.table.strategy} in {sp.table.seconds:.1f} s")
    with registered_scene_writer(scene if getattr(args, "scene_gltf", False) else None) as scene_writer:
        path, ps = bake_to_directory(scene, out, exr=args.exr, previews=args.previews, writers=writers + scene_writer,
                                     report=report, resolution=args.resolution, spacing=args.spacing, height=args.height,
                                     quality=args.quality, sun_in_sky=args.sun_in_sky, verbose=not quiet, **placed,
                                     crossings=bool(getattr(args, "crossings", False)),
                                     **({} if getattr(args, "ladder", "paper") == "paper" else {"ladder_mode": args.ladder}))
    n = ps.layer_count
    print(f"wrote {n} probes ({args.resolution}^2 x 6, {len(ps.levels)} levels) of '{scene.name}' to {path}"
          f" in {time.perf_counter() - t0:.1f} s")
    return path


def run(args: argparse.Namespace) -> int:
    check_bake_arguments(args)
    if city_requested(args):
        if getattr(args, "scene_gltf", False):
            raise ValueError("--scene-gltf is for one scene's probe set, not a city bake")
        if getattr(args, "sky_visibility", False):
            raise ValueError("--sky-visibility is for one scene's probe set, not a city bake")
        if getattr(args, "inverse_distance", None):      # None: the default, off for a city
            raise ValueError("--inverse-distance is for one scene's probe set, not a city bake")
        if placement_requested(args):
            raise ValueError("--placement and --probes-per-street are for one scene's probe set, not a city bake "
                             "(city shards place their probes at --spacing)")
        if getattr(args, "ladder", "paper") != "paper":
            raise ValueError("--ladder is for one scene's probe set, not a city bake (city shards hold the paper's chain)")
        return run_city(args)
    with claim_output_dir(args.out, kind="probe-set", inputs=scene_input_files(args.scene), force=args.force) as out:
        bake_to_dir(args, args.scene, out)
    return 0
