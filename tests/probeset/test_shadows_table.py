"""A scene's [shadows] table fits the sun's shadow map to the streets and sets its texel (issue 10,
wall 9: before, only the Python API could change a map stretched over the whole mesh); the bake
records the texel size reached in the manifest."""

import pytest

from envcap.probeset.bake import bake_probe_set
from envcap.probeset.manifest import Manifest
from envcap.scene import scene_from_dict

DOC = {
    "name": "far",
    "effects": ["sun_light", "sun_shadows"],
    "sky": {"type": "uniform", "radiance": 1000.0, "sun": {"elevation_deg": 50.0, "azimuth_deg": 30.0,
                                                         "illuminance": 1.0e5}},
    "streets": [{"name": "s", "axis": "x", "start": -20.0, "end": 20.0, "width": 12.0,
                 "side_min": {"wall": {"height": 10.0}}, "side_max": {"wall": {"height": 10.0}}},
                {"name": "far", "axis": "x", "start": 1980.0, "end": 2000.0, "width": 12.0, "cross": 1500.0}],
}


def _texel(shadows: dict | None) -> float | None:
    doc = {**DOC, "shadows": shadows} if shadows is not None else DOC
    scene = scene_from_dict(doc)
    scene.streets = scene.streets[:1]          # bake only the near street; the far one stretches the mesh
    ps = bake_probe_set(scene, resolution=4, spacing=40.0, filter_levels=False, progress=False)
    m = Manifest.from_json(ps.manifest.to_json())
    return m.shadow_texel_m


def test_shadows_fitted_to_the_streets_at_a_chosen_texel() -> None:
    whole = _texel(None)
    fitted = _texel({"fit": "streets", "texel_m": 0.1})
    assert whole is not None and whole > 0.5          # ~2 km of ground and streets over 2048 texels
    assert fitted is not None and fitted <= 0.1


def test_bad_shadows_tables_are_named() -> None:
    with pytest.raises(ValueError, match="shadows"):
        scene_from_dict({**DOC, "shadows": {"fit": "city"}})
    with pytest.raises(ValueError, match="shadows"):
        scene_from_dict({**DOC, "shadows": {"texel_m": -1.0}})
    with pytest.raises(ValueError, match="shadows"):
        scene_from_dict({**DOC, "shadows": {"texel": 0.1}})
