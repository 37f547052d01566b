"""Generated buildings keep clear of a street at an angle by its turned roadway, not by the world
box around it (review of issue 10: a 45-degree street 10 m wide removed every building of a
crossing street within its 130 m box)."""

import math

import numpy as np

from envcap.scene import scene_from_dict
from envcap.scene.clearing import turned_span

SIDE = {"random": {"width": [10.0, 10.0], "height": 20.0, "depth": 12.0}}
DOC = {"name": "t", "effects": [], "sky": {"type": "uniform", "radiance": 1.0},
       "streets": [{"name": "a", "axis": "x", "start": -100.0, "end": 100.0, "width": 16.0,
                    "side_min": SIDE, "side_max": SIDE},
                   {"name": "d", "p0": [-60.0, 60.0], "p1": [60.0, -60.0], "width": 10.0}]}


def test_turned_span_of_a_diamond_by_hand():
    diamond = np.array([[0.0, -2.0], [2.0, 0.0], [0.0, 2.0], [-2.0, 0.0]])   # |x| + |z| <= 2
    lo, hi = turned_span(diamond, 0, 1.0, 5.0)               # the strip 1 < z < 5: |x| <= 2 - z
    assert math.isclose(lo, -1.0, abs_tol=1e-5) and math.isclose(hi, 1.0, abs_tol=1e-5)
    lo, hi = turned_span(diamond, 2, -0.5, 0.5)              # along z, strip |x| < 0.5: |z| <= 2
    assert math.isclose(lo, -2.0) and math.isclose(hi, 2.0)
    assert turned_span(diamond, 0, 2.5, 3.0) is None


def test_buildings_stay_out_of_the_turned_roadway_only():
    scene = scene_from_dict(DOC)
    m = scene.mesh
    tri = m.positions[m.indices].astype(np.float64) + m.origin
    c = tri[tri[:, :, 1].max(axis=1) > 0.5].reshape(-1, 3)   # vertices of building triangles (not the ground)
    u = np.array([1.0, -1.0]) / math.sqrt(2.0)                # the diagonal's direction, hand-derived
    rel = c[:, [0, 2]] - [-60.0, 60.0]
    along, across = rel @ u, rel @ np.array([-u[1], u[0]])
    inside = (along > 1e-3) & (along < math.hypot(120, 120) - 1e-3) & (np.abs(across) < 5.0 - 1e-3)
    assert not np.any(inside)
    in_box = (np.abs(c[:, 0]) < 55.0) & (np.abs(c[:, 2]) < 55.0)   # well inside its world box
    assert np.count_nonzero(in_box) > 400                      # the buildings there are kept (600; the box: 0)
