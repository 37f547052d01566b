"""The scene ``envcap streets`` writes (``envcap.scene.streets_scene``, ``envcap/cli/streets.py``):
it loads as it is from any working directory, its paths and strings survive any file name, its
geometry is the input's, its ground is off over a mesh that brings one; and the command checks its
options and ``--out`` before it reads a mesh, and reports progress on stderr."""

from __future__ import annotations

import os
import tomllib
from pathlib import Path

import numpy as np
import pytest
import trimesh

from envcap.cli import main
from envcap.scene import load_scene
from envcap.scene.streets_scene import DEFAULT_EFFECTS, DEFAULT_SKY, path_text


def street_mesh(folder: Path, ground_y: float | None = 0.0, name: str = "street.ply", buildings: bool = True) -> Path:
    """A 64 m street along +X, facades at z = -8 / +8 (three 20 m boxes a side, 15 m high), and
    with ``ground_y`` an up-facing 90 m x 60 m ground quad at that height; one PLY, +Y up."""
    parts = [trimesh.creation.box(bounds=[[x0, 0.0, z0], [x0 + 20.0, 15.0, z1]])
             for x0 in (0.0, 22.0, 44.0) for z0, z1 in ((-22.0, -8.0), (8.0, 22.0))] if buildings else []
    if ground_y is not None:
        g = ground_y
        parts.append(trimesh.Trimesh([[-10, g, -30], [80, g, -30], [80, g, 30], [-10, g, 30]], [[0, 2, 1], [0, 3, 2]],
                                     process=False))
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    trimesh.util.concatenate(parts).export(path)
    return path


def sorted_triangles(scene) -> np.ndarray:
    """Every triangle of a scene (world corners, albedo, emission), sorted: geometry compared as a set."""
    m = scene.mesh
    idx = m.indices.astype(np.int64)
    t = (m.positions.astype(np.float64) + m.origin)[idx].reshape(len(idx), -1)
    rows = np.concatenate([t, m.albedo[idx[:, 0]], m.emission[idx[:, 0]]], axis=1)
    return rows[np.lexsort(rows.T[::-1])]


def comment_before(text: str, line_start: str) -> str:
    """The line before the first line of ``text`` that starts with ``line_start``."""
    lines = text.splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith(line_start))
    return lines[i - 1]


def test_a_mesh_with_any_file_name_gives_a_scene_that_bakes_from_anywhere(tmp_path: Path, monkeypatch,
                                                                         capsys: pytest.CaptureFixture[str]) -> None:
    weird = tmp_path / 'a "quoted" \\ back\nslashed dir'     # a quote, a backslash and a newline in a folder name
    mesh = street_mesh(weird)
    out = tmp_path / "found"
    assert main(["streets", str(mesh), "--out", str(out), "--quiet"]) == 0
    text = (out / "scene.toml").read_text(encoding="utf-8")
    doc = tomllib.loads(text)                                  # a valid TOML file
    assert not os.path.isabs(doc["mesh"]["file"])              # both under tmp_path: relative to the written file
    assert (out / doc["mesh"]["file"]).resolve() == mesh.resolve()
    assert doc["effects"] == list(DEFAULT_EFFECTS) and doc["sky"] == DEFAULT_SKY
    assert doc["ground"] == {"enabled": False}                 # the mesh's own ground lies under the street
    assert len(doc["streets"]) == 1 and doc["streets"][0]["axis"] == "x"
    for start in ("effects =", "[sky]", "[mesh]", "[ground]", "[[streets]]"):
        assert comment_before(text, start).startswith("# "), start
    assert "progress:" not in capsys.readouterr().err          # --quiet

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    scene = load_scene(out / "scene.toml")
    assert scene.mesh.triangle_count == 6 * 12 + 2 and scene.effects == frozenset(DEFAULT_EFFECTS)
    assert scene.streets[0].facade_min == pytest.approx(-8.0, abs=0.05)
    assert scene.streets[0].facade_max == pytest.approx(8.0, abs=0.05)
    assert "z-fight" not in capsys.readouterr().err


