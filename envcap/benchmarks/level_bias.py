"""level_bias: a held-out calibration of the level a depth-aware lookup reads.

The narrow streets' budget (docs/evaluation.md, "A depth-aware lookup within 3x") measured that
reading one level sharper (``w' x 1.2``) lowers the error of the single-lookup methods, but on the
evaluation's own positions.  This benchmark fits that factor where it may be fitted and reports it
where it may not:

* **fit** positions: ``--fit-seed`` (default 11; street ``i`` uses ``seed + i``), ``--positions`` per
  street, drawn like the default sweep otherwise (:class:`envcap.evaluate.sweep.Sweep`).  The factor
  ``k`` of ``--biases`` with the lowest mean of ``error(k) / error(1)`` over every scene and power
  is chosen there, and only there;
* **check** positions: ``--check-seed`` (default 23), the same count: held out from the fit.  The
  factor is kept only if ``error(k) < error(1)`` in every scene at every power there;
* **report** positions: the default sweep's own (seed 5, 16 per street): ``nearest / method`` at
  every ``k``; never used to choose anything.

The same two rules are also applied per power (``per_power`` in the JSON: one factor per ``w``, a
table ``k(w)`` instead of one ``k``).

The seeds' streets (``seed + i``) must not meet the sweep's (5, 6, ...): 11 / 23 leave room for
six streets per scene.  ``k`` multiplies the method's power multiplier (``w' = w q k``: > 1 reads a
sharper level); the method must take a ``level_bias`` parameter (``depth_refine`` does).
``--ladder half_octave`` bakes the rung ladder instead of the paper's chain (``envcap capture
--ladder``): the same positions, to see whether the ladder moves the narrow streets' ratios;
``--also`` adds other methods at their defaults.  Same bake, truth and metric as the default sweep
(60 m in memory, 64^2, 5 m; truth filtered at exactly ``w``, sun out of the sky; mean over positions
of the relative RMSE of luminance).  Writes ``level_bias.json`` to ``--out``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from envcap.core import cube as cubemod
from envcap.evaluate.metrics import relative_rmse
from envcap.evaluate.predict import Predictor
from envcap.evaluate.sweep import Sweep, sample_positions
from envcap.evaluate.truth import TruthRenderer, truth_grid_size
from envcap.gpu.context import create_context
from envcap.outputs import atomic_output_dir
from envcap.probeset.bake import bake_probe_set
from envcap.runtime import methods
from envcap.runtime.sampling import composite
from envcap.scene import load_scene
from envcap.scene.segment import street_segment

SWEEP_SEED = 5
SWEEP_PER_STREET = 16
"""The default sweep's positions (``envcap evaluate``): the report role."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", required=True, type=Path, help="output directory (written atomically)")
    parser.add_argument("--scenes", default="canyon,crossing,asymmetric", help="bundled scenes, comma-separated")
    parser.add_argument("--method", default="depth_refine", help="method with a level_bias parameter (default depth_refine)")
    parser.add_argument("--biases", default="1,1.1,1.2,1.3,1.4,1.6", help="factors k on w' to try (1 among them)")
    parser.add_argument("--powers", default="64,256,1024", help="lobe powers (default 64,256,1024)")
    parser.add_argument("--positions", type=int, default=8, metavar="K", help="fit / check positions per street (default 8)")
    parser.add_argument("--fit-seed", type=int, default=11, help="sweep seed of the fit positions (default 11)")
    parser.add_argument("--check-seed", type=int, default=23, help="sweep seed of the held-out check (default 23)")
    parser.add_argument("--roles", default="fit,check,report", help="which position sets to run (default all three)")
    parser.add_argument("--ladder", default="paper", help="bake ladder mode: paper (default) or half_octave / octave")
    parser.add_argument("--also", default="", help="more methods at their defaults, comma-separated")


def _floats(text: str) -> list[float]:
    return [float(v) for v in text.split(",") if v.strip()]


def choose_bias(fit: dict[str, dict[str, dict[str, float]]], biases: list[float]) -> float:
    """The ``k`` with the lowest mean over scenes and powers of ``error(k) / error(1)``; ``fit``:
    scene -> power -> ``str(k)`` -> mean error.  Ties go to the smaller ``k`` (1 first)."""
    def score(k: float) -> float:
        return float(np.mean([e[str(k)] / e[str(1.0)] for sc in fit.values() for e in sc.values()]))
    return min(sorted(biases), key=score)


def helps_everywhere(check: dict[str, dict[str, dict[str, float]]], k: float) -> bool:
    """Whether ``error(k) < error(1)`` in every scene at every power of ``check``."""
    return all(e[str(k)] < e[str(1.0)] for sc in check.values() for e in sc.values())


