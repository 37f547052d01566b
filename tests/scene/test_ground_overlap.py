"""Imported surfaces on the default ground plane are warned about at load, once per mesh table
(``envcap.scene.ground_overlap``): a real PLY with a terrain quad at, near and above y = 0."""

from __future__ import annotations

from pathlib import Path

import pytest
import trimesh

from envcap.scene import load_scene
from envcap.scene.ground_overlap import GROUND_OVERLAP_TOLERANCE_M, ground_overlap
from envcap.scene.mesh_import import import_mesh


def city(folder: Path, ground_y: float) -> Path:
    """Two 20 m boxes standing on y = 0 (their floors face down there) and an up-facing 90 m x
    60 m terrain quad at ``ground_y``, as one PLY."""
    g = ground_y
    terrain = trimesh.Trimesh([[-10, g, -30], [80, g, -30], [80, g, 30], [-10, g, 30]], [[0, 2, 1], [0, 3, 2]],
                              process=False)
    boxes = [trimesh.creation.box(bounds=[[x, 0.0, 8.0], [x + 20.0, 15.0, 22.0]]) for x in (0.0, 30.0)]
    path = folder / f"city_{g:g}.ply"
    trimesh.util.concatenate([terrain, *boxes]).export(path)
    return path


def scene(folder: Path, mesh: Path, ground: str = "") -> Path:
    path = folder / f"{mesh.stem}{'_off' if ground else ''}.toml"
    path.write_text(f'effects = []\n[sky]\ntype = "uniform"\nradiance = 1.0\n{ground}\n'
                    f'[[mesh]]\nfile = "{mesh.name}"\n[[mesh]]\nfile = "{mesh.name}"\noffset = [0.0, 5.0, 0.0]\n'
                    f'[[streets]]\nname = "s"\naxis = "x"\nstart = 0.0\nend = 50.0\nwidth = 16.0\n')
    return path


def test_the_area_on_the_plane_is_the_up_facing_surface_within_the_tolerance(tmp_path: Path) -> None:
    on = ground_overlap(import_mesh(city(tmp_path, 0.0)))
    assert on.area_m2 == pytest.approx(90.0 * 60.0) and on.triangles == 2     # the box floors face down: not counted
    assert ground_overlap(import_mesh(city(tmp_path, 0.03))).area_m2 == pytest.approx(5400.0)   # close to it
    assert ground_overlap(import_mesh(city(tmp_path, 0.5))).area_m2 == 0.0
    assert 0.03 < GROUND_OVERLAP_TOLERANCE_M < 0.5


def test_a_scene_with_a_mesh_on_its_default_ground_is_warned_at_load(tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    path = scene(tmp_path, city(tmp_path, 0.0))
    load_scene(path)
    warnings = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("envcap: warning:")]
    # mesh[0] lies on the plane; mesh[1], the same file raised by 5 m, does not
    assert len(warnings) == 1, warnings
    assert warnings[0].startswith(f"envcap: warning: {path}: mesh[0]: 5,400 m² of its up-facing surfaces")
    assert "z-fight" in warnings[0] and "[ground] enabled = false" in warnings[0]

    load_scene(scene(tmp_path, city(tmp_path, 0.0), ground="[ground]\nenabled = false\n"))
    load_scene(scene(tmp_path, city(tmp_path, 0.5)))
    assert "z-fight" not in capsys.readouterr().err
