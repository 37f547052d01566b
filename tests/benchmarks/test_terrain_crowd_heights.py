"""The dynamic-street benchmark's shading points on a street that follows the terrain (review of
issue 10): :data:`HEIGHT_M` (spheres) and :data:`AVATAR_POINT_HEIGHT_M` (avatars) above the ground
under each point (the nearest probe's ground plane with its slope, along the street's frame), not
at absolute heights (a plateau 50 m up put them under the terrain)."""

from __future__ import annotations

import numpy as np
import pytest
from terrain_manifest import hand_ground, terrain_manifest

from envcap.benchmarks.dynamic_street import HEIGHT_M, crowd_positions
from envcap.benchmarks.dynamic_street_avatars import (
    AVATAR_POINT_HEIGHT_M,
    avatar_points,
)

CASES = [((50.0, 50.0), (0.0, 0.0), 0.0), ((50.0, 52.5), (0.5, 0.5), 0.0), ((10.0, 12.5), (0.0, 0.0), 0.0),
         ((50.0, 52.5), (0.5, 0.5), 37.0), ((-3.0, 4.0), (0.25, -0.75), 37.0)]


@pytest.mark.parametrize("grounds,slopes,yaw", CASES)
def test_crowd_and_avatar_points_stand_above_the_ground_under_them(grounds, slopes, yaw):
    m = terrain_manifest(grounds, slopes, yaw)
    pts = crowd_positions(m, 6, 5.0)
    for p in pts:
        assert p[1] == pytest.approx(hand_ground(np.array(p), grounds, slopes, yaw) + HEIGHT_M, abs=1e-9)
    lifted = avatar_points(m, "main", pts)
    for p, q in zip(pts, lifted):
        assert (q[0], q[2]) == (p[0], p[2])
        assert q[1] == pytest.approx(hand_ground(np.array(p), grounds, slopes, yaw) + AVATAR_POINT_HEIGHT_M, abs=1e-9)
    if grounds == (50.0, 50.0):
        assert {p[1] for p in pts} == {50.0 + HEIGHT_M} and {q[1] for q in lifted} == {50.0 + AVATAR_POINT_HEIGHT_M}


def test_a_street_on_its_nominal_ground_keeps_todays_heights():
    m = terrain_manifest((0.0, 0.0), (0.0, 0.0))
    assert {p[1] for p in crowd_positions(m, 6, 20.0)} == {HEIGHT_M}
    assert {q[1] for q in avatar_points(m, "main", [[1.0, 7.0, 2.0]])} == {AVATAR_POINT_HEIGHT_M}
