"""A city with a street at an oblique angle, baked through the city path (plan, shard, index,
street map): the shard's manifest frame and the index agree, the index's world box is the
rotated rectangle's (derived from the end points by hand), city.json follows its schema and
keeps today's keys for axis-aligned streets, and locate finds the oblique street at its probes
and inside its rectangle, with the position in its frame."""

import json
import math
import tomllib
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from envcap.city.bake import bake_city
from envcap.city.locate import load_city_map
from envcap.city.plan import BakeSettings
from envcap.probeset.city_index import INDEX_FILE, CityIndex, read_city_index
from envcap.probeset.manifest import ManifestError, read_manifest
from envcap.probeset.store import read_probe_set

from city_fixtures import plan_coords

ROOT = Path(__file__).resolve().parents[2]
P0, P1, WIDTH = (40.0, 40.0), (140.0, 100.0), 12.0       # in the open quadrant of `crossing`


@pytest.fixture(scope="module")
def oblique_city(gl_ctx, tmp_path_factory):
    doc = tomllib.loads((ROOT / "city_scenes" / "crossing.toml").read_text())
    doc["name"] = "crossing_oblique"
    doc["streets"].append({"name": "diagonal", "p0": list(P0), "p1": list(P1), "width": WIDTH})
    out = tmp_path_factory.mktemp("oblique") / "city"
    bake_city(doc, out, BakeSettings(resolution=8, spacing=50.0), budget_mb=0, ctx=gl_ctx)
    return out


def test_the_shard_manifest_and_the_index_carry_the_same_frame(oblique_city):
    ix = read_city_index(oblique_city)
    k = [st.name for st in ix.streets].index("diagonal")
    st = ix.streets[k]
    (ms,) = read_manifest(oblique_city / ix.shards[st.shard].path / "manifest.json").streets
    assert ms.name == "diagonal" and (ms.yaw_deg, ms.origin_xz) == (st.yaw_deg, st.origin_xz)
    assert st.yaw_deg == pytest.approx(math.degrees(math.atan2(60.0, 100.0)), abs=1e-12) and st.origin_xz == P0
    assert (st.axis, st.start, st.end, st.center) == ("x", 0.0, pytest.approx(math.hypot(100.0, 60.0)), 0.0)
    # world box: the end points moved +- WIDTH / 2 along the plan normal n = (-t_z, t_x)
    t = np.subtract(P1, P0) / math.hypot(100.0, 60.0)
    n = np.array([-t[1], t[0]])
    corners = np.array([P0 + s * WIDTH / 2 * n for s in (-1, 1)] + [P1 + s * WIDTH / 2 * n for s in (-1, 1)])
    np.testing.assert_allclose(st.bounds, [corners[:, 0].min(), corners[:, 0].max(), corners[:, 1].min(),
                                           corners[:, 1].max()], atol=1e-9)
    # the merged city keeps the frame; the axis-aligned streets stay in the world frame
    merged = {s.name: s for s in read_probe_set(oblique_city).manifest.streets}
    assert (merged["diagonal"].yaw_deg, merged["diagonal"].origin_xz) == (st.yaw_deg, st.origin_xz)
    assert all(s.yaw_deg is None and s.origin_xz is None for s in ix.streets if s.name != "diagonal")


def test_city_json_follows_the_schema_and_axis_streets_keep_their_keys(oblique_city):
    obj = json.loads((oblique_city / INDEX_FILE).read_text())
    jsonschema.validate(obj, json.loads((ROOT / "docs/city_index.schema.json").read_text()))
    assert CityIndex.from_json(obj).to_json() == obj
    keys = {s["name"]: list(s) for s in obj["streets"]}
    today = ["name", "axis", "start", "end", "center", "planes", "bounds", "frame_origin", "shard", "layers"]
    assert keys["east_west"] == keys["north_south"] == today and keys["diagonal"] == today + ["yaw_deg", "origin_xz"]
    bad = json.loads(json.dumps(obj))
    next(s for s in bad["streets"] if s["name"] == "diagonal")["axis"] = "z"
    with pytest.raises(ManifestError, match="runs along its frame's x"):
        CityIndex.from_json(bad)


def test_locate_finds_the_oblique_street_with_its_frame_and_range(oblique_city):
    cm = load_city_map(oblique_city)
    ix = cm.index
    k = [st.name for st in ix.streets].index("diagonal")
    st = ix.streets[k]
    probes = read_manifest(oblique_city / ix.shards[st.shard].path / "manifest.json").streets[0].probes
    pos = np.array([p.position for p in probes])
    # the probes, points inside the rectangle (1 m from its edges at most) and one between streets
    rng = np.random.default_rng(2)
    a, c = rng.uniform(1.0, math.hypot(100, 60) - 1.0, 2000), rng.uniform(-WIDTH / 2 + 1, WIDTH / 2 - 1, 2000)
    t = np.subtract(P1, P0) / math.hypot(100.0, 60.0)
    x = np.concatenate([pos[:, 0], P0[0] + a * t[0] - c * t[1], [100.0]])
    z = np.concatenate([pos[:, 2], P0[1] + a * t[1] + c * t[0], [20.0]])
    got = cm.locate(x, z)
    on = slice(0, -1)
    assert np.all(got.street[on] == k) and np.all(got.shard[on] == st.shard) and np.all(got.count[on] == len(probes))
    assert np.all(got.city_first[on] == st.layers[0]) and np.all(got.shard_first[on] == 0)
    assert np.all(got.yaw_deg[on] == st.yaw_deg) and np.all(got.origin_xz[on] == P0) and np.all(got.along[on] == 0)
    ref_a, ref_c = plan_coords(P0, P1, x, z)
    np.testing.assert_allclose(got.frame_xz[on], np.stack([ref_a, ref_c], 1)[on], atol=1e-9)
    assert np.allclose(got.frame_xz[:len(probes), 1], 0.0, atol=1e-9)            # the probes: on the centre line
    assert got.street[-1] == -1 and got.count[-1] == 0 and tuple(got.frame_xz[-1]) == (100.0, 20.0)
    # the GPU table: same street and range, the street-local position in float32
    ids, ranges, local = cm.street_table().locate(cm.map, x, np.full_like(x, 2.0), z)
    assert np.array_equal(ids.astype(np.int64) - 1, got.street)
    np.testing.assert_array_equal(ranges[on], np.tile([st.shard, 0, st.layers[0], len(probes)], (len(x) - 1, 1)))
    want = got.frame_xz[on] - np.asarray(st.frame_origin)[[0, 2]]
    np.testing.assert_allclose(local[on][:, [0, 2]], want, atol=1e-4)
