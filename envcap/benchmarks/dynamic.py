"""Eq. 7 (a sphere blocking a BRDF lobe) against float64 quadrature of the spherical cap.

For caps of half-angle ``theta`` (``sin theta = r / l``: size and distance enter only through
their ratio), lobe powers ``w`` and angles ``gamma = m theta`` between the sphere's direction and
the lobe axis, the blocked fraction of the lobe ``f = I / (2 pi / (1 + w))`` is computed by
:func:`envcap.dynamic.quadrature.cap_lobe_integral` (truth) and by Eq. 7
(:func:`envcap.dynamic.lobe_product.lobe_product`) with

* ``paper``: the solid-angle power ``t`` (:func:`envcap.dynamic.sphere_lobe.sphere_lobe`) and
  exponent 0.7;
* ``k=0.5``, ``k=1``: the same with another exponent;
* ``matched``: exponent 0.7 and the per-lobe power ``t_w``
  (:func:`envcap.dynamic.sphere_lobe.lobe_power_matched`, exact at ``gamma = 0``).

The error is ``|f_eq7 - f_true|`` (fraction of the lobe's light, what a shader gets wrong); the
table gives, per ``(theta, w)``, ``f_true`` at ``gamma = 0`` and the largest error over the
``gamma`` grid.  Writes ``dynamic.json`` and ``dynamic.md`` to ``--out``.  No GPU.
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np

from envcap.dynamic.lobe_product import lobe_product
from envcap.dynamic.quadrature import cap_lobe_integral
from envcap.dynamic.sphere_lobe import lobe_power_matched, sphere_lobe
from envcap.outputs import atomic_output_dir

THETAS_DEG = (2.0, 5.0, 10.0, 20.0, 40.0, 60.0, 85.0)
POWERS = (1.0, 10.0, 100.0, 1000.0)
GAMMA_MULTIPLES = (0.0, 0.5, 1.0, 1.5, 2.0, 3.0)
VARIANTS = ("paper", "k=0.5", "k=1", "matched")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (JSON + Markdown table)")


def eq7_fraction(theta: float, gamma: float, w: float, variant: str) -> float:
    """Blocked fraction of the lobe by Eq. 7 for one configuration and variant."""
    s = math.sin(theta)
    D, t = sphere_lobe(np.zeros(3), np.array([0.0, 0.0, 1.0]), s)
    if variant == "matched":
        t = lobe_power_matched(s, w)
    C = np.array([math.sin(gamma), 0.0, math.cos(gamma)])
    k = {"k=0.5": 0.5, "k=1": 1.0}.get(variant, 0.7)
    return float(lobe_product(D, C, t, w, exponent=k).integral) * (1 + w) / (2 * math.pi)


def measure() -> list[dict]:
    """One row per (theta, w): truth at gamma = 0, and per variant the largest error over gamma."""
    rows = []
    for theta_deg in THETAS_DEG:
        theta = math.radians(theta_deg)
        for w in POWERS:
            gammas = [min(m * theta, math.pi) for m in GAMMA_MULTIPLES]
            truth = [cap_lobe_integral(theta, g, w) * (1 + w) / (2 * math.pi) for g in gammas]
            row = {"theta_deg": theta_deg, "w": w, "f_true_gamma0": truth[0], "f_true": truth}
            for v in VARIANTS:
                f = [eq7_fraction(theta, g, w, v) for g in gammas]
                row[v] = f
                row[f"max_err_{v}"] = max(abs(a - b) for a, b in zip(f, truth))
            rows.append(row)
    return rows


def markdown(rows: list[dict]) -> str:
    head = ("| theta | w | f true (gamma=0) | f paper (gamma=0) | " + " | ".join(f"max err {v}" for v in VARIANTS) + " |\n"
            + "| --- " * (4 + len(VARIANTS)) + "|\n")
    body = "".join(f"| {r['theta_deg']:g}° | {r['w']:g} | {r['f_true_gamma0']:.3f} | {r['paper'][0]:.3f} | "
                   + " | ".join(f"{r[f'max_err_{v}']:.3f}" for v in VARIANTS) + " |\n" for r in rows)
    return head + body


def run(args: argparse.Namespace) -> int:
    rows = measure()
    table = markdown(rows)
    print(table)
    with atomic_output_dir(args.out) as tmp:
        (tmp / "dynamic.json").write_text(json.dumps({"gamma_multiples": GAMMA_MULTIPLES, "rows": rows}, indent=2))
        (tmp / "dynamic.md").write_text(table)
    return 0
