"""The capture effect registry: an effect defined and registered in this file alone is captured
with, its pass recorded and its uniforms checked; the built-in effects and scene validation come
from the registry."""

import numpy as np
import pytest

from envcap.capture import effects
from envcap.capture.effects.base import CaptureEffect, EffectParameter, EffectSetup, capture_fragment_source
from envcap.capture.renderer import CubeCapture
from envcap.scene import EFFECTS, scene_from_dict
from envcap.scene.model import SceneMesh
from envcap.scene.synthetic import quad


def _rgb(v):
    a = np.asarray(v, dtype=np.float64)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"constant_tint parameter 'color' must be 3 finite numbers, got {v!r}")
    return a


# A complete effect: name, GLSL, a uniform, a parameter, and a per-set pass.  Nothing else in
# envcap changes to add it.
CONSTANT_TINT = CaptureEffect(
    name="constant_tint",
    summary="multiplies the outgoing radiance by a constant RGB factor",
    parameters={"color": EffectParameter((1.0, 1.0, 1.0), "RGB factor", _rgb)},
    uniforms=("tint",),
    pass_name="tint_setup",
    prepare=lambda inputs, params: EffectSetup(uniforms={"tint": params["color"]}),
    glsl_declarations="uniform vec3 tint;\n",
    glsl_radiance="L *= tint;\n",
)


@pytest.fixture
def tint_registered():
    effects.register(CONSTANT_TINT)
    try:
        yield
    finally:
        effects.unregister("constant_tint")


EMISSION = np.array([5.0, 4.0, 3.0])
WINDOW = quad((3, -1, 1), (0, 2, 0), (0, 0, -2), (0.5, 0.5, 0.5), EMISSION)  # faces -X, toward the probe


def test_effect_registered_from_a_test_file_is_captured_with(gl_ctx, tint_registered):
    color = np.array([0.5, 2.0, 0.25])
    params = {"constant_tint": {"color": color}}
    with CubeCapture(WINDOW, 16, ctx=gl_ctx, effects={"emissive_windows", "constant_tint"},
                     effect_parameters=params) as cap:
        assert cap.applied == {"emissive_windows", "constant_tint"}
        tinted = cap.capture([0, 0, 0])
    with CubeCapture(WINDOW, 16, ctx=gl_ctx, effects={"emissive_windows"}) as cap:
        plain = cap.capture([0, 0, 0])
    seen = plain.rgba[..., 3] == 1
    assert seen.sum() > 10
    np.testing.assert_array_equal(tinted.rgba[..., 3], plain.rgba[..., 3])
    np.testing.assert_array_equal(tinted.distance, plain.distance)
    # The window's radiance is its emission; the tint multiplies it (float32, exact products).
    want = (EMISSION.astype(np.float32) * color.astype(np.float32)).astype(np.float32)
    np.testing.assert_array_equal(tinted.rgba[seen][:, :3], np.broadcast_to(want, (seen.sum(), 3)))
    np.testing.assert_array_equal(plain.rgba[seen][:, :3],
                                  np.broadcast_to(EMISSION.astype(np.float32), (seen.sum(), 3)))
    # Its per-set pass is recorded, after the built-in passes, before the per-probe passes.
    assert tinted.passes_run == ["tint_setup", "render", "readback"]
    assert plain.passes_run == ["render", "readback"]


def test_registered_effect_order_and_scene_validation(tint_registered):
    assert effects.effect_names()[-1] == "constant_tint"
    assert effects.check_effects(["constant_tint"]) == {"constant_tint"}
    with pytest.raises(ValueError, match="unknown effect"):
        effects.check_effects(["fog"])
    with pytest.raises(ValueError, match="already registered"):
        effects.register(CONSTANT_TINT)


