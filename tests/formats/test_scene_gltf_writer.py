"""``scene.glb`` (envcap.formats.scene_gltf, the ``scene_gltf`` writer): the crop keeps exactly the
triangles near the streets (checked against a per-triangle float64 loop), the file reads back with
trimesh's own glTF importer with the cropped mesh's triangles at its world positions, and the writer
is registered only for one bake and recorded in the manifest's ``files``."""

import dataclasses
import io
import json
import struct
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh

from envcap.formats.registry import WRITERS, select_writers
from envcap.formats.scene_gltf import crop_to_streets, write_scene_glb
from envcap.formats.scene_gltf_writer import NAME, registered_scene_writer
from envcap.probeset.store import read_probe_set, write_probe_set
from envcap.scene import load_scene
from envcap.scene.model import SceneMesh

ORIGIN = np.array([654000.0, 12.0, -5432000.0])   # far from the world origin, like projected coordinates
X0, Z0 = ORIGIN[0], ORIGIN[2]
STREETS = [SimpleNamespace(name="a", axis="x", start=X0 - 40, end=X0 + 40, facade_min=Z0 - 6, facade_max=Z0 + 6),
           SimpleNamespace(name="b", axis="z", start=Z0 + 10, end=Z0 + 90, facade_min=X0 + 100, facade_max=X0 + 110)]


def scattered_mesh(n=300, seed=4, origin=ORIGIN):
    """``n`` small flat-shaded triangles scattered over 400 m x 400 m, plus one 300 m triangle whose
    vertices all lie outside the street boxes but whose box covers street ``a``; some emit."""
    rng = np.random.default_rng(seed)
    c = rng.uniform(-200, 200, (n, 3)) * [1, 0.1, 1]
    tri = c[:, None, :] + rng.uniform(-2, 2, (n, 3, 3))
    tri = np.concatenate([tri, [[[-150, 0, -150], [150, 0, -150], [0, 0, 150]]]])  # (n+1, 3, 3) local m
    pos = tri.reshape(-1, 3).astype(np.float32)
    nrm = np.tile(np.float32([0, 1, 0]), (len(pos), 1))
    alb = rng.uniform(0, 1, (len(pos), 3)).astype(np.float32)
    emi = np.where(rng.uniform(size=(len(pos), 1)) < 0.1, 5.0, 0.0).astype(np.float32) * np.ones(3, np.float32)
    return SceneMesh(pos, nrm, alb, emi, np.arange(len(pos), dtype=np.uint32).reshape(-1, 3), origin)


def reference_keep(mesh, pad, streets=STREETS):
    """Per triangle, float64 world x-z bounds against each padded box (the definition, looped)."""
    keep = []
    for t in mesh.indices:
        w = mesh.origin + mesh.positions[t].astype(np.float64)
        x0, x1, z0, z1 = w[:, 0].min(), w[:, 0].max(), w[:, 2].min(), w[:, 2].max()
        hit = False
        for st in streets:
            a0, a1, c0, c1 = st.start - pad, st.end + pad, st.facade_min - pad, st.facade_max + pad
            bx = (a0, a1, c0, c1) if st.axis == "x" else (c0, c1, a0, a1)
            hit |= x0 <= bx[1] and x1 >= bx[0] and z0 <= bx[3] and z1 >= bx[2]
        keep.append(hit)
    return np.array(keep)


def glb_json(path):
    b = path.read_bytes()
    n = struct.unpack("<I", b[12:16])[0]
    return json.loads(b[20:20 + n])


def test_crop_keeps_the_triangles_near_the_streets():
    mesh = scattered_mesh()
    ref = reference_keep(mesh, 20.0)
    got = crop_to_streets(mesh, STREETS, 20.0)
    assert 5 < ref.sum() < len(ref) - 5 and ref[-1]   # a real crop, the big triangle kept
    world = lambda m: ORIGIN + m.positions[m.indices].astype(np.float64)  # noqa: E731
    np.testing.assert_array_equal(world(got), ORIGIN + mesh.positions[mesh.indices[ref]].astype(np.float64))
    np.testing.assert_array_equal(got.albedo[got.indices], mesh.albedo[mesh.indices[ref]])
    np.testing.assert_array_equal(got.origin, ORIGIN)
    with pytest.raises(ValueError, match="padding"):
        crop_to_streets(mesh, STREETS, -1.0)


def test_glb_reads_back_with_trimesh_at_world_positions(tmp_path):
    mesh = crop_to_streets(scattered_mesh(), STREETS, 20.0)
    path = write_scene_glb(tmp_path / "scene.glb", mesh)
    loaded = trimesh.load(io.BytesIO(path.read_bytes()), file_type="glb", process=False).to_geometry()
    ref = ORIGIN + mesh.positions[mesh.indices].astype(np.float64)          # (T, 3, 3) world m
    got = loaded.vertices[loaded.faces]
    assert got.shape == ref.shape
    # float32 positions + float64 origin: equal to float32 rounding of the local coordinates
    np.testing.assert_allclose(got, ref, rtol=0, atol=np.spacing(np.float32(300.0)))
    np.testing.assert_array_equal(loaded.visual.vertex_colors[loaded.faces][..., :3],
                                  np.round(mesh.albedo[mesh.indices] * 255))
    doc = glb_json(path)
    assert doc["scenes"][0]["extras"]["envcap"]["origin"] == ORIGIN.tolist()
    prim = doc["meshes"][0]["primitives"][0]
    assert {"POSITION", "NORMAL", "COLOR_0", "_EMISSION"} <= set(prim["attributes"])
    assert doc["accessors"][prim["attributes"]["_EMISSION"]]["max"] == [5.0, 5.0, 5.0]
    with pytest.raises(ValueError, match="no triangles"):
        write_scene_glb(tmp_path / "empty.glb", crop_to_streets(scattered_mesh(), [SimpleNamespace(
            name="c", axis="x", start=X0 + 1e4, end=X0 + 1e4 + 1, facade_min=Z0, facade_max=Z0 + 1)], 0.0))


def test_writer_registered_for_one_bake_and_in_the_manifest(canyon_probe_set, tmp_path):
    small = scattered_mesh(40, origin=np.zeros(3))  # around the canyon's street (x in [-300, 300])
    scene = dataclasses.replace(load_scene("canyon"), mesh=small)
    with registered_scene_writer(scene) as names:
        assert names == [NAME] and NAME in WRITERS
        with pytest.raises(ValueError, match="already registered"):
            with registered_scene_writer(scene):
                pass
        d = write_probe_set(tmp_path / "set", canyon_probe_set, exr=False, previews=False, writers=["ktx2", *names])
    assert NAME not in WRITERS
    with pytest.raises(ValueError, match="unknown"):
        select_writers([NAME])
    assert read_probe_set(d, distance=False).manifest.files.extra[NAME] == "scene.glb"
    loaded = trimesh.load(d / "scene.glb", process=False).to_geometry()
    st = canyon_probe_set.manifest.streets[0]
    as_box = SimpleNamespace(axis=st.axis, start=st.start, end=st.end, facade_min=st.planes.facade_min,
                             facade_max=st.planes.facade_max)
    expected = reference_keep(small, 60.0, [as_box]).sum()   # the writer's default padding, 60 m
    assert 0 < expected < small.triangle_count and loaded.faces.shape[0] == expected
