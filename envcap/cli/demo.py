"""``envcap demo [--out DIR]``: the main job on a bundled scene, end to end, in about a minute.

Bakes probes along the bundled ``canyon`` street (capture, plane fitting, cosine-lobe chains),
writes the probe set with previews and the WebGL2 face atlas (``probes_atlas.ktx2``: what
``envcap view`` and ``envcap export web`` read; at demo sizes it costs a few milliseconds) to
``DIR/probes``, then runs a short parallax-error evaluation against fresh captures into
``DIR/evaluation`` and prints where the report and pictures are and how to view them
(``envcap view DIR``).  Both outputs are claimed before any work (see :mod:`envcap.outputs`).
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import shlex
import time
from pathlib import Path

from envcap.cli.capture import add_bake_arguments, bake_to_dir, check_bake_arguments
from envcap.cli.output_options import scene_input_files
from envcap.evaluate.run import quick_evaluation
from envcap.outputs import claim_output_dir
from envcap.outputs.atomic import retire_output_dir
from envcap.probeset.progress import BakeProgress
from envcap.scene import load_scene

DEMO_SCENE = "canyon"
DEMO_SPACING = 10.0
"""Probe spacing (m) of the demo: 60 probes on the canyon's 600 m, a bake of about a minute."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help=f"capture, filter and evaluate the bundled '{DEMO_SCENE}' scene")
    p.add_argument("--out", type=Path, default=Path("envcap-demo"), help="output directory (default ./envcap-demo)")
    p.add_argument("--scene", default=DEMO_SCENE, help=f"bundled scene (default {DEMO_SCENE})")
    p.add_argument("--no-eval", action="store_true",
                   help="skip the short evaluation (an earlier DIR/evaluation that envcap wrote is removed: it "
                        "evaluated other probes)")
    add_bake_arguments(p, 64, files=True, spacing=DEMO_SPACING)
    p.set_defaults(func=run, webgl2=True)   # the atlas: 'envcap view DIR' works on the demo's output


def _retire_evaluation(folder: Path) -> None:
    """``--no-eval``: an evaluation left beside the new probes evaluated other probes: remove it when
    envcap wrote it (its marker), else say that it is stale (it is never removed)."""
    if retire_output_dir(folder):
        print(f"envcap: note: removed {folder}, envcap's evaluation of the earlier probes (--no-eval)", file=sys.stderr)
    elif folder.exists():
        print(f"envcap: note: {folder} is stale (it is not an evaluation of these probes) and was not written "
              f"by envcap: left as it is", file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    out: Path = args.out
    check_bake_arguments(args)
    inputs = scene_input_files(args.scene)
    with contextlib.ExitStack() as claims:
        probes = claims.enter_context(claim_output_dir(out / "probes", kind="probe-set", inputs=inputs, force=args.force))
        evaluation = None if args.no_eval else claims.enter_context(
            claim_output_dir(out / "evaluation", kind="evaluation-report", inputs=inputs, force=args.force))
        probes_dir = bake_to_dir(args, args.scene, probes)
        if args.previews:
            print(f"previews: {probes_dir / 'previews' / 'contact_sheet.png'}")
        if evaluation is not None:
            quick_evaluation(load_scene(args.scene), probes_dir, evaluation,
                             report=BakeProgress("off" if args.quiet else "auto", unit="position"))
        else:
            _retire_evaluation(out / "evaluation")
    print(f"demo finished in {time.perf_counter() - t0:.1f} s; outputs in {out.resolve()}")
    print(f"view them: envcap view {shlex.quote(str(out))}")
    return 0
