"""``envcap evaluate SCENE --probes DIR --out DIR``: parallax error of a probe set against fresh captures."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from envcap.cli.output_options import add_force_argument, scene_input_files
from envcap.core.input_path import require_file
from envcap.dynamic.avatar_attributes import is_envcap_avatar
from envcap.evaluate.dynamic_avatars import load_rigged
from envcap.evaluate.bounds import check_evaluation, estimate_evaluation
from envcap.evaluate.occluder_report import (
    OCCLUDER_KINDS,
    append_occluder_report,
    evaluate_occluders,
)
from envcap.evaluate.report import write_report
from envcap.evaluate.result import EvaluationResult
from envcap.evaluate.run import DEFAULT_LOBE_POWERS, evaluate_scene
from envcap.evaluate.predict import CROSSING_MODE, CROSSING_MODES
from envcap.evaluate.sweep import DEFAULT_SWEEP, Sweep
from envcap.outputs import claim_output_dir
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.progress import BakeProgress
from envcap.probeset.store import read_probe_set
from envcap.runtime import methods as runtime_methods
from envcap.scene import Scene, load_scene
from envcap.scene.segment import street_segment


def _powers(text: str) -> list[float]:
    out = []
    for tok in text.split(","):
        tok = tok.strip().lower()
        if not tok:
            continue
        if tok in ("inf", "mirror"):
            out.append(math.inf)
            continue
        try:
            v = float(tok)
        except ValueError:
            raise argparse.ArgumentTypeError(f"lobe power {tok!r} is not a number (or 'inf')") from None
        if math.isnan(v) or v < 0:
            raise argparse.ArgumentTypeError(f"lobe power must be >= 0 or 'inf', got {tok!r}")
        out.append(v)
    if not out:
        raise argparse.ArgumentTypeError("no lobe powers given")
    return out


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("evaluate", help="parallax error of a probe set against fresh captures (report + plots)")
    p.add_argument("scene", nargs="+", help="bundled scene name(s) or scene .toml path(s); one with --probes")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--probes", type=Path, help="probe-set directory of SCENE (from 'envcap capture')")
    src.add_argument("--bake", type=float, metavar="M",
                     help="instead: bake a probe set in memory on an M-meter segment around the middle of each street")
    p.add_argument("--probe-resolution", type=int, default=64, metavar="N", help="with --bake: probe face size (default 64)")
    p.add_argument("--spacing", type=float, default=5.0, metavar="M", help="with --bake: probe spacing (default 5)")
    p.add_argument("--crossings", action="store_true",
                   help="with --bake: add a probe at each crossing's centre and record the crossings (as envcap capture does)")
    p.add_argument("--crossing-lookup", choices=list(CROSSING_MODES), default=CROSSING_MODE,
                   help=f"positions inside a crossing of a set that records them: {CROSSING_MODE} (default: each direction "
                        "on the meeting street it looks down, with the crossing probe among its probes), shared (the "
                        "position's street with the crossing probe among its probes), probe (the crossing probe alone), "
                        "plan (the meeting street whose probe is nearest in plan), off (per street); docs/crossings.md")
    p.add_argument("--out", required=True, type=Path, help="report directory (written atomically)")
    p.add_argument("--positions", type=int, default=DEFAULT_SWEEP.per_street, metavar="K",
                   help=f"evaluation positions per street (default {DEFAULT_SWEEP.per_street})")
    p.add_argument("--seed", type=int, default=DEFAULT_SWEEP.seed, help=f"sweep seed, >= 0 (default {DEFAULT_SWEEP.seed})")
    p.add_argument("--margin", type=float, default=None, metavar="M",
                   help=f"lateral margin from the facades in meters, less than half of every street's width "
                        f"(default {DEFAULT_SWEEP.margin:g}; a street narrower than twice the default is sampled on its probe line)")
    p.add_argument("--resolution", type=int, default=None, metavar="N",
                   help="face size of the truth captures (default: the probe set's, at most 64)")
    known = runtime_methods.registered()
    p.add_argument("--methods", default=",".join(known),
                   help=f"comma-separated parallax methods, registered: {', '.join(known)} (default: all)")
    p.add_argument("--lobes", type=_powers, default=None, metavar="W,...",
                   help="lobe powers, 'inf' = mirror (default inf,1024,256,64,16,4,1)")
    p.add_argument("--no-images", action="store_true", help="skip plots and image strips")
    p.add_argument("--occluders", choices=OCCLUDER_KINDS, default="none",
                   help="also evaluate the dynamic terms against fresh captures with rings of spheres ('ring'), "
                        "walker avatars ('avatars') or both ('all') around crowd positions (default none)")
    p.add_argument("--avatar", type=Path, metavar="FILE",
                   help="with --occluders avatars|all: crowds of this avatar, a .glb written by 'envcap avatar' "
                        "(its skin, animation and proxy spheres; default: the bundled walker)")
    p.add_argument("--quiet", action="store_true",
                   help="no progress on stderr (warnings and errors still); progress is a bar on a terminal, "
                        "else a line per stage and every 10 s")
    add_force_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.positions < 1:
        raise ValueError(f"--positions must be >= 1, got {args.positions}")
    if args.margin is not None and not (math.isfinite(args.margin) and args.margin >= 0):
        raise ValueError(f"--margin must be a finite number >= 0, got {args.margin:g}")
    if args.probes is None and args.probe_resolution < 4:
        raise ValueError(f"--probe-resolution must be >= 4, got {args.probe_resolution}")
    if args.seed < 0:
        raise ValueError(f"--seed must be an integer >= 0, got {args.seed}")
    methods = checked_methods(args.methods)
    if args.probes is not None and len(args.scene) != 1:
        raise ValueError("--probes goes with exactly one scene (use --bake to evaluate several)")
    # Bounds before work: positions per street (one street at least) and, if given, the truth face size.
    powers = args.lobes or DEFAULT_LOBE_POWERS
    check_evaluation(estimate_evaluation(args.positions, args.resolution if args.resolution is not None else 64,
                                         len(powers), len(methods)))
    sweep = Sweep(per_street=args.positions, margin=DEFAULT_SWEEP.margin if args.margin is None else args.margin,
                  seed=args.seed)
    check_avatar(args)
    inputs = [f for name in args.scene for f in scene_input_files(name)]
    if args.probes is not None:
        inputs.append(args.probes)
    if args.avatar is not None:
        inputs.append(args.avatar)
    with claim_output_dir(args.out, kind="evaluation-report", inputs=inputs, force=args.force) as out:
        occluders: list[dict] = []
        results = [evaluate_one(name, args, sweep, methods, occluders) for name in args.scene]
        write_report(results, out, images=not args.no_images)
        if occluders:
            append_occluder_report(out.path, occluders, images=not args.no_images)
    print(f"report: {out.path / 'report.md'}")
    return 0


def check_avatar(args: argparse.Namespace) -> None:
    """Refuse, before any work, an ``--avatar`` without avatar crowds, missing, or not a file
    ``envcap avatar`` wrote (one line naming it); a good one is read here, once (its skin and
    stored proxy spheres; the crowds reuse them), so a broken file costs nothing either."""
    if args.avatar is None:
        return
    if args.occluders not in ("avatars", "all"):
        raise ValueError(f"--avatar goes with --occluders avatars or all (got --occluders {args.occluders})")
    require_file(args.avatar, "--avatar", f"--avatar {args.avatar}: no such file")
    if not is_envcap_avatar(args.avatar):
        raise ValueError(f"--avatar {args.avatar} was not written by envcap avatar (it has no proxy spheres); "
                         f"make one with: envcap avatar {args.avatar} --out NAME.glb")
    load_rigged(str(args.avatar))


def checked_methods(text: str) -> list[str]:
    """The method names of ``--methods`` (comma-separated), each registered
    (:mod:`envcap.runtime.methods`), else ``ValueError`` naming the option and the registered ones."""
    names = [m.strip() for m in text.split(",") if m.strip()]
    known = runtime_methods.registered()
    bad = [m for m in names if m not in known]
    if bad or not names:
        what = f"unknown method(s) {', '.join(map(repr, bad))}" if bad else f"no method in {text!r}"
        raise ValueError(f"--methods: {what}; registered: {', '.join(known)}")
    return names


def check_margin(scene: Scene, margin: float) -> None:
    """Refuse a ``--margin`` (m) that leaves no room between the facades of one of ``scene``'s
    streets (``ValueError`` naming the street and its width).  Only a margin the user gave: with
    the default, a street narrower than twice it is sampled on its probe line (:mod:`envcap.evaluate.sweep`)."""
    for st in scene.streets:
        if 2 * margin >= st.width:
            raise ValueError(f"--margin {margin:g} m leaves no room across street '{st.name}' of scene '{scene.name}', "
                             f"{st.width:g} m between its facades: give a margin below {st.width / 2:g} m")


def evaluate_one(name: str, args: argparse.Namespace, sweep: Sweep, methods: list[str],
                 occluders: list[dict] | None = None) -> EvaluationResult:
    """Evaluate scene ``name`` against its probe set (``--probes``) or one baked in memory (``--bake``);
    with ``--occluders``, the dynamic-occluder evaluation is appended to ``occluders``."""
    scene = load_scene(name)
    if getattr(args, "margin", None) is not None:
        check_margin(scene, args.margin)
    report = BakeProgress("off" if getattr(args, "quiet", False) else "auto", unit="position")
    if args.probes is not None:
        ps = read_probe_set(args.probes)
    else:
        scene = street_segment(scene, args.bake)
        ps = bake_probe_set(scene, resolution=args.probe_resolution, spacing=args.spacing,
                            report=BakeProgress(report.mode), progress=False if report.mode == "off" else None,
                            crossings=bool(getattr(args, "crossings", False)))
    res = evaluate_scene(scene, ps, sweep=sweep, methods=methods, lobe_powers=args.lobes or DEFAULT_LOBE_POWERS,
                         resolution=args.resolution, report=report,
                         crossings=getattr(args, "crossing_lookup", CROSSING_MODE))
    if occluders is not None and getattr(args, "occluders", "none") != "none":
        occluders.append(evaluate_occluders(scene, ps, args.occluders, avatar=getattr(args, "avatar", None),
                                            resolution=args.resolution if args.resolution is not None else 64))
    t = res.timings
    print(f"evaluated {len(res.positions)} positions of '{scene.name}' in {t['total_s']:.1f} s "
          f"(captures {t['captures_s']:.1f} s, filtering {t['filtering_s']:.1f} s, predictions {t['predictions_s']:.1f} s, "
          f"shading {t['shading_s']:.1f} s)")
    return res
