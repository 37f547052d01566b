"""Materials and several meshes on import: Mitsuba 3 XML (to_world, bsdfs, emitters), OBJ + MTL,
glTF factors, several [[mesh]] tables, crop by triangle.  Expected values are hand-derived from the
files the tests write."""

from pathlib import Path

import numpy as np
import pytest
import trimesh

from envcap.scene import scene_from_dict
from envcap.scene.mesh_import import import_meshes


def _unit_triangle_ply(path: Path) -> None:
    """One triangle (0,0,0) (1,0,0) (0,1,0), normal +Z, no colors."""
    trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], process=False).export(path)


XML = """<scene version="3.0.0">
  <default name="grey" value="0.3"/>
  <bsdf type="twosided" id="blue"><bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.4, 0.6"/></bsdf></bsdf>
  <bsdf type="conductor" id="metal"/>
  <emitter type="constant"/>
  <shape type="ply">
    <string name="filename" value="tri.ply"/>
    <transform name="to_world"><scale value="2"/><rotate y="1" angle="90"/><translate x="10" y="0" z="0"/></transform>
    <ref id="blue"/>
  </shape>
  <shape type="ply">
    <string name="filename" value="tri.ply"/>
    <bsdf type="plastic"><float name="diffuse_reflectance" value="$grey"/></bsdf>
  </shape>
  <shape type="ply">
    <string name="filename" value="tri.ply"/>
    <ref id="metal"/>
    <emitter type="area"><rgb name="radiance" value="5, 6, 7"/></emitter>
  </shape>
  <shape type="rectangle"/>
</scene>
"""


def test_mitsuba_xml_transforms_materials_and_skips(tmp_path: Path) -> None:
    _unit_triangle_ply(tmp_path / "tri.ply")
    (tmp_path / "city.xml").write_text(XML)
    mesh, report = import_meshes([tmp_path / "city.xml"], albedo=(0.9, 0.9, 0.9), winding="keep")
    world = (mesh.positions.astype(np.float64) + mesh.origin)[mesh.indices]
    # shape 0: scale 2, then +90 deg about +Y ((1,0,0) -> (0,0,-1)), then +10 x
    np.testing.assert_allclose(world[0], [[10, 0, 0], [10, 0, -2], [10, 2, 0]], atol=1e-5)
    np.testing.assert_allclose(world[1], [[0, 0, 0], [1, 0, 0], [0, 1, 0]], atol=1e-6)
    albedo = mesh.albedo[mesh.indices[:, 0]]
    np.testing.assert_allclose(albedo, [[0.2, 0.4, 0.6], [0.3, 0.3, 0.3], [0.9, 0.9, 0.9]], atol=1e-6)
    np.testing.assert_allclose(mesh.emission[mesh.indices[:, 0]], [[0, 0, 0], [0, 0, 0], [5, 6, 7]])
    text = " | ".join(report.notes)
    for skipped in ("emitter 'constant'", "shape type 'rectangle'", "twosided", "'conductor'"):
        assert skipped in text


@pytest.mark.parametrize("xml, message", [
    ("<scene><shape type='ply'><string name='filename' value='none.ply'/></shape></scene>", "none.ply not found"),
    ("<scene><shape type='ply'><string name='filename' value='tri.ply'/><ref id='x'/></shape></scene>",
     "names no top-level bsdf"),
    ("<scene><shape type='ply'>", "cannot read Mitsuba scene"),
    ("<mesh/>", "not a Mitsuba scene"),
    ("<scene><emitter type='constant'/></scene>", "no ply or obj shapes"),
])
def test_bad_mitsuba_files_name_the_problem(tmp_path: Path, xml: str, message: str) -> None:
    _unit_triangle_ply(tmp_path / "tri.ply")
    (tmp_path / "bad.xml").write_text(xml)
    with pytest.raises(ValueError, match=message):
        import_meshes([tmp_path / "bad.xml"])


