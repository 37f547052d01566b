"""The generated test city (envcap.scene.city_layout / city_files): its files agree with its truth.

Every check reads the written files back through independent readers (envcap's importer, trimesh,
ElementTree) and measures the geometry, rather than re-running the layout arithmetic."""

import hashlib
import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import trimesh

from envcap.core.resources import city_scenes_dir
from envcap.scene.city_files import building_mesh, write_city
from envcap.scene.city_layout import CitySpec, generate_city_layout
from envcap.scene.mesh_import import import_meshes

BUNDLED = city_scenes_dir() / "generated_city" / "data"


@pytest.fixture(scope="module")
def city(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("city") / "c"
    return out, write_city(generate_city_layout(CitySpec()), out)


def _digest(root: Path) -> dict[str, str]:
    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def test_bundled_city_is_what_the_generator_writes(city: tuple[Path, dict]) -> None:
    out, _ = city
    assert _digest(out) == _digest(BUNDLED), "city_scenes/generated_city/data is stale: rerun its generate.py"


def test_write_city_refuses_a_non_empty_directory(tmp_path: Path) -> None:
    (tmp_path / "keep.txt").write_text("user file")
    with pytest.raises(FileExistsError, match="not empty"):
        write_city(generate_city_layout(CitySpec()), tmp_path)
    assert (tmp_path / "keep.txt").read_text() == "user file"


def _world_triangles(out: Path, truth: dict) -> np.ndarray:
    files = sorted((out / "buildings").glob("*.ply"))
    mesh, report = import_meshes(files, up_axis="z", offset=truth["frame"]["offset"])
    assert report.flipped_files and sorted(report.flipped_files) == sorted(Path(f).name for f in truth["inward_files"])
    return mesh.positions.reshape(-1, 3, 3).astype(np.float64) + np.asarray(mesh.origin)


def test_facades_lie_on_the_truth_facade_lines_and_no_building_enters_a_street(city: tuple[Path, dict]) -> None:
    out, truth = city
    tri = _world_triangles(out, truth)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    wall = np.abs(normal[:, 1]) < 1e-6 * np.linalg.norm(normal, axis=1)
    pts = tri[wall].reshape(-1, 3)
    for s in truth["streets"]:
        p0, p1 = np.array(s["p0"]), np.array(s["p1"])
        along = (p1 - p0) / np.linalg.norm(p1 - p0)
        across = np.array([-along[1], along[0]])
        rel = pts[:, [0, 2]] - p0
        u, v = rel @ along, rel @ across
        inside = (u > 0.05 * s["length"]) & (u < 0.95 * s["length"]) & (np.abs(v) < s["width"] / 2 + 30)
        lo, hi = s["facade_offsets"]
        assert not np.any(inside & (v > lo + 1e-3) & (v < hi - 1e-3)), f"a building stands in street {s['name']}"
        assert np.min(np.abs(v[inside & (v >= hi - 1e-3)] - hi)) < 1e-3, s["name"]
        assert np.min(np.abs(v[inside & (v <= lo + 1e-3)] - lo)) < 1e-3, s["name"]
        ang = np.degrees(np.arctan2(along[1], along[0])) % 360
        assert abs((ang - s["angle_deg"] + 180) % 360 - 180) < 1e-9


def test_terrain_slope_along_the_radial_streets(city: tuple[Path, dict]) -> None:
    out, truth = city
    terrain = trimesh.load(out / "terrain.ply", process=False)
    e0, _, n0 = truth["frame"]["offset"]
    x, z, y = terrain.vertices[:, 0] + e0, -(terrain.vertices[:, 1] - n0), terrain.vertices[:, 2]
    for s in truth["streets"]:
        if s["district"] != "radial":
            continue
        heights = []
        for end in (s["p0"], s["p1"]):
            near = np.hypot(x - end[0], z - end[1]) < 15.0      # a local plane through the grid's vertices
            a = np.stack([np.ones(near.sum()), x[near] - end[0], z[near] - end[1]], axis=1)
            heights.append(np.linalg.lstsq(a, y[near], rcond=None)[0][0])
        assert (heights[1] - heights[0]) / s["length"] == pytest.approx(s["slope"], abs=2e-3), s["name"]


def test_mitsuba_xml_references_every_file_and_material(city: tuple[Path, dict]) -> None:
    out, truth = city
    root = ET.parse(out / "city.xml").getroot()
    bsdfs = {b.get("id") for b in root.findall("bsdf")}
    shapes = root.findall("shape")
    assert len(shapes) == truth["buildings"] - 1 + 1          # the glTF house is not a Mitsuba shape; + terrain
    for shape in shapes:
        assert (out / shape.find("string[@name='filename']").get("value")).is_file()
        assert shape.find("ref").get("id") in bsdfs
    assert sorted(e.get("type") for e in root.findall("emitter")) == ["constant", "directional"]
    assert root.find("bsdf[@type='twosided']/bsdf[@type='diffuse']") is not None


def test_textured_gltf_and_obj_carry_their_textures(city: tuple[Path, dict]) -> None:
    out, _ = city
    glb = trimesh.load(out / "textured" / "facade_house.glb", force="mesh", process=False)
    assert glb.visual.material.baseColorTexture.size == (64, 64)
    assert glb.visual.uv.shape == (len(glb.vertices), 2)
    mtl = (out / "textured" / "obj_house.mtl").read_text()
    assert "map_Kd obj_house_windows.png" in mtl and (out / "textured" / "obj_house_windows.png").is_file()
    obj = trimesh.load(out / "textured" / "obj_house.obj", force="mesh", process=False)
    assert np.asarray(obj.visual.material.image).shape[:2] == (64, 64)


def test_facade_cells_scale_the_triangle_count() -> None:
    layout = generate_city_layout(CitySpec(facade_cells=3))
    _, faces, _ = building_mesh(layout.buildings[0], 3)
    assert len(faces) == 4 * 2 * 9 + 2
    assert json.dumps([b.name for b in layout.buildings]) == json.dumps([b.name for b in generate_city_layout(CitySpec()).buildings])
