"""City scenes: bundled TOML scenes, hand-derived buildings and windows, street planes, mesh import
transform, and bad inputs.  References are hand-derived coordinates, not the builder itself."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest
import trimesh

from envcap.cli import main as cli_main
from envcap.scene import EFFECTS, import_mesh, import_transform, list_scenes, load_scene, scene_from_dict

BUNDLED = ("canyon", "asymmetric", "crossing", "avenue", "planes", "imported")


def _scene(**over):
    """A minimal valid scene dict: one street along X, facades at z = 0 and z = 10, no ground."""
    d = {
        "name": "t",
        "effects": ["sky_light"],
        "sky": {"type": "uniform", "radiance": [1.0, 1.0, 1.0]},
        "ground": {"enabled": False},
        "streets": [{"name": "s", "axis": "x", "start": 0.0, "end": 10.0, "width": 10.0, "cross": 5.0}],
    }
    d.update(over)
    return d


def _street(**over):
    s = {"name": "s", "axis": "x", "start": 0.0, "end": 10.0, "width": 10.0, "cross": 5.0}
    s.update(over)
    return s


def _tri(mesh):
    return mesh.positions[mesh.indices].astype(np.float64)  # (T, 3, 3)


def _face_normals(mesh):
    t = _tri(mesh)
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


# ------------------------------------------------------------------------------------ bundled


@pytest.fixture(scope="module")
def bundled():
    return {name: load_scene(name) for name in BUNDLED}


def test_list_scenes_has_all_bundled_with_descriptions():
    listed = dict(list_scenes())
    for name in BUNDLED:
        assert name in listed and len(listed[name]) > 20


@pytest.mark.parametrize("name", BUNDLED)
def test_bundled_scene_is_sane(bundled, name):
    s = bundled[name]
    m = s.mesh
    v, t = m.positions.shape[0], m.triangle_count
    assert m.positions.dtype == np.float32 and m.indices.dtype == np.uint32
    assert m.indices.shape == (t, 3) and int(m.indices.max()) < v
    for a in (m.positions, m.normals, m.albedo, m.emission):
        assert a.shape == (v, 3) and np.all(np.isfinite(a))
    np.testing.assert_allclose(np.linalg.norm(m.normals, axis=1), 1.0, atol=1e-6)
    assert np.all((m.albedo >= 0) & (m.albedo <= 1)) and np.all(m.emission >= 0)
    # winding (counter-clockwise seen from the front) agrees with the stored normal, every triangle
    fn = _face_normals(m)
    np.testing.assert_allclose(fn, m.normals[m.indices[:, 0]], atol=1e-4)
    # nothing below the ground, nothing absurdly tall
    assert m.positions[:, 1].min() >= 0.0 and 5.0 < m.positions[:, 1].max() < 100.0
    assert s.streets and set(s.effects) <= set(EFFECTS)
    # no geometry above the ground strictly inside any roadway (buildings stand at or behind the
    # nominal facade planes; window quads stand out by 1.5 cm only)
    up = m.positions[:, 1] > 1e-4
    for st in s.streets:
        p = m.positions[up].astype(np.float64)
        a, c = p[:, st.along_index], p[:, st.cross_index]
        inside = (a > st.start + 1e-3) & (a < st.end - 1e-3) & (c > st.facade_min + 0.05) & (c < st.facade_max - 0.05)
        assert not np.any(inside), f"{name}/{st.name}: {int(inside.sum())} vertices inside the roadway"


def test_bundled_triangle_counts_and_effects(bundled):
    assert 40_000 <= bundled["canyon"].mesh.triangle_count <= 60_000
    for name in ("canyon", "asymmetric", "crossing", "avenue"):
        assert bundled[name].meta["windows"] > 500, name
    assert bundled["canyon"].effects == frozenset(EFFECTS)
    assert "sun_shadows" not in bundled["crossing"].effects
    assert "sun_light" not in bundled["avenue"].effects
    assert "emissive_windows" not in bundled["asymmetric"].effects
    assert len({s.effects for s in bundled.values()}) >= 4
    # lit windows carry emission, scenes that call for it have some
    for name in ("canyon", "crossing", "avenue"):
        assert bundled[name].meta["lit_windows"] > 0 and bundled[name].mesh.emission.max() >= 50.0
    crossing = bundled["crossing"]
    assert sorted(st.axis for st in crossing.streets) == ["x", "z"]
    avenue = bundled["avenue"].streets[0]
    assert avenue.width == pytest.approx(60.0)


def test_asymmetric_has_setbacks_and_gaps(bundled):
    s = bundled["asymmetric"]
    st = s.streets[0]
    m = s.mesh
    fn = m.normals[m.indices[:, 0]]
    tri = _tri(m)
    # front faces of the low side: normal +X (toward the street), above ground, left of the street
    front = (fn[:, 0] > 0.99) & (tri[:, :, 1].max(1) > 0) & (tri[:, 0, 0] < st.facade_min + 0.1)
    xs = np.unique(np.round(tri[front, 0, 0], 3))
    assert xs.max() > st.facade_min - 0.1  # some flush (window quads in front of flush walls)
    assert xs.min() < st.facade_min - 2.0  # and some set back by meters
    # gaps: the low side's fronts do not cover the whole street length
    zs = tri[front][:, :, 2]
    covered = np.zeros(300, bool)
    for z0, z1 in zip(zs.min(1), zs.max(1)):
        covered[int(np.floor(z0 - st.start)):int(np.ceil(z1 - st.start))] = True
    assert 0.5 < covered.mean() < 0.97


def test_planes_scene_facades_lie_exactly_on_the_planes(bundled):
    s = bundled["planes"]
    st = s.streets[0]
    m = s.mesh
    tri, fn = _tri(m), m.normals[m.indices[:, 0]]
    for sign, plane in ((1, st.facade_min), (-1, st.facade_max)):
        facing = fn[:, 2] * sign > 0.99  # faces turned toward the street
        near = np.abs(tri[:, :, 2] - plane).max(1) < 1.0
        sel = facing & near
        assert sel.sum() > 500
        assert np.all(tri[sel][:, :, 2] == np.float32(plane))
        assert len(np.unique(m.albedo[m.indices[sel, 0]], axis=0)) == 2  # a checker of two colors
    ground = fn[:, 1] > 0.99
    assert np.all(tri[ground][:, :, 1][tri[ground][:, :, 1].max(1) < 1.0] == 0.0)


def test_loading_is_deterministic():
    a, b = load_scene("asymmetric"), load_scene("asymmetric")
    assert np.array_equal(a.mesh.positions, b.mesh.positions) and np.array_equal(a.mesh.emission, b.mesh.emission)


def test_imported_bundled_block_lands_beside_its_street(bundled):
    s = bundled["imported"]
    tri = _tri(s.mesh)
    boxes = tri[tri[:, :, 1].max(1) > 0].reshape(-1, 3)
    # generate.py: file x in [-40, 40], file y in [5, 15] u [-15, -5]; z-up, rot 90, offset (100, 0, 50)
    np.testing.assert_allclose(boxes.min(0)[[0, 2]], [85.0, 10.0], atol=1e-4)
    np.testing.assert_allclose(boxes.max(0)[[0, 2]], [115.0, 90.0], atol=1e-4)
    assert np.all((boxes[:, 0] <= 95.0 + 1e-4) | (boxes[:, 0] >= 105.0 - 1e-4))
    st = s.streets[0]
    assert (st.axis, st.facade_min, st.facade_max) == ("z", 95.0, 105.0)
    assert len(np.unique(s.mesh.albedo, axis=0)) > 5  # vertex colors became albedo


# ------------------------------------------------------------------------------- hand-derived


def test_explicit_buildings_are_boxes_where_expected():
    street = _street(
        side_min={"buildings": [{"gap": 2.0, "width": 4.0, "height": 6.0, "depth": 3.0, "setback": 1.0}]},
        side_max={"buildings": [{"width": 3.0, "height": 9.0, "depth": 2.0, "setback": 0.5}]},
    )
    s = scene_from_dict(_scene(streets=[street]))
    assert s.meta["buildings"] == 2 and s.mesh.triangle_count == 20  # 2 boxes x 5 faces x 2
    tri, fn = _tri(s.mesh), s.mesh.normals[s.mesh.indices[:, 0]]
    # facades at z = 0 (min side) and z = 10 (max side)
    boxes = {
        "min": (np.array([2.0, 0.0, -4.0]), np.array([6.0, 6.0, -1.0]), np.array([0, 0, 1.0])),
        "max": (np.array([0.0, 0.0, 10.5]), np.array([3.0, 9.0, 12.5]), np.array([0, 0, -1.0])),
    }
    for key, (lo, hi, front_n) in boxes.items():
        sel = np.all((tri >= lo - 1e-5) & (tri <= hi + 1e-5), axis=(1, 2))
        assert sel.sum() == 10, key
        corners = np.unique(tri[sel].reshape(-1, 3), axis=0)
        expect = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        np.testing.assert_allclose(np.sort(corners, axis=0), np.sort(expect, axis=0), atol=1e-5)
        # normals point out of the box, and the street-facing face is at the front line
        center = 0.5 * (lo + hi)
        assert np.all(np.einsum("ij,ij->i", tri[sel].mean(1) - center, fn[sel]) > 0)
        assert not np.any(fn[sel][:, 1] < -0.5)  # no bottom face
        fr = sel & (fn @ front_n > 0.99)
        assert fr.sum() == 2
        assert np.allclose(tri[fr][:, :, 2], hi[2] if front_n[2] > 0 else lo[2])
    st = s.streets[0]
    assert (st.facade_min, st.facade_max) == (0.0, 10.0)  # nominal planes ignore setbacks


def test_window_grid_hand_derived():
    win = {"width": 1.2, "height": 1.6, "spacing": 3.0, "floor_height": 3.2, "sill": 0.9, "top_margin": 0.5,
           "emissive_fraction": 1.0, "emission": [100.0, 80.0, 60.0], "albedo": [0.05, 0.05, 0.05]}
    street = _street(facade={"windows": win},
                     side_min={"buildings": [{"gap": 1.0, "width": 6.0, "height": 10.0, "depth": 5.0}]})
    s = scene_from_dict(_scene(streets=[street]))
    m = s.mesh
    assert s.meta["windows"] == 6 and s.meta["lit_windows"] == 6  # 2 columns x 3 floors
    tri = _tri(m)
    glass = np.abs(tri[:, :, 2] - 0.015).max(1) < 1e-6  # 1.5 cm in front of the z = 0 facade
    assert glass.sum() == 12
    np.testing.assert_allclose(m.normals[m.indices[glass, 0]], [[0, 0, 1]] * 12)
    rects = {(round(float(t[:, 0].min()), 4), round(float(t[:, 0].max()), 4), round(float(t[:, 1].min()), 4),
              round(float(t[:, 1].max()), 4)) for t in tri[glass]}
    # columns centered at x = 1 + 1.5 and 1 + 4.5; floors at y0 = 0.9, 4.1, 7.3 (12.6 > 10 stops)
    expect = {(x0, x0 + 1.2, y0, y0 + 1.6) for x0 in (1.9, 4.9) for y0 in (0.9, 4.1, 7.3)}
    assert {tuple(round(v, 4) for v in r) for r in rects} == {tuple(round(v, 4) for v in r) for r in expect}
    np.testing.assert_allclose(m.emission[m.indices[glass, 0]], [[100.0, 80.0, 60.0]] * 12)
    # no lit windows when the fraction is 0; frames add 4 strips per window
    win0 = dict(win, emissive_fraction=0.0, frame=0.1)
    s0 = scene_from_dict(_scene(streets=[_street(facade={"windows": win0},
                                                 side_min={"buildings": [{"gap": 1.0, "width": 6.0, "height": 10.0}]})]))
    assert s0.meta["lit_windows"] == 0 and s0.mesh.emission.max() == 0.0
    assert s0.mesh.triangle_count == 10 + 6 * 2 * 5


def test_street_planes_from_description():
    s = scene_from_dict(_scene(streets=[
        {"name": "a", "axis": "z", "along_center": 20.0, "length": 50.0, "width": 12.0, "cross": -3.0, "probe_line": -5.0},
        {"name": "b", "axis": "x", "start": -7.0, "end": 9.0, "width": 4.0},
    ]))
    a, b = s.streets
    assert (a.axis, a.start, a.end, a.facade_min, a.facade_max, a.center_line) == ("z", -5.0, 45.0, -9.0, 3.0, -5.0)
    assert (b.axis, b.start, b.end, b.facade_min, b.facade_max, b.center_line) == ("x", -7.0, 9.0, -2.0, 2.0, 0.0)


def test_street_without_buildings_is_ground_only():
    s = scene_from_dict(_scene(ground={"extent": 100.0, "albedo": 0.3}))
    assert s.mesh.triangle_count == 2
    np.testing.assert_allclose(s.mesh.positions[:, 1], 0.0)
    np.testing.assert_allclose(s.mesh.normals, [[0, 1, 0]] * 4)
    # centered on the street's rectangle (x 0..10, z 0..10)
    np.testing.assert_allclose(s.mesh.positions.min(0), [-45.0, 0.0, -45.0])
    np.testing.assert_allclose(s.mesh.positions.max(0), [55.0, 0.0, 55.0])
    assert (s.streets[0].facade_min, s.streets[0].facade_max) == (0.0, 10.0)


def test_crossing_streets_keep_roadways_clear():
    rnd = {"random": {"width": [5.0, 9.0], "height": [10.0, 20.0], "depth": [10.0, 10.0]}}
    s = scene_from_dict(_scene(streets=[
        {"name": "ew", "axis": "x", "start": -50.0, "end": 50.0, "width": 10.0, "side_min": rnd, "side_max": rnd},
        {"name": "ns", "axis": "z", "start": -50.0, "end": 50.0, "width": 8.0, "side_min": rnd, "side_max": rnd},
    ]))
    p = s.mesh.positions.astype(np.float64)
    assert s.meta["buildings"] > 20
    assert not np.any((np.abs(p[:, 0]) < 4.0 - 1e-4) & (np.abs(p[:, 2]) < 50.0))  # ns roadway
    assert not np.any((np.abs(p[:, 2]) < 5.0 - 1e-4) & (np.abs(p[:, 0]) < 50.0))  # ew roadway
    # corner blocks do not overlap: box interiors are disjoint in the ground plane
    tri, fn = _tri(s.mesh), s.mesh.normals[s.mesh.indices[:, 0]]
    roofs = tri[fn[:, 1] > 0.99]
    rect = np.stack([roofs[:, :, 0].min(1), roofs[:, :, 0].max(1), roofs[:, :, 2].min(1), roofs[:, :, 2].max(1)], 1)
    rect = np.unique(rect, axis=0)
    ox = np.minimum(rect[:, None, 1], rect[None, :, 1]) - np.maximum(rect[:, None, 0], rect[None, :, 0])
    oz = np.minimum(rect[:, None, 3], rect[None, :, 3]) - np.maximum(rect[:, None, 2], rect[None, :, 2])
    overlap = (ox > 1e-4) & (oz > 1e-4)
    np.fill_diagonal(overlap, False)
    assert not overlap.any()


# -------------------------------------------------------------------------------- mesh import


def _box_ply(path: Path, lo, hi, rgb=(255, 128, 0)):
    box = trimesh.creation.box(bounds=[lo, hi])
    box.visual.vertex_colors = np.tile(np.r_[rgb, 255].astype(np.uint8), (len(box.vertices), 1))
    box.export(path)


def test_import_transform_hand_derived(tmp_path):
    f = tmp_path / "box.ply"
    _box_ply(f, [1.0, 2.0, 0.0], [3.0, 5.0, 4.0])  # Z-up box: x 1..3, y 2..5, height 4
    m = import_mesh(f, up_axis="z", offset=(10.0, 0.0, 20.0))
    # (x, y, z) -> (x, z, -y) + offset
    np.testing.assert_allclose(m.positions.min(0), [11.0, 0.0, 15.0], atol=1e-5)
    np.testing.assert_allclose(m.positions.max(0), [13.0, 4.0, 18.0], atol=1e-5)
    # scale 2, rotation 90 deg: file corner (3, 5, 4) -> (6, 10, 8) -> (6, 8, -10) -> (-10, 8, -6) -> +off
    m2 = import_mesh(f, up_axis="z", rotation_deg=90.0, scale=2.0, offset=(10.0, 0.0, 20.0))
    assert np.min(np.linalg.norm(m2.positions - [0.0, 8.0, 14.0], axis=1)) < 1e-4
    np.testing.assert_allclose(m2.positions.min(0), [0.0, 0.0, 14.0], atol=1e-4)
    np.testing.assert_allclose(m2.positions.max(0), [6.0, 8.0, 18.0], atol=1e-4)
    # the same via the matrix
    M = import_transform("z", 90.0, 2.0, (10.0, 0.0, 20.0))
    np.testing.assert_allclose(M @ [3.0, 5.0, 4.0, 1.0], [0.0, 8.0, 14.0, 1.0], atol=1e-12)
    assert np.linalg.det(M[:3, :3]) > 0  # no mirroring
    # flat shading with outward normals, and sRGB 128 -> linear 0.2158605 (published table value)
    assert m2.triangle_count == 12 and m2.positions.shape == (36, 3)
    c = np.array([3.0, 4.0, 16.0])
    tri = m2.positions[m2.indices]
    assert np.all(np.einsum("ij,ij->i", tri.mean(1) - c, m2.normals[m2.indices[:, 0]]) > 0)
    np.testing.assert_allclose(m2.albedo, [[1.0, 0.2158605, 0.0]] * 36, atol=1e-6)


def test_import_directory_of_ply_and_scene_table(tmp_path):
    d = tmp_path / "blk"
    d.mkdir()
    _box_ply(d / "a.ply", [0, 0, 0], [1, 1, 1])
    _box_ply(d / "b.ply", [2, 0, 0], [3, 1, 2])
    (d / "notes.txt").write_text("ignored")
    toml = tmp_path / "s.toml"
    toml.write_text(textwrap.dedent("""
        effects = ["sky_light"]
        sky = { type = "uniform", radiance = [1, 1, 1] }
        ground = { enabled = false }
        [mesh]
        file = "blk"
        up_axis = "y"
        offset = [0.0, 0.0, 5.0]
        [[streets]]
        axis = "x"
        start = 0.0
        end = 3.0
        width = 4.0
        cross = 8.0
    """))
    s = load_scene(toml)
    assert s.name == "s" and s.mesh.triangle_count == 24
    # up_axis "y": file coordinates are world coordinates, then the offset
    np.testing.assert_allclose(s.mesh.positions.min(0), [0.0, 0.0, 5.0], atol=1e-6)
    np.testing.assert_allclose(s.mesh.positions.max(0), [3.0, 1.0, 7.0], atol=1e-6)


# ------------------------------------------------------------------------------- bad inputs


@pytest.mark.parametrize(
    "change, words",
    [
        ({"effects": ["sun_light", "sun_lite"]}, ["sun_lite", "unknown effect"]),
        ({"effects": ["sun_shadows"]}, ["sun_shadows", "needs"]),
        ({"efects": []}, ["efects"]),
        ({"streets": [_street(widht=3.0)]}, ["widht"]),
        ({"streets": [_street(width=0.0)]}, ["width", "positive"]),
        ({"streets": [_street(width=-4.0)]}, ["width", "positive"]),
        ({"streets": [_street(end=0.0)]}, ["end", "start"]),
        ({"streets": [_street(width=float("nan"))]}, ["width", "finite"]),
        ({"streets": [_street(width=True)]}, ["width", "number"]),
        ({"streets": [_street(axis="y")]}, ["axis"]),
        ({"streets": [_street(), _street()]}, ["unique"]),
        ({"streets": [_street(side_min={"buildings": [{"width": 4.0, "height": -1.0}]})]}, ["height", "positive"]),
        ({"streets": [_street(side_min={"buildings": [{"width": 4.0, "height": 5.0, "setback": -1.0}]})]}, ["setback"]),
        ({"streets": [_street(side_min={"random": {"width": [9.0, 3.0], "height": 5.0}})]}, ["width", "larger"]),
        ({"streets": [_street(side_min={"random": {"width": [3.0, 5.0], "height": 5.0, "colour": 1}})]}, ["colour"]),
        ({"streets": [_street(side_min={"random": {"width": 3.0, "height": 5.0}, "wall": {"height": 3.0}})]}, ["only one"]),
        ({"streets": [_street(facade={"windows": {"spacng": 3.0}})]}, ["spacng"]),
        ({"streets": [_street(facade={"windows": {"width": 3.5, "spacing": 3.0}})]}, ["spacing"]),
        ({"streets": [_street(facade={"windows": {"height": 3.0, "floor_height": 3.0}})]}, ["fit"]),
        ({"streets": [_street(facade={"albedo": [1.5, 0.2, 0.2]})]}, ["albedo", "<= 1"]),
        ({"ground": {"extent": 0.0}}, ["extent", "positive"]),
        ({"sky": {"type": "preetham", "turbidty": 3.0}}, ["turbidty"]),
        ({"sky": {"type": "hosek"}}, ["hosek"]),
        ({"streets": []}, ["at least one"]),
    ],
)
def test_bad_scene_dicts_raise_clear_errors(change, words):
    with pytest.raises(ValueError) as ei:
        scene_from_dict(_scene(**change))
    msg = str(ei.value)
    for w in words:
        assert w in msg, msg


def test_bad_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.toml"):
        load_scene(tmp_path / "nope.toml")
    with pytest.raises(FileNotFoundError, match="no bundled scene named 'nope'"):
        load_scene("nope")
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\neffects = ["sky_light"]\nsky = { type = "uniform" \n')
    with pytest.raises(ValueError, match=r"bad\.toml.*line 3"):
        load_scene(bad)
    base = 'effects = ["sky_light"]\nsky = { type = "uniform", radiance = [1, 1, 1] }\n'
    missing = tmp_path / "m.toml"
    missing.write_text(base + '[mesh]\nfile = "gone.ply"\n')
    with pytest.raises(FileNotFoundError, match="gone.ply"):
        load_scene(missing)
    junk = tmp_path / "junk.ply"
    junk.write_bytes(b"this is not a ply file\x00\x01")
    with pytest.raises(ValueError, match="junk.ply"):
        import_mesh(junk)
    nanply = tmp_path / "nan.ply"
    nanply.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n")
    with pytest.raises(ValueError, match="NaN"):
        import_mesh(nanply)
    with pytest.raises(ValueError, match="up_axis"):
        import_mesh(nanply, up_axis="x")
    ll = tmp_path / "ll.toml"
    ll.write_text('effects = ["sky_light"]\nsky = { type = "latlong", file = "sky.exr", scale = 1.0 }\n'
                  '[[streets]]\naxis = "x"\nstart = 0.0\nend = 1.0\nwidth = 1.0\n')
    with pytest.raises(FileNotFoundError, match="sky.exr"):
        load_scene(ll)


def test_degenerate_triangles_are_dropped(tmp_path):
    f = tmp_path / "deg.ply"
    f.write_text("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                 "element face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n2 0 0\n"
                 "3 0 1 2\n3 0 1 3\n")
    m = import_mesh(f)
    assert m.triangle_count == 1
    np.testing.assert_allclose(m.normals, [[0, 0, 1]] * 3)


# ------------------------------------------------------------------------------------- CLI


def test_cli_lists_scenes_and_reports_errors(capsys):
    assert cli_main(["scenes"]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert [ln.split()[0] for ln in out] == [n for n, _ in list_scenes()]
    assert cli_main(["scenes", "--details", "planes"]) == 0
    out = capsys.readouterr().out
    assert "triangles" in out and "facade planes z = -10 / 10 m" in out
    assert cli_main(["scenes", "nope"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("envcap: error:") and "nope" in err and len(err.splitlines()) == 1


def test_preview_shows_walls_and_sky(gl_ctx, tmp_path):
    from PIL import Image

    from envcap.scene.scene_preview import save_previews

    out = save_previews(gl_ctx, load_scene("planes"), tmp_path / "p.png", width=160)
    img = np.asarray(Image.open(out)).astype(int)
    sh = int(160 * 0.6)
    street = img[:sh]
    sky = np.array([0.55, 0.7, 0.9]) * 255
    assert np.abs(street[2, 80] - sky).max() <= 2  # looking down the street: sky in the middle top
    assert np.abs(street[2, 2] - sky).max() > 20  # walls on the sides
    assert np.abs(street[-2, 80] - sky).max() > 20  # ground below
