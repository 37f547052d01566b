"""The lit crowd per density (``envcap/evaluate/crowd_placement.py``, ``crowd_accuracy.py``,
``envcap bench crowd_accuracy``), checked against independent references:

* placement: the same seed gives the same crowd, another seed another; the neighbour count is
  density x area (the area of a disc cut by a half-plane against the circular segment's closed
  form); every spacing and clearance holds; headings go both ways along the street; too dense is
  refused;
* self points: the point lies ``SELF_OFFSET_M`` off the posed walker's surface along its normal
  (a float64 ray cast of the posed triangles back along the normal, written here); a point at a
  capsule's axis is inside the body, one a metre off is not;
* the quick benchmark: its JSON has every density x kind x term x material x static; at density 0
  the neighbours add nothing (``+self+neighbours`` equals ``+self`` exactly), and with neighbours
  the last term differs.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from envcap.cli import main
from envcap.evaluate.crowd_accuracy import SELF_OFFSET_M, TERMS, evaluation_points, site_avatars
from envcap.evaluate.crowd_placement import (
    HEADING_JITTER_DEG,
    HOST_CLEARANCE_M,
    POINT_CLEARANCE_M,
    SPACING_M,
    disc_area,
    inside_body,
    place_crowd,
)
from envcap.evaluate.dynamic_avatars import walker_path
from envcap.evaluate.shading import MATERIALS

C = (10.0, 0.0, -1.0)


def test_placement_is_seeded_and_respects_density_and_spacing():
    a = place_crowd(C, 0.5, heading_deg=90.0, phases=(0.0, 0.25, 0.5, 0.75), seed=3, radius=4.0, free_points=2)
    b = place_crowd(C, 0.5, heading_deg=90.0, phases=(0.0, 0.25, 0.5, 0.75), seed=3, radius=4.0, free_points=2)
    other = place_crowd(C, 0.5, heading_deg=90.0, phases=(0.0, 0.25, 0.5, 0.75), seed=4, radius=4.0, free_points=2)
    assert a.walkers == b.walkers and np.array_equal(a.free_xz, b.free_xz)
    assert a.walkers != other.walkers
    assert len(a.neighbours) == round(0.5 * math.pi * 16)          # 25 walkers on 50.3 m^2
    feet = np.array([w.root_xz for w in a.walkers])
    gaps = np.linalg.norm(feet[:, None] - feet[None], axis=-1) + np.eye(len(feet)) * 99
    assert gaps.min() >= SPACING_M
    assert np.linalg.norm(feet[1:] - [C[0], C[2]], axis=1).min() >= HOST_CLEARANCE_M
    assert np.linalg.norm(feet[1:] - [C[0], C[2]], axis=1).max() <= 4.0
    for f in a.free_xz:
        assert np.linalg.norm(feet[1:] - f, axis=1).min() >= POINT_CLEARANCE_M
        assert np.linalg.norm(f - [C[0], C[2]]) <= 2.0
    dev = np.array([(w.yaw_deg - 90.0 + 90.0) % 180.0 - 90.0 for w in a.walkers])   # from the nearest of 90 / 270
    assert np.abs(dev).max() <= HEADING_JITTER_DEG
    ways = np.array([math.cos(math.radians(w.yaw_deg - 90.0)) > 0 for w in a.walkers])
    assert 0 < ways.sum() < len(ways)                                  # both ways along the street
    assert {w.time for w in a.walkers} == {0.0, 0.25, 0.5, 0.75}
    # the host and the free points do not depend on the density
    dense = place_crowd(C, 1.0, heading_deg=90.0, phases=(0.0, 0.25, 0.5, 0.75), seed=3, radius=4.0, free_points=2)
    assert dense.host == a.host and np.array_equal(dense.free_xz, a.free_xz) and len(dense.neighbours) == 50
    assert place_crowd(C, 0.0, heading_deg=90.0, phases=(0.0, 0.25, 0.5, 0.75), seed=3).neighbours == ()


def test_density_counts_the_area_on_the_street_and_too_dense_is_refused():
    # a half-plane 1 m from the centre cuts the disc (r = 4): area = pi r^2 - segment(h = r - 1)
    r, dist = 4.0, 1.0
    segment = r * r * math.acos(dist / r) - dist * math.sqrt(r * r - dist * dist)
    on_street = math.pi * r * r - segment

    def inside(xz):
        return np.asarray(xz)[:, 1] <= C[2] + dist
    assert disc_area((C[0], C[2]), r, inside) == pytest.approx(on_street, rel=5e-3)
    site = place_crowd(C, 0.5, heading_deg=90.0, phases=(0.0, 0.25, 0.5, 0.75), seed=0, radius=r, inside=inside)
    assert len(site.neighbours) == round(0.5 * site.area)
    assert all(w.root_xz[1] <= C[2] + dist for w in site.neighbours)
    with pytest.raises(ValueError, match="too high to place"):
        place_crowd(C, 8.0, heading_deg=90.0, phases=(0.0, 0.25, 0.5, 0.75), seed=0, radius=1.5)
    with pytest.raises(ValueError, match="density"):
        place_crowd(C, -1.0, heading_deg=90.0, phases=(0.0, 0.25, 0.5, 0.75), seed=0)


def first_hit(origin, direction, positions, triangles):
    """Distance along the ray to the nearest triangle (both faces; inf: none), float64."""
    tri = positions[triangles]
    best = np.inf
    for a, b, c in tri:
        e1, e2 = b - a, c - a
        p = np.cross(direction, e2)
        det = e1 @ p
        if abs(det) < 1e-14:
            continue
        s = origin - a
        u = (s @ p) / det
        q = np.cross(s, e1)
        v = (direction @ q) / det
        t = (e2 @ q) / det
        if u >= 0 and v >= 0 and u + v <= 1 and t > 0:
            best = min(best, t)
    return best


def test_self_points_lie_on_the_walker_surface():
    site = place_crowd(C, 0.0, heading_deg=90.0, phases=(0.0, 0.25, 0.5, 0.75), seed=5, free_points=1)
    host = site_avatars(site, lambda root: 0.25, str(walker_path()))[0]
    pts = evaluation_points(site, host, lambda root: 0.25, 3)
    selfs = [(v, x, n) for kind, v, x, n in pts if kind == "self"]
    assert len(selfs) == 3 and [k for k, *_ in pts].count("free") == 1
    m = host.mesh
    for v, x, n in selfs:
        assert np.allclose(x - SELF_OFFSET_M * n, m.positions[v])
        assert 0.3 <= m.positions[v][1] - 0.25 <= 1.7
        # back along the normal the body's surface is SELF_OFFSET_M away (the vertex itself, or a
        # triangle of its fan within a millimetre of the smooth normal's plane)
        assert first_hit(x, -n, m.positions, m.triangles) == pytest.approx(SELF_OFFSET_M, abs=2e-3)
    free = [x for kind, _, x, _ in pts if kind == "free"][0]
    assert free[1] == pytest.approx(1.25)
    hips = host.bone_centers[np.argmax(host.bone_radii)]              # the torso's sphere centre: inside it
    assert inside_body(hips, np.array([0.0, 1.0, 0.0]), m.positions, m.normals, m.triangles)
    assert not inside_body(hips + [0.0, 0.0, 1.0], np.array([0.0, 0.0, 1.0]), m.positions, m.normals, m.triangles)


@pytest.mark.slow
def test_quick_bench_has_every_cell_and_density_zero_adds_nothing(tmp_path):
    assert main(["bench", "crowd_accuracy", "--quick", "--out", str(tmp_path / "b")]) == 0
    res = json.loads((tmp_path / "b" / "crowd_accuracy.json").read_text())
    assert {p.name for p in (tmp_path / "b").iterdir()} - {".envcap-output"} == {"crowd_accuracy.json", "crowd_accuracy.md",
                                                            "crowd_accuracy.png"}
    cells = {(s["density"], s["kind"], s["term"], s["material"], s["static"]) for s in res["summary"]}
    want = {(d, k, t, m.name, st) for d in res["densities"] for k, terms in TERMS.items() for t in terms
            for m in MATERIALS for st in ("probes", "oracle")}
    assert cells == want
    assert all(np.isfinite(r["rel_err"]) for r in res["rows"])
    key = ("site", "point", "static", "material")
    by = {}
    for r in res["rows"]:
        by.setdefault((r["density"], r["term"]) + tuple(r[k] for k in key), r["rel_err"])
    zero = [k for k in by if k[0] == 0.0 and k[1] == "+self"]
    assert zero and all(by[(0.0, "+self+neighbours") + k[2:]] == by[k] for k in zero)
    dense = [k for k in by if k[0] == 0.5 and k[1] == "+self"]
    assert any(by[(0.5, "+self+neighbours") + k[2:]] != by[k] for k in dense)
    assert all(r["neighbours"] == 0 for r in res["rows"] if r["density"] == 0.0)
    assert "PASS" in (tmp_path / "b" / "crowd_accuracy.md").read_text() or "FAIL" in res["goal"][0]
