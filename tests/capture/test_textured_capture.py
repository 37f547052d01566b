"""Textured surfaces are captured with their textures: a glTF wall with a 2 x 2 checker
(baseColorTexture) against the same wall untextured, lit by the same sun.  The expected ratio at
each pixel is the checker's linear value where the pixel's ray meets the wall (ray-plane
intersection, independent of the renderer)."""

from pathlib import Path

import numpy as np
import trimesh
from PIL import Image

from envcap.capture.renderer import CubeCapture
from envcap.core import cube
from envcap.core.color import srgb_to_linear
from envcap.scene.mesh_import import import_meshes
from envcap.sky.sun import Sun
from envcap.sky.uniform import UniformSky

CHECKER_SRGB = (60, 230)   # sRGB codes of the two checker cells


def _wall_glb(path: Path, textured: bool) -> None:
    """A 4 m x 4 m wall in the plane z = -3 (glTF is +Y up), facing +Z, UV (0..1, 0..1)."""
    verts = np.array([[-2, 0, -3], [2, 0, -3], [2, 4, -3], [-2, 4, -3]], np.float64)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    img = np.full((64, 64, 3), CHECKER_SRGB[0], np.uint8)
    img[:32, :32] = img[32:, 32:] = CHECKER_SRGB[1]          # image rows top to bottom
    material = trimesh.visual.material.PBRMaterial(baseColorTexture=Image.fromarray(img) if textured else None,
                                                   baseColorFactor=[255, 255, 255, 255])
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float64)
    trimesh.Trimesh(verts, faces, visual=trimesh.visual.TextureVisuals(uv=uv, material=material),
                    process=False).export(path)


def test_a_textured_wall_is_captured_with_its_texture(gl_ctx, tmp_path: Path) -> None:
    sky = UniformSky((0.0, 0.0, 0.0), Sun(np.array([0.0, 0.3, 1.0]), np.array([1e5, 1e5, 1e5])))
    images = {}
    for textured in (True, False):
        path = tmp_path / f"wall_{textured}.glb"
        _wall_glb(path, textured)
        mesh, _ = import_meshes([path])
        assert mesh.textured == textured
        with CubeCapture(mesh, 32, ctx=gl_ctx, sky=sky, effects={"sun_light"}) as cap:
            images[textured] = cap.capture((0.0, 2.0, 0.0)).rgba
    face = 5                                                   # -Z: the wall
    n = 32
    d = cube.texel_directions(n)[face]                       # [row = t, column = s], OpenGL face order
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    hit = np.array([0.0, 2.0, 0.0]) + d * (-3.0 / d[..., 2:3])  # ray meets z = -3
    u, v = (hit[..., 0] + 2.0) / 4.0, hit[..., 1] / 4.0        # the wall's UV (v up, OpenGL)
    on_wall = (u > 0) & (u < 1) & (v > 0) & (v < 1)
    cell = (np.floor(u * 2) + np.floor(v * 2)) % 2             # 0: bottom-left cell
    away = (np.minimum(np.abs(u * 2 - np.round(u * 2)), np.abs(v * 2 - np.round(v * 2))) > 0.15) & on_wall
    # image row 0 is the top: the top-left (u < .5, v > .5) and bottom-right cells are bright
    bright = np.where(cell == 1, 1, 0)
    expected = srgb_to_linear(np.where(bright == 1, CHECKER_SRGB[1], CHECKER_SRGB[0]) / 255.0)
    ratio = images[True][face, ..., 1] / np.maximum(images[False][face, ..., 1], 1e-30)
    assert away.sum() > 100
    np.testing.assert_allclose(ratio[away], expected[away], rtol=0.02)
    assert np.all(images[False][face, ..., 1][away] > 0)
