"""Shadow cascades (issue 10: a long street at a fine texel needs more texels than one map can
hold): a small caster beside a probe of a 2 km street, its shadow on the ground checked against
a float64 ray-box reference, resolved with cascades and lost with the one map of today."""

from pathlib import Path

import numpy as np
import pytest

from envcap.capture.effects.sun_shadows import MAX_CASCADES, plan_shadow_map
from envcap.capture.renderer import CubeCapture
from envcap.core.cube import texel_directions
from envcap.scene.model import SceneMesh
from envcap.scene.synthetic import box, quad
from envcap.sky.sun import Sun
from envcap.sky.uniform import UniformSky

SUN_DIR = np.array([1.0, 1.2, 0.4]) / np.linalg.norm([1.0, 1.2, 0.4])
SUN = Sun(SUN_DIR, np.array([1e5, 1e5, 1e5]))
ALBEDO = 0.5
PROBES = np.array([[400.0, 2.0, 0.0], [-600.0, 2.0, 0.0]])      # 1 km apart on the street
CASTER = (np.array([0.4, 0.0, -0.7]), np.array([0.8, 1.0, -0.3]))  # 0.4 m box, 1 m high, beside each probe
N = 48


def _scene() -> SceneMesh:
    street = quad((-1000, 0, -20), (0, 0, 40), (2000, 0, 0), albedo=(ALBEDO,) * 3)   # 2 km street, faces up
    far = box((2900, 0, -5), (3000, 10, 5))                                          # spreads the mesh over 4 km
    casters = [box(p + CASTER[0] * [1, 1, 1] - [0, 2, 0], p + CASTER[1] - [0, 2, 0]) for p in PROBES]
    return SceneMesh.concatenate([street, far, *casters])


