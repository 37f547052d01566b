"""Dynamic occluders on a street that follows the terrain (review of issue 10): the occluder
report's shading points and the avatars around them stand on the ground under them (the nearest
probe's ground plane with its slope, along the street's own frame), not on the street's nominal
ground 0 (a plateau 50 m up put them 50 m under the terrain)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from terrain_manifest import ORIGIN, PROBE_S, along_unit, hand_ground, terrain_manifest

from envcap.evaluate.dynamic_avatars import (
    AvatarRing,
    Crowd,
    crowd_avatars,
    load_rigged,
    walker_path,
)
from envcap.evaluate.occluder_report import occluder_positions
from envcap.evaluate.sweep import street_extent

# plateau 50 m up; a slope of 0.5 continuous between the probes (52.5 at the second); steps; turned
CASES = [((50.0, 50.0), (0.0, 0.0), 0.0), ((50.0, 52.5), (0.5, 0.5), 0.0), ((10.0, 12.5), (0.0, 0.0), 0.0),
         ((50.0, 52.5), (0.5, 0.5), 37.0)]


@pytest.mark.parametrize("grounds,slopes,yaw", CASES)
def test_occluder_positions_stand_on_the_ground_under_them(grounds, slopes, yaw):
    m = terrain_manifest(grounds, slopes, yaw)
    name, pts = occluder_positions(m, 1.5)
    assert name == "main" and len(pts) == 2
    o = np.array(ORIGIN) if yaw else np.zeros(2)
    s = [float((np.array(p)[[0, 2]] - o) @ along_unit(yaw)) for p in pts]
    assert s == pytest.approx([PROBE_S[1], 0.5 * (PROBE_S[0] + PROBE_S[1])], abs=1e-9)   # probe 1, half way to 0
    for p in pts:
        assert p[1] == pytest.approx(hand_ground(np.array(p), grounds, slopes, yaw) + 1.5, abs=1e-9)
    if grounds == (50.0, 50.0):
        assert [p[1] for p in pts] == [51.5, 51.5]


def test_the_canyon_on_its_nominal_ground_keeps_todays_positions():
    flat = terrain_manifest((0.0, 0.0), (0.0, 0.0))
    assert [p[1] for p in occluder_positions(flat, 1.0)[1]] == [1.0, 1.0]
    with pytest.raises(ValueError, match="no street named 'side'"):
        street_extent(flat, "side")


@pytest.mark.parametrize("yaw", [0.0, 37.0])
def test_avatars_stand_on_the_ground_under_their_feet(yaw):
    grounds, slopes = (50.0, 52.5), (0.5, 0.5)
    m = terrain_manifest(grounds, slopes, yaw)
    o = np.array(ORIGIN) if yaw else np.zeros(2)
    xz = o + PROBE_S[0] * along_unit(yaw)
    x = np.array([xz[0], 51.0, xz[1]])
    avatar, proxies = load_rigged(str(walker_path()))
    ring = AvatarRing(4, 1.5)
    crowd = Crowd((ring,))
    on_terrain = crowd_avatars(crowd, x, street_extent(m, "main").ground_under, avatar, proxies)
    at_zero = crowd_avatars(crowd, x, 0.0, avatar, proxies)
    for i, (a, b) in enumerate(zip(on_terrain, at_zero)):
        az = math.radians(ring.azimuth_deg) + 2 * math.pi * i / ring.count      # the ring's feet, by hand
        root = x + ring.distance * np.array([math.cos(az), 0.0, math.sin(az)])
        lift = hand_ground(root, grounds, slopes, yaw)
        assert 49.0 < lift < 51.0
        shift = a.mesh.positions - b.mesh.positions
        np.testing.assert_allclose(shift, np.tile([0.0, lift, 0.0], (len(shift), 1)), atol=1e-9)
        np.testing.assert_allclose(a.one.center - b.one.center, [0.0, lift, 0.0], atol=1e-9)
