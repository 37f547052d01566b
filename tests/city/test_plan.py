"""Shard plans and keys: a size budget packs streets, a key names exactly the inputs."""

import dataclasses

import numpy as np
import pytest

from envcap.city.plan import BakeSettings, code_digest, plan_shards, probe_bytes, scene_hash, shard_key
from envcap.scene import load_scene


@pytest.fixture(scope="module")
def crossing():
    return load_scene("crossing")


def test_probe_bytes_is_the_ktx2_chain_by_hand():
    # 6 faces x RGBA16F (8 B) x (8^2 + 4^2 + 2^2 + 1^2) texels
    assert probe_bytes(8) == 6 * 8 * (64 + 16 + 4 + 1)


def test_the_budget_packs_streets_in_scene_order(crossing):
    s = BakeSettings(resolution=8, spacing=100.0)
    per = probe_bytes(8) * 3                                        # 3 probes per 300 m street
    assert [t.streets for t in plan_shards(crossing, s, 0)] == [("east_west",), ("north_south",)]
    assert [t.streets for t in plan_shards(crossing, s, per)] == [("east_west",), ("north_south",)]
    assert [t.streets for t in plan_shards(crossing, s, 2 * per)] == [("east_west", "north_south")]
    tasks = plan_shards(crossing, s, 0)
    assert [t.probes for t in tasks] == [3, 3]
    assert tasks[1].path == f"shards/0001-north_south-{tasks[1].key[:20]}"


def test_a_key_changes_with_each_input_and_only_with_them(crossing):
    d, code = scene_hash(crossing), code_digest()
    st = crossing.streets[:1]
    base = shard_key(d, st, BakeSettings(resolution=8, spacing=5), code)
    assert base == shard_key(d, st, BakeSettings(resolution=8, spacing=5.0, writers=("ktx2",)), code)
    others = [shard_key(d, st, BakeSettings(resolution=16, spacing=5), code),
              shard_key(d, st, BakeSettings(resolution=8, spacing=5, writers=("ktx2", "exr")), code),
              shard_key(d, crossing.streets[1:], BakeSettings(resolution=8, spacing=5), code),
              shard_key(d, st, BakeSettings(resolution=8, spacing=5), "0" * 64),
              shard_key(d, st, BakeSettings(resolution=8, spacing=5), code, version="9.9"),
              # the same street turned by 0.5 degrees, or its frame moved 1 cm: other probes, another key
              shard_key(d, [dataclasses.replace(st[0], yaw_deg=0.5)], BakeSettings(resolution=8, spacing=5), code),
              shard_key(d, [dataclasses.replace(st[0], origin_xz=(0.0, 0.01))], BakeSettings(resolution=8, spacing=5), code)]
    moved = crossing.mesh.positions.copy()
    moved[0, 1] = np.nextafter(moved[0, 1], np.float32(1e9))        # one vertex, one float32 step
    other_scene = dataclasses.replace(crossing, mesh=dataclasses.replace(crossing.mesh, positions=moved))
    others.append(shard_key(scene_hash(other_scene), st, BakeSettings(resolution=8, spacing=5), code))
    assert len({base, *others}) == len(others) + 1
