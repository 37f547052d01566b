"""Issue 10, walls 1, 4 and 8 on import: winding detected and fixed per part, a crop box keeps
whole parts, and files are chosen with files / glob / include / exclude (real PLY files)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from envcap.scene import load_scene
from envcap.scene.mesh_import import import_meshes
from envcap.scene.mesh_parts import component_labels, inward_parts
from envcap.scene.mesh_select import select_mesh_files
from envcap.scene.model import Street

HEAD = 'effects = ["sky_light"]\nsky = { type = "uniform", radiance = 1.0 }\n[ground]\nenabled = false\n'


def _box(path, lo, hi, inward=False, floor=True):
    m = trimesh.creation.box(bounds=[lo, hi])
    faces = m.faces
    if not floor:  # drop the two triangles facing -Y (an open shell, like a building without a floor)
        n = m.face_normals
        faces = faces[n[:, 1] > -0.5]
    m = trimesh.Trimesh(m.vertices, faces[:, ::-1] if inward else faces, process=False)
    m.export(path)
    return path


def _outward_share(mesh, center):
    """Area-free check: share of triangles whose normal points away from ``center`` (x, z)."""
    p = mesh.origin + mesh.positions[mesh.indices].astype(np.float64).mean(axis=1)
    n = mesh.normals[mesh.indices[:, 0]]
    return float(np.mean(np.einsum("ij,ij->i", (p - center)[:, [0, 2]], n[:, [0, 2]]) >= 0))


def test_inward_closed_and_open_boxes_are_flipped(tmp_path):
    files = [_box(tmp_path / "a.ply", [0, 0, 0], [4, 6, 4], inward=True),
             _box(tmp_path / "b.ply", [10, 0, 0], [14, 6, 4], inward=True, floor=False),
             _box(tmp_path / "c.ply", [20, 0, 0], [24, 6, 4])]
    mesh, rep = import_meshes(files)
    assert (rep.parts, rep.flipped, rep.flipped_files) == (3, 2, ("a.ply", "b.ply"))
    for cx in (2.0, 12.0, 22.0):
        sub = mesh  # every wall of every box now faces away from its own box's center
        p = sub.origin + sub.positions[sub.indices].astype(np.float64).mean(axis=1)
        mine = np.abs(p[:, 0] - cx) <= 2.0 + 1e-9
        n = sub.normals[sub.indices[mine, 0]]
        d = p[mine] - [cx, 3.0, 2.0]
        assert np.all(np.einsum("ij,ij->i", d, n) > 0)
    kept, rep = import_meshes(files, winding="keep")
    assert rep.flipped == 0 and _outward_share(kept, [2.0, 0, 2.0]) < 1.0
    _, rep = import_meshes(files, winding="flip")
    assert rep.flipped == 3


def test_a_facade_sheet_is_turned_to_face_the_street(tmp_path):
    """A single wall (no volume) at z = 5 facing +Z, away from a street along X at z = 0."""
    m = trimesh.Trimesh([[0, 0, 5], [10, 0, 5], [10, 8, 5], [0, 8, 5]], [[0, 1, 2], [0, 2, 3]], process=False)
    m.export(tmp_path / "wall.ply")
    street = Street("s", "x", -5.0, 15.0, -5.0, 5.0, 0.0)
    tri = np.asarray(m.vertices, np.float64)[m.faces]
    assert inward_parts(tri, component_labels(tri), [street]).tolist() == [True]
    assert inward_parts(tri, component_labels(tri)).tolist() == [False]  # no street: left alone
    mesh, rep = import_meshes([tmp_path / "wall.ply"], streets=[street])
    assert rep.flipped == 1 and np.all(mesh.normals[:, 2] < -0.99)


def test_the_scene_note_and_the_winding_key(tmp_path, capsys):
    _box(tmp_path / "a.ply", [0, 0, 0], [4, 6, 4], inward=True)
    (tmp_path / "s.toml").write_text(HEAD + '[mesh]\nfile = "a.ply"\n')
    load_scene(tmp_path / "s.toml")
    assert "flipped 1 of 1 meshes wound inward (files a.ply)" in capsys.readouterr().err
    (tmp_path / "s.toml").write_text(HEAD + '[mesh]\nfile = "a.ply"\nwinding = "keep"\n')
    load_scene(tmp_path / "s.toml")
    assert "flipped" not in capsys.readouterr().err
    (tmp_path / "s.toml").write_text(HEAD + '[mesh]\nfile = "a.ply"\nwinding = "inside"\n')
    with pytest.raises(ValueError, match=r"mesh.winding: 'inside' is not one of \['auto', 'keep', 'flip'\]"):
        load_scene(tmp_path / "s.toml")


def test_a_z_up_file_read_as_y_up_is_warned_about(tmp_path, capsys):
    _box(tmp_path / "a.ply", [0, -10, 0], [4, 10, 8])  # as a Z-up file: 8 m tall, 20 m deep
    (tmp_path / "s.toml").write_text(HEAD + '[mesh]\nfile = "a.ply"\n')
    load_scene(tmp_path / "s.toml")
    assert '50 % of the imported geometry\'s height lies below the ground' in capsys.readouterr().err
    (tmp_path / "s.toml").write_text(HEAD + '[mesh]\nfile = "a.ply"\nup_axis = "z"\n')
    load_scene(tmp_path / "s.toml")
    assert "below the ground" not in capsys.readouterr().err


def test_crop_keeps_whole_parts_that_meet_the_box(tmp_path):
    """Old: the whole city was imported (``crop`` was an unknown key)."""
    for k in range(4):
        _box(tmp_path / f"b{k}.ply", [20 * k, 0, 0], [20 * k + 10, 5, 10])
    two = trimesh.util.concatenate([trimesh.creation.box(bounds=[[0, 0, 50], [4, 4, 54]]),
                                    trimesh.creation.box(bounds=[[30, 0, 50], [34, 4, 54]])])
    two.export(tmp_path / "district.ply")  # one file, two connected buildings
    (tmp_path / "s.toml").write_text(HEAD + '[mesh]\nglob = "*.ply"\ncrop = { min = [15, -1, -1], max = [35, 10, 60] }\n')
    mesh = load_scene(tmp_path / "s.toml").mesh
    lo, hi = mesh.world_bounds()
    np.testing.assert_allclose(lo, [20, 0, 0])
    np.testing.assert_allclose(hi, [34, 5, 54])  # the district's second box is kept whole past x = 35
    assert mesh.triangle_count == 12 * 2  # b1 and that box; b0, b2, b3 and the first district box dropped
    (tmp_path / "s.toml").write_text(HEAD + '[mesh]\nglob = "*.ply"\ncrop = { min = [500, 0, 0], max = [600, 1, 1] }\n')
    with pytest.raises(ValueError, match="crop box .* meets none of the 6 parts"):
        load_scene(tmp_path / "s.toml")
    (tmp_path / "s.toml").write_text(HEAD + '[mesh]\nglob = "*.ply"\ncrop = { min = [5, 0, 0], max = [1, 1, 1] }\n')
    with pytest.raises(ValueError, match=r"mesh.crop: min .* must be below max"):
        load_scene(tmp_path / "s.toml")


def test_files_glob_include_exclude(tmp_path):
    """Old: ``file`` only, a directory meant every ``*.ply`` in it."""
    (tmp_path / "city" / "old").mkdir(parents=True)
    for name in ("city/a_house.ply", "city/b_house.ply", "city/tree.ply", "city/old/c_house.ply", "extra.ply"):
        _box(tmp_path / name, [0, 0, 0], [1, 1, 1])
    sel = select_mesh_files(tmp_path, globs=["city/**/*.ply"], include=["*house*"], exclude=["old/*", "city/old/*"][1:])
    assert [p.relative_to(tmp_path).as_posix() for p in sel] == ["city/a_house.ply", "city/b_house.ply"]
    sel = select_mesh_files(tmp_path, files=[tmp_path / "extra.ply", tmp_path / "city"], exclude=["tree.ply"])
    assert [p.name for p in sel] == ["extra.ply", "a_house.ply", "b_house.ply"]
    with pytest.raises(ValueError, match=r"mesh.glob: 'town/\*.ply' matches no mesh file"):
        select_mesh_files(tmp_path, globs=["town/*.ply"])
    with pytest.raises(ValueError, match=r"mesh.include: 'shop\*' matches none of the 5 selected"):
        select_mesh_files(tmp_path, globs=["**/*.ply"], include=["shop*"])
    with pytest.raises(ValueError, match="include/exclude leave no file"):
        select_mesh_files(tmp_path, globs=["extra.ply"], exclude=["*.ply"])
    with pytest.raises(FileNotFoundError, match="gone.ply"):
        select_mesh_files(tmp_path, files=[tmp_path / "gone.ply"])
    (tmp_path / "s.toml").write_text(HEAD + '[mesh]\nfiles = ["extra.ply"]\nglob = ["city/*.ply"]\n'
                                     'exclude = "tree.ply"\n')
    assert load_scene(tmp_path / "s.toml").mesh.triangle_count == 3 * 12
    (tmp_path / "s.toml").write_text(HEAD + '[mesh]\nup_axis = "z"\n')
    with pytest.raises(ValueError, match="mesh: give the mesh files with 'file', 'files' or 'glob'"):
        load_scene(tmp_path / "s.toml")
    (tmp_path / "s.toml").write_text(HEAD + '[mesh]\nglob = "nothing/*.obj"\n')
    with pytest.raises(ValueError, match=r"s.toml: mesh: mesh.glob: 'nothing/\*.obj' matches no mesh file"):
        load_scene(tmp_path / "s.toml")
