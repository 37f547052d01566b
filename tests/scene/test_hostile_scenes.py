"""Scene files that were accepted silently (issue 20, item 10): sizes with no sane minimum
(``width = 1e-300``) and a Mitsuba ``<include>`` dropped without a word.  Sizes now have
minimums (:mod:`envcap.scene.limits`) with one-line errors naming the key; an include is
followed, within the scene's folder only."""

from __future__ import annotations

import os
import tomllib
from pathlib import Path

import numpy as np
import pytest
import trimesh

from envcap.scene.limits import MIN_SIZE_M, MIN_STREET_LENGTH_M, MIN_STREET_WIDTH_M
from envcap.scene.mesh_import import import_meshes
from envcap.scene.parse import parse_scene

REPO = Path(__file__).resolve().parents[2]


def _canyon() -> dict:
    return tomllib.loads((REPO / "city_scenes" / "canyon.toml").read_text())


@pytest.mark.parametrize("edit, key, least", [
    (lambda d: d["streets"][0].update(width=1e-300), "streets[0].width", MIN_STREET_WIDTH_M),
    (lambda d: d["streets"][0].update(width=0.5), "streets[0].width", MIN_STREET_WIDTH_M),
    (lambda d: d["streets"][0]["facade"]["windows"].update(spacing=1e-300), "streets[0].facade.windows.spacing", MIN_SIZE_M),
    (lambda d: d["streets"][0]["facade"]["windows"].update(width=1e-9), "streets[0].facade.windows.width", MIN_SIZE_M),
    (lambda d: d["ground"].update(extent=1e-300), "ground.extent", MIN_SIZE_M),
    (lambda d: d["streets"][0]["side_min"]["random"].update(height=[1e-300, 5.0]), "streets[0].side_min.random.height", MIN_SIZE_M),
])
def test_sizes_below_their_minimum_are_one_line_naming_the_key(edit, key, least):
    data = _canyon()
    edit(data)
    with pytest.raises(ValueError) as err:
        parse_scene(data)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(f"{key}: must be >= {least:g}, got "), msg


def test_a_street_shorter_than_a_meter_is_refused_in_each_form():
    for street, words in (({"start": 0.0, "end": 1e-9}, "long (start 0, end 1e-09)"),
                          ({"length": 1e-300}, "length: must be >="),
                          ({"p0": [0.0, 0.0], "p1": [1e-6, 0.0]}, "p0 to p1 is 1e-06 m")):
        data = _canyon()
        st = {k: v for k, v in data["streets"][0].items() if k not in ("start", "end", "side_min", "side_max")}
        if "p0" in street:
            st.pop("axis")
        data["streets"][0] = {**st, **street}
        with pytest.raises(ValueError, match=f"{MIN_STREET_LENGTH_M:g}") as err:
            parse_scene(data)
        assert words in str(err.value), str(err.value)
    parse_scene(_canyon())   # the bundled scene itself is fine


def _tri(path: Path, x: float = 0.0) -> None:
    trimesh.Trimesh([[x, 0, 0], [x + 1, 0, 0], [x, 1, 0]], [[0, 1, 2]], process=False).export(path)


def test_a_mitsuba_include_is_followed_within_the_scene_folder(tmp_path):
    """Before: ``<include>`` was dropped without a note, the shapes and bsdfs in it lost."""
    (tmp_path / "parts").mkdir()
    _tri(tmp_path / "a.ply")
    _tri(tmp_path / "parts" / "b.ply", 5.0)
    (tmp_path / "parts" / "materials.xml").write_text(
        '<scene version="3.0.0"><bsdf type="diffuse" id="red"><rgb name="reflectance" value="0.8, 0.1, 0.1"/></bsdf></scene>')
    (tmp_path / "parts" / "more.xml").write_text(   # names are relative to the main file's folder, as in Mitsuba
        '<scene version="3.0.0"><include filename="parts/materials.xml"/>'
        '<shape type="ply"><string name="filename" value="parts/b.ply"/><ref id="red"/></shape></scene>')
    (tmp_path / "city.xml").write_text(
        '<scene version="3.0.0"><include filename="parts/more.xml"/>'
        '<shape type="ply"><string name="filename" value="a.ply"/><ref id="red"/></shape></scene>')
    mesh, _ = import_meshes([tmp_path / "city.xml"], albedo=(0.5, 0.5, 0.5), winding="keep")
    world = (mesh.positions.astype(np.float64) + mesh.origin)[mesh.indices]
    assert sorted(world[:, 0, 0].round(6).tolist()) == [0.0, 5.0]       # both shapes, the included one too
    np.testing.assert_allclose(mesh.albedo[mesh.indices[:, 0]], [[0.8, 0.1, 0.1]] * 2, atol=1e-6)


@pytest.mark.parametrize("include, message", [
    ("../outside.xml", "leads outside the scene's folder"),
    ("link.xml", "leads outside the scene's folder"),          # a link to a file outside
    ("city.xml", "a cycle"),
    ("missing.xml", "missing.xml not found"),
    ("", "an <include> without a filename"),
])
def test_a_mitsuba_include_never_leaves_the_scene_folder(tmp_path, include, message):
    scene = tmp_path / "scene"
    scene.mkdir()
    _tri(scene / "a.ply")
    (tmp_path / "outside.xml").write_text('<scene version="3.0.0"/>')
    os.symlink(tmp_path / "outside.xml", scene / "link.xml")
    (scene / "city.xml").write_text(f'<scene version="3.0.0"><include filename="{include}"/>'
                                    '<shape type="ply"><string name="filename" value="a.ply"/></shape></scene>')
    with pytest.raises(ValueError, match=message) as err:
        import_meshes([scene / "city.xml"])
    assert "\n" not in str(err.value) and str(scene / "city.xml") in str(err.value)
