"""Street frame positions (issue 10): ``world_to_frame`` / ``frame_to_world`` against hand-derived
points, their round trip far from the origin, the exact identity at yaw 0, and clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from envcap.core.street_frame import frame_to_world, plan_rotation, world_to_frame


def test_world_to_frame_against_hand_derived_points():
    # Street from p0 = (10, 5) at 90 deg (towards +z): the world point (10, 7, 8) is 3 m along, 0 across.
    assert np.allclose(world_to_frame([10.0, 7.0, 8.0], 90.0, (10.0, 5.0)), [3.0, 7.0, 0.0], atol=1e-12)
    # 30 deg: the unit direction (cos 30, sin 30) is frame +x; its left normal (-sin, cos) frame +z.
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    w = np.array([[1 + 2 * c - 4 * s, 0.5, -2 + 2 * s + 4 * c]])
    assert np.allclose(world_to_frame(w, 30.0, (1.0, -2.0)), [[2.0, 0.5, 4.0]], atol=1e-12)
    rng = np.random.default_rng(3)
    pts = rng.normal(size=(20, 3)) * 1e3
    assert np.allclose(frame_to_world(world_to_frame(pts, -123.4, (5e5, -7e5)), -123.4, (5e5, -7e5)), pts, atol=1e-8)
    assert np.array_equal(world_to_frame(pts, 0.0), pts)
    for bad in ((float("nan"), (0.0, 0.0)), (10.0, (0.0, float("inf"))), (10.0, (1.0, 2.0, 3.0))):
        with pytest.raises(ValueError, match="street"):
            world_to_frame(pts, *bad)


def test_frame_axes_are_the_street_direction_and_its_left_normal():
    r = plan_rotation(37.0)
    a = np.radians(37.0)
    assert np.allclose(r @ [np.cos(a), 0.0, np.sin(a)], [1.0, 0.0, 0.0], atol=1e-15)
    assert np.allclose(r @ [-np.sin(a), 0.0, np.cos(a)], [0.0, 0.0, 1.0], atol=1e-15)
    assert np.allclose(frame_to_world([[0.0, 0.0, 1.0]], 37.0, (0.0, 0.0)), [[-np.sin(a), 0.0, np.cos(a)]], atol=1e-15)
