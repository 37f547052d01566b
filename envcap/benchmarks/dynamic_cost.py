"""Cost of the dynamic terms per shading point against the number of spheres (GLSL, llvmpipe).

For each sphere count, the full-screen pass of :func:`envcap.benchmarks.dynamic_street_cost.gl_cost`
(``size^2`` shading points, plastic: one diffuse and one specular lobe) with that many spheres
around every point, as a multiple of a plain Eq. 3 in the same run, for the paper's form (overlap
rule), envcap's form with the overlap rule and envcap's defaults (the rings rule); the slope gives
the cost of one more sphere, the intercept the fixed cost of the terms (the K = ENVCAP_SPHERE_CAP
slots are visited whatever the count).

    envcap bench dynamic_cost --out DIR [--counts 1 4 8 16] [--size 256]
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from envcap.benchmarks.dynamic_street_cost import MAX_SPHERES, gl_cost
from envcap.outputs import atomic_output_dir

MODES = ("paper", "envcap_overlap", "envcap")
"""The passes of :data:`envcap.benchmarks.dynamic_street_cost.GL_MODES` in the table."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (dynamic_cost.json, dynamic_cost.md)")
    p.add_argument("--counts", type=int, nargs="+", default=[1, 4, 8, 16], help=f"sphere counts (1..{MAX_SPHERES})")
    p.add_argument("--size", type=int, default=256, help="the pass is size x size shading points (default 256)")
    p.add_argument("--repeats", type=int, default=5, help="timed passes per mode (median; default 5)")


def run(args: argparse.Namespace) -> int:
    if not all(1 <= n <= MAX_SPHERES for n in args.counts):
        raise ValueError(f"--counts: each count must be in 1..{MAX_SPHERES}, got {args.counts}")
    rows = []
    for n in args.counts:
        r = gl_cost(size=args.size, spheres=n, repeats=args.repeats)
        rows.append({"spheres": n, **{k: float(v) for k, v in r["ratio_to_plain"].items()}})
        print(f"{n:>3} spheres: " + ", ".join(f"{m} {rows[-1][m]:.1f}x" for m in MODES) + " a plain Eq. 3", flush=True)
    counts = np.array([r["spheres"] for r in rows], float)
    fits = {m: np.polyfit(counts, [r[m] for r in rows], 1) if len(rows) > 1 else np.array([0.0, rows[0][m]])
            for m in MODES}
    lines = ["| spheres | paper form | envcap form, overlap rule | envcap form, rings rule |", "| ---: | ---: | ---: | ---: |"]
    lines += [f"| {r['spheres']} | " + " | ".join(f"{r[m]:.1f}x" for m in MODES) + " |" for r in rows]
    lines += ["", "Least squares over the counts (multiples of a plain Eq. 3): "
              + "; ".join(f"{m}: {b:.1f} + {a:.2f} per sphere" for m, (a, b) in fits.items())]
    with atomic_output_dir(args.out) as d:
        (d / "dynamic_cost.json").write_text(json.dumps({"rows": rows, "size": args.size,
                                                         "per_sphere": {m: float(f[0]) for m, f in fits.items()},
                                                         "fixed": {m: float(f[1]) for m, f in fits.items()}}, indent=1))
        (d / "dynamic_cost.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0
