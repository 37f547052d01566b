"""The cube convention of envcap.core.cube, checked against the OpenGL sampler itself."""

import numpy as np
import pytest

from envcap.core import cube
from envcap.gpu.cube_array import CubeArrayTexture, cube_texture
from gl_sampling import SAMPLE_CUBE, SAMPLE_CUBE_ARRAY, sample_with_gl


def _index_cube(n, layers=1):
    """Cube(s) whose texels hold (face, row, col, layer) exactly."""
    f, r, c = np.meshgrid(np.arange(6), np.arange(n), np.arange(n), indexing="ij")
    one = np.stack([f, r, c, np.zeros_like(f)], axis=-1).astype(np.float32)
    return np.stack([one + np.array([0, 0, 0, layer], np.float32) for layer in range(layers)])


@pytest.mark.parametrize("n", [1, 2, 5, 16])
def test_samplercube_returns_every_texel_at_its_center_direction(gl_ctx, n):
    data = _index_cube(n)[0]
    tex = cube_texture(gl_ctx, [data])
    dirs = cube.texel_directions(n).reshape(-1, 3)
    d4 = np.concatenate([dirs, np.zeros((dirs.shape[0], 1))], axis=1)
    linear = sample_with_gl(gl_ctx, SAMPLE_CUBE, d4, tex.use)
    tex.filter = (0x2600, 0x2600)  # GL_NEAREST
    nearest = sample_with_gl(gl_ctx, SAMPLE_CUBE, d4, tex.use)
    tex.release()
    np.testing.assert_array_equal(nearest, data.reshape(-1, 4))
    # Bilinear at a texel center returns that texel, up to float32 rounding of (s, t).
    np.testing.assert_allclose(linear, data.reshape(-1, 4), rtol=0, atol=1e-5 * n)


def test_cube_map_array_layers_and_faces_match_convention(gl_ctx):
    n, layers = 8, 3
    data = _index_cube(n, layers)
    tex = CubeArrayTexture([data], filter="nearest")
    dirs = cube.texel_directions(n).reshape(-1, 3)
    d4 = np.concatenate(
        [np.concatenate([dirs, np.full((dirs.shape[0], 1), layer)], axis=1) for layer in range(layers)]
    )
    got = sample_with_gl(gl_ctx, SAMPLE_CUBE_ARRAY, d4, tex.use)
    back = tex.read(0)
    tex.release()
    np.testing.assert_array_equal(got, data.reshape(-1, 4))
    np.testing.assert_array_equal(back, data)


def test_direction_to_texel_agrees_with_gl_at_random_directions(gl_ctx):
    n = 16
    data = _index_cube(n)[0]
    tex = cube_texture(gl_ctx, [data])
    tex.filter = (0x2600, 0x2600)  # GL_NEAREST: GL picks the texel that contains the direction
    rng = np.random.default_rng(1)
    dirs = rng.normal(size=(20000, 3))
    face, row, col = cube.direction_to_texel(dirs, n)
    # Stay away from texel borders, where float32 rounding may pick either neighbour.
    _, s, t = cube.direction_to_face_st(dirs)
    inner = (np.abs(s * n - np.round(s * n)) > 1e-3) & (np.abs(t * n - np.round(t * n)) > 1e-3)
    d4 = np.concatenate([dirs, np.zeros((dirs.shape[0], 1))], axis=1)[inner]
    got = sample_with_gl(gl_ctx, SAMPLE_CUBE, d4, tex.use)
    tex.release()
    want = np.stack([face, row, col], axis=-1)[inner]
    np.testing.assert_array_equal(got[:, :3], want)
