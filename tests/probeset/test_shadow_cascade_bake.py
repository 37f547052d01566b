"""A bake of a 2 km street at 0.1 m shadow texels (issue 10: more than one map can hold): the
sun shadows become cascades, and the manifest records each cascade's texel; a bake that one map
can hold keeps its manifest without the new key.  A street turned in plan is fitted with its
world box."""

import json
from pathlib import Path

import numpy as np

from envcap.probeset.bake import bake_probe_set
from envcap.probeset.manifest import Manifest
from envcap.probeset.shadow_fit import street_shadow_box
from envcap.scene import load_scene, scene_from_dict
from envcap.scene.model import SHADOW_STREET_PAD_M as PAD
from envcap.scene.model import ShadowSettings

SCENE = Path(__file__).with_name("long_street_shadows.toml")


def _manifest(shadows: ShadowSettings | None = None) -> dict:
    scene = load_scene(SCENE)
    if shadows is not None:
        scene.shadows = shadows
    ps = bake_probe_set(scene, resolution=4, spacing=500.0, filter_levels=False, progress=False)
    return json.loads(json.dumps(ps.manifest.to_json()))


def test_a_long_street_at_a_fine_texel_gets_cascades_in_the_manifest() -> None:
    fine = _manifest()                                  # fit "mesh": the 4 km ground, texel 0.1 m
    texels = fine["shadow_cascade_texels_m"]
    assert fine["shadow_texel_m"] == 0.1 and texels[:2] == [0.1, 0.4] and len(texels) == 3
    assert 2.0 < texels[2] < 3.0                        # the ~5.5 km light window over 2048 texels
    assert Manifest.from_json(fine).shadow_cascade_texels_m == tuple(texels)
    street = _manifest(ShadowSettings(texel_m=0.1, fit="streets"))
    assert street["shadow_cascade_texels_m"][:2] == [0.1, 0.4] and 0.9 < street["shadow_cascade_texels_m"][2] < 1.3
    coarse = _manifest(ShadowSettings(texel_m=1.0, fit="streets"))   # ~2200 texels: one map, as before
    assert "shadow_cascade_texels_m" not in coarse and 0.9 < coarse["shadow_texel_m"] <= 1.0


def test_a_street_turned_in_plan_is_fitted_with_its_world_box() -> None:
    doc = {"name": "turned", "effects": ["sun_light", "sun_shadows"], "shadows": {"fit": "streets", "texel_m": 0.1},
           "sky": {"type": "uniform", "radiance": 1.0},
           "streets": [{"name": "d", "p0": [100.0, 50.0], "p1": [300.0, 250.0], "width": 12.0}]}
    lo, hi = street_shadow_box(scene_from_dict(doc))
    u, v = np.array([1.0, 1.0]) / np.sqrt(2.0), np.array([-1.0, 1.0]) / np.sqrt(2.0)   # along, across (45 deg)
    length = np.hypot(200.0, 200.0)
    corners = np.array([[100.0, 50.0] + a * u + c * v for a in (-PAD, length + PAD) for c in (-6 - PAD, 6 + PAD)])
    np.testing.assert_allclose([lo[0], hi[0], lo[2], hi[2]], [corners[:, 0].min(), corners[:, 0].max(),
                                                               corners[:, 1].min(), corners[:, 1].max()], atol=1e-9)
