"""Issue 9, mesh files: what the loaders need is installed, and whatever a loader raises becomes
one line naming the file (``envcap.scene.mesh_import``).  Real files, written here."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from envcap.scene import import_mesh, load_scene

REPO = Path(__file__).resolve().parents[2]

TRIANGLE_OBJ = b"v 0 0 0\nv 2 0 0\nv 0 3 0\nf 1 2 3\n"


def test_an_obj_with_a_latin1_byte_in_a_comment_imports(tmp_path):
    """Old: one Latin-1 byte (0xE9, 'e' acute) in a comment made trimesh reach for
    ``charset_normalizer``, which envcap did not install: ``No module named 'charset_normalizer'``."""
    obj = tmp_path / "cafe.obj"
    obj.write_bytes(b"# caf\xe9 on the corner\n" + TRIANGLE_OBJ)
    with pytest.raises(UnicodeDecodeError):
        obj.read_bytes().decode("utf-8")  # the file really is not UTF-8
    m = import_mesh(obj)
    assert m.triangle_count == 1
    np.testing.assert_array_equal(m.positions, [[0, 0, 0], [2, 0, 0], [0, 3, 0]])
    np.testing.assert_array_equal(m.normals, [[0, 0, 1]] * 3)  # counter-clockwise seen from +Z
    scene = tmp_path / "scene.toml"
    scene.write_text('effects = []\nsky = { type = "uniform", radiance = 1.0 }\n[mesh]\nfile = "cafe.obj"\n')
    assert load_scene(scene).mesh.triangle_count == 1 + 2  # the triangle and the ground quad


def test_the_mesh_loaders_dependencies_are_declared():
    """``pip install .`` must bring what trimesh needs to read text meshes in any encoding."""
    deps = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["dependencies"]
    names = {d.split(">")[0].split("=")[0].split("<")[0].split("[")[0].strip().lower().replace("_", "-") for d in deps}
    assert {"trimesh", "charset-normalizer"} <= names, sorted(names)


BROKEN_FILES = {
    "garbage.glb": b"glTF\x02\x00\x00\x00\xff\xff\xff\xff" + bytes(range(256)),
    "garbage.gltf": b'{"asset": {"version": "2.0"}, "meshes": [{"primitives": [{"attributes": {"POSITION": 7}}]}]}',
    "garbage.obj": bytes(range(256)) * 4,
    "garbage.ply": b"ply\nformat binary_little_endian 1.0\nelement vertex 999999\nproperty float x\nend_header\n\x00",
    "garbage.stl": b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0\nendloop\n",
    "garbage.off": b"OFF\n3 1 0\n0 0 0\n1 0 0\n",
}
"""Broken files of every supported type: each makes trimesh (or the arrays read from it) fail."""


@pytest.mark.parametrize("name", sorted(BROKEN_FILES))
def test_any_loader_failure_is_one_line_naming_the_file(tmp_path, name):
    path = tmp_path / name
    path.write_bytes(BROKEN_FILES[name])
    with pytest.raises(ValueError) as ei:
        import_mesh(path)
    msg = str(ei.value)
    assert str(path) in msg and "\n" not in msg and len(msg) < 500, msg
