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


def test_a_city_with_enough_work_is_cut_for_parallel_workers_whatever_the_cluster(crossing):
    """Issue 19: 171 streets, 1,150 probes at 32^2 were one shard (75 MB, under the 256 MB budget),
    so one of two workers did everything.  The plan now has shards for 2-16 workers, from the
    scene and settings alone (no worker count enters it)."""
    from envcap.city.plan import MIN_SHARD_SECONDS, PARALLEL_SHARDS, shard_probe_cap

    streets = [dataclasses.replace(crossing.streets[i % 2], name=f"street_{i:03d}") for i in range(171)]
    city = dataclasses.replace(crossing, streets=streets)
    s = BakeSettings(resolution=32, spacing=50.0, quality="composed")   # 6 probes a street: 1,026 probes
    tasks = plan_shards(city, s, 256_000_000, "0" * 64, "0" * 64)
    cap = shard_probe_cap(1026, s)
    # by hand: a probe at 32^2 is 37 ms + 6 x 32^2 x 1 us = 43.1 ms, so 4 s of work is 93 probes
    # (more than 1,026 / 16 = 65): shards of 15 streets (90 probes), 12 of them
    assert MIN_SHARD_SECONDS == 4.0 and cap == 93 and len(tasks) == 12 <= PARALLEL_SHARDS
    assert [n for t in tasks for n in t.streets] == [st.name for st in streets]        # scene order, every street
    assert sum(t.probes for t in tasks) == 1026
    # a small city is not cut below the work a shard is worth; the size budget still applies
    assert [t.streets for t in plan_shards(crossing, s, 256_000_000)] == [("east_west", "north_south")]
    assert len(plan_shards(city, s, probe_bytes(32) * 6, "0" * 64, "0" * 64)) == 171