def test_obj_mtl_and_gltf_materials(tmp_path: Path) -> None:
    (tmp_path / "a.mtl").write_text("newmtl lit\nKd 0.2 0.3 0.4\nKe 0.5 0.25 0\n")
    (tmp_path / "a.obj").write_text("mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl lit\nf 1 2 3\n")
    mesh, _ = import_meshes([tmp_path / "a.obj"], emission_scale=80.0)
    np.testing.assert_allclose(mesh.albedo[0], [0.2, 0.3, 0.4], atol=1e-6)    # Kd is linear
    np.testing.assert_allclose(mesh.emission[0], [40.0, 20.0, 0.0], atol=1e-5)  # Ke x emission_scale
    material = trimesh.visual.material.PBRMaterial(baseColorFactor=[0.5, 0.25, 1.0, 1.0], emissiveFactor=[0, 0.1, 0])
    visual = trimesh.visual.TextureVisuals(uv=np.zeros((3, 2)), material=material)
    trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], visual=visual, process=False).export(tmp_path / "b.glb")
    mesh, _ = import_meshes([tmp_path / "b.glb"])
    np.testing.assert_allclose(mesh.albedo[0], [0.5, 0.25, 1.0], atol=2.5e-3)   # stored as 8-bit by trimesh
    np.testing.assert_allclose(mesh.emission[0], [0.0, 10.0, 0.0], atol=1e-5)
    assert not mesh.textured


def test_several_mesh_tables_each_with_its_transform(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _unit_triangle_ply(tmp_path / "tri.ply")
    doc = {"name": "two", "effects": [], "sky": {"type": "uniform", "radiance": 1.0}, "ground": {"enabled": False},
           "mesh": [{"file": "tri.ply", "albedo": 0.2},
                    {"file": "tri.ply", "offset": [5.0, 0.0, 0.0], "scale": 3.0, "albedo": 0.7}]}
    scene = scene_from_dict(doc, base_dir=tmp_path)
    world = (scene.mesh.positions.astype(np.float64) + scene.mesh.origin)[scene.mesh.indices]
    np.testing.assert_allclose(world[1], [[5, 0, 0], [8, 0, 0], [5, 3, 0]], atol=1e-5)
    np.testing.assert_allclose(scene.mesh.albedo[scene.mesh.indices[:, 0], 0], [0.2, 0.7], atol=1e-6)
    doc["mesh"][1]["file"] = "missing.ply"
    with pytest.raises(FileNotFoundError, match=r"mesh\[1\]: .*missing\.ply"):
        scene_from_dict(doc, base_dir=tmp_path)


def test_crop_by_triangle_clips_terrain_and_by_part_keeps_it_whole(tmp_path: Path) -> None:
    xs, zs = np.meshgrid(np.arange(11.0), np.arange(11.0))       # a 10 x 10 m grid of 1 m cells
    verts = np.stack([xs.ravel(), np.zeros(121), zs.ravel()], axis=1)
    i = (np.arange(10)[:, None] * 11 + np.arange(10)[None, :]).ravel()
    faces = np.concatenate([np.stack([i, i + 11, i + 1], 1), np.stack([i + 1, i + 11, i + 12], 1)])
    trimesh.Trimesh(verts, faces, process=False).export(tmp_path / "terrain.ply")
    box = ((2.5, -1.0, 2.5), (4.5, 1.0, 4.5))                      # meets cells 2..4 in x and z
    by_triangle, _ = import_meshes([tmp_path / "terrain.ply"], crop=box, crop_by="triangle")
    whole, _ = import_meshes([tmp_path / "terrain.ply"], crop=box)
    assert by_triangle.triangle_count == 3 * 3 * 2
    assert whole.triangle_count == 200
    with pytest.raises(ValueError, match="crop_by"):
        import_meshes([tmp_path / "terrain.ply"], crop=box, crop_by="tile")


def _uv_triangle_ply(path: Path) -> None:
    """The unit triangle with texture coordinates (0,0) (1,0) (0,1) and no texture."""
    visual = trimesh.visual.TextureVisuals(uv=np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))
    mesh = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], visual=visual, process=False)
    path.write_bytes(trimesh.exchange.ply.export_ply(mesh))


