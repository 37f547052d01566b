"""Probes that follow the terrain (issue 10, wall 6: the ground was fixed at y = 0): each probe
stands its height above the ground under it, and its nominal ground plane is there."""

from pathlib import Path

import numpy as np
import pytest
import trimesh

from envcap.probeset.bake import bake_probe_set
from envcap.scene import scene_from_dict
from envcap.scene.ground_height import ground_heights

SLOPE = 0.08


def _slope_file(path: Path) -> None:
    """A 400 m x 400 m ramp y = SLOPE * x, facing up, split into 20 m cells."""
    xs = np.arange(-200.0, 201.0, 20.0)
    gx, gz = np.meshgrid(xs, xs)
    verts = np.stack([gx.ravel(), SLOPE * gx.ravel(), gz.ravel()], axis=1)
    n = len(xs)
    i = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    faces = np.concatenate([np.stack([i, i + n, i + 1], 1), np.stack([i + 1, i + n, i + n + 1], 1)])
    trimesh.Trimesh(verts, faces, process=False).export(path)


def _doc(tmp_path: Path, follow: bool) -> dict:
    _slope_file(tmp_path / "ramp.ply")
    return {"name": "ramp", "effects": [], "sky": {"type": "uniform", "radiance": 1.0}, "ground": {"enabled": False},
            "mesh": {"file": "ramp.ply"},
            "streets": [{"name": "up", "axis": "x", "start": -50.0, "end": 50.0, "width": 12.0, "follow_terrain": follow}]}


def test_probes_stand_above_the_sloped_ground_under_them(tmp_path: Path) -> None:
    scene = scene_from_dict(_doc(tmp_path, True), base_dir=tmp_path)
    ps = bake_probe_set(scene, resolution=4, spacing=20.0, height=2.0, filter_levels=False, progress=False)
    probes = ps.manifest.streets[0].probes
    x = np.array([p.position[0] for p in probes])
    np.testing.assert_allclose([p.position[1] for p in probes], SLOPE * x + 2.0, atol=1e-4)
    np.testing.assert_allclose([p.planes.ground for p in probes], SLOPE * x, atol=1e-4)
    flat = bake_probe_set(scene_from_dict(_doc(tmp_path, False), base_dir=tmp_path), resolution=4, spacing=20.0,
                          filter_levels=False, progress=False)
    assert {p.position[1] for p in flat.manifest.streets[0].probes} == {2.0}      # as before: street.ground + height


def test_ground_heights_take_the_highest_up_facing_surface_and_say_where_there_is_none(tmp_path: Path) -> None:
    scene = scene_from_dict(_doc(tmp_path, True), base_dir=tmp_path)
    h = ground_heights(scene.mesh, [[13.0, 7.0], [-150.5, 3.0], [500.0, 0.0]])
    np.testing.assert_allclose(h[:2], [SLOPE * 13.0, SLOPE * -150.5], atol=1e-4)
    assert np.isnan(h[2])
    doc = _doc(tmp_path, True)
    doc["streets"][0]["start"], doc["streets"][0]["end"] = 180.0, 260.0               # off the ramp's end
    with pytest.raises(ValueError, match="follows the terrain, but no up-facing surface lies under probe"):
        bake_probe_set(scene_from_dict(doc, base_dir=tmp_path), resolution=4, spacing=20.0, filter_levels=False,
                       progress=False)
