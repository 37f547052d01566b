"""Cubes turned with their street (issue 10: streets at any angle): a capture at yaw a equals a
capture of the scene turned by -a about the probe, and the hand-derived case a = 90 deg."""

import numpy as np
import pytest

from envcap.capture.renderer import CubeCapture
from envcap.core.street_frame import from_frame, plan_rotation, to_frame
from envcap.scene.model import SceneMesh
from envcap.scene.synthetic import box, quad

PROBE = np.array([3.0, 2.0, -1.0])


def _scene() -> SceneMesh:
    parts = [quad((-20, 0, -20), (0, 0, 40), (40, 0, 0), emission=(1.0, 1.0, 1.0)),          # ground, facing up
             box((8, 0, -6), (12, 9, 4), emission=(5.0, 1.0, 0.5)),
             box((-9, 0, -4), (-4, 15, 3), emission=(0.5, 4.0, 1.0)),
             box((0, 0, 7), (6, 6, 11), emission=(1.0, 0.5, 6.0))]
    return SceneMesh.concatenate(parts)


def _turned(mesh: SceneMesh, rotation: np.ndarray) -> SceneMesh:
    world = mesh.positions.astype(np.float64) + mesh.origin
    pos = (world - PROBE) @ rotation.T + PROBE
    return SceneMesh.from_world(pos, mesh.normals @ rotation.T.astype(np.float32), mesh.albedo, mesh.emission,
                                mesh.indices)


@pytest.mark.parametrize("yaw", [31.0, -117.5])
def test_a_turned_cube_sees_the_scene_turned_the_other_way(gl_ctx, yaw: float) -> None:
    mesh = _scene()
    with CubeCapture(mesh, 32, ctx=gl_ctx, effects={"emissive_windows"}) as cap:
        turned_cam = cap.capture(PROBE, yaw_deg=yaw)
    with CubeCapture(mesh, 32, ctx=gl_ctx, effects={"emissive_windows"}, cull_chunks=False) as cap:
        turned_cam_unculled = cap.capture(PROBE, yaw_deg=yaw)
    with CubeCapture(_turned(mesh, plan_rotation(yaw)), 32, ctx=gl_ctx, effects={"emissive_windows"}) as cap:
        turned_scene = cap.capture(PROBE)
    np.testing.assert_array_equal(turned_cam.rgba, turned_cam_unculled.rgba)   # culling follows the turn
    close = np.isclose(turned_cam.rgba, turned_scene.rgba, rtol=1e-4, atol=1e-4).all(axis=-1)
    assert close.mean() > 0.99, f"{1 - close.mean():.2%} of texels differ"   # only rasterization at edges
    assert np.abs(turned_cam.distance - turned_scene.distance)[close].max() < 1e-3


def test_at_90_degrees_the_cube_x_face_looks_along_world_z(gl_ctx) -> None:
    wall = quad((-2, -2, 10), (0, 4, 0), (4, 0, 0), emission=(3.0, 2.0, 1.0))   # facing -Z, 10 m along +Z
    with CubeCapture(wall, 16, ctx=gl_ctx, effects={"emissive_windows"}) as cap:
        plain = cap.capture((0.0, 0.0, 0.0))
        turned = cap.capture((0.0, 0.0, 0.0), yaw_deg=90.0)
    np.testing.assert_allclose(plain.rgba[4, 8, 8, :3], (3.0, 2.0, 1.0))      # +Z face, world frame
    np.testing.assert_allclose(turned.rgba[0, 8, 8, :3], (3.0, 2.0, 1.0))     # +X of the frame = world +Z
    assert turned.rgba[4, ..., 3].max() == 0.0
    np.testing.assert_allclose(to_frame([0.0, 0.0, 1.0], 90.0), [1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(from_frame(to_frame([0.3, 0.4, 0.5], 23.0), 23.0), [0.3, 0.4, 0.5], atol=1e-15)
    with pytest.raises(ValueError, match="finite"):
        plan_rotation(float("nan"))
