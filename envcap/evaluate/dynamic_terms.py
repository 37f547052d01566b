"""The dynamic terms as the street evaluation uses them: named models of the runtime's
:func:`envcap.dynamic.terms.dynamic_terms` (Eq. 3 - blocked + bounced, many spheres), with the
light that the spheres bounce taken from a separate environment.

A model (:class:`Model`, :data:`MODELS`) picks the per-sphere occlusion ``form`` (the paper's Eq.
4-7 or envcap's ring integral, :mod:`envcap.dynamic.cap_lobe`), the ``bounce`` direction (the
paper's horizontal mirror of ``M`` or ``-M``, the sphere's face toward the point,
:data:`envcap.dynamic.terms.BounceRule`) and what lights the spheres: ``light="local"`` the
static environment at the shading point (the paper: one environment for everything), ``"sky"``
the sky's upper hemisphere, unoccluded (how the capture's ``sky_light`` lights every surface, so
the truth's spheres).  Overlapping caps combine by the runtime's default rule
(:func:`envcap.dynamic.spheres.combine`, ``"rings"`` since issue 21; the tables of
``docs/dynamic.md`` before it were measured with ``"overlap"``).

With ``light="sky"`` the terms are computed twice (:func:`model_terms`): ``blocked`` with the
static environment, ``bounced`` with the light; each is exactly what the runtime computes with
that one environment.  Lookups are clamped to power :data:`MAX_LOOKUP_POWER` (the exact float64
environments of the evaluator need a finite power; empty sphere slots ask for 1e30).
Derivation and measurements: ``docs/dynamic.md``, "Street evaluation".
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.dynamic.spheres import SphereBuffer
from envcap.dynamic.terms import dynamic_terms
from envcap.evaluate.shading import Material
from envcap.runtime.lafortune import Lafortune
from envcap.runtime.shading import EnvironmentFn, shade_lafortune

MAX_LOOKUP_POWER = 1.0e6
"""Lobe powers passed to the environments are clamped to this (a needle: the nearest texel)."""


@dataclass(frozen=True)
class Model:
    """A dynamic-terms model: ``form`` (``"paper"`` or ``"envcap"``), ``bounce`` (``"paper"`` or
    ``"facing"``) and ``light`` (``"local"`` or ``"sky"``); module docstring."""

    form: str
    bounce: str
    light: str


MODELS: dict[str, Model] = {
    "paper": Model("paper", "paper", "local"),
    "paper+skyb": Model("paper", "facing", "sky"),
    "envcap+localb": Model("envcap", "facing", "local"),
    "envcap": Model("envcap", "facing", "sky"),
}
"""Models by name: the paper as given (Eq. 4-7, the environment at the point along the horizontal
mirror of ``M``); envcap's (the ring integral, the sphere's face toward the point, ``-M``, lit by
the sky); and the two mixed."""
DEFAULT_MODELS: tuple[str, ...] = tuple(MODELS)


def sphere_buffer(spheres: Sequence[object]) -> SphereBuffer:
    """A :class:`SphereBuffer` from objects with ``center``, ``radius``, ``albedo`` (e.g.
    :class:`envcap.scene.occluder_spheres.OccluderSphere`)."""
    return SphereBuffer(np.array([s.center for s in spheres], np.float64).reshape(-1, 3),  # type: ignore[attr-defined]
                        np.array([s.radius for s in spheres], np.float64).reshape(-1),     # type: ignore[attr-defined]
                        np.array([s.albedo for s in spheres], np.float64).reshape(-1, 3))  # type: ignore[attr-defined]


def lafortune(mat: Material) -> Lafortune:
    """The evaluator's material as the runtime's :class:`Lafortune`."""
    return Lafortune(mat.rho_d, mat.C, mat.w, mat.rho_s)


def clamped(env: EnvironmentFn) -> EnvironmentFn:
    """``env`` with the lobe power clamped to :data:`MAX_LOOKUP_POWER`."""
    def out(d: NDArray, w: NDArray) -> NDArray:
        return env(d, np.minimum(np.broadcast_to(np.asarray(w, np.float64), np.shape(d)[:-1]), MAX_LOOKUP_POWER))
    return out


def model_terms(model: str, static_env: EnvironmentFn, light_env: EnvironmentFn | None, x: ArrayLike, frames: NDArray,
                views: NDArray, mat: Lafortune, spheres: SphereBuffer) -> tuple[NDArray, NDArray]:
    """``(blocked, bounced)`` ``(F, 3)`` of ``model`` for shading frames ``(F, 3, 3)`` (rows T, B,
    N) and local views ``(F, 3)`` at the point ``x`` (3,) m.  ``light_env``: the sky light (needed
    by models with ``light="sky"``)."""
    if model not in MODELS:
        raise ValueError(f"unknown dynamic model {model!r}; known: {', '.join(MODELS)}")
    m = MODELS[model]
    if m.light == "sky" and light_env is None:
        raise ValueError(f"model {model!r} needs the sky light (light_env)")
    xs = np.broadcast_to(np.asarray(x, np.float64), frames.shape[:-2] + (3,))
    opts = {"form": m.form, "bounce": m.bounce}
    terms = dynamic_terms(xs, frames, views, mat, spheres, clamped(static_env), **opts)  # type: ignore[arg-type]
    if m.light == "local":
        return terms.blocked, terms.bounced
    lit = dynamic_terms(xs, frames, views, mat, spheres, clamped(light_env), **opts)  # type: ignore[arg-type]
    return terms.blocked, lit.bounced


def shade_model(model: str, static_env: EnvironmentFn, light_env: EnvironmentFn | None, x: ArrayLike, frames: NDArray,
                views: NDArray, mat: Material, spheres: SphereBuffer) -> NDArray[np.float64]:
    """Eq. 3 radiance ``(F, 3)`` of ``mat`` lit by ``static_env``, minus the blocked and plus the
    bounced light of ``model`` (:func:`model_terms`)."""
    laf = lafortune(mat)
    static = shade_lafortune(static_env, views, frames, laf.rho_d, np.array(laf.C, np.float64).reshape(-1, 3),
                             np.array(laf.w, np.float64), np.array(laf.rho_s, np.float64).reshape(-1, 3))
    blocked, bounced = model_terms(model, static_env, light_env, x, frames, views, laf, spheres)
    return static - blocked + bounced
