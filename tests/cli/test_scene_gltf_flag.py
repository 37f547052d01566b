"""``envcap capture --scene-gltf``: the probe set gets ``scene.glb`` (manifest ``files.scene_gltf``)
holding the scene's triangles near the streets; the writer is gone from the registry afterwards;
on a city bake the flag is refused before anything is written."""

import numpy as np
import trimesh

from envcap.cli import main
from envcap.formats.registry import WRITERS
from envcap.formats.scene_gltf import crop_to_streets
from envcap.probeset.store import read_probe_set
from envcap.scene import load_scene


def test_capture_scene_gltf_writes_the_cropped_scene(gl_ctx, tmp_path, capsys):
    out = tmp_path / "set"
    assert main(["capture", "planes", "--out", str(out), "--resolution", "8", "--spacing", "100",
                 "--quiet", "--scene-gltf"]) == 0
    m = read_probe_set(out, distance=False).manifest
    assert m.files.extra["scene_gltf"] == "scene.glb" and "scene_gltf" not in WRITERS
    scene = load_scene("planes")
    ref = crop_to_streets(scene.mesh, m.streets)
    got = trimesh.load(out / "scene.glb", process=False).to_geometry()
    assert got.faces.shape == ref.indices.shape
    np.testing.assert_allclose(got.vertices[got.faces], ref.origin + ref.positions[ref.indices].astype(np.float64),
                               rtol=0, atol=1e-9)


def test_scene_gltf_on_a_city_bake_is_refused(tmp_path, capsys):
    assert main(["capture", "planes", "--out", str(tmp_path / "city"), "--workers", "0", "--scene-gltf"]) == 2
    err = capsys.readouterr().err
    assert "--scene-gltf" in err and "city" in err, err
    assert list(tmp_path.iterdir()) == []
