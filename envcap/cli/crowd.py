"""``envcap crowd SCENE --probes DIR --avatars N --out OUT``: render a crowd of walkers on a
street of SCENE, lit by the probe set DIR through the runtime GLSL (docs/crowd.md).

Options: ``--avatar FILE.glb`` (a file ``envcap avatar`` wrote; default the bundled walker),
``--seed S``, ``--frames F`` (at ``--fps``), ``--size WxH``, ``--terms probes|self|neighbours``,
``--street NAME``, ``--method M`` (the runtime lookup), ``--force``.  Writes ``frame_0000.png`` ...
and ``crowd.json`` into OUT (claimed first, written atomically; never over a directory envcap did
not write).  Bad input: one line, exit 2, nothing written.  The memory estimate is checked before
any GL work (:func:`envcap.core.budget.check_bytes`); progress per frame on stderr.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from envcap.cli.output_options import add_force_argument
from envcap.crowd.run import CrowdJob, run_crowd
from envcap.outputs import atomic_output_dir, claim_output_dir


def parse_size(text: str) -> tuple[int, int]:
    """``"WxH"`` -> ``(W, H)``, each 1..8192."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"--size {text!r}: expected WxH, e.g. 1680x1050") from None
    if not (1 <= w <= 8192 and 1 <= h <= 8192):
        raise ValueError(f"--size {text!r}: width and height must be 1..8192")
    return w, h


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("crowd", help="render a crowd of walkers lit by a probe set (runtime GLSL)")
    p.add_argument("scene", metavar="SCENE", help="scene name or file (the street the walkers walk on)")
    p.add_argument("--probes", required=True, help="probe set directory (envcap capture SCENE --out DIR)")
    p.add_argument("--avatars", type=int, required=True, help="number of walkers (>= 0)")
    p.add_argument("--avatar", default=None, help="skinned .glb written by envcap avatar (default: the bundled walker)")
    p.add_argument("--seed", type=int, default=0, help="placement seed (default %(default)s)")
    p.add_argument("--frames", type=int, default=1, help="frames to render (default %(default)s)")
    p.add_argument("--fps", type=float, default=10.0, help="frames per second of walking time (default %(default)s)")
    p.add_argument("--size", default="640x400", help="frame size WxH (default %(default)s)")
    p.add_argument("--terms", choices=("probes", "self", "neighbours"), default="neighbours",
                   help="lighting terms: probes only, + own blockers, + neighbours (default %(default)s)")
    p.add_argument("--out", required=True, help="output directory (frames and crowd.json)")
    p.add_argument("--street", default=None, help="street of the probe set (default: its first)")
    p.add_argument("--method", default=None, help="runtime lookup method (default: see docs/crowd.md)")
    add_force_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.avatars < 0:
        raise ValueError(f"--avatars must be >= 0, got {args.avatars}")
    if args.frames < 1:
        raise ValueError(f"--frames must be >= 1, got {args.frames}")
    if not args.fps > 0:
        raise ValueError(f"--fps must be > 0, got {args.fps}")
    job = CrowdJob.prepare(args.scene, args.probes, args.avatars, avatar=args.avatar, seed=args.seed,
                           frames=args.frames, fps=args.fps, size=parse_size(args.size), terms=args.terms,
                           street=args.street, method=args.method)
    print(f"envcap crowd: {job.describe()}", file=sys.stderr, flush=True)
    inputs = [Path(args.probes)] + ([Path(args.avatar)] if args.avatar else [])
    t0 = time.perf_counter()
    with claim_output_dir(args.out, kind="crowd", inputs=inputs, force=args.force) as claim, \
            atomic_output_dir(claim) as tmp:
        summary = run_crowd(job, Path(tmp), progress=lambda i, n, s: print(
            f"envcap crowd: frame {i + 1}/{n} in {s:.1f} s", file=sys.stderr, flush=True))
    print(f"{Path(args.out)}: {job.frames} frame(s) of {args.avatars} walkers, {summary}, "
          f"{time.perf_counter() - t0:.1f} s")
    return 0
