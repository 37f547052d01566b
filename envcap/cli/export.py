"""``envcap export TARGET DIR --out OUT``: a baked probe set for a platform, through the export
targets of :mod:`envcap.export.registry` (``web``: a static site for WebGL2 / three.js).

``DIR`` is what ``envcap view`` takes: a probe set, a city probe set or a directory holding one
(``envcap demo``'s output).  ``OUT`` is claimed before any work and written atomically
(:mod:`envcap.outputs`): a failed export leaves nothing.
"""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from envcap.cli.output_options import add_force_argument
from envcap.export.registry import get_target, target_names
from envcap.outputs import atomic_output_dir, claim_output_dir


def register(sub: argparse._SubParsersAction) -> None:
    names = target_names()
    p = sub.add_parser("export", help=f"export a probe set for a platform ({', '.join(names)})",
                       description="; ".join(f"{n}: {get_target(n).summary}" for n in names))
    p.add_argument("target", choices=names, metavar="TARGET", help=f"one of: {', '.join(names)}")
    p.add_argument("probes", type=Path, metavar="DIR",
                   help="probe-set directory, city directory (city.json), or a directory holding one (envcap demo's --out)")
    p.add_argument("--out", required=True, type=Path, help="output directory (written atomically)")
    p.add_argument("--report", type=Path, metavar="DIR",
                   help="evaluation report to include; default: a directory holding report.json in or beside the probe set")
    add_force_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    target = get_target(args.target)
    if not args.probes.is_dir():
        raise FileNotFoundError(f"probe-set directory not found: {args.probes.resolve()}")
    with claim_output_dir(args.out, kind=target.kind, inputs=[args.probes], force=args.force) as out:
        with atomic_output_dir(out) as tmp:
            note = target.write(args.probes, tmp, args.report)
    print(f"wrote the {target.name} export of {args.probes} to {out.path}")
    print(note.replace("{out}", shlex.quote(str(out.path))))
    return 0
