"""Issue 10, walls 1-3: plane fitting never crashes, wrong setups are reported before the bake,
far fitted planes are reported, and the inside-geometry warning says where and why."""

from __future__ import annotations

import numpy as np
import trimesh

from envcap.core import cube
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.planes import FittedPlanes, PerPlane, Planes, fit_planes, unfitted_but_seen
from envcap.probeset.street_checks import inside_geometry_warning, plane_fit_warnings, street_setup_warnings
from envcap.scene import load_scene


def _sparse_ground(n: int = 32, count: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """A capture that sees ``count`` downward texels, each at a very different distance."""
    dirs = cube.texel_directions(n)
    d, a = np.full((6, n, n), 1000.0), np.zeros((6, n, n))
    for k, (f, i, j) in enumerate(np.argwhere(dirs[..., 1] < -0.9)[:count]):
        a[f, i, j], d[f, i, j] = 1.0, 1.0 + 3.0 * k
    return d, a


def test_sparse_votes_fall_back_instead_of_crashing():
    """Old: ``ValueError: attempt to get argmin of an empty sequence`` (after the whole capture)."""
    d, a = _sparse_ground()
    f = fit_planes((0.0, 2.0, 0.0), d, a, "x")
    assert f.ground is None and f.coverage_sr.ground >= 0.05
    assert unfitted_but_seen(f) == ("ground",)
    lines = plane_fit_warnings("main", 10.0, [(3, Planes(-5, 5, 0), f)])
    assert len(lines) == 1 and "street 'main'" in lines[0] and "probe 3 (of 1)" in lines[0]
    assert "no clear ground plane" in lines[0] and "nominal plane is used" in lines[0]


def test_far_fitted_planes_are_reported_with_street_and_distance():
    per = PerPlane(1.0, 1.0, 1.0)
    near = FittedPlanes(-5.5, 5.0, 0.0, per, per)
    far = FittedPlanes(-205.0, 5.0, 0.0, per, per)
    assert plane_fit_warnings("s", 10.0, [(0, Planes(-5, 5, 0), near)]) == []
    (line,) = plane_fit_warnings("s", 10.0, [(0, Planes(-5, 5, 0), near), (1, Planes(-5, 5, 0), far)])
    assert "street 's'" in line and "up to 200.00 m" in line and "probe 1, facade_min" in line and "5 m" in line


def _box_scene(tmp_path, boxes, street: str, mesh_extra: str = "", inward: bool = False) -> str:
    for k, bounds in enumerate(boxes):
        m = trimesh.creation.box(bounds=bounds)
        if inward:
            m.faces = m.faces[:, ::-1]
        m.export(tmp_path / f"b{k}.ply")
    path = tmp_path / "s.toml"
    path.write_text('effects = ["sky_light"]\nsky = { type = "uniform", radiance = 1.0 }\n'
                    f'[mesh]\nglob = "*.ply"\n{mesh_extra}\n[[streets]]\n{street}\n')
    return str(path)


STREET = 'name = "main"\naxis = "x"\nstart = -20.0\nend = 20.0\nwidth = 10.0\ncross = 0.0'
BOXES = [[[-20, 0, 5], [20, 12, 15]], [[-20, 0, -15], [20, 9, -5]]]


def test_a_street_outside_the_mesh_is_reported_before_the_bake(tmp_path):
    """Old: nothing said; the fitted planes came out hundreds of meters off."""
    far = STREET.replace("cross = 0.0", "cross = 300.0")
    scene = load_scene(_box_scene(tmp_path, BOXES, far))
    (line,) = street_setup_warnings(scene)
    assert "street 'main'" in line and "lies outside the scene's walls" in line and "up_axis" in line
    assert street_setup_warnings(load_scene(_box_scene(tmp_path, BOXES, STREET))) == []


def test_a_street_with_no_wall_near_it_is_reported(tmp_path):
    boxes = BOXES + [[[100, 0, 100], [110, 5, 110]]]
    shifted = STREET.replace("start = -20.0\nend = 20.0", "start = 40.0\nend = 60.0")
    (line,) = street_setup_warnings(load_scene(_box_scene(tmp_path, boxes, shifted)))
    assert "has no wall near its facade planes" in line


def test_inward_boxes_are_fixed_and_the_inside_warning_says_why(tmp_path, capsys):
    """Old: black facades and, per probe, ``stands inside geometry`` with float noise in the position."""
    path = _box_scene(tmp_path, BOXES, STREET, 'winding = "keep"', inward=True)
    bake_probe_set(load_scene(path), resolution=8, spacing=20.0, progress=False)
    err = capsys.readouterr().err
    assert "probe 0 of street 'main' at (-10.00, 2.00, 0.00) stands inside geometry" in err, err
    assert "back faces over" in err and "inward-wound" in err
    path = _box_scene(tmp_path, BOXES, STREET, "", inward=True)
    ps = bake_probe_set(load_scene(path), resolution=8, spacing=20.0, progress=False)
    err = capsys.readouterr().err
    assert "flipped 2 of 2 meshes wound inward (files b0.ply, b1.ply)" in err and "inside geometry" not in err
    fitted = ps.manifest.streets[0].probes[0].fitted_planes
    assert abs(fitted.facade_min + 5.0) < 0.1 and abs(fitted.facade_max - 5.0) < 0.1


def test_the_inside_warning_names_a_closed_volume():
    line = inside_geometry_warning("a", 4, (1.234567, 2.0, -0.4800000000000004), np.ones((6, 4, 4), bool))
    assert line.startswith("probe 4 of street 'a' at (1.23, 2.00, -0.48)") and "100 %" in line
    assert "inside a closed volume" in line
