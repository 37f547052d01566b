"""Street evaluation of the dynamic terms (spheres), checked against independent references:

* extra spheres in a scene: the scene's own vertices untouched, a 16^2 capture with a big sphere
  is darker toward it and its distance there is the sphere's near surface (l - r);
* sky coverage against the closed-form solid angle of a cap;
* the dynamic terms against a hand-derived case (uniform sky, one sphere on the normal: the
  diffuse lobe loses ``sin^2 theta (1 - a)``), and the overlap clamp;
* a miniature of the street evaluation: a ring hiding much of the sky, fresh capture as truth, the
  dynamic terms cut the Eq. 3 error at least in half.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from envcap.capture.renderer import CubeCapture
from envcap.core import cube
from envcap.core.color import luminance
from envcap.evaluate.dynamic_occluders import Ring, evaluate_rings, sky_coverage, visible_sky_hidden
from envcap.evaluate.dynamic_terms import lafortune, model_terms, shade_model, sphere_buffer
from envcap.evaluate.predict import Predictor
from envcap.evaluate.shading import MATERIALS, Material
from envcap.scene import load_scene
from envcap.scene.occluder_spheres import OccluderSphere, sphere_mesh, unit_icosphere, with_spheres

X = np.array([0.0, 1.5, 0.0])   # on the canyon's center line (street along x), 1.5 m up


@pytest.fixture(scope="module")
def canyon():
    return load_scene("canyon")


def test_with_spheres_keeps_the_scene_and_places_the_sphere(canyon, gl_ctx):
    before = canyon.mesh.positions.copy()
    assert with_spheres(canyon, []) is canyon
    big = OccluderSphere((3.0, 1.5, 0.0), 1.0, (0.1, 0.1, 0.1))
    sc = with_spheres(canyon, [big])
    nv = canyon.mesh.positions.shape[0]
    assert np.array_equal(canyon.mesh.positions, before)
    assert np.array_equal(sc.mesh.positions[:nv], before) and np.array_equal(sc.mesh.origin, canyon.mesh.origin)
    assert sc.mesh.triangle_count == canyon.mesh.triangle_count + 1280
    sky = canyon.sky.build()
    with CubeCapture.from_scene(canyon, 16, sky=sky, ctx=gl_ctx) as cap:
        plain = cap.capture(X)
    with CubeCapture.from_scene(sc, 16, sky=sky, ctx=gl_ctx) as cap:
        withs = cap.capture(X)
    # +X face (index 0), its central 4 x 4 texels: within 10 deg of the sphere's direction (theta = 19.5 deg)
    c = slice(6, 10)
    u = cube.texel_directions(16)[0, c, c]                                # ray-sphere hit: l cos a - sqrt(r^2 - l^2 sin^2 a)
    hit = 3.0 * u[..., 0] - np.sqrt(1.0 - 9.0 * (1 - u[..., 0] ** 2))
    assert np.allclose(withs.distance[0, c, c], hit, rtol=0.01)           # up to the icosphere's facets
    assert np.all(withs.rgba[0, c, c, 3] == 1)
    # the truth is darker in the sphere's direction: sky (alpha 0, composited) or street behind it
    sky16 = sky.cube(16, include_sun=False)
    lum = [luminance(cc.rgba[0, c, c, :3] + (1 - cc.rgba[0, c, c, 3:]) * sky16[0, c, c]).mean() for cc in (plain, withs)]
    assert lum[1] < 0.5 * lum[0]
    assert np.array_equal(withs.rgba[1], plain.rgba[1])                  # -X face: nothing changed


def test_icosphere_is_closed_and_outward():
    v, t = unit_icosphere(2)
    assert v.shape == (162, 3) and t.shape == (320, 3)
    n = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    assert np.all(np.sum(n * v[t].mean(axis=1), axis=1) > 0)            # counter-clockwise seen from outside
    m = sphere_mesh([OccluderSphere((1.0, 2.0, 3.0), 0.5)], origin=(1.0, 0.0, 0.0), subdivisions=2)
    r = np.linalg.norm(m.positions.astype(np.float64) - [0.0, 2.0, 3.0], axis=1)
    assert np.all((r > 0.5) & (r < 0.5 * 1.02))
    with pytest.raises(ValueError, match="radius"):
        OccluderSphere((0.0, 0.0, 0.0), 0.0)
    with pytest.raises(ValueError, match="subdivisions"):
        unit_icosphere(9)


def test_sky_coverage_against_the_cap_solid_angle():
    s = OccluderSphere((0.0, 3.0, 0.0), 1.0)                              # straight up, sin theta = 1/3
    assert sky_coverage((0.0, 0.0, 0.0), [s]) == pytest.approx(1 - math.sqrt(8 / 9), rel=2e-3)
    side = OccluderSphere((3.0, 0.0, 0.0), 1.0)                           # on the horizon: half of it
    assert sky_coverage((0.0, 0.0, 0.0), [side]) == pytest.approx(0.5 * (1 - math.sqrt(8 / 9)), rel=5e-3)
    assert sky_coverage((0.0, 0.0, 0.0), [OccluderSphere((0.0, 0.5, 0.0), 1.0)]) == 1.0


UP_FRAME = np.array([[[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]])   # rows T, B, N: normal +Y


def uniform(d, w):
    return np.ones(np.shape(d)[:-1] + (3,))


@pytest.mark.parametrize("model, tol", [("paper", 0.02), ("envcap", 2e-3), ("envcap+localb", 2e-3)])
def test_dynamic_terms_hand_checked(model, tol):
    """Uniform radiance 1, a sphere of albedo a with sin theta = 1/2 on the normal: the cosine lobe
    loses sin^2 theta of its light to the sphere and gets a sin^2 theta back (E_1 of a uniform
    environment is 1 along any bounce direction)."""
    a = 0.4
    buf = sphere_buffer([OccluderSphere((0.0, 2.0, 0.0), 1.0, (a, a, a))])
    unit = Material("unit", (1.0, 1.0, 1.0))
    blocked, bounced = model_terms(model, uniform, uniform, np.zeros(3), UP_FRAME, np.array([[0.0, 0.0, 1.0]]),
                                   lafortune(unit), buf)
    assert blocked[0, 0] == pytest.approx(0.25, abs=tol) and bounced[0, 0] == pytest.approx(0.25 * a, abs=tol)
    got = shade_model(model, uniform, uniform, np.zeros(3), UP_FRAME, np.array([[0.0, 0.0, 1.0]]), unit, buf)[0, 0]
    truth = 1 - 0.25 * (1 - a)
    assert abs(got - truth) < 0.1 * abs(1 - truth)                      # toward the truth from the static 1.0


def test_overlapping_spheres_block_at_most_everything():
    buf = sphere_buffer([OccluderSphere((0.0, 0.1 * k, 0.0), 2.0, (0.0, 0.0, 0.0)) for k in range(3)])
    got = shade_model("paper", uniform, None, np.zeros(3), UP_FRAME, np.array([[0.0, 0.0, 1.0]]),
                      Material("unit", (1.0, 1.0, 1.0)), buf)
    assert got == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(ValueError, match="sky light"):
        shade_model("envcap", uniform, None, np.zeros(3), UP_FRAME, np.array([[0.0, 0.0, 1.0]]),
                    Material("unit", (1.0, 1.0, 1.0)), buf)


def test_street_ring_halves_the_error(canyon, canyon_probe_set, gl_ctx):
    """A ring of spheres hiding much of the canyon's sky: against a fresh 16^2 capture with the
    spheres, the probes alone are far off; with envcap's dynamic terms the error is at least halved."""
    predictor = Predictor(canyon_probe_set, sky=canyon.sky.build(), ctx=gl_ctx)
    x = [canyon_probe_set.manifest.streets[0].probes[3].position[0], 1.5, 0.0]
    rows, terms = evaluate_rings(canyon, predictor, "main", [x], rings=[Ring(6, 1.0, 0.45, 35.0)], ctx=gl_ctx,
                                 resolution=16, materials=MATERIALS[:1], models=("envcap",))
    err = {r["variant"]: r["rel_err"] for r in rows}
    assert rows[0]["sky_hidden"] > 0.2
    assert err["static"] > 0.15 and err["oracle"] > 0.15
    assert err["static+envcap"] < 0.5 * err["static"] and err["oracle+envcap"] < 0.5 * err["oracle"]
    t = terms[0]   # the true terms are the capture's own: truth - oracle = bounced - blocked
    assert t["true_blocked"] > t["true_bounced"] > 0


def test_visible_sky_hidden_counts_solid_angle():
    n = 4
    plain = np.zeros((6, n, n, 4), np.float32)
    withs = plain.copy()
    withs[2, ..., 3] = 1                                                  # the whole +Y face now covered
    assert visible_sky_hidden(plain, withs) == pytest.approx(1 / 6)
