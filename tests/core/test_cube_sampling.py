"""envcap.core.cube_sampling (numpy textureLod twin) against the llvmpipe sampler itself."""

import numpy as np
import pytest

from envcap.core import cube
from envcap.core import cube_sampling as cs
from envcap.gpu.cube_array import CubeArrayTexture, cube_texture
from envcap.gpu.glsl_harness import run_glsl

# Measured: |GL - twin| <= 6e-7 for N <= 8 with texel values in [0, 1] (float32 (s, t) in GL).
def _tol(n):
    return 2e-7 * max(n, 4)


def _levels(rng, n, layers=None):
    shape = lambda k: (() if layers is None else (layers,)) + (6, max(n >> k, 1), max(n >> k, 1), 4)
    return [rng.random(shape(k)).astype(np.float32) for k in range(n.bit_length())]


@pytest.mark.parametrize("n", [1, 2, 4, 8])
def test_cube_array_trilinear_seamless_matches_gl(gl_ctx, n):
    rng = np.random.default_rng(n)
    levels = _levels(rng, n, layers=3)
    tex = CubeArrayTexture(levels)
    m = 100_000
    d = rng.normal(size=(m, 3))
    lay = rng.uniform(-0.7, 2.7, m)            # includes layers outside [0, 2] (clamped)
    lod = rng.uniform(-2, len(levels) + 1, m)  # includes lods outside the chain (clamped)
    got = run_glsl(gl_ctx, "o[i] = textureLod(probes, vec4(d[i].xyz, d[i].w), l[i].x);",
                   {"d": np.c_[d, lay], "l": lod}, {"o": 4}, probes=tex)["o"]
    tex.release()
    np.testing.assert_allclose(got, cs.sample_cube_array(levels, d, lay, lod), rtol=0, atol=_tol(n))


@pytest.mark.parametrize("n", [1, 3, 8])
def test_cube_edges_and_corners_match_gl(gl_ctx, n):
    """Directions on face edges and cube corners, where the 2x2 footprint leaves the face."""
    rng = np.random.default_rng(10 + n)
    levels = _levels(rng, n)[:1]
    tex = cube_texture(gl_ctx, levels)
    s = np.array([-1.0, 1.0])
    corners = np.stack(np.meshgrid(s, s, s, indexing="ij"), -1).reshape(-1, 3)
    u = rng.uniform(-1, 1, 200)
    edges = []
    for k in range(3):
        for a in s:
            for b in s:
                e = np.empty((u.size, 3))
                o1, o2 = [j for j in range(3) if j != k]
                e[:, k], e[:, o1], e[:, o2] = u, a, b
                edges.append(e)
    near_corner = corners[:, None, :] + rng.uniform(-0.3, 0.3, (8, 50, 3)) / max(n, 1)
    d = np.concatenate([corners, np.concatenate(edges), near_corner.reshape(-1, 3), np.eye(3), -np.eye(3)])
    got = run_glsl(gl_ctx, "o[i] = textureLod(sky, d[i].xyz, 0.0);", {"d": d}, {"o": 4}, sky=tex)["o"]
    tex.release()
    np.testing.assert_allclose(got, cs.sample_cube(levels, d), rtol=0, atol=_tol(n))


def test_hand_cases():
    n = 4
    const = [np.full((6, n >> k, n >> k, 2), 2.5) for k in range(3)]
    d = np.random.default_rng(0).normal(size=(1000, 3))
    np.testing.assert_allclose(cs.sample_cube(const, d, np.linspace(-1, 4, 1000)), 2.5, rtol=1e-12)
    # at a texel center, level 0 returns that texel exactly
    data = np.random.default_rng(1).random((6, n, n, 1))
    dirs = cube.texel_directions(n)
    np.testing.assert_allclose(cs.sample_cube([data], dirs.reshape(-1, 3)).reshape(data.shape), data, atol=1e-12)
    # at a cube corner the value is the mean of the three texels meeting there
    one = np.random.default_rng(2).random((6, 1, 1, 1))
    got = cs.sample_cube([one], np.array([[1.0, 1.0, 1.0]]))
    np.testing.assert_allclose(got[0, 0], one[[0, 2, 4], 0, 0, 0].mean(), atol=1e-12)


def test_bad_inputs_raise():
    lv = [np.zeros((6, 2, 2, 4)), np.zeros((6, 1, 1, 4))]
    with pytest.raises(ValueError, match="NaN"):
        cs.sample_cube(lv, np.array([[1.0, 0, 0]]), np.nan)
    with pytest.raises(ValueError, match="zero-length"):
        cs.sample_cube(lv, np.zeros((1, 3)))
    with pytest.raises(ValueError, match="level 1"):
        cs.sample_cube([np.zeros((6, 4, 4, 4)), np.zeros((6, 1, 1, 4))], np.ones((1, 3)))
