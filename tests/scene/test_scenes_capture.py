"""Bundled scenes seen by the real GL capture (llvmpipe): the street planes bound the geometry.

Reference: the three-plane ray distance computed in float64 by hand (ray/plane intersection),
against the distance channel rasterized by ``envcap.capture.renderer.CubeCapture``.
"""

from __future__ import annotations

import numpy as np
import pytest

from envcap.core import cube
from envcap.capture.renderer import CubeCapture
from envcap.scene import load_scene

N = 32


def _probe(st, frac=0.5, height=2.0):
    p = np.zeros(3)
    p[st.along_index] = st.start + frac * st.length
    p[st.cross_index] = st.center_line
    p[1] = height
    return p


def _plane_distance(st, p, d, slack=0.0):
    """Ray distance from p along unit d to the first of the street's three planes, each moved
    ``slack`` meters toward the probe; inf where the ray is parallel to or leaves all of them."""
    c = st.cross_index
    dc, dy = d[..., c], d[..., 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        tc = np.where(dc > 0, (st.facade_max - slack - p[c]) / dc,
                      np.where(dc < 0, (st.facade_min + slack - p[c]) / dc, np.inf))
        ty = np.where(dy < 0, (st.ground - p[1]) / dy, np.inf)
    return np.minimum(tc, ty)


@pytest.fixture(scope="module")
def dirs():
    return cube.texel_directions(N)


def test_planes_scene_is_exactly_three_planes(gl_ctx, dirs):
    s = load_scene("planes")
    st = s.streets[0]
    p = np.array([3.0, 2.0, 1.5])  # off-center on purpose
    with CubeCapture(s.mesh, N, ctx=gl_ctx) as cap:
        c = cap.capture(p)
    t = _plane_distance(st, p, dirs)
    hit = p + np.where(np.isfinite(t), t, 0.0)[..., None] * dirs
    # where the analytic hit lies on a wall (below its 20 m top, within the street) or the ground
    ok = np.isfinite(t) & (hit[..., 1] < 19.5) & (np.abs(hit[..., 0]) < 99.0)
    assert ok.mean() > 0.7
    np.testing.assert_allclose(c.distance[ok], t[ok], rtol=1e-5)
    assert np.all(c.rgba[..., 3][ok] == 1.0)
    # straight up is sky
    assert c.rgba[2, N // 2, N // 2, 3] == 0.0


@pytest.mark.parametrize("name", ["canyon", "asymmetric", "crossing", "avenue", "imported"])
def test_nothing_stands_in_front_of_the_street_planes(gl_ctx, dirs, name):
    s = load_scene(name)
    for st in s.streets:
        for frac in (0.3, 0.5):
            p = _probe(st, frac)
            with CubeCapture(s.mesh, N, ctx=gl_ctx) as cap:
                c = cap.capture(p)
            geo = c.rgba[..., 3] > 0
            assert np.all(np.isfinite(c.rgba)) and not c.inside_geometry
            # window quads stand 1.5 cm in front of flush facades: allow 2 cm
            bound = _plane_distance(st, p, dirs, slack=0.02)
            assert np.all(c.distance[geo] >= bound[geo] * (1 - 1e-5)), f"{name}/{st.name} at {p}"
            # the ground has no holes: every direction clearly below the horizon hits something
            assert np.all(geo[dirs[..., 1] < -0.05])
