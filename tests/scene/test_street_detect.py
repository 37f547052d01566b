"""Street detection (envcap.scene.street_detect, ``envcap streets``) graded against known truth:
the generated city's truth.json (streets at 7-318 deg, 10-18 m wide, files wound inward, projected
coordinates) and the bundled axis-aligned scenes' street planes."""

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from envcap.cli import main
from envcap.core.resources import city_scenes_dir
from envcap.scene import load_scene
from envcap.scene.mesh_import import import_meshes
from envcap.scene.street_detect import StreetSearch, detect_streets, intersections

CITY = city_scenes_dir() / "generated_city" / "data"


def _tri(mesh) -> np.ndarray:
    return (mesh.positions.astype(np.float64) + mesh.origin)[mesh.indices.astype(np.int64)]


@pytest.fixture(scope="module")
def city_triangles() -> tuple[np.ndarray, dict]:
    truth = json.loads((CITY / "truth.json").read_text())
    mesh, _ = import_meshes(sorted((CITY / "buildings").glob("*.ply")), up_axis="z", offset=truth["frame"]["offset"])
    parts = [_tri(mesh)]
    for tf in truth["textured_files"]:
        m, _ = import_meshes([CITY / tf["file"]], up_axis=tf["up_axis"], offset=tf["offset"])
        parts.append(_tri(m))
    return np.concatenate(parts), truth


def _match(truth_street: dict, found: list) -> object | None:
    p0, p1 = np.array(truth_street["p0"]), np.array(truth_street["p1"])
    mid = (p0 + p1) / 2
    for s in found:
        d_angle = abs((s.angle_deg - truth_street["angle_deg"] + 90.0) % 180.0 - 90.0)
        a = np.radians(s.angle_deg)
        normal = np.array([-np.sin(a), np.cos(a)])
        if d_angle < 0.5 and abs((mid - np.array(s.p0)) @ normal) < 0.5:
            return s
    return None


def test_every_street_of_the_generated_city_is_found(city_triangles: tuple[np.ndarray, dict]) -> None:
    tri, truth = city_triangles
    found = detect_streets(tri)
    matched = set()
    for t in truth["streets"]:
        assert t["length"] >= 60.0
        s = _match(t, found)
        assert s is not None, f"street {t['name']} ({t['angle_deg']:.0f} deg, {t['width']} m) not found"
        assert s.width == pytest.approx(t["width"], abs=0.5)
        assert sorted(abs(o) for o in s.facade_offsets) == pytest.approx([t["width"] / 2] * 2, abs=0.5)
        overlap = min(s.length, t["length"]) / t["length"]
        assert overlap > 0.98, t["name"]        # one-sided stretches included (the street goes on there)
        matched.add(s.name)
    assert matched == {s.name for s in found}, "a street was found that the city does not have"
    # 2 x 3 grid crossings; none in the irregular district (its streets stop short of the plaza)
    assert len(intersections(found)) == 6


def test_no_found_street_runs_through_a_building(city_triangles: tuple[np.ndarray, dict]) -> None:
    tri, _ = city_triangles
    verts = tri.reshape(-1, 3)
    for s in detect_streets(tri):
        a = np.radians(s.angle_deg)
        t, n = np.array([np.cos(a), np.sin(a)]), np.array([-np.sin(a), np.cos(a)])
        rel = verts[:, [0, 2]] - np.array(s.p0)
        u, v = rel @ t, rel @ n
        lo, hi = s.facade_offsets
        inside = (u > 1.0) & (u < s.length - 1.0) & (v > lo + 0.05) & (v < hi - 0.05)
        assert not inside.any(), s.name


@pytest.mark.parametrize("name", ["canyon", "crossing", "imported"])
def test_bundled_scene_streets_found_on_their_planes(name: str) -> None:
    scene = load_scene(name)
    found = detect_streets(_tri(scene.mesh))
    assert len(found) == len(scene.streets)
    for st in scene.streets:
        k = 0 if st.axis == "x" else 1
        hits = [s for s in found if abs(np.cos(np.radians(s.angle_deg)) ** 2 - (1.0 - k)) < 1e-3]
        assert len(hits) == 1, st.name
        s = hits[0]
        cross = s.p0[1 - k]
        sign = 1.0 if st.axis == "x" else -1.0
        planes = sorted(cross + sign * o for o in s.facade_offsets)
        assert planes == pytest.approx([st.facade_min, st.facade_max], abs=0.05)


def test_hard_inputs_are_clear_errors() -> None:
    flat = np.array([[[0, 0, 0], [1, 0, 0], [0, 0, 1]]], dtype=np.float64)   # only a ground triangle
    with pytest.raises(ValueError, match="no walls found"):
        detect_streets(flat)
    with pytest.raises(ValueError, match=r"\(T, 3, 3\)"):
        detect_streets(np.full((2, 3, 3), np.nan))
    with pytest.raises(ValueError, match="min_length"):
        StreetSearch(min_length=0.0)


def test_envcap_streets_writes_a_scene_a_map_and_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "streets"
    assert main(["streets", "crossing", "--out", str(out)]) == 0
    assert "2 streets, 1 intersections" in capsys.readouterr().out
    scene = tomllib.loads((out / "scene.toml").read_text())
    axes = sorted(s["axis"] for s in scene["streets"])
    assert axes == ["x", "z"]
    doc = json.loads((out / "streets.json").read_text())
    assert len(doc["streets"]) == 2 and len(doc["intersections"]) == 1
    assert (out / "streets_map.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["streets", "no_such_scene", "--out", str(tmp_path / "x")]) == 2
    assert capsys.readouterr().err.startswith("envcap: error:") and not (tmp_path / "x").exists()


def test_heights_and_segments_of_the_generated_city(city_triangles: tuple[np.ndarray, dict]) -> None:
    tri, truth = city_triangles
    lo, hi = truth["spec"]["height_range"]
    found = detect_streets(tri)
    for s in found:
        # buildings stand 1 m below the terrain: every side's median height is a building's height + 1
        assert all(lo + 1.0 <= h <= hi + 1.0 for h in s.heights), (s.name, s.heights)
        t = next(t for t in truth["streets"] if _match(t, [s]) is s)
        widths = [o["width"] for o in truth["streets"] if o["name"] != t["name"] and o["district"] == "grid"
                  and abs((o["angle_deg"] - t["angle_deg"]) % 180 - 90) < 1]
        if t["district"] == "grid":     # split at each crossing: one stretch more than crossings
            assert len(s.segments) == len(t["intersections"]) + 1 == len(widths) + 1
            assert sum(b - a for a, b in s.segments) == pytest.approx(s.length - sum(widths), abs=2.0)
        else:
            assert s.segments == ((0.0, s.length),)