def test_a_mesh_without_ground_keeps_the_default_plane(tmp_path: Path) -> None:
    out = tmp_path / "found"
    assert main(["streets", str(street_mesh(tmp_path / "m", ground_y=None)), "--out", str(out), "--quiet"]) == 0
    text = (out / "scene.toml").read_text()
    assert tomllib.loads(text)["ground"] == {"enabled": True}
    assert "only 0%" in comment_before(text, "[ground]")
    assert load_scene(out / "scene.toml").mesh.triangle_count == 6 * 12 + 2     # the boxes + the default quad


def test_path_text_is_relative_below_a_common_folder_else_absolute(tmp_path: Path) -> None:
    assert path_text(tmp_path / "a" / "m.ply", tmp_path / "b" / "c") == os.path.join("..", "..", "a", "m.ply")
    assert path_text(Path("/") / "m.ply", tmp_path) == str(Path("/") / "m.ply")


def test_a_bundled_scene_with_procedural_buildings_is_taken_whole(tmp_path: Path) -> None:
    out = tmp_path / "s"
    assert main(["streets", "crossing", "--out", str(out), "--quiet"]) == 0
    text = (out / "scene.toml").read_text()
    doc = tomllib.loads(text)
    assert doc["mesh"] == [{"scene": "crossing"}]
    source = tomllib.loads((Path(__file__).resolve().parents[2] / "city_scenes" / "crossing.toml").read_text())
    assert doc["effects"] == source["effects"] and doc["sky"] == source["sky"]
    written, crossing = load_scene(out / "scene.toml"), load_scene("crossing")
    assert len(written.streets) == 2
    # the same buildings, windows and ground, triangle for triangle
    assert np.array_equal(sorted_triangles(written), sorted_triangles(crossing))


def test_a_scene_file_s_mesh_tables_are_copied_with_paths_for_the_written_file(tmp_path: Path, monkeypatch) -> None:
    src = tmp_path / "project"
    street_mesh(src / "parts", ground_y=None)
    street_mesh(src / "parts", ground_y=None, name="skip_me.ply")
    street_mesh(src / "terrain", ground_y=0.0, name="ground.ply", buildings=False)
    (src / "city.toml").write_text(
        'name = "city"\neffects = ["sun_light", "sky_light"]\n'
        '[sky]\ntype = "uniform"\nradiance = 1.0\n'
        '[[mesh]]\nglob = "parts/*.ply"\nexclude = ["*skip*"]\n'
        '[[mesh]]\nfile = "terrain/ground.ply"\ncrop = { min = [-50.0, -5.0, -50.0], max = [100.0, 5.0, 50.0] }\n'
        'crop_by = "triangle"\n')
    out = tmp_path / "deep" / "out"
    assert main(["streets", str(src / "city.toml"), "--out", str(out), "--quiet"]) == 0
    text = (out / "scene.toml").read_text()
    doc = tomllib.loads(text)
    assert doc["mesh"][0] == {"files": [os.path.join("..", "..", "project", "parts", "street.ply")]}
    assert "expanded" in comment_before(text, "[[mesh]]")
    assert doc["mesh"][1]["file"] == os.path.join("..", "..", "project", "terrain", "ground.ply")
    assert doc["mesh"][1]["crop_by"] == "triangle" and doc["mesh"][1]["crop"]["max"] == [100.0, 5.0, 50.0]
    assert doc["effects"] == ["sun_light", "sky_light"] and doc["sky"] == {"type": "uniform", "radiance": 1.0}
    assert doc["ground"] == {"enabled": False}
    assert "it is on in" in comment_before(text, "[ground]")
    monkeypatch.chdir(tmp_path)
    written, source = load_scene(out / "scene.toml"), load_scene(src / "city.toml")
    assert written.mesh.triangle_count == 6 * 12 + 2 == source.mesh.triangle_count - 2     # less the default ground


