"""Streets at any angle in the scene (issue 10): ``[[streets]] p0/p1/width`` in TOML, the framed
:class:`envcap.scene.model.Street` (frame coordinates, world plan box) and its one-line errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from envcap.core.resources import city_scenes_dir
from envcap.scene import scene_from_dict
from envcap.scene.model import Street
from envcap.scene.parse import parse_scene, read_toml


def _doc(**street) -> dict:
    return {"name": "s", "effects": [], "sky": {"type": "uniform", "radiance": 1.0},
            "streets": [{"name": "diag", **street}]}


def test_p0_p1_street_is_a_framed_street_along_its_frame_x():
    spec = parse_scene(_doc(p0=[10.0, 5.0], p1=[10.0 + 30.0 * math.cos(math.radians(30)),
                                                  5.0 + 30.0 * math.sin(math.radians(30))], width=8.0, cross=1.0))
    st = spec.streets[0].street
    assert (st.axis, st.start, st.origin_xz, st.framed) == ("x", 0.0, (10.0, 5.0), True)
    assert st.yaw_deg == pytest.approx(30.0, abs=1e-12) and st.end == pytest.approx(30.0, abs=1e-12)
    assert (st.facade_min, st.facade_max, st.center_line) == (-3.0, 5.0, 1.0)
    # the centre line's far end is p1, shifted by `cross` along the left normal (-sin 30, cos 30)
    a = math.radians(30)
    end = st.to_world([st.end, 0.0, st.center_line])
    assert np.allclose(end, [10 + 30 * math.cos(a) - math.sin(a), 0.0, 5 + 30 * math.sin(a) + math.cos(a)], atol=1e-12)
    assert np.allclose(st.to_frame(end), [st.end, 0.0, 1.0], atol=1e-12)
    # the world plan box of the rectangle: corners (0|30 along) x (-3|5 across), turned by 30 deg
    c, s = math.cos(a), math.sin(a)
    xs = [10 + u * c - v * s for u in (0, 30) for v in (-3, 5)]
    zs = [5 + u * s + v * c for u in (0, 30) for v in (-3, 5)]
    assert np.allclose(st.plan_box(), (min(xs), max(xs), min(zs), max(zs)), atol=1e-12)
    assert np.allclose(st.plan_box(2.0), (min(xs) - 2 * (c + s), max(xs) + 2 * (c + s),
                                          min(zs) - 2 * (c + s), max(zs) + 2 * (c + s)), atol=1e-12)


def test_axis_streets_keep_the_world_frame():
    st = parse_scene(_doc(axis="z", start=-5.0, end=5.0, width=4.0, cross=2.0)).streets[0].street
    assert (st.yaw_deg, st.origin_xz, st.framed) == (0.0, (0.0, 0.0), False)
    assert st.plan_box(1.0) == (-1.0, 5.0, -6.0, 6.0)
    pts = np.array([[1.5, 2.0, -3.25]])
    assert np.array_equal(st.to_frame(pts), pts) and np.array_equal(st.to_world(pts), pts)


@pytest.mark.parametrize("street,msg", [
    ({"p0": [0, 0], "p1": [10, 5], "axis": "x", "width": 5}, r"streets\[0\]: give either p0/p1 or axis .* \(also has axis\)"),
    ({"p0": [0, 0], "p1": [10, 5], "start": 0, "end": 3, "width": 5}, r"not both \(also has start, end\)"),
    ({"p0": [3, 4], "p1": [3, 4], "width": 5}, r"streets\[0\]: p0 and p1 are the same point \[3.0, 4.0\]"),
    ({"p0": [0, float("nan")], "p1": [1, 1], "width": 5}, r"streets\[0\].p0: must be finite"),
    ({"p0": [0, 0], "p1": [float("inf"), 1], "width": 5}, r"streets\[0\].p1: must be finite"),
    ({"p0": [0, 0], "width": 5}, r"streets\[0\]: a street by its ends needs both p0 and p1"),
    ({"p0": [0, 0, 0], "p1": [1, 1], "width": 5}, r"streets\[0\].p0: expected a list of 2 numbers"),
    ({"p0": [0, 0], "p1": [10, 5], "width": 5, "side_min": {"wall": {"height": 5}}},
     r"streets\[0\]: side_min build along an axis street; a p0/p1 street takes its buildings from a \[mesh\]"),
    ({"p0": [0, 0], "p1": [10, 5], "width": 0}, r"streets\[0\].width: must be positive"),
])
def test_p0_p1_errors_are_one_line_and_name_the_street(street, msg):
    with pytest.raises(ValueError, match=msg) as err:
        parse_scene(_doc(**street))
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("kw,msg", [
    ({"axis": "z", "yaw_deg": 10.0}, "must have axis 'x'"),
    ({"axis": "z", "origin_xz": (1.0, 0.0)}, "must have axis 'x'"),
    ({"yaw_deg": float("nan")}, "yaw_deg and origin_xz must be finite"),
    ({"origin_xz": (0.0, float("inf"))}, "yaw_deg and origin_xz must be finite"),
    ({"origin_xz": (1.0,)}, "origin_xz two numbers"),
])
def test_framed_street_model_errors(kw, msg):
    args = {"name": "a", "axis": "x", "start": 0.0, "end": 10.0, "facade_min": -2.0, "facade_max": 2.0} | kw
    with pytest.raises(ValueError, match=msg):
        Street(**args)


def test_generated_city_all_lists_streets_at_many_angles_some_on_terrain():
    path = city_scenes_dir() / "generated_city_all.toml"
    spec = parse_scene(read_toml(path), base_dir=path.parent, default_name="generated_city_all")
    streets = [s.street for s in spec.streets]
    yaws = sorted({round(st.yaw_deg % 180.0) for st in streets})
    assert yaws == [7, 12, 17, 71, 82, 97, 133, 138]
    assert all(st.framed and st.axis == "x" for st in streets)
    assert sum(st.follow_terrain for st in streets) == 6 and len(streets) == 11
    assert [m.rotation_deg for m in spec.meshes] == [0.0, 0.0]      # the city as its files are: no turn


def test_framed_street_without_mesh_builds_the_ground_under_it():
    scene = scene_from_dict(_doc(p0=[100.0, 200.0], p1=[140.0, 230.0], width=10.0))
    lo, hi = scene.mesh.world_bounds()
    x0, x1, z0, z1 = scene.streets[0].plan_box()
    assert lo[0] <= x0 and hi[0] >= x1 and lo[2] <= z0 and hi[2] >= z1   # the ground quad is centred on it


def _turned_street_scene(tmp_path, ramp: bool):
    """Two 80 m buildings 12 m apart, turned so the street between them runs at 30 deg, over a
    ramp rising 0.1 m per m along world x (or nothing)."""
    import trimesh

    for k, b in enumerate([[[-40, 0, 6], [40, 12, 16]], [[-40, 0, -16], [40, 10, -6]]]):
        trimesh.creation.box(bounds=b).export(tmp_path / f"b{k}.ply")
    text = ('effects = []\nsky = { type = "uniform", radiance = 1.0 }\n[ground]\nenabled = false\n'
            '[[mesh]]\nglob = "b*.ply"\nrotation_deg = -30.0\n')
    if ramp:
        xs = np.arange(-100.0, 101.0, 10.0)
        gx, gz = np.meshgrid(xs, xs)
        k = len(xs)
        i = (np.arange(k - 1)[:, None] * k + np.arange(k - 1)[None, :]).ravel()
        faces = np.concatenate([np.stack([i, i + k, i + 1], 1), np.stack([i + 1, i + k, i + k + 1], 1)])
        verts = np.stack([gx.ravel(), 0.1 * gx.ravel() + 10.0, gz.ravel()], axis=1)
        trimesh.Trimesh(verts, faces, process=False).export(tmp_path / "ramp.ply")
        text += '[[mesh]]\nfile = "ramp.ply"\n'
    (tmp_path / "s.toml").write_text(text)
    return tmp_path / "s.toml"


@pytest.mark.parametrize("ramp", [True, False])
def test_envcap_streets_writes_p0_p1_streets_and_follow_terrain(tmp_path, ramp, capsys):
    from envcap.cli import main

    path = _turned_street_scene(tmp_path, ramp)
    assert main(["streets", str(path), "--out", str(tmp_path / "out")]) == 0
    found = (tmp_path / "out" / "scene.toml").read_text()
    tables = found[found.index("[[streets]]"):]
    assert "axis" not in tables and "p0 = [" in tables and "p1 = [" in tables and "width = 12.00" in tables
    assert ("follow_terrain = true" in tables) == ramp
    if ramp:  # 0.1 m/m over the street's 68.4 m of world x
        assert "varies by 6.8" in tables
    # The written tables are a scene's streets: appended to the source, they load as a framed street.
    import tomllib

    doc = tomllib.loads(path.read_text() + "\n" + tables)
    st = scene_from_dict(doc, base_dir=tmp_path).streets[0]
    assert st.yaw_deg == pytest.approx(30.0, abs=0.05) and st.width == pytest.approx(12.0, abs=0.01)
    assert st.follow_terrain == ramp
