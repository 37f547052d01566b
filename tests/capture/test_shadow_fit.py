"""Shadow maps fitted to a box (issue 10, wall 9: one map stretched over a whole city gave 0.2-2 m
texels): a texel size to reach, reported; geometry outside the box still casts into it."""

import numpy as np
import pytest

from envcap.capture.renderer import CubeCapture
from envcap.scene.model import SceneMesh
from envcap.scene.synthetic import box, quad
from envcap.sky.sun import Sun
from envcap.sky.uniform import UniformSky

SUN = Sun(np.array([1.0, 1.0, 0.0]), np.array([1e5, 1e5, 1e5]))      # 45 deg up, from +X


def _scene() -> SceneMesh:
    ground = quad((-200, 0, -200), (0, 0, 400), (400, 0, 0), albedo=(0.5, 0.5, 0.5))
    wall = box((10, 0, -5), (11, 20, 5))       # 20 m high, 10-11 m toward the sun: shades x in [-10, 10]
    far = box((150, 0, -5), (160, 5, 5))        # far away: stretches the whole-mesh map
    return SceneMesh.concatenate([ground, wall, far])


def _ground_below(cap: CubeCapture) -> np.ndarray:
    return cap.capture((0.0, 2.0, 0.0)).rgba[3, 12:20, 12:20, 1]      # -Y face, around straight down


def test_a_fitted_box_reports_its_texel_and_keeps_outside_occluders(gl_ctx) -> None:
    sky = UniformSky((0.0, 0.0, 0.0), SUN)
    effects = {"sun_light", "sun_shadows"}
    with CubeCapture(_scene(), 32, ctx=gl_ctx, sky=sky, effects=effects) as whole:
        whole_texel = whole.effect_facts["sun_shadows.texel_m"]
        shaded_whole = _ground_below(whole)
    box_lo, box_hi = np.array([-5.0, 0.0, -5.0]), np.array([5.0, 3.0, 5.0])   # the wall is outside it
    params = {"sun_shadows": {"bounds": (box_lo, box_hi), "texel_m": 0.02}}
    with CubeCapture(_scene(), 32, ctx=gl_ctx, sky=sky, effects=effects, effect_parameters=params) as fitted:
        fitted_texel = fitted.effect_facts["sun_shadows.texel_m"]
        shaded_fitted = _ground_below(fitted)
    with CubeCapture(_scene(), 32, ctx=gl_ctx, sky=sky, effects={"sun_light"}) as lit:
        unshaded = _ground_below(lit)
    assert whole_texel > 0.1 and fitted_texel <= 0.02 and fitted.effect_facts["sun_shadows.resolution"] < 2048
    assert unshaded.min() > 0
    assert shaded_whole.max() == 0.0 and shaded_fitted.max() == 0.0   # the wall outside the box still shades


def test_a_texel_too_fine_for_the_gpu_is_a_clear_error(gl_ctx) -> None:
    sky = UniformSky((0.0, 0.0, 0.0), SUN)
    params = {"sun_shadows": {"texel_m": 1e-4}}
    with pytest.raises(ValueError, match="past the single-map limit .*cascades.*fit a smaller box"):
        CubeCapture(_scene(), 8, ctx=gl_ctx, sky=sky, effects={"sun_light", "sun_shadows"}, effect_parameters=params)
    with pytest.raises(ValueError, match="texel_m"):
        CubeCapture(_scene(), 8, ctx=gl_ctx, sky=sky, effects={"sun_light", "sun_shadows"},
                    effect_parameters={"sun_shadows": {"texel_m": -1.0}})
