"""Streets at any angle, baked (issue 10): a framed street in a scene turned by its yaw gives the
probes and planes of the same street built along X (its frame), and sloped terrain gives each
probe the terrain's slope along the street, nominal and fitted, against the hand-derived slope."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import trimesh

from envcap.core.street_frame import frame_to_world
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.placement import slope_step
from envcap.scene import scene_from_dict
from envcap.scene.model import SceneMesh, Street

YAW, ORIGIN = 33.0, (50.0, -20.0)
RES = 16


def _axis_scene():
    """A street along X (-20..20 m, 12 m wide) between two checkered walls, over a checkered
    ground, lit by a uniform sky: the street in its own frame."""
    wall = {"height": 10.0, "tile": 2.0, "albedo": [0.7, 0.25, 0.2], "albedo2": [0.15, 0.2, 0.6]}
    return scene_from_dict({
        "name": "axis", "effects": ["sky_light"], "sky": {"type": "uniform", "radiance": 1.0},
        "ground": {"albedo": 0.5, "albedo2": 0.1, "checker": 2.0, "checker_extent": 80.0, "extent": 300.0},
        "streets": [{"name": "main", "axis": "x", "start": -20.0, "end": 20.0, "width": 12.0, "cross": 1.0,
                     "side_min": {"wall": wall}, "side_max": {"wall": dict(wall, albedo=[0.2, 0.6, 0.25])}}]})


def _turned(scene, other_street: Street):
    """``scene`` turned to the world of a street at YAW from ORIGIN: mesh positions and normals
    by ``frame_to_world``, the street framed (same frame coordinates), and ``other_street`` added
    (a world-frame street: the bake then captures runs of two yaws)."""
    m = scene.mesh
    world = frame_to_world(m.positions.astype(np.float64) + m.origin, YAW, ORIGIN)
    normals = frame_to_world(m.normals.astype(np.float64), YAW, (0.0, 0.0))
    mesh = SceneMesh.from_world(world, normals, m.albedo, m.emission, m.indices)
    st = dataclasses.replace(scene.streets[0], yaw_deg=YAW, origin_xz=ORIGIN)
    return dataclasses.replace(scene, name="turned", mesh=mesh, streets=[st, other_street])


def test_a_framed_street_in_a_turned_scene_bakes_as_the_street_along_x(gl_ctx):
    axis = _axis_scene()
    other = Street("other", "z", -30.0, -10.0, 80.0, 90.0)
    turned = _turned(axis, other)
    a = bake_probe_set(axis, resolution=RES, spacing=10.0, filter_levels=False, ctx=gl_ctx, progress=False)
    chunks = []
    b = bake_probe_set(turned, resolution=RES, spacing=10.0, filter_levels=False, ctx=gl_ctx, progress=False,
                       on_captured=lambda first, rgba, dist: chunks.append((first, rgba.copy())))
    sa, sb = a.manifest.streets[0], b.manifest.streets[0]
    assert (sb.yaw_deg, sb.origin_xz, sb.axis, sb.start, sb.end, sb.center) == (YAW, ORIGIN, "x", -20.0, 20.0, 1.0)
    assert sb.planes == sa.planes and a.manifest.streets[0].yaw_deg is None
    pa = np.array([p.position for p in sa.probes])
    pb = np.array([p.position for p in sb.probes])
    np.testing.assert_allclose(pb, frame_to_world(pa, YAW, ORIGIN), atol=1e-9)   # world positions of frame points
    assert [p.planes for p in sb.probes] == [p.planes for p in sa.probes]
    # Planes fitted in the frame: the same within the fit's bin (5 cm).
    for qa, qb in zip(sa.probes, sb.probes):
        fa, fb = qa.fitted_planes, qb.fitted_planes
        for name in ("facade_min", "facade_max", "ground"):
            assert getattr(fb, name) == pytest.approx(getattr(fa, name), abs=0.05), (qa.index, name)
        assert fb.ground_slope is None and fa.ground_slope is None
    assert sa.probes[0].fitted_planes.facade_min == pytest.approx(-5.0, abs=0.05)
    # Texels: the framed cube's faces are the frame's axes, so texel (face, t, s) sees what the
    # axis street's texel (face, t, s) sees; only triangle edges rasterized from other float32
    # coordinates may differ.
    n = len(sa.probes)
    la, lb = a.levels[0][:n], b.levels[0][:n]
    diff = np.abs(lb - la).max(axis=-1)
    assert np.mean(diff > 1e-3) < 0.01 and np.median(diff) < 1e-5      # yaw ignored: ~48 % differ
    da, db = a.distance[:n], b.distance[:n]
    assert np.array_equal(np.isfinite(da), np.isfinite(db))
    fin = np.isfinite(da)
    assert np.mean(np.abs(db[fin] - da[fin]) > 1e-3 * da[fin]) < 0.01
    # Two runs of yaws (33 deg, then the world street): every layer reached on_captured, in order.
    assert len(b.manifest.streets[1].probes) >= 1 and b.manifest.streets[1].yaw_deg is None
    got = np.concatenate([c for _, c in sorted(chunks, key=lambda c: c[0])])
    assert [f for f, _ in chunks] == sorted(f for f, _ in chunks) and np.array_equal(got, b.levels[0])


SLOPE = 0.1            # the ramp: y = SLOPE * x (world)
STREET_YAW = 30.0      # the street's direction; its slope along itself is SLOPE * cos(30 deg)


def _ramp(path: Path) -> None:
    xs = np.arange(-100.0, 101.0, 10.0)
    gx, gz = np.meshgrid(xs, xs)
    verts = np.stack([gx.ravel(), SLOPE * gx.ravel(), gz.ravel()], axis=1)
    k = len(xs)
    i = (np.arange(k - 1)[:, None] * k + np.arange(k - 1)[None, :]).ravel()
    faces = np.concatenate([np.stack([i, i + k, i + 1], 1), np.stack([i + 1, i + k, i + k + 1], 1)])
    trimesh.Trimesh(verts, faces, process=False).export(path)


def test_terrain_slope_along_a_framed_street_nominal_and_fitted(tmp_path: Path, gl_ctx) -> None:
    _ramp(tmp_path / "ramp.ply")
    a = math.radians(STREET_YAW)
    p0, p1 = [-20.0, 5.0], [-20.0 + 40.0 * math.cos(a), 5.0 + 40.0 * math.sin(a)]
    doc = {"name": "ramp", "effects": [], "sky": {"type": "uniform", "radiance": 1.0}, "ground": {"enabled": False},
           "mesh": {"file": "ramp.ply"},
           "streets": [{"name": "up", "p0": p0, "p1": p1, "width": 12.0, "follow_terrain": True},
                       {"name": "flat", "p0": p0, "p1": p1, "width": 12.0}]}
    ps = bake_probe_set(scene_from_dict(doc, base_dir=tmp_path), resolution=RES, spacing=10.0, filter_levels=False,
                        ctx=gl_ctx, progress=False)
    up, flat = ps.manifest.streets
    want = SLOPE * math.cos(a)                         # gradient (SLOPE, 0) . direction (cos a, sin a)
    assert len(up.probes) == 4 and slope_step(10.0) == 5.0
    for p in up.probes:
        assert p.position[1] == pytest.approx(SLOPE * p.position[0] + 2.0, abs=1e-4)
        assert p.planes.ground_slope == pytest.approx(want, abs=1e-9)
        f = p.fitted_planes
        assert f.ground_slope == pytest.approx(want, abs=2e-3) and f.ground == pytest.approx(p.planes.ground, abs=0.02)
    assert all(p.planes.ground_slope is None and p.fitted_planes.ground_slope is None for p in flat.probes)


def test_setup_checks_use_the_framed_streets_world_box_and_frame_corridor(tmp_path: Path) -> None:
    from envcap.probeset.street_checks import street_setup_warnings

    for k, b in enumerate([[[-20, 0, 5], [20, 12, 15]], [[-20, 0, -15], [20, 9, -5]]]):
        trimesh.creation.box(bounds=b).export(tmp_path / f"b{k}.ply")

    def warnings(*streets: dict) -> list[str]:
        doc = {"name": "boxes", "effects": [], "sky": {"type": "uniform", "radiance": 1.0}, "ground": {"enabled": False},
               "mesh": {"glob": "*.ply"}, "streets": [{"width": 10.0, **s} for s in streets]}
        return street_setup_warnings(scene_from_dict(doc, base_dir=tmp_path))

    # Between the boxes, given by its ends (framed: origin (-20, 0)): no warning.
    assert warnings({"name": "between", "p0": [-20.0, 0.0], "p1": [20.0, 0.0]}) == []
    # At 90 deg 100 m east: outside the walls, its WORLD box named (x = 100 -+ (5 + 20), z -20..20).
    (line,) = warnings({"name": "east", "p0": [100.0, -20.0], "p1": [100.0, 20.0]})
    assert "street 'east' (x 75.0..125.0, z -20.0..20.0 with 20 m margins) lies outside the scene's walls" in line
    # At 45 deg: its world box holds wall triangles, its turned corridor none.
    (line,) = warnings({"name": "diagonal", "p0": [10.0, -100.0], "p1": [110.0, 0.0]})
    assert "street 'diagonal'" in line and "has no wall near its facade planes" in line


def test_scene_crop_boxes_of_framed_streets_are_their_world_plan_boxes() -> None:
    from envcap.formats.scene_gltf import street_boxes

    st = Street("d", "x", 0.0, 40.0, -5.0, 7.0, yaw_deg=STREET_YAW, origin_xz=(3.0, -4.0))
    corners = frame_to_world([[u, 0.0, v] for u in (-2.0, 42.0) for v in (-7.0, 9.0)], STREET_YAW, (3.0, -4.0))
    want = [corners[:, 0].min(), corners[:, 0].max(), corners[:, 2].min(), corners[:, 2].max()]
    np.testing.assert_allclose(street_boxes([st], 2.0)[0], want, atol=1e-12)
    np.testing.assert_allclose(st.plan_box(2.0), want, atol=1e-12)
    assert street_boxes([Street("a", "z", 0.0, 40.0, -5.0, 7.0)], 2.0).tolist() == [[-7.0, 9.0, -2.0, 42.0]]


def test_ground_line_fit_is_robust_and_says_when_there_is_no_slope() -> None:
    from envcap.probeset.planes import fit_ground_line

    rng = np.random.default_rng(5)
    ds = rng.uniform(-4.0, 4.0, 2000)
    y = 1.25 + 0.07 * ds + rng.normal(0.0, 0.005, ds.size)
    y[:300] += rng.uniform(0.3, 1.5, 300)                     # 15 % of the votes on cars and curbs
    w = rng.uniform(0.5, 1.0, ds.size) * 1e-4
    g, k, mad = fit_ground_line(ds, y, w, None)
    assert g == pytest.approx(1.25, abs=2e-3) and k == pytest.approx(0.07, abs=1e-3) and mad < 0.01
    flat = fit_ground_line(ds, np.full(ds.size, -3.0), w, -3.0)
    assert flat is not None and flat[:2] == (pytest.approx(-3.0, abs=1e-12), pytest.approx(0.0, abs=1e-12))
    assert fit_ground_line(ds * 0.01, y, w, None) is None     # a sliver of ground: no slope
    assert fit_ground_line(ds, 2.0 * ds, w, 0.0) is None      # 63 deg: not a street
    assert fit_ground_line(ds[:2], y[:2], w[:2], None) is None
