"""What travels to Dask workers (issue 19, a cluster without a shared disk): the built scene and
the bytes of its sky file, never a path of the client's machine; and what comes back is
installed only under the shard's own directory."""

import pickle

import numpy as np
import pytest

from envcap.city.plan import BakeSettings, code_digest, plan_shards, scene_hash
from envcap.city.scene_parcel import pack_scene, unpack_scene
from envcap.city.shard import ShardJob, install_shard_files
from envcap.scene import load_scene

SCENE = """name = "own"
effects = ["sky_light"]

[sky]
type = "latlong"
file = "sky/overcast.exr"

[ground]
albedo = [0.2, 0.2, 0.2]
extent = 400.0

[[streets]]
name = "main"
axis = "x"
start = -50.0
end = 50.0
width = 12.0
"""


@pytest.fixture
def own_scene(tmp_path):
    """A user's scene in a folder named ``users-own-folder-q7`` with a lat-long sky file."""
    import OpenEXR

    folder = tmp_path / "users-own-folder-q7"
    (folder / "sky").mkdir(parents=True)
    (folder / "own.toml").write_text(SCENE)
    y, x = np.mgrid[0:8, 0:16].astype(np.float32)
    rgb = np.stack([1 + x / 16, 1 + y / 8, np.full_like(x, 2.0)], -1)
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                 {c: np.ascontiguousarray(rgb[..., i]) for i, c in enumerate("RGB")}).write(str(folder / "sky" / "overcast.exr"))
    return folder / "own.toml"


def test_a_parcel_and_its_jobs_hold_no_client_path_and_rebuild_the_same_sky(own_scene, tmp_path):
    scene = load_scene(own_scene)
    digest = scene_hash(scene)
    settings = BakeSettings(resolution=8, spacing=50.0)
    jobs = [ShardJob(digest, t, settings, code_digest()) for t in plan_shards(scene, settings, 0, digest)]
    parcel = pack_scene(scene, digest)
    sent = pickle.dumps((parcel, jobs))
    assert b"users-own-folder-q7" not in sent and str(tmp_path).encode() not in sent

    elsewhere = tmp_path / "worker-files"
    shipped = unpack_scene(pickle.loads(sent)[0], elsewhere)
    assert shipped.sky.params.path.is_relative_to(elsewhere)
    assert shipped.sky.params.file == "sky/overcast.exr"             # as the scene wrote it (manifests)
    np.testing.assert_array_equal(shipped.sky.build().cube(8), scene.sky.build().cube(8))
    np.testing.assert_array_equal(shipped.mesh.positions, scene.mesh.positions)
    assert [st.name for st in shipped.streets] == ["main"]
    again = unpack_scene(parcel, elsewhere)                           # a second unpack reuses the file
    assert again.sky.params.path == shipped.sky.params.path and len(list(elsewhere.rglob("*.exr"))) == 1


def test_a_missing_sky_file_is_named_when_packing(own_scene):
    scene = load_scene(own_scene)
    (own_scene.parent / "sky" / "overcast.exr").unlink()
    with pytest.raises(FileNotFoundError, match="sky.path: .*overcast.exr not found"):
        pack_scene(scene, "0" * 64)


@pytest.mark.parametrize("name", ["../escape.ktx2", "/abs.ktx2", "a/../../b", ""])
def test_shard_files_from_a_worker_stay_inside_their_shard(tmp_path, name):
    scene = load_scene("crossing")
    task = plan_shards(scene, BakeSettings(resolution=8, spacing=100.0), 0)[0]
    with pytest.raises(ValueError, match="not a plain relative path"):
        install_shard_files(tmp_path / "city", task, {"manifest.json": b"{}", name: b"x"})
    assert not (tmp_path / "escape.ktx2").exists() and not list((tmp_path / "city").rglob("*.json"))
