"""Typed scene specs: every table of a scene document is checked and typed by ``parse_scene`` (defaults
as documented in docs/scenes.md), before and apart from building geometry; files are read by the build."""

from __future__ import annotations

import numpy as np
import pytest

from envcap.scene import SceneSpec, build_scene, parse_scene, scene_from_dict
from envcap.scene.spec import BuildingSpec, GroundSpec, MeshSpec, RandomBuildingsSpec, WallSpec
from envcap.sky import SkySpec
from envcap.sky.uniform import UniformParams

DOC = {
    "name": "typed",
    "effects": ["sky_light"],
    "sky": {"type": "uniform", "radiance": 2},
    "streets": [
        {"name": "a", "axis": "x", "start": 0.0, "end": 40.0, "width": 10.0,
         "side_min": {"seed": 3, "buildings": [{"width": 4.0, "height": 5.0}, {"gap": 1.0, "width": 6.0, "height": 9.0,
                                                                             "albedo": 0.5, "windows": False}]},
         "side_max": {"facade": {"albedo": 0.3}, "wall": {"height": 3.0}}},
        {"name": "b", "axis": "z", "length": 30.0, "along_center": 50.0, "width": 8.0, "cross": 60.0,
         "side_min": {"random": {"width": [3.0, 5.0], "height": 5.0}}},
    ],
}


def test_every_table_is_typed_with_the_documented_defaults():
    spec = parse_scene(DOC)
    assert isinstance(spec, SceneSpec) and spec.name == "typed" and spec.effects == frozenset({"sky_light"})
    assert spec.sky == SkySpec("uniform", UniformParams((2.0, 2.0, 2.0), None))
    a, b = spec.streets
    assert (a.street.facade_min, a.street.facade_max, b.street.start, b.street.end) == (-5.0, 5.0, 35.0, 65.0)
    facade = (0.35, 0.33, 0.3)  # the documented default facade albedo
    assert a.side_min.seed == 3 and a.side_min.layout == (
        BuildingSpec(gap=0.0, width=4.0, height=5.0, depth=12.0, setback=0.0, albedo=facade, windows=True),
        BuildingSpec(gap=1.0, width=6.0, height=9.0, depth=12.0, setback=0.0, albedo=(0.5, 0.5, 0.5), windows=False))
    assert a.side_max.facade.albedo == (0.3, 0.3, 0.3)
    assert a.side_max.layout == WallSpec(height=3.0, tile=2.0, albedo=(0.3, 0.3, 0.3), albedo2=(0.1, 0.1, 0.1),
                                         thickness=0.5)
    assert b.side_min.layout == RandomBuildingsSpec(count=None, width=(3.0, 5.0), height=(5.0, 5.0),
                                                    depth=(10.0, 15.0), setback=(0.0, 0.0), gap_probability=0.0,
                                                    gap_width=(2.0, 6.0))
    assert b.side_max is None and spec.meshes == ()
    assert spec.ground == GroundSpec(albedo=(0.18, 0.18, 0.18), extent=1000.0, center=None, checker=0.0,
                                     albedo2=(0.08, 0.08, 0.08), checker_extent=200.0)
    assert parse_scene({**DOC, "ground": {"enabled": False}}).ground is None


def test_building_a_spec_is_deterministic_and_is_what_scene_from_dict_gives():
    spec = parse_scene(DOC)
    s1, s2, s3 = build_scene(spec), build_scene(spec), scene_from_dict(DOC)
    for s in (s2, s3):
        for k in ("positions", "normals", "albedo", "emission", "indices"):
            np.testing.assert_array_equal(getattr(s.mesh, k), getattr(s1.mesh, k))
    assert s1.sky is spec.sky and s1.meta["buildings"] >= 2
    # Two listed buildings on side_min of street a: x in [0, 4] and [5, 11], 5 and 9 m tall, z in [-17, -5].
    top = s1.mesh.positions[(s1.mesh.normals[:, 1] > 0.5) & (s1.mesh.positions[:, 1] > 0)]
    assert {float(y) for y in top[top[:, 2] < -5.0 - 1e-6][:, 1]} == {5.0, 9.0}


def test_layout_errors_are_parse_errors(tmp_path):
    bad = {**DOC, "streets": [{**DOC["streets"][1], "side_min": {"random": {"width": 3.0, "height": 5.0, "colour": 1}}}]}
    with pytest.raises(ValueError, match=r"streets\[0\]\.side_min\.random: unknown key\(s\) \['colour'\]"):
        parse_scene(bad)
    mesh_doc = {**DOC, "mesh": {"file": "gone.ply", "up_axis": "z"}}
    spec = parse_scene(mesh_doc, base_dir=tmp_path)  # the mesh file is read by the build, not the parse
    assert spec.meshes == (MeshSpec(path=tmp_path / "gone.ply", up_axis="z", rotation_deg=0.0, offset=(0.0, 0.0, 0.0),
                                 scale=1.0, albedo=(0.5, 0.5, 0.5), base_dir=tmp_path),)
    with pytest.raises(FileNotFoundError, match="gone.ply"):
        build_scene(spec)