def _ray_box(origins: np.ndarray, d: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """float64 slab test: does origin + t d, t > 0, meet the box [lo, hi]?"""
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (lo - origins) / d, (hi - origins) / d
    near = np.nanmax(np.minimum(t0, t1), axis=-1)
    far = np.nanmin(np.maximum(t0, t1), axis=-1)
    return (far >= np.maximum(near, 0.0))


def _ground_truth(probe: np.ndarray, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """Per texel of the -Y face that sees the ground (y = 0) past the caster: (sure shadow, sure
    lit) from the ray to the sun there; 'sure' when the ground points within ``margin`` m agree."""
    d = texel_directions(N)[3]                                       # -Y face, (N, N, 3)
    hit = probe + d * (probe[1] / -d[..., 1])[..., None]
    lo, hi = probe + CASTER[0] - [0, 2, 0], probe + CASTER[1] - [0, 2, 0]
    votes = []
    for dx in (-margin, 0.0, margin):
        for dz in (-margin, 0.0, margin):
            votes.append(_ray_box(hit + [dx, 1e-9, dz], SUN_DIR, lo, hi))
    votes = np.array(votes)
    ground = ~_ray_box(np.broadcast_to(probe, d.shape), d, lo, hi)   # the view ray reaches the ground
    return ground & votes.all(axis=0), ground & ~votes.any(axis=0)


def _visibility(params: dict | None, gl_ctx) -> tuple[np.ndarray, dict]:
    """Sun visibility of the -Y face's texels of both probes, (2, N, N), and the effect facts."""
    sky = UniformSky((0.0, 0.0, 0.0), SUN)
    with CubeCapture(_scene(), N, ctx=gl_ctx, sky=sky, effects={"sun_light", "sun_shadows"},
                     effect_parameters=params) as cap:
        got = cap.capture_many(PROBES, progress=False)
        facts = dict(cap.effect_facts)
    lit = ALBEDO / np.pi * SUN.illuminance[1] * SUN_DIR[1]          # albedo/pi E cos, unshadowed
    return got.rgba[:, 3, :, :, 1] / lit, facts


def test_cascades_resolve_a_small_caster_that_one_map_loses(gl_ctx) -> None:
    fine, facts = _visibility({"sun_shadows": {"texel_m": 0.02}}, gl_ctx)
    coarse, facts_today = _visibility(None, gl_ctx)
    assert facts["sun_shadows.cascades"] == 4 and facts["sun_shadows.texel_m"] == 0.02
    assert facts_today["sun_shadows.texel_m"] > 1.0                 # 2048 texels over ~3 km of light window
    for i, probe in enumerate(PROBES):                              # the second probe: tiles redrawn
        shadow, lit = _ground_truth(probe, margin=0.08)
        assert shadow.sum() > 25 and lit.sum() > 1000
        assert fine[i][shadow].max() < 0.02, "cascades: a texel in the caster's umbra is lit"
        assert fine[i][lit].min() > 0.98, "cascades: a lit texel is shaded"
        assert np.median(coarse[i][shadow]) > 0.5, "one map: the small shadow should be lost"


def test_the_plan_follows_the_asked_texel_and_refuses_what_cannot_fit() -> None:
    single = plan_shadow_map(400.0, texel_m=0.1)                    # 4000 texels: one map, as before
    assert single.cascades == 0 and single.resolution == 4000 and single.texels_m == (0.1,)
    street = plan_shadow_map(4096.0, texel_m=0.1)                   # 40960 texels: 3 cascades
    assert street.texels_m == (0.1, 0.4, 2.0) and street.resolution == 2048
    assert street.atlas == (3 * 2048 + 4, 2048) and street.cells[2] == (2 * 2050, 0)
    assert street.bytes < 2**27 and "3 shadow cascades" in street.describe()
    with pytest.raises(ValueError, match=f"more than {MAX_CASCADES}: fit a smaller box"):
        plan_shadow_map(40000.0, texel_m=0.001)
    with pytest.raises(ValueError, match="GL_MAX_TEXTURE_SIZE"):
        plan_shadow_map(100.0, resolution=32768)
    grid = plan_shadow_map(4096.0, texel_m=0.1, max_texture_size=5000)   # cells wrap into rows
    assert grid.atlas == (2 * 2050 - 2, 2 * 2050 - 2) and grid.cells == ((0, 0), (2050, 0), (0, 2050))
    with pytest.raises(ValueError, match="past GL_MAX_TEXTURE_SIZE 4096"):
        plan_shadow_map(4096.0, texel_m=0.1, max_texture_size=4096)


def _today_scene() -> SceneMesh:
    ground = quad((-60, 0, -60), (0, 0, 120), (120, 0, 0), albedo=(0.5, 0.4, 0.3))
    return SceneMesh.concatenate([ground, box((4, 0, -6), (9, 14, 3)), box((-8, 0, 2), (-3, 9, 8)),
                                  box((-0.6, 0, -2.2), (-0.2, 1.5, -1.8))])


def test_without_cascades_the_captures_are_those_of_before(gl_ctx) -> None:
    """``shadow_single_map_today.npz``: the same captures made by envcap before cascades (commit
    cdbf57f); bit-identical on the GL that made them, else within float rounding."""
    ref = np.load(Path(__file__).with_name("shadow_single_map_today.npz"))
    sky = UniformSky((800.0, 900.0, 1000.0), Sun(np.array([0.6, 1.0, -0.35]), np.array([2e6, 1.9e6, 1.7e6])))
    probes = np.array([[0.0, 2.0, 0.0], [-3.3, 1.7, -4.1]])
    same_gl = str(ref["gl"][0]) == gl_ctx.info["GL_RENDERER"] + " | " + gl_ctx.info["GL_VERSION"]
    for tag, params in [("default", None),
                        ("texel", {"sun_shadows": {"bounds": ((-10, 0, -10), (10, 5, 10)), "texel_m": 0.03}})]:
        with CubeCapture(_today_scene(), 16, ctx=gl_ctx, sky=sky, effects={"sun_light", "sky_light", "sun_shadows"},
                         effect_parameters=params) as cap:
            got = cap.capture_many(probes, progress=False).rgba
            assert "sun_shadows.cascades" not in cap.effect_facts
        assert (ref[tag][..., 0] == 0).mean() > 0.05                  # shadows in view
        if same_gl:
            np.testing.assert_array_equal(got, ref[tag])
        else:
            assert np.isclose(got, ref[tag], rtol=1e-4, atol=1e-3).mean() > 0.999