def run(args: argparse.Namespace) -> int:
    biases, powers = sorted(set(_floats(args.biases)) | {1.0}), _floats(args.powers)
    roles = [r.strip() for r in args.roles.split(",") if r.strip()]
    if (args.positions < 1 or not powers or any(not (w > 0 and math.isfinite(w)) for w in powers)
            or any(not (k > 0 and math.isfinite(k)) for k in biases) or set(roles) - {"fit", "check", "report"}):
        raise ValueError("--positions >= 1, positive finite --powers and --biases, --roles of fit,check,report")
    seeds = {"fit": (args.fit_seed, args.positions), "check": (args.check_seed, args.positions),
             "report": (SWEEP_SEED, SWEEP_PER_STREET)}
    scenes = [s.strip() for s in args.scenes.split(",") if s.strip()]
    if {"fit", "check"} & set(roles) and any(abs(seeds[r][0] - SWEEP_SEED) < 6 or abs(args.fit_seed - args.check_seed) < 6
                                             for r in ("fit", "check")):
        raise ValueError("--fit-seed and --check-seed must be >= 6 apart from each other and from the sweep's 5")
    base = methods.get(args.method)
    variants = {k: dataclasses.replace(base, name=f"{base.name}_bias", parameters={**base.parameters, "level_bias": k})
                for k in biases}
    also = [methods.get(m.strip()).name for m in args.also.split(",") if m.strip()]
    t0 = time.perf_counter()
    ctx = create_context()
    # errors[role][scene][power][key] = mean error; key: "nearest", str(k), or an --also method
    errors: dict[str, dict[str, dict[str, dict[str, float]]]] = {r: {} for r in roles}
    counts: dict[str, dict[str, int]] = {r: {} for r in roles}
    try:
        for name in scenes:
            scene = street_segment(load_scene(name), 60.0)
            ps = bake_probe_set(scene, resolution=64, spacing=5.0, ladder_mode=args.ladder, ctx=ctx, progress=False)
            truth = TruthRenderer(scene, 64, ctx)
            pred = Predictor(ps, sky=truth.sky, ctx=ctx)
            for role in roles:
                seed, per = seeds[role]
                acc: dict[float, dict[str, list[float]]] = {w: {} for w in powers}
                positions = sample_positions(ps.manifest, Sweep(per_street=per, seed=seed))
                for ep in positions:
                    x = np.array(ep.position)
                    parts = truth.filtered(truth.capture(x).rgba, powers)
                    for w in powers:
                        d = cubemod.texel_directions(truth_grid_size(w, 64)).reshape(-1, 3)
                        t = composite(parts[w]["street"], truth.sky_at(w, False))
                        ww = np.full(d.shape[0], w)
                        keyed: list[tuple[str, Any]] = [("nearest", "nearest")] + [(m, m) for m in also]
                        keyed += [(str(k), variants[k]) for k in biases]
                        for key, meth in keyed:
                            p = pred.predict(meth, ep.street, x, d, ww, sun=False)
                            acc[w].setdefault(key, []).append(relative_rmse(p.reshape(t.shape), t))
                errors[role][name] = {str(int(w)): {k: float(np.mean(v)) for k, v in acc[w].items()} for w in powers}
                counts[role][name] = len(positions)
                print(name, role, json.dumps(errors[role][name]), flush=True)
            truth.release()
    finally:
        ctx.release()

    def only_bias(role: str) -> dict[str, dict[str, dict[str, float]]]:
        return {s: {w: {str(k): e[str(k)] for k in biases} for w, e in sc.items()} for s, sc in errors[role].items()}

    def at(sets: dict[str, dict[str, dict[str, float]]], w: str) -> dict[str, dict[str, dict[str, float]]]:
        return {s: {w: sc[w]} for s, sc in sets.items()}

    chosen = choose_bias(only_bias("fit"), biases) if "fit" in roles else None
    kept = bool(chosen is not None and chosen != 1.0 and "check" in roles and helps_everywhere(only_bias("check"), chosen))
    per_power: dict[str, dict[str, Any]] = {}
    if "fit" in roles:         # the same rules, one factor per power (a table k(w) instead of one k)
        for w in (str(int(v)) for v in powers):
            k = choose_bias(at(only_bias("fit"), w), biases)
            per_power[w] = {"chosen_bias": k, "kept": bool(k != 1.0 and "check" in roles
                                                           and helps_everywhere(at(only_bias("check"), w), k))}
    doc = {"benchmark": "level_bias", "method": base.name, "ladder": args.ladder, "powers": powers, "biases": biases,
           "seeds": {r: {"seed": seeds[r][0], "per_street": seeds[r][1]} for r in roles}, "positions": counts,
           "chosen_bias": chosen, "kept": kept, "per_power": per_power, "also": also,
           "error": "mean rel. RMSE of luminance, sun out of the sky", "errors": errors,
           "total_s": time.perf_counter() - t0}
    with atomic_output_dir(args.out) as tmp:
        (Path(tmp) / "level_bias.json").write_text(json.dumps(doc, indent=1) + "\n")
    for role in roles:
        print(f"{role} (seed {seeds[role][0]}, {seeds[role][1]} per street): nearest / {base.name} at k = "
              + ", ".join(f"{k:g}" for k in biases) + (f"; nearest / {', '.join(also)}" if also else ""))
        for name, sc in errors[role].items():
            for w, e in sc.items():
                print(f"  {name:>11} w={w:>5}: nearest {e['nearest']:.3f}  "
                      + " ".join(f"{e['nearest'] / e[str(k)]:.2f}" for k in biases)
                      + ("  | " + " ".join(f"{e['nearest'] / e[m]:.2f}" for m in also) if also else ""))
    if chosen is not None:
        print(f"fitted k = {chosen:g} on seed {args.fit_seed}; helps on every held-out scene and power "
              f"(seed {args.check_seed}): {kept}")
        for w, v in per_power.items():
            print(f"  w = {w}: fitted k = {v['chosen_bias']:g}, helps on every held-out scene: {v['kept']}")
    print(f"total {doc['total_s']:.1f} s; wrote {Path(args.out) / 'level_bias.json'}")
    return 0
