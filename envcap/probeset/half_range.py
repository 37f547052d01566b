"""Captured probe radiance against the half-float range of ``probes.ktx2``, before any filtering.

``probes.ktx2`` stores probe radiance as RGBA16F, whose largest finite value is 65504
(:data:`envcap.formats.ktx2.HALF_MAX`).  A window brighter than that is refused when the scene is
parsed (:data:`envcap.scene.limits.EMISSION_LIMIT`); what only the capture can tell (sunlight or
sky light on a bright albedo, emission plus the light reflected on it) is checked here, on
level 0 right after the capture: one max over the array, before the prefilter spends its time.
The filtered levels are normalized weighted averages of level 0, so they stay within its peak.

Past the limit the bake stops with one line (:func:`check_half_range`) that names the brightest
probe (street, index, world position), the peak, the limit and the likely cause: the shading term
of the scene (:mod:`envcap.capture.effects`) whose estimated radiance is largest, with the scene
keys that lower it.  Nothing is clamped: a clamped probe would be a silently wrong answer.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from envcap.formats.ktx2 import HALF_MAX
from envcap.scene.model import Scene
from envcap.sky.base import Sky

__all__ = ["LightTerm", "check_half_range", "light_terms"]

SKY_PEAK_FACE = 32
"""Face size (texels) of the sky cube whose peak estimates the sky dome's radiance."""


@dataclass(frozen=True)
class LightTerm:
    """One shading term of the capture and an upper estimate of the radiance it gives a surface.

    ``name``: what it is (``"sunlight"``); ``peak``: estimated largest radiance (cd/m^2-scaled);
    ``detail``: how the estimate is made, naming the scene keys; ``change``: the keys that lower it.
    """

    name: str
    peak: float
    detail: str
    change: str


def light_terms(scene: Scene, sky: Sky) -> list[LightTerm]:
    """The radiance terms the scene's effects add, largest estimate first.

    Lambertian surfaces of albedo ``a`` (at most the mesh's largest albedo channel) reflect
    ``a E / pi``: under the sun ``E`` is at most its illuminance at normal incidence
    (``sun_light``), under the sky dome at most ``pi`` times its peak radiance (``sky_light``);
    lit windows add their emission (``emissive_windows``).  Terms of effects the scene does not
    call for, or that lack their input (no sun), are left out.
    """
    mesh = scene.mesh
    albedo = float(mesh.albedo.max()) if mesh.albedo.size else 0.0
    sky_type = sky.spec().get("type")
    terms: list[LightTerm] = []
    if "emissive_windows" in scene.effects and mesh.emission.size:
        e = float(mesh.emission.max())
        terms.append(LightTerm("lit windows", e, f"window emission up to {e:.6g}", "windows.emission"))
    if "sun_light" in scene.effects and sky.sun is not None:
        illum = float(np.max(sky.sun.illuminance))
        key = "sky.scale" if sky_type == "preetham" else "sky.sun.illuminance"
        terms.append(LightTerm("sunlight", albedo * illum / math.pi,
                               f"sun illuminance {illum:.6g} lux x albedo {albedo:.3g} / pi", f"{key} or the albedos"))
    if "sky_light" in scene.effects:
        dome = float(sky.cube(SKY_PEAK_FACE, include_sun=False).max())
        key = "sky.radiance" if sky_type == "uniform" else "sky.scale"
        terms.append(LightTerm("sky light", albedo * dome, f"sky radiance up to {dome:.6g} x albedo {albedo:.3g}",
                               f"{key} or the albedos"))
    return sorted(terms, key=lambda t: -t.peak)


def check_half_range(rgba: NDArray[np.float32], probes: Sequence[tuple[str, int]],
                     positions: NDArray[np.float64], scene: Scene, sky: Sky) -> None:
    """Raise ``ValueError`` (one line) if any captured RGB texel exceeds the half-float maximum.

    ``rgba``: the captured level 0, shape ``(P, 6, N, N, 4)`` (premultiplied RGB radiance, alpha);
    ``probes``: ``(street name, index along the street)`` of each layer; ``positions``: ``(P, 3)``
    world positions (m).  NaN texels are left to the probe-set checks.  The light terms
    (:func:`light_terms`) are computed only when the check fails.
    """
    rgb = rgba[..., :3]
    peak = float(np.fmax.reduce(rgb, axis=None)) if rgb.size else 0.0
    if not peak > HALF_MAX:
        return
    per_probe = np.array([np.fmax.reduce(layer, axis=None) for layer in rgb])
    worst = int(np.nanargmax(per_probe))
    over = int(np.count_nonzero(per_probe > HALF_MAX))
    street, index = probes[worst]
    x, y, z = (float(v) for v in positions[worst])
    more = f" (and {over - 1} more probe(s))" if over > 1 else ""
    terms = light_terms(scene, sky)
    if terms:
        top = terms[0]
        rest = "".join(f"; {t.name} up to {t.peak:.3g}" for t in terms[1:])
        cause = f"likely cause: {top.name} up to {top.peak:.3g} ({top.detail}{rest}); lower {top.change}"
    else:
        cause = "no light term of the scene explains it"
    source = scene.meta.get("source")
    where = f"{source}: " if source else ""
    raise ValueError(
        f"{where}probe {index} of street '{street}' at ({x:.6g}, {y:.6g}, {z:.6g}) m{more}: radiance {peak:.6g} "
        f"is past {HALF_MAX:g}, the largest half float that probes.ktx2 (RGBA16F) stores; {cause} "
        f"(nothing clamped, nothing written)")
