"""The precision benchmark's scene mover and probe line on a street given by its ends (review of
issue 10: a ``p0``/``p1`` street got ``along_center`` and ``cross`` keys, a parse error, and its
probes were placed on world axes instead of along the street)."""

import math

import numpy as np

from envcap.benchmarks.precision import offset_scene_dict, street_probes
from envcap.scene import scene_from_dict

DOC = {"name": "turned", "effects": [], "sky": {"type": "uniform", "radiance": 1.0},
       "streets": [{"name": "d", "p0": [10.0, -4.0], "p1": [40.0, 48.0], "width": 12.0, "cross": 1.0}],
       "mesh": [{"path": "a.ply", "offset": [1.0, 2.0, 3.0], "crop": {"min": [0.0, -1.0, 0.0], "max": [5.0, 9.0, 6.0]}}]}
D = (1e6 + 123.456, 1e6 - 77.7)


def test_a_street_by_its_ends_moves_with_its_ends_and_its_probes_lie_along_it():
    moved = offset_scene_dict(DOC, *D)
    assert moved["streets"][0] == {**DOC["streets"][0], "p0": [10.0 + D[0], -4.0 + D[1]], "p1": [40.0 + D[0], 48.0 + D[1]]}
    mesh = moved["mesh"][0]
    assert mesh["offset"] == [1.0 + D[0], 2.0, 3.0 + D[1]]
    assert mesh["crop"] == {"min": [D[0], -1.0, D[1]], "max": [5.0 + D[0], 9.0, 6.0 + D[1]]}
    streets_only = {k: v for k, v in DOC.items() if k != "mesh"}          # no mesh files here
    a, b = scene_from_dict(streets_only), scene_from_dict({k: v for k, v in moved.items() if k != "mesh"})
    pa, pb = street_probes(a, 8), street_probes(b, 8)
    np.testing.assert_allclose(pb - pa, np.tile([D[0], 0.0, D[1]], (8, 1)), atol=1e-6)
    # hand-derived: along the unit direction of p1 - p0, across it by the centre line's +-1/3 width
    u = np.array([30.0, 52.0]) / math.hypot(30.0, 52.0)
    rel = pa[:, [0, 2]] - np.array([10.0, -4.0])
    along, across = rel @ u, rel @ np.array([-u[1], u[0]])
    length = math.hypot(30.0, 52.0)
    np.testing.assert_allclose(along, length * (np.arange(8) + 0.5) / 8, atol=1e-9)
    assert np.all(np.abs(across - 1.0) <= 12.0 / 3 + 1e-9)
