"""The sun's shadow map of a bake, from the scene's ``[shadows]`` table (issue 10: a map stretched
over a whole city had 0.2-2 m texels).

``fit = "mesh"`` (the default) lets the ``sun_shadows`` effect cover the whole mesh;
``fit = "streets"`` covers the union of the streets' boxes, each grown by
:data:`~envcap.scene.model.SHADOW_STREET_PAD_M` along and across, from the mesh's lowest to its
highest point (the effect still reaches every occluder toward the sun); a street turned in plan
counts with its world box (``Street.plan_box``).  ``texel_m`` sets the texel size; when one map
cannot hold it over the fitted window (a long street, a whole city), the effect draws cascades
that follow the probe (:func:`envcap.capture.effects.sun_shadows.plan_shadow_map`).  The bake
records the finest texel size reached in the manifest (``shadow_texel_m``) and, with cascades,
the texel of each (``shadow_cascade_texels_m``, :func:`cascade_texels`).
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from envcap.formats.scene_gltf import street_boxes
from envcap.scene.model import SHADOW_STREET_PAD_M, Scene


def street_shadow_box(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """World box ``(lo (3,), hi (3,))`` (m) of the scene's streets, padded
    (``Street.plan_box``, else :func:`envcap.formats.scene_gltf.street_boxes`), over the mesh's height."""
    if all(hasattr(st, "plan_box") for st in scene.streets):
        boxes = np.array([st.plan_box(SHADOW_STREET_PAD_M) for st in scene.streets], np.float64).reshape(-1, 4)
    else:
        boxes = street_boxes(scene.streets, SHADOW_STREET_PAD_M)      # (S, 4): x0, x1, z0, z1
    mesh_lo, mesh_hi = scene.mesh.world_bounds()
    lo = np.array([boxes[:, 0].min(), min(float(mesh_lo[1]), 0.0), boxes[:, 2].min()])
    hi = np.array([boxes[:, 1].max(), max(float(mesh_hi[1]), 1.0), boxes[:, 3].max()])
    return lo, hi


def shadow_effect_parameters(scene: Scene) -> dict[str, dict[str, Any]]:
    """``effect_parameters`` for :class:`envcap.capture.renderer.CubeCapture` from
    ``scene.shadows`` (empty when the table changes nothing or the scene has no sun shadows)."""
    if scene.shadows.default or "sun_shadows" not in scene.effects or not scene.streets:
        return {}
    params: dict[str, Any] = {}
    if scene.shadows.fit == "streets":
        params["bounds"] = street_shadow_box(scene)
    if scene.shadows.texel_m is not None:
        params["texel_m"] = scene.shadows.texel_m
    return {"sun_shadows": params}


def cascade_texels(facts: Mapping[str, float]) -> tuple[float, ...] | None:
    """The texel size (m, rounded to 1 um) of each shadow cascade, finest first, from a capture's
    ``effect_facts`` (``"sun_shadows.cascade<k>_texel_m"``); ``None`` without cascades."""
    count = int(facts.get("sun_shadows.cascades", 0))
    if count == 0:
        return None
    return tuple(round(float(facts[f"sun_shadows.cascade{k}_texel_m"]), 6) for k in range(count))


def shadow_summary(facts: Mapping[str, float]) -> str | None:
    """One line on the shadow cascades of a capture (count, texels, size, memory), from its
    ``effect_facts``; ``None`` without cascades."""
    texels = cascade_texels(facts)
    if texels is None:
        return None
    res = int(facts["sun_shadows.resolution"])
    mib = 4 * len(texels) * res * res / 2**20
    return (f"sun shadows: {len(texels)} cascades of {res}^2 texels, texels {', '.join(f'{t:g}' for t in texels)} m "
            f"(the finer ones follow the probe), {mib:.0f} MiB")
