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

from envcap.scene.model import SHADOW_STREET_PAD_M, Scene


def street_shadow_box(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """World box ``(lo (3,), hi (3,))`` (m) of the scene's streets, padded, over the mesh's height."""
    mesh_lo, mesh_hi = scene.mesh.world_bounds()
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for st in scene.streets:
        a, c = st.along_index, st.cross_index
        s_lo, s_hi = np.zeros(3), np.zeros(3)
        s_lo[a], s_hi[a] = st.start - SHADOW_STREET_PAD_M, st.end + SHADOW_STREET_PAD_M
        s_lo[c], s_hi[c] = st.facade_min - SHADOW_STREET_PAD_M, st.facade_max + SHADOW_STREET_PAD_M
        lo, hi = np.minimum(lo, s_lo), np.maximum(hi, s_hi)
    lo[1], hi[1] = min(float(mesh_lo[1]), 0.0), max(float(mesh_hi[1]), 1.0)
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
