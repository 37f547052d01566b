"""``envcap capture CITY --out DIR --workers N``: the city options of ``capture`` and their run.

With ``--workers N`` (N >= 1: a Dask ``LocalCluster`` of N worker processes; 0: this process) or
``--scheduler ADDRESS`` (an existing Dask cluster), ``capture`` bakes a sharded city probe set
(:func:`envcap.city.bake.bake_city`, ``docs/scale.md``) instead of one probe set: resumable (a
rerun skips finished shards) and bit-identical whichever way it runs.  ``--workers`` and
``--scheduler`` exclude each other; ``--quiet`` silences the progress lines on stderr.
"""

from __future__ import annotations

import argparse

from envcap.city.bake import DEFAULT_BUDGET_MB, DEFAULT_MAP_CELL, DEFAULT_TIMEOUT_S, bake_city
from envcap.city.plan import BakeSettings
from envcap.cli.output_options import scene_input_files
from envcap.formats.registry import default_writer_names


def add_city_arguments(p: argparse.ArgumentParser) -> None:
    """The city options of ``capture``."""
    g = p.add_argument_group("city (sharded, resumable; docs/scale.md)")
    g.add_argument("--workers", type=int, default=None, metavar="N",
                   help="bake a sharded city probe set on a Dask LocalCluster of N processes (0: in this process)")
    g.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="bake a sharded city probe set on an existing Dask cluster (e.g. tcp://host:8786)")
    g.add_argument("--shard-mb", type=float, default=DEFAULT_BUDGET_MB, metavar="MB",
                   help=f"shard size budget in MB of probes.ktx2 (default {DEFAULT_BUDGET_MB:g}; 0: one shard per street)")
    g.add_argument("--map-cell", type=float, default=DEFAULT_MAP_CELL, metavar="M",
                   help=f"street-map cell size in meters (default {DEFAULT_MAP_CELL:g})")
    g.add_argument("--retries", type=int, default=2, metavar="K", help="Dask retries of a failing shard (default 2)")
    g.add_argument("--cluster-timeout", type=float, default=DEFAULT_TIMEOUT_S, metavar="S",
                   help=f"seconds to wait for any answer of the Dask scheduler (default {DEFAULT_TIMEOUT_S:g})")


def city_requested(args: argparse.Namespace) -> bool:
    """Whether the options ask for a city probe set."""
    return getattr(args, "workers", None) is not None or getattr(args, "scheduler", None) is not None


def writer_names(args: argparse.Namespace) -> tuple[str, ...]:
    """The output writers the bake options select: the default writers, EXR and previews as
    ``--exr`` / ``--previews`` say (or ``--no-exr`` / ``--no-previews``, whichever ``capture``
    has), and the optional ``--webgl2`` / ``--latlong`` ones."""
    exr = getattr(args, "exr", None)
    exr = not getattr(args, "no_exr", False) if exr is None else exr
    previews = getattr(args, "previews", None)
    previews = not getattr(args, "no_previews", False) if previews is None else previews
    names = [n for n in default_writer_names() if (exr or n != "exr") and (previews or n != "previews")]
    return tuple(names + [w for w in ("exr", "previews") if {"exr": exr, "previews": previews}[w] and w not in names]
                 + [w for w in ("webgl2", "latlong") if getattr(args, w, False)])


def run_city(args: argparse.Namespace) -> int:
    """Bake the city probe set of ``args.scene`` into ``args.out``."""
    if args.workers is not None and args.scheduler is not None:
        raise ValueError("--workers starts a LocalCluster on this machine; with --scheduler the cluster's own workers "
                         "bake: give one of them")
    settings = BakeSettings(resolution=args.resolution, spacing=args.spacing, height=args.height, quality=args.quality,
                            sun_in_sky=args.sun_in_sky, writers=writer_names(args))
    workers = 0 if args.workers is None else args.workers
    r = bake_city(args.scene, args.out, settings, workers=workers, scheduler=args.scheduler, budget_mb=args.shard_mb,
                  map_cell=args.map_cell, retries=args.retries, inputs=scene_input_files(args.scene), force=args.force,
                  quiet=bool(getattr(args, "quiet", False)), timeout_s=args.cluster_timeout)
    print(f"wrote city probe set of '{args.scene}' to {r.path}: {r.baked} shard(s) baked, {r.skipped} already done,"
          f" in {r.wall_s:.1f} s")
    return 0