def test_texture_coordinates_without_a_texture_keep_the_table_albedo(tmp_path: Path) -> None:
    _uv_triangle_ply(tmp_path / "uv.ply")             # trimesh invents a grey 2x2 image for it
    mesh, _ = import_meshes([tmp_path / "uv.ply"], albedo=(0.3, 0.3, 0.3))
    assert not mesh.textured
    np.testing.assert_allclose(mesh.albedo[0], [0.3, 0.3, 0.3], atol=1e-7)


def test_mitsuba_bitmaps_mirrors_and_shared_textures(tmp_path: Path) -> None:
    from PIL import Image

    _uv_triangle_ply(tmp_path / "uv.ply")
    _unit_triangle_ply(tmp_path / "tri.ply")
    Image.new("RGB", (8, 8), (188, 188, 188)).save(tmp_path / "wall.png")      # sRGB 188 -> 0.5029 linear
    (tmp_path / "s.xml").write_text("""<scene version="3.0.0">
      <bsdf type="diffuse" id="tex"><texture type="bitmap" name="reflectance">
        <string name="filename" value="wall.png"/></texture></bsdf>
      <shape type="ply"><string name="filename" value="uv.ply"/><ref id="tex"/></shape>
      <shape type="ply"><string name="filename" value="uv.ply"/><ref id="tex"/>
        <transform name="to_world"><scale x="-1"/></transform></shape>
      <shape type="ply"><string name="filename" value="tri.ply"/><ref id="tex"/></shape>
    </scene>""")
    mesh, report = import_meshes([tmp_path / "s.xml"], winding="keep")
    assert mesh.textures.shape[0] == 1                                  # one layer for the shared bitmap
    uvl = mesh.uv_layer.reshape(-1, 3, 3)
    world = (mesh.positions.astype(np.float64) + mesh.origin).reshape(-1, 3, 3)
    for t in (0, 1):                                                    # uv follows its corner through the mirror
        for corner, uv in zip(world[t], uvl[t]):
            np.testing.assert_allclose(uv[:2], [abs(corner[0]), corner[1]], atol=1e-6)
    np.testing.assert_allclose(mesh.albedo.reshape(-1, 3, 3)[2, 0], [0.5029] * 3, atol=2e-3)   # no UVs: the mean
    assert uvl[2, 0, 2] == -1 and "without texture coordinates" in " ".join(report.notes)


@pytest.mark.parametrize("element, message", [
    ("<transform name='to_world'><lookat target='0 0 1'/></transform>", "needs 'origin' and 'target'"),
    ("<transform name='to_world'><translate x='nan'/></transform>", "must be finite"),
    ("<transform name='to_world'><rotate y='1' angle='ninety'/></transform>", "angle: expected numbers"),
    ("<bsdf type='diffuse'><float name='reflectance'/></bsdf>", "reflectance.*expected numbers"),
])
def test_bad_mitsuba_attributes_name_the_shape(tmp_path: Path, element: str, message: str) -> None:
    _unit_triangle_ply(tmp_path / "tri.ply")
    (tmp_path / "bad.xml").write_text(f"<scene><shape type='ply'><string name='filename' value='tri.ply'/>{element}"
                                      "</shape></scene>")
    with pytest.raises(ValueError, match=f"bad.xml: shape 0 \\(ply\\).*{message}"):
        import_meshes([tmp_path / "bad.xml"])


def test_a_glob_does_not_take_a_mitsuba_xml(tmp_path: Path) -> None:
    _unit_triangle_ply(tmp_path / "tri.ply")
    (tmp_path / "scene.xml").write_text("<scene><shape type='ply'><string name='filename' value='tri.ply'/></shape></scene>")
    doc = {"name": "g", "effects": [], "sky": {"type": "uniform", "radiance": 1.0}, "ground": {"enabled": False},
           "mesh": {"glob": "*"}}
    assert scene_from_dict(doc, base_dir=tmp_path).mesh.triangle_count == 1     # not twice
