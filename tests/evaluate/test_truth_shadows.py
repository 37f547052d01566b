"""The evaluator's truth casts the sun's shadows with the map the bake used (the scene's
``[shadows]`` table: fit and texel), so a fresh truth capture at a probe's position is that probe's
capture bit for bit (review of issue 10: the truth drew the default 2048^2 map over the mesh)."""

import numpy as np

from envcap.evaluate.truth import TruthRenderer
from envcap.probeset.bake import bake_probe_set
from envcap.scene import scene_from_dict

SCENE = {"name": "shadowed", "effects": ["sun_light", "sun_shadows"],
         "sky": {"type": "uniform", "radiance": 1000.0,
                 "sun": {"elevation_deg": 35.0, "azimuth_deg": 60.0, "illuminance": 1.0e5}},
         "ground": {"extent": 300.0},
         "streets": [{"name": "s", "axis": "x", "start": -20.0, "end": 20.0, "width": 10.0,
                      "side_min": {"wall": {"height": 12.0}}, "side_max": {"wall": {"height": 6.0}}}],
         "shadows": {"fit": "streets", "texel_m": 1.0}}


def test_truth_capture_at_a_probe_is_the_baked_capture(gl_ctx):
    scene = scene_from_dict(SCENE)
    ps = bake_probe_set(scene, resolution=16, spacing=20.0, filter_levels=False, ctx=gl_ctx, progress=False)
    truth = TruthRenderer(scene, 16, gl_ctx)
    try:
        assert round(truth.cap.effect_facts["sun_shadows.texel_m"], 6) == ps.manifest.shadow_texel_m
        for probe in ps.manifest.streets[0].probes:
            cap = truth.capture(np.array(probe.position))
            assert np.array_equal(cap.rgba, ps.levels[0][probe.layer])
    finally:
        truth.release()
