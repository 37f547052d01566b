"""mipshift: the level error of each mip shift against the exact footprint of the lobe.

The crowd setup of issue 12: a 12 m street (facades at +-6 m, ground at 0), a probe at 2 m
height, shading points 0-2 m high within +-5 m of it (along and across), lobe axes uniform over
the sphere that hit one of the three planes (the others get no shift), lobe powers ``--powers``.
For each lookup the exact footprint (float64, ``--samples`` rays of the cos^w lobe traced through
the planes and seen from the probe: :mod:`envcap.evaluate.footprint_truth`) gives the power
``W`` an isotropic lookup should read, and the powers along the footprint's two axes.  The level
error of a shift that reads ``w'`` is ``|z(w') - z(W)|`` with ``z = -log2(w + 2) / 2`` (a ladder
whose lobe angle doubles per level, the default 4x ladder; unclamped, so that the chain's ends do
not hide errors).  The axis error is the larger of the two axes' level errors (an isotropic
lookup reads ``w'`` on both; ``planes_mip_aniso`` reads its tap power across and the taps' spread
along the long axis).

Shifts: ``paper`` (``w (d_p/d_s)^2``, ``planes_mip``), ``oblique`` (closed form, ``planes_mip_oblique``),
``footprint`` (four traced sigma rays, ``planes_mip_footprint``) and ``aniso`` (its 2 taps,
``planes_mip_aniso``; same isotropic level as ``footprint``).  Writes ``mipshift.json`` to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.evaluate.footprint_truth import exact_footprint
from envcap.outputs import atomic_output_dir
from envcap.runtime.footprint import footprint, sigma_footprint
from envcap.runtime.parallax import exit_distance
from envcap.runtime.limits import FAR

PLANES = np.array([-6.0, 6.0, 0.0])
"""The street of the crowd setup: facades at -6 and +6 m (cross axis z), ground at 0; along x."""
PROBE = np.array([0.0, 2.0, 0.0])
"""The probe of the crowd setup (m)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", required=True, type=Path, help="output directory (written atomically)")
    parser.add_argument("--lookups", type=int, default=4000, help="lookups per lobe power (default 4000)")
    parser.add_argument("--powers", default="16,64,256,1024", help="lobe powers (default 16,64,256,1024)")
    parser.add_argument("--samples", type=int, default=1024, help="rays per exact footprint (default 1024)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")


def crowd_lookups(n: int, seed: int = 0) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(x, d)``: up to ``n`` shading points and unit lobe axes of the crowd setup whose axis hits a plane."""
    rng = np.random.default_rng(seed)
    x = np.c_[rng.uniform(-5, 5, n), rng.uniform(0, 2, n), rng.uniform(-5, 5, n)]
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    hit = exit_distance(x, d, PLANES, 0) < FAR
    return x[hit], d[hit]


def level(w: NDArray) -> NDArray[np.float64]:
    """``-log2(w + 2) / 2``: the level of power ``w`` on a ladder whose lobe angle doubles per level."""
    with np.errstate(divide="ignore", over="ignore"):
        return -0.5 * np.log2(np.asarray(w, np.float64) + 2.0)


def shifted_powers(x: NDArray, d: NDArray, w: float) -> dict[str, tuple[NDArray, NDArray, NDArray]]:
    """``{shift: (w_iso, w_minor_axis, w_major_axis)}`` that each shift reads."""
    fp = footprint(x, d, PROBE, PLANES, 0)
    sf = sigma_footprint(x, d, np.full(len(d), w), PROBE, PLANES, 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        w_fp = sf.power()
        v_tap = np.maximum(sf.var_minor, sf.var_major / 2.0)          # 2 taps
        w_tap = np.maximum(1.0 / v_tap - 3.0, 0.0)
        w_major = np.maximum(1.0 / sf.var_major - 3.0, 0.0)           # the taps' spread restores V_major
    paper = w * fp.ratio ** 2
    oblique = w * fp.q_iso
    return {"paper": (paper, paper, paper), "oblique": (oblique, oblique, oblique),
            "footprint": (w_fp, w_fp, w_fp), "aniso": (w_fp, w_tap, w_major)}


def stats(err: NDArray) -> dict[str, float]:
    """Median, p90 and the share above half a level of absolute level errors."""
    return {"median": float(np.median(err)), "p90": float(np.percentile(err, 90)),
            "above_half_level": float(np.mean(err > 0.5))}


def run(args: argparse.Namespace) -> int:
    if args.lookups < 10 or args.samples < 16:
        raise ValueError("--lookups must be >= 10 and --samples >= 16")
    powers = [float(v) for v in args.powers.split(",") if v.strip()]
    if not powers or any(not (np.isfinite(w) and w > 0) for w in powers):
        raise ValueError(f"--powers: positive finite numbers, got {args.powers!r}")
    t0 = time.perf_counter()
    x, d = crowd_lookups(args.lookups, args.seed)
    errs: dict[str, dict[str, list[NDArray]]] = {}
    rows: list[dict[str, Any]] = []
    for w in powers:
        ex = exact_footprint(x, d, np.full(len(d), w), PROBE, PLANES, 0, samples=args.samples, seed=args.seed)
        for name, (wi, wmin, wmaj) in shifted_powers(x, d, w).items():
            e_iso = np.abs(level(wi) - level(ex.w_iso))
            e_axis = np.maximum(np.abs(level(wmin) - level(ex.w_minor)), np.abs(level(wmaj) - level(ex.w_major)))
            errs.setdefault(name, {"iso": [], "axis": []})
            errs[name]["iso"].append(e_iso)
            errs[name]["axis"].append(e_axis)
            rows.append({"w": w, "shift": name, "level_error": stats(e_iso), "axis_error": stats(e_axis)})
    pooled = {name: {"level_error": stats(np.concatenate(e["iso"])), "axis_error": stats(np.concatenate(e["axis"])),
                     "level_error_w_ge_64": stats(np.concatenate([a for a, w in zip(e["iso"], powers) if w >= 64]))}
              for name, e in errs.items()}
    doc = {"benchmark": "mipshift", "street": {"planes": PLANES.tolist(), "probe": PROBE.tolist(),
           "points": "along, across uniform in +-5 m, height 0-2 m"}, "lookups_per_power": int(len(d)),
           "powers": powers, "samples": args.samples, "level": "-log2(w + 2) / 2 (lobe angle doubles per level)",
           "rows": rows, "pooled": pooled, "total_s": time.perf_counter() - t0}
    with atomic_output_dir(args.out) as tmp:
        (Path(tmp) / "mipshift.json").write_text(json.dumps(doc, indent=1) + "\n")
    print(f"{'w':>6} {'shift':>10}  level error median / p90 / >0.5   axis error median / p90")
    for r in rows + [{"w": "all", "shift": k, **v} for k, v in pooled.items()]:
        le, ae = r["level_error"], r["axis_error"]
        print(f"{str(r['w']):>6} {r['shift']:>10}  {le['median']:.3f} / {le['p90']:.3f} / {le['above_half_level']:.3f}"
              f"      {ae['median']:.3f} / {ae['p90']:.3f}")
    for k, v in pooled.items():
        s = v["level_error_w_ge_64"]
        print(f"  w >= 64 {k:>10}: median {s['median']:.3f}, p90 {s['p90']:.3f}")
    print(f"total {doc['total_s']:.1f} s; wrote {Path(args.out) / 'mipshift.json'}")
    return 0
