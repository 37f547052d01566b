"""Many spheres against float64 quadrature (helper of ``envcap bench dynamic``, no GPU).

Scenes of spheres around a shading point at the origin (m): ``ring`` (8 spheres of radius 0.3 m
on a horizontal circle of radius 1.2 m: people around a person), ``cluster`` (8 spheres, radius
0.2-0.6 m, centers 1-3 m away: overlapping caps) and ``crowd`` (24 such spheres, 1-6 m away: the
cap ``K = 8`` truncates).  BRDF lobes: random axes, powers ``w`` in ``POWERS``.

* **Union** of the caps: the blocked fraction ``U`` of the lobe by each form (``paper`` Eq. 4-7,
  ``envcap`` ring integral, ``exact``: per-sphere quadrature) and overlap rule, against
  :func:`envcap.dynamic.quadrature.union_lobe_fraction` over *all* spheres.
* **Blocked and bounced radiance** under a linear sky ``L(u) = 1 + 0.8 u_y + 0.3 u_x`` (its
  convolutions are closed forms: ``E_w(d) = 1 + (0.8 d_y + 0.3 d_x) (w + 1)/(w + 2)``), truth by a
  direction grid (cube texels) with ray-sphere hits: blocked = ``int lobe 1[hit] L``, bounced =
  ``int lobe 1[hit] albedo E_1(n_hit)`` (diffuse spheres, no inter-reflection).  The runtime's
  terms (:func:`envcap.dynamic.terms.dynamic_terms`, env = ``E_w``) for both forms and both
  bounce rules (``paper``: the horizontal mirror of ``M``; ``facing``: ``-M``).  Errors in units
  of the lobe's unblocked light ``E_w(C)``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from envcap.dynamic.cap_lobe import occlusion
from envcap.dynamic.quadrature import cap_lobe_integral, union_lobe_fraction
from envcap.dynamic.spheres import COMBINE_RULES, SphereBuffer, combine, select_spheres
from envcap.dynamic.terms import dynamic_terms
from envcap.runtime.lafortune import Lafortune, quadrature

SCENES = ("ring", "cluster", "crowd")
POWERS = (1.0, 10.0, 100.0)
SAMPLES = 10
CAP = 8
SKY = np.array([0.3, 0.8, 0.0])
"""``L(u) = 1 + SKY . u``."""


def scene(name: str, rng: np.random.Generator) -> SphereBuffer:
    """One random sphere layout around the origin (module docstring)."""
    if name == "ring":
        a = rng.uniform(0, 2 * np.pi) + np.arange(8) * (2 * np.pi / 8)
        c = np.c_[1.2 * np.cos(a), rng.uniform(-0.3, 0.3, 8), 1.2 * np.sin(a)]
        r = np.full(8, 0.3)
    else:
        n, lo, hi = (8, 1.0, 3.0) if name == "cluster" else (24, 1.0, 6.0)
        d = rng.normal(size=(n, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        c = d * rng.uniform(lo, hi, (n, 1))
        r = np.minimum(rng.uniform(0.2, 0.6, n), 0.9 * np.linalg.norm(c, axis=1))
    return SphereBuffer(c, r, rng.uniform(0.2, 0.8, (len(r), 3)))


def sky_env(d: NDArray, w: NDArray) -> NDArray:
    """The linear sky convolved with the normalized cos^w lobe, grey: ``(..., 3)``."""
    w = np.asarray(w, np.float64)
    v = 1 + np.einsum("...i,i->...", d, SKY) * np.where(w > 1e15, 1.0, (w + 1) / (w + 2))
    return np.repeat(v[..., None], 3, axis=-1)


def union_errors(rng: np.random.Generator) -> list[dict]:
    """Per scene and power: mean and max ``|U - U_true|`` per (form, rule)."""
    rows = []
    for name in SCENES:
        for w in POWERS:
            errs: dict[str, list[float]] = {}
            for _ in range(SAMPLES):
                sb = scene(name, rng)
                C = rng.normal(size=3)
                C /= np.linalg.norm(C)
                live = sb.radii > 0
                th_all = np.arcsin(sb.radii / np.linalg.norm(sb.centers, axis=1))
                D_all = sb.centers / np.linalg.norm(sb.centers, axis=1, keepdims=True)
                truth = union_lobe_fraction(D_all[live], th_all[live], C, w)
                sel = select_spheres(np.zeros(3), sb, CAP)
                ok = sel.index >= 0
                per = {f: np.where(ok, occlusion(sel.D, C, sel.t, w, form=f).integral * (1 + w) / (2 * np.pi), 0)
                       for f in ("paper", "envcap")}
                gam = np.arccos(np.clip(sel.D @ C, -1, 1))
                th = np.arcsin(np.minimum(sb.radii[np.maximum(sel.index, 0)] /
                                          np.linalg.norm(sb.centers[np.maximum(sel.index, 0)], axis=1), 1))
                per["exact"] = np.array([cap_lobe_integral(a, g, w) * (1 + w) / (2 * np.pi) if k else 0.0
                                         for a, g, k in zip(th, gam, ok)])
                for form, f in per.items():
                    for rule in COMBINE_RULES:
                        U, _ = combine(f, rule, sel.overlap, lobe=(sel.D, sel.t, C, w))
                        errs.setdefault(f"{form}/{rule}", []).append(abs(float(U) - truth))
                errs.setdefault("truth", []).append(truth)
            rows.append({"scene": name, "w": w, "mean_U_true": float(np.mean(errs.pop("truth"))),
                         **{k: {"mean": float(np.mean(v)), "max": float(np.max(v))} for k, v in errs.items()}})
    return rows


def grid_truth(sb: SphereBuffer, C: NDArray, w: float, n: int = 96) -> tuple[float, float, float]:
    """``(blocked, bounced, unblocked)`` radiance of the normalized lobe at the origin, by cube
    texel quadrature with ray-sphere hits (module docstring)."""
    dirs, dw = quadrature(n)
    lobe = np.maximum(dirs @ C, 0) ** w * dw * (w + 1) / (2 * np.pi)
    b = dirs @ sb.centers.T                                               # (P, N): u . c
    disc = b * b - (np.sum(sb.centers ** 2, axis=1) - sb.radii ** 2)
    dist = np.where((disc >= 0) & (b > 0), b - np.sqrt(np.maximum(disc, 0)), np.inf)
    k = np.argmin(dist, axis=1)
    hit = np.isfinite(dist[np.arange(len(dirs)), k])
    L = 1 + dirs @ SKY
    s = np.where(hit, dist[np.arange(len(dirs)), k], 0.0)
    nrm = (dirs * s[:, None] - sb.centers[k]) / sb.radii[k][:, None]
    bounce = np.where(hit, sb.albedo[k, 0] * (1 + (nrm @ SKY) * 2 / 3), 0.0)
    return float(np.sum(lobe * hit * L)), float(np.sum(lobe * bounce)), float(np.sum(lobe * L))


def radiance_errors(rng: np.random.Generator) -> list[dict]:
    """Per scene and power: mean / max error of the blocked and bounced terms (fraction of the
    lobe's unblocked light) per form, and of the bounce along ``-M``."""
    rows = []
    for name in SCENES:
        for w in POWERS:
            acc: dict[str, list[float]] = {}
            for _ in range(SAMPLES):
                sb = scene(name, rng)
                sb = SphereBuffer(sb.centers, sb.radii, np.repeat(sb.albedo[:, :1], 3, axis=1))
                C = rng.normal(size=3)
                C /= np.linalg.norm(C)
                blocked, bounced, E = grid_truth(sb, C, w)
                # one lobe along C, |Cv| = 1 (C sqrt 3 times v = (1, 1, 1)/sqrt 3), paper Eq. 3 weight 2 pi/(1 + w)
                v = np.full((1, 3), 1 / math.sqrt(3))
                mat = Lafortune((0.0, 0.0, 0.0), (tuple(C * math.sqrt(3)),), (w,), ((1.0, 1.0, 1.0),))
                scale = (1 + w) / (2 * np.pi)
                for form in ("paper", "envcap"):
                    for bounce in ("paper", "facing"):
                        d = dynamic_terms(np.zeros((1, 3)), np.eye(3)[None], v, mat, sb, sky_env, cap=CAP, form=form,
                                          eq3_form="paper", bounce=bounce)
                        if bounce == "paper":
                            acc.setdefault(f"blocked/{form}", []).append(abs(d.blocked[0, 0] * scale - blocked) / E)
                        acc.setdefault(f"bounced {bounce}/{form}", []).append(abs(d.bounced[0, 0] * scale - bounced) / E)
                acc.setdefault("blocked_true", []).append(blocked / E)
                acc.setdefault("bounced_true", []).append(bounced / E)
            rows.append({"scene": name, "w": w, **{k: {"mean": float(np.mean(v)), "max": float(np.max(v))}
                                                   for k, v in acc.items()}})
    return rows
