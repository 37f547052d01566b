"""The light spheres block from, and bounce onto, a shading point (the paper's Section IV on top
of Eq. 3; numpy twin of ``envcap_dynamic_terms`` in ``shaders/runtime/envcap_dynamic_spheres.glsl``;
``docs/dynamic.md``, "Blocked and bounced light").

For a Lafortune material, Eq. 3 lights the point with one diffuse lobe (axis ``N``, power 1,
weight ``rho_d``) and one lobe per specular term (axis ``c_i``, power ``w_i``, weight
``rho_s[i] * wt_i``, :func:`envcap.runtime.shading.lafortune_lobe`), each times the environment
convolved at its power.  For every lobe and each of the ``cap`` most occluding spheres ``k``
(:func:`envcap.dynamic.spheres.select_spheres`), the sphere blocks the fraction ``f_k`` of the
lobe's light (:func:`envcap.dynamic.cap_lobe.occlusion`, ``form``), centered on ``M_k``; the
fractions of one lobe combine by ``rule`` (:func:`envcap.dynamic.spheres.combine`) into shares
``s_k``.  Then, per lobe of weight ``W`` and power ``w``:

    blocked += W sum_k s_k env(M_k, w + t_k)
    bounced += W sum_k s_k albedo_k env(-M_k, 1)            (bounce="facing", default)
    bounced += W sum_k s_k albedo_k env(mirror(M_k), 1)     (bounce="paper")

``env(M, w + t)``: the environment convolved at the product lobe's power (``cos^w cos^t`` is
``cos^(w+t)`` where the lobes meet); ``-M``: the normal of the sphere's face towards the point,
convolved at power 1 (a diffuse sphere's radiance is ``albedo E_1(n)``); ``mirror(M)``: ``M`` with
its horizontal components negated, the paper's rule (its "x and y negated" in its z-up frame;
envcap is +Y up, so ``x`` and ``z`` here).  Static + dynamic lighting is ``static - blocked + bounced``
(:func:`shade_with_spheres`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.dynamic.cap_lobe import OcclusionForm, check_form, occlusion
from envcap.dynamic.lobe_product import MAX_POWER
from envcap.dynamic.spheres import (DEFAULT_RULE, SPHERE_CAP, CombineRule, SphereBuffer, check_rule, combine,
                                    select_spheres)
from envcap.runtime.lafortune import Lafortune
from envcap.runtime.shading import EnvironmentFn, Eq3Form, lafortune_lobe, shade_lafortune

BounceRule = Literal["paper", "facing"]
"""Where a sphere's bounced light is looked up: ``"facing"`` (default) along ``-M``, the normal of
the sphere's face towards the point (measured closer to the truth, ``docs/dynamic.md``);
``"paper"`` along ``mirror(M)`` (horizontal components negated).  GLSL: ``#define
ENVCAP_DYNAMIC_BOUNCE_PAPER`` selects ``"paper"``."""

UP = (0.0, 1.0, 0.0)
"""World up (envcap's convention, ``docs/architecture.md``): the axis ``mirror`` keeps."""


@dataclass(frozen=True)
class DynamicTerms:
    """``blocked``, ``bounced``: ``(..., 3)`` radiance (the environment's units) to subtract from
    and add to Eq. 3; ``union``: ``(..., 1 + lobes)`` each lobe's blocked fraction (diffuse first)."""

    blocked: NDArray[np.float64]
    bounced: NDArray[np.float64]
    union: NDArray[np.float64]


def mirror(d: ArrayLike, up: ArrayLike = UP) -> NDArray[np.float64]:
    """``d`` ``(..., 3)`` with its components across ``up`` (unit) negated: ``2 (d.up) up - d``."""
    d = np.asarray(d, np.float64)
    up = np.asarray(up, np.float64)
    return 2 * np.einsum("...i,i->...", d, up)[..., None] * up - d


def dynamic_terms(x: ArrayLike, frame: ArrayLike, v_local: ArrayLike, material: Lafortune, spheres: SphereBuffer,
                  env: EnvironmentFn, *, cap: int = SPHERE_CAP, form: OcclusionForm = "envcap",
                  rule: CombineRule = DEFAULT_RULE, eq3_form: Eq3Form = "envcap",
                  bounce: BounceRule = "facing") -> DynamicTerms:
    """Blocked and bounced light of ``spheres`` at shading points (module docstring).

    ``x``: ``(..., 3)`` world positions (m); ``frame``: ``(..., 3, 3)`` rows T, B, N (world, as
    :func:`envcap.runtime.shading.shade_lafortune`); ``v_local``: ``(..., 3)`` unit view
    directions in that frame; ``env(dirs (..., K, 3), w (..., K)) -> (..., K, 3)``: the
    cos^w-convolved environment (the same callback as Eq. 3; ``w`` up to 1e30 means "unblurred").
    ``cap``: spheres per point; ``form``: per-sphere occlusion (``"envcap"`` or ``"paper"`` Eq.
    4-7); ``rule``: how overlapping caps combine (:data:`envcap.dynamic.spheres.CombineRule`);
    ``eq3_form``: the lobe weights' Eq. 3 form; ``bounce``:
    :data:`BounceRule`.
    """
    check_form(form)
    check_rule(rule)
    if bounce not in get_args(BounceRule):
        raise ValueError(f"bounce must be one of {get_args(BounceRule)}, got {bounce!r}")
    x = np.asarray(x, np.float64)
    F = np.asarray(frame, np.float64)
    v = np.asarray(v_local, np.float64)
    shp = x.shape[:-1]
    sel = select_spheres(x, spheres, cap, normal=F[..., 2, :])   # spheres below the horizon do not count
    live = sel.index >= 0
    albedo = np.where(live[..., None], spheres.albedo[np.maximum(sel.index, 0)] if len(spheres) else 0.0, 0.0)
    lobes = [(F[..., 2, :], np.ones(shp), np.broadcast_to(np.asarray(material.rho_d, np.float64), shp + (3,)))]
    for Ci, wi, rs in zip(material.C, material.w, material.rho_s):
        c, wt = lafortune_lobe(v, Ci, wi, form=eq3_form)
        lobes.append((np.einsum("...i,...ij->...j", c, F), np.full(shp, float(wi)), np.asarray(rs) * wt[..., None]))
    blocked = np.zeros(shp + (3,))
    bounced = np.zeros(shp + (3,))
    unions = []
    for axis, w, weight in lobes:
        occ = occlusion(sel.D, axis[..., None, :], sel.t, w[..., None], form=form)
        f = np.where(live, occ.integral * (1 + w[..., None]) / (2 * np.pi), 0.0)
        U, share = combine(f, rule, sel.overlap, lobe=(sel.D, sel.t, axis, w))
        unions.append(U)
        power = np.minimum(w[..., None] + sel.t, MAX_POWER)
        Lb = env(occ.axis, power)
        Lr = env(mirror(occ.axis) if bounce == "paper" else -occ.axis, np.ones_like(power))
        blocked = blocked + weight * np.sum(share[..., None] * Lb, axis=-2)
        bounced = bounced + weight * np.sum((share[..., None] * albedo) * Lr, axis=-2)
    return DynamicTerms(blocked, bounced, np.stack(unions, axis=-1))


def shade_with_spheres(env: EnvironmentFn, x: ArrayLike, frame: ArrayLike, v_local: ArrayLike, material: Lafortune,
                       spheres: SphereBuffer, **options: object) -> NDArray[np.float64]:
    """Eq. 3 (:func:`envcap.runtime.shading.shade_lafortune`) ``- blocked + bounced`` ``(..., 3)``;
    ``options`` as :func:`dynamic_terms` (``eq3_form`` also selects Eq. 3's form)."""
    eq3_form = options.get("eq3_form", "envcap")
    static = shade_lafortune(env, v_local, frame, material.rho_d, material.C, material.w, material.rho_s,
                             form=eq3_form)  # type: ignore[arg-type]
    dyn = dynamic_terms(x, frame, v_local, material, spheres, env, **options)  # type: ignore[arg-type]
    return static - dyn.blocked + dyn.bounced
