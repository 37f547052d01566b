"""``envcap avatar IN --out OUT.glb [--k K] [--reduce mean|max] [--animation A] [--exclude-weight W]``:
proxy spheres and per-vertex blockers of a skinned glTF 2.0 avatar, written into a new ``.glb``.

``OUT`` gets the input's content plus the vertex attributes ``_ENVCAP_BLOCKERS`` /
``_ENVCAP_BLOCKER_WEIGHTS`` and the extras of :mod:`envcap.dynamic.avatar_attributes`, written to
a temporary name ``.OUT.tmp-XXXXXXXX.glb`` and renamed at the end, under the lock ``.OUT.lock``
(a second run on the same ``OUT`` fails at once; a run removes the temporary files that killed
runs left).  ``OUT`` may never be ``IN``; an existing ``OUT`` is replaced only when envcap wrote it
(``asset.extras.envcap == "avatar"``); with ``--force`` another file there is moved aside
(``NAME.envcap-replaced-YYYYmmdd-HHMMSS.glb``), never deleted.

Before any buffer is decoded, the input's counts (vertices, joints, keyframes) give the memory
and time of the run (:mod:`envcap.dynamic.avatar_cost`): past the memory limit it stops with one
line giving the estimate; a long run prints its estimate first, then progress per stage
(``--quiet``: none).  The blocking work runs in blocks of vertices, so its memory is bounded
whatever the bone count; its time grows with vertices x joints x keyframes.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

from envcap.core.input_path import require_file
from envcap.dynamic.avatar_attributes import BLOCKERS_ATTRIBUTE, is_envcap_avatar, write_annotated
from envcap.dynamic.avatar_blockers import MAX_BLOCKERS, REDUCTIONS, check_options
from envcap.dynamic.avatar_cost import check_avatar_cost, estimate_avatar, read_counts
from envcap.outputs import OutputRefused, atomic_output_file
from envcap.outputs.guard import check_file_target, resolve_output
from envcap.probeset.progress import BakeProgress

LISTED_JOINTS = 40
"""The summary lists the spheres of at most this many joints."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("avatar", help="proxy spheres and per-vertex blocking bones of a skinned glTF avatar")
    p.add_argument("input", metavar="IN", help="skinned glTF 2.0 avatar (.glb, or .gltf with its buffers)")
    p.add_argument("--out", required=True, help="output .glb (a new file; never IN)")
    p.add_argument("--k", type=int, default=MAX_BLOCKERS, help=f"blockers per vertex, 1..{MAX_BLOCKERS} (default %(default)s)")
    p.add_argument("--reduce", choices=REDUCTIONS, default="mean",
                   help="over the keyframes: mean (default) or max of each bone's blocking")
    p.add_argument("--animation", type=int, default=0, help="animation whose keyframes are used (default 0)")
    p.add_argument("--exclude-weight", type=float, default=0.0,
                   help="a vertex ignores the bones it is skinned to with a weight above this (default 0: all)")
    p.add_argument("--force", action="store_true",
                   help="replace OUT even if envcap did not write it (that file is renamed beside it, never deleted)")
    p.add_argument("--quiet", action="store_true", help="no estimate or progress on stderr (warnings and errors still)")
    p.set_defaults(func=run)


def check_target(source: Path, target: Path, force: bool) -> None:
    """Refuse ``target`` when it is ``source``, a directory, or a file envcap did not write (unless ``force``)."""
    if target.suffix.lower() != ".glb":
        raise OutputRefused(f"output {target} must end in .glb (envcap writes glTF binary)")
    if source.exists() and target.exists() and os.path.samefile(source, target):
        raise OutputRefused(f"output {target} is the input; choose another file (--force does not change this)")
    if target.is_dir():
        raise OutputRefused(f"output {target} is a directory")
    check_file_target(target)
    if target.exists() and not force and not is_envcap_avatar(target):
        raise OutputRefused(f"{target} exists and was not written by envcap avatar; choose another file, "
                            f"or use --force to move it aside")


def run(args: argparse.Namespace) -> int:
    source = Path(args.input)
    target = resolve_output(args.out)
    check_target(source, target, args.force)
    require_file(source, "input avatar", f"input avatar {source} does not exist")
    check_options(args.k, args.reduce, args.exclude_weight)
    counts = read_counts(source, args.animation)
    if counts is not None and counts.animations and not 0 <= args.animation < counts.animations:
        raise ValueError(f"animation {args.animation} (--animation) does not exist (the avatar has "
                         f"{counts.animations}, numbered from 0)")
    if counts is not None:   # else the loader says what is wrong with the file
        estimate = estimate_avatar(counts)
        check_avatar_cost(estimate, source)
        if estimate.big and not args.quiet:
            print(f"{source}: estimate: {estimate.describe()}", file=sys.stderr, flush=True)
    report = BakeProgress("off" if args.quiet else "auto", unit="vertex", units="vertices")
    foreign = target.exists() and not is_envcap_avatar(target)     # only with --force: moved aside
    with atomic_output_file(target, keep_existing=foreign, lock=True) as tmp:
        avatar, spheres, blockers = write_annotated(source, tmp, k=args.k, reduce=args.reduce, animation=args.animation,
                                                    exclude_weight=args.exclude_weight, report=report)
    print(f"{target}: {len(avatar.positions)} vertices, {avatar.joint_count} joints, "
          f"{len(blockers.keyframes)} keyframes ({blockers.reduce}), {BLOCKERS_ATTRIBUTE} k={blockers.joints.shape[1]}")
    for name, r, n in list(zip(avatar.joint_names, spheres.radii, spheres.vertex_counts))[:LISTED_JOINTS]:
        print(f"    {name:<16} sphere radius {r:.3f} m from {n} vertices")
    if avatar.joint_count > LISTED_JOINTS:
        print(f"    ... {avatar.joint_count - LISTED_JOINTS:,} more joints (their spheres are in OUT: "
              f"skins[{avatar.skin_index}].extras.envcap_proxy_spheres)")
    used = (blockers.scores > 0.01).sum(axis=1)
    print(f"    blockers hiding > 1% of the hemisphere per vertex: mean {used.mean():.2f}, max {int(np.max(used))}")
    return 0