def test_effect_parameter_and_uniform_checks(gl_ctx, tint_registered):
    with pytest.raises(ValueError, match="has no parameter"):
        CubeCapture(WINDOW, 2, ctx=gl_ctx, effects={"constant_tint"},
                    effect_parameters={"constant_tint": {"colour": 1}})
    with pytest.raises(ValueError, match="3 finite numbers"):
        CubeCapture(WINDOW, 2, ctx=gl_ctx, effects={"constant_tint"}, effect_parameters={"constant_tint": {"color": 2}})
    with pytest.raises(ValueError, match="unknown effect"):
        CubeCapture(WINDOW, 2, ctx=gl_ctx, effect_parameters={"fog": {}})
    with pytest.raises(ValueError, match="sh_resolution"):
        CubeCapture(WINDOW, 2, ctx=gl_ctx, effect_parameters={"sky_light": {"sh_resolution": 0}})


def test_effect_that_misdeclares_or_misnames_a_uniform_is_refused(gl_ctx):
    liar = CaptureEffect(name="liar", summary="sets a uniform it does not declare", uniforms=("tint",),
                         prepare=lambda i, p: EffectSetup(uniforms={"tint": (1, 1, 1), "extra": 1.0}),
                         glsl_declarations="uniform vec3 tint;\n", glsl_radiance="L *= tint;\n")
    typo = CaptureEffect(name="typo", summary="its GLSL names the uniform differently", uniforms=("tint",),
                         prepare=lambda i, p: EffectSetup(uniforms={"tint": (1, 1, 1)}),
                         glsl_declarations="uniform vec3 tnit;\n", glsl_radiance="L *= tnit;\n")
    for effect, err in ((liar, RuntimeError), (typo, KeyError)):
        effects.register(effect)
        try:
            with pytest.raises(err, match="extra" if effect is liar else "tint"):
                CubeCapture(WINDOW, 2, ctx=gl_ctx, effects={effect.name})
        finally:
            effects.unregister(effect.name)


def test_builtin_effects_are_the_scene_effects():
    assert effects.effect_names() == EFFECTS == ("sun_light", "sky_light", "sun_shadows", "emissive_windows")
    with pytest.raises(ValueError, match="needs 'sun_light'"):
        effects.check_effects(["sun_shadows"])
    with pytest.raises(ValueError, match="required by"):
        effects.unregister("sun_light")
    with pytest.raises(ValueError, match="lower_case"):
        CaptureEffect(name="Fog", summary="")
    with pytest.raises(ValueError, match="unknown needs"):
        CaptureEffect(name="fog", summary="", needs=frozenset({"moon"}))


def test_scene_effects_are_checked_against_the_registry(gl_ctx, tint_registered):
    table = {"name": "t", "sky": {"type": "uniform", "radiance": [1.0, 1.0, 1.0]}, "ground": {"enabled": False},
             "streets": [{"name": "s", "axis": "x", "start": 0.0, "end": 10.0, "width": 10.0, "cross": 5.0}]}
    with pytest.raises(ValueError, match="unknown effect"):
        scene_from_dict({**table, "effects": ["fog"]})
    sc = scene_from_dict({**table, "effects": ["constant_tint", "emissive_windows"]})
    assert sc.effects == {"constant_tint", "emissive_windows"}
    with CubeCapture.from_scene(sc, 2, ctx=gl_ctx) as cap:
        assert cap.applied == {"constant_tint", "emissive_windows"} and cap.sky is None


def test_fragment_source_without_effects_compiles_and_draws_geometry_only(gl_ctx):
    src = capture_fragment_source(())
    assert "// @effects:irradiance" not in src and "#define" not in src
    with CubeCapture(WINDOW, 4, ctx=gl_ctx) as cap:
        got = cap.capture([0, 0, 0])
    assert got.rgba[..., 3].any() and not got.rgba[..., :3].any()


def test_sun_and_sky_effects_are_not_applied_without_a_sky(gl_ctx):
    mesh = SceneMesh.concatenate([WINDOW])
    with CubeCapture(mesh, 2, ctx=gl_ctx, effects=set(EFFECTS)) as cap:
        assert cap.applied == {"emissive_windows"} and cap.passes_run == []