def test_bad_options_are_one_line_naming_the_option_before_anything(tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    mesh = street_mesh(tmp_path / "m")
    out = tmp_path / "out"
    for option, value in (("--spacing", "1e-9"), ("--spacing", "nan"), ("--min-length", "0"),
                          ("--min-length", "-inf"), ("--rotation", "inf")):
        assert main(["streets", str(mesh), "--out", str(out), f"{option}={value}"]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"envcap: error: {option} must be") and err.count("\n") == 1, err
        assert "StreetSearch" not in err and not out.exists()
    assert main(["streets", str(tmp_path / "missing.ply"), "--out", str(out)]) == 2
    assert "mesh file" in capsys.readouterr().err and not out.exists()


def test_a_mesh_without_walls_names_the_up_axis_option(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A mesh read with the wrong up axis has no wall standing up: the error names the option the
    user typed (``--up-axis``), not the library's keyword (``up_axis``), and leaves no output."""
    flat = tmp_path / "flat.ply"
    trimesh.Trimesh([[0, 0, 0], [10, 0, 0], [0, 0, 10]], [[0, 1, 2]]).export(flat)   # a ground triangle, y up
    out = tmp_path / "out"
    assert main(["streets", str(flat), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err == (f"envcap: error: {flat}: no walls found: the mesh has no near-vertical triangles when read with "
                   f"--up-axis y; is that the file's up axis?\n"), err
    assert not out.exists()
    assert main(["streets", str(flat), "--out", str(out), "--quiet", "--up-axis", "z"]) == 0   # z up: it stands


def test_out_is_claimed_before_the_mesh_is_read(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    broken = tmp_path / "broken.ply"
    broken.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 999999\nproperty float x\nend_header\n\x00")
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    # a refused output is reported, not the unreadable mesh: nothing was read before the claim
    assert main(["streets", str(broken), "--out", str(foreign)]) == 2
    err = capsys.readouterr().err
    assert "not written by envcap" in err and "broken.ply" not in err and "progress:" not in err
    assert (foreign / "notes.txt").read_text() == "mine"
    assert main(["streets", str(broken), "--out", str(tmp_path / "fresh")]) == 2
    err = capsys.readouterr().err
    assert "broken.ply" in err.splitlines()[-1] and not (tmp_path / "fresh").exists()


def test_progress_goes_to_stderr_stage_by_stage(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["streets", str(street_mesh(tmp_path / "m")), "--out", str(tmp_path / "out")]) == 0
    captured = capsys.readouterr()
    stages = [ln.split(":")[1].strip() for ln in captured.err.splitlines() if ln.startswith("progress: ")]
    assert stages == ["import", "import", "streets", "streets", "ground", "ground", "write", "write"]
    assert "progress: " not in captured.out and "1 streets, 0 intersections" in captured.out


def test_a_mesh_table_scene_key_takes_nothing_else_and_one_level(tmp_path: Path) -> None:
    def scene(text: str) -> Path:
        path = tmp_path / f"s{len(list(tmp_path.iterdir()))}.toml"
        path.write_text('effects = []\n[sky]\ntype = "uniform"\nradiance = 1.0\n' + text)
        return path

    with pytest.raises(ValueError, match=r"mesh: 'scene' takes .* no other key \(also has file\)"):
        load_scene(scene('[mesh]\nscene = "canyon"\nfile = "x.ply"\n'))
    with pytest.raises(FileNotFoundError, match="mesh.scene: no bundled scene named 'nope'"):
        load_scene(scene('[mesh]\nscene = "nope"\n'))
    inner = scene('[mesh]\nscene = "canyon"\n')
    with pytest.raises(ValueError, match="only one level"):
        load_scene(scene(f'[mesh]\nscene = "{inner.name}"\n'))
    alone = scene('[ground]\nenabled = false\n[mesh]\nscene = "canyon"\n')
    assert load_scene(alone).mesh.triangle_count == load_scene("canyon").mesh.triangle_count - 2   # canyon less its ground


def test_a_scene_that_can_be_written_neither_way_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Buildings from its own streets (taken whole by ``scene = ...``) and geometry from another scene
    (one level only): refused, nothing written."""
    src = tmp_path / "two_levels.toml"
    src.write_text('effects = []\n[sky]\ntype = "uniform"\nradiance = 1.0\n[[mesh]]\nscene = "canyon"\n'
                   '[[streets]]\nname = "s"\naxis = "x"\nstart = 0.0\nend = 60.0\nwidth = 16.0\n'
                   '[streets.side_min]\nrandom = { width = [12.0, 20.0], height = [10.0, 20.0] }\n')
    assert main(["streets", str(src), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "one level only" in err and not (tmp_path / "out").exists()
