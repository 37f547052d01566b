"""The city index: shards are probe sets of today's format, the index reads as one probe set
(the readers and the evaluator accept a shard or the index), and city.json follows its schema."""

import json
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from envcap.evaluate.run import evaluate_scene
from envcap.probeset.city_index import INDEX_FILE, CityIndex, read_city_index
from envcap.probeset.manifest import ManifestError
from envcap.probeset.store import read_probe_set
from envcap.scene import load_scene

ROOT = Path(__file__).resolve().parents[2]
SCHEMA = json.loads((ROOT / "docs/city_index.schema.json").read_text())


def test_each_shard_is_a_probe_set_and_the_index_reads_as_their_concatenation(crossing_city):
    ix = read_city_index(crossing_city)
    shards = [read_probe_set(crossing_city / sh.path) for sh in ix.shards]
    assert [tuple(st.name for st in ps.manifest.streets) for ps in shards] == [("east_west",), ("north_south",)]
    city = read_probe_set(crossing_city)
    assert city.layer_count == ix.layer_count == sum(ps.layer_count for ps in shards) == 6
    for k in range(len(ix.levels)):
        np.testing.assert_array_equal(city.levels[k], np.concatenate([ps.levels[k] for ps in shards]))
    np.testing.assert_array_equal(city.distance, np.concatenate([ps.distance for ps in shards]))
    # city layer of a probe = its shard layer + the shard's first city layer, for every probe
    for sh, ps in zip(ix.shards, shards):
        for st in ps.manifest.streets:
            merged = next(s for s in city.manifest.streets if s.name == st.name)
            assert [p.layer for p in merged.probes] == [p.layer + sh.layers[0] for p in st.probes]
            assert [p.position for p in merged.probes] == [p.position for p in st.probes]
            entry = next(s for s in ix.streets if s.name == st.name)
            assert entry.layers == (sh.layers[0] + min(p.layer for p in st.probes), len(st.probes))


def test_the_evaluator_accepts_the_index_and_a_shard(crossing_city, gl_ctx):
    scene = load_scene("crossing")
    kw = dict(methods=["nearest"], lobe_powers=[64.0], resolution=8, ctx=gl_ctx, materials=(), keep_worst=0,
              floor_probes=0, sun_variants=(False,), progress=False)
    pos = np.array([[-40.0, 2.0, 1.0], [2.0, 2.0, 60.0]])
    whole = evaluate_scene(scene, read_probe_set(crossing_city), positions=pos, **kw)
    shard = read_city_index(crossing_city).shards[1].path
    one = evaluate_scene(scene, read_probe_set(crossing_city / shard), positions=pos[1:], **kw)
    assert {r["street"] for r in whole.rows} == {"east_west", "north_south"}
    a = [r for r in whole.rows if r["street"] == "north_south"]
    b = one.rows
    assert len(a) == len(b) > 0
    assert [r["rel_rmse"] for r in a] == [r["rel_rmse"] for r in b]


def test_city_json_validates_against_the_published_schema(crossing_city):
    jsonschema.Draft202012Validator.check_schema(SCHEMA)
    obj = json.loads((crossing_city / INDEX_FILE).read_text())
    jsonschema.validate(obj, SCHEMA)
    assert CityIndex.from_json(obj).to_json() == obj


@pytest.mark.parametrize("edit, words", [
    (lambda o: o.update(extra=1), "unknown key"),
    (lambda o: o.pop("shards"), "missing key"),
    (lambda o: o["shards"][1].update(path="../elsewhere"), "relative path inside the city"),
    (lambda o: o["shards"][1].update(layers=[4, 3]), "must start at 3"),
    (lambda o: o["streets"][0].update(axis="y"), "axis"),
    (lambda o: o.update(version=2), "version 2 not supported"),
])
def test_the_reader_and_the_schema_reject_a_bad_index(crossing_city, edit, words):
    obj = json.loads((crossing_city / INDEX_FILE).read_text())
    edit(obj)
    with pytest.raises(ManifestError, match=words):
        CityIndex.from_json(obj)
    if words not in ("must start at 3",):  # the layer chain is a reader rule, not a schema one
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate(obj, SCHEMA)


def test_a_shard_that_disagrees_with_the_index_is_named(crossing_city, tmp_path):
    import shutil
    city = tmp_path / "c"
    shutil.copytree(crossing_city, city)
    ix = json.loads((city / INDEX_FILE).read_text())
    ix["shards"][0]["path"], ix["shards"][1]["path"] = ix["shards"][1]["path"], ix["shards"][0]["path"]
    (city / INDEX_FILE).write_text(json.dumps(ix))
    with pytest.raises(ValueError, match="holds streets \\['north_south'\\]"):
        read_probe_set(city)
