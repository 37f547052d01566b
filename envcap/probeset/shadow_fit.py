"""The sun's shadow map of a bake, from the scene's ``[shadows]`` table (issue 10: a map stretched
over a whole city had 0.2-2 m texels).

``fit = "mesh"`` (the default) lets the ``sun_shadows`` effect cover the whole mesh;
``fit = "streets"`` covers the union of the streets' boxes, each grown by
:data:`~envcap.scene.model.SHADOW_STREET_PAD_M` along and across, from the mesh's lowest to its
highest point (the effect still reaches every occluder toward the sun).  ``texel_m`` sets the
texel size; the bake records the texel size reached in the manifest (``shadow_texel_m``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from envcap.formats.scene_gltf import street_boxes
from envcap.scene.model import SHADOW_STREET_PAD_M, Scene


def street_shadow_box(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """World box ``(lo (3,), hi (3,))`` (m) of the scene's streets, padded
    (:func:`envcap.formats.scene_gltf.street_boxes`), over the mesh's height."""
    boxes = street_boxes(scene.streets, SHADOW_STREET_PAD_M)          # (S, 4): x0, x1, z0, z1
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
