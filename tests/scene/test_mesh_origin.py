"""SceneMesh.origin: float32 positions relative to a float64 origin near the geometry.

References: hand-computed origins, float64 world coordinates, and the float32 rounding bound
``2^-24 |x|`` of a coordinate ``x`` relative to the origin.
"""

import numpy as np
import pytest

from envcap.scene.model import ORIGIN_GRID_M, SceneMesh, local_origin


def _quad(center, size=10.0):
    """One quad (2 triangles) in the y = 0 plane around ``center`` (x, z), float64 world."""
    cx, cz = center
    h = size / 2
    pos = np.array([[cx - h, 0, cz - h], [cx + h, 0, cz - h], [cx + h, 0, cz + h], [cx - h, 0, cz + h]], np.float64)
    one = np.ones((4, 3))
    return pos, one * [0, 1, 0], 0.5 * one, 0 * one, np.array([[0, 1, 2], [0, 2, 3]], np.uint32)


def test_local_origin_rounds_the_box_center_to_whole_kilometers():
    assert ORIGIN_GRID_M == 1000.0
    np.testing.assert_array_equal(local_origin([-300, 0, -20], [300, 48, 20]), [0, 0, 0])
    np.testing.assert_array_equal(local_origin([999_700, 0, 999_990], [1_000_300, 48, 1_000_010]), [1e6, 0, 1e6])
    np.testing.assert_array_equal(local_origin([-1_000_600, 0, 0], [-1_000_000, 0, 0]), [-1_000_000, 0, 0])
    o = local_origin([-400, -10, -1], [0, 0, 1])
    assert not np.signbit(o).any()  # no -0.0


def test_near_the_origin_positions_are_the_absolute_float32_ones():
    """Scenes centered within 500 m of the world origin keep origin 0 and exactly the float32
    positions they had before origins existed (their bakes are byte-identical)."""
    pos, *rest = _quad((123.456, -77.7))
    m = SceneMesh.from_world(pos, *rest)
    np.testing.assert_array_equal(m.origin, [0, 0, 0])
    np.testing.assert_array_equal(m.positions, pos.astype(np.float32))
    assert m.positions.dtype == np.float32 and m.origin.dtype == np.float64


def test_far_from_the_origin_positions_keep_the_precision_of_their_own_size():
    pos, *rest = _quad((1e6 + 123.456, 1e6 - 77.7))
    m = SceneMesh.from_world(pos, *rest)
    np.testing.assert_array_equal(m.origin, [1e6, 0, 1e6])
    world = m.origin + m.positions.astype(np.float64)
    err = np.abs(world - pos).max()
    assert err <= 2.0 ** -24 * 130  # float32 rounding of coordinates <= 130 m from the origin
    assert np.abs(pos.astype(np.float32).astype(np.float64) - pos).max() > 1e-3  # absolute float32: cm
    lo, hi = m.world_bounds()
    np.testing.assert_allclose(lo, pos.min(0), atol=1e-5)
    np.testing.assert_allclose(hi, pos.max(0), atol=1e-5)


def test_rebased_and_concatenate_keep_world_positions():
    a = SceneMesh.from_world(*_quad((1e6 + 20.0, 1e6)))
    b = SceneMesh.from_world(*_quad((1e6 + 900.0, 1e6)))   # center rounds to 1_001_000 m
    np.testing.assert_array_equal(b.origin, [1_001_000, 0, 1e6])
    assert a.rebased(a.origin) is a
    both = SceneMesh.concatenate([a, b])
    np.testing.assert_array_equal(both.origin, [1e6, 0, 1e6])  # joint box center x = 1_000_460 m
    world = both.origin + both.positions.astype(np.float64)
    expect = np.concatenate([a.origin + a.positions, b.origin + b.positions])
    np.testing.assert_allclose(world, expect, rtol=0, atol=2.0 ** -24 * 1024)
    np.testing.assert_array_equal(both.indices, [[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    same = SceneMesh.concatenate([a, a])  # one origin: positions kept bit for bit
    np.testing.assert_array_equal(same.origin, a.origin)
    np.testing.assert_array_equal(same.positions[:4], a.positions)


def test_origin_is_checked():
    pos, *rest = _quad((0.0, 0.0))
    with pytest.raises(ValueError, match="origin"):
        SceneMesh(pos.astype(np.float32), *(np.asarray(r, np.float32) for r in rest[:3]), rest[3], origin=[0, np.nan, 0])
    with pytest.raises(ValueError, match="origin"):
        SceneMesh(pos.astype(np.float32), *(np.asarray(r, np.float32) for r in rest[:3]), rest[3], origin=[0, 0])
