"""The manifest's optional ``placement`` entry (docs/formats.md, docs/placement.md): written by a
placed bake, validated by the published schema, read back equal; a set without it (every older
set) reads as before; bad entries are one line naming the field; the evaluator sweeps the whole
street of a placed set, whatever its probes chose."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from envcap.evaluate.sweep import Sweep, sample_positions
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.manifest import Manifest, manifest_text, read_manifest
from envcap.probeset.placement_table import PlacementTable
from envcap.scene import load_scene
from envcap.scene.segment import street_segment

ROOT = Path(__file__).resolve().parents[2]
SCHEMA = json.loads((ROOT / "docs/manifest.schema.json").read_text())
V1_FILE = Path(__file__).parent / "data/manifest_v1_canyon.json"


@pytest.fixture(scope="module")
def placed(gl_ctx):
    """The canyon's middle 40 m with 3 probes crowded at one end, as a strategy would record them."""
    scene = street_segment(load_scene("canyon"), 40.0)
    table = PlacementTable("crowded", 3, {"weight": [1.0, 2.0], "note": None}, 0.25, {"main": {"training_error": 0.1}})
    ps = bake_probe_set(scene, resolution=8, ctx=gl_ctx, progress=False, along={"main": [-19.0, -18.0, 5.0]},
                        placement=table)
    return scene, ps


def test_a_placed_set_records_its_placement(placed, tmp_path):
    scene, ps = placed
    m = ps.manifest
    obj = m.to_json()
    jsonschema.validate(obj, SCHEMA)
    assert obj["placement"] == {"strategy": "crowded", "probes_per_street": 3, "parameters": {"weight": [1.0, 2.0], "note": None},
                                "seconds": 0.25, "streets": {"main": {"training_error": 0.1}}}
    assert list(obj).index("placement") == list(obj).index("probe_spacing") + 1
    assert m.probe_spacing == pytest.approx(40.0 / 3)                   # the mean spacing
    assert [p.position[0] for p in m.streets[0].probes] == [-19.0, -18.0, 5.0]
    (tmp_path / "m.json").write_text(manifest_text(m))
    back = read_manifest(tmp_path / "m.json")
    assert back.placement == PlacementTable("crowded", 3, {"weight": [1.0, 2.0], "note": None}, 0.25,
                                            {"main": {"training_error": 0.1}})
    assert manifest_text(back) == manifest_text(m)


def test_a_set_without_the_entry_reads_as_before():
    raw = json.loads(V1_FILE.read_text())
    m = Manifest.from_json(raw)
    assert m.placement is None and "placement" not in m.to_json()
    without = copy.deepcopy(raw)
    without["placement"] = {"strategy": "uniform", "parameters": {}, "seconds": 0.0, "streets": {}}
    assert Manifest.from_json(without).placement == PlacementTable("uniform")


@pytest.mark.parametrize("entry,msg", [
    ({"strategy": "", "parameters": {}, "seconds": 0, "streets": {}}, "placement.strategy must be a strategy name"),
    ({"strategy": "two words", "parameters": {}, "seconds": 0, "streets": {}}, "placement.strategy must be"),
    ({"strategy": "u", "probes_per_street": 0, "parameters": {}, "seconds": 0, "streets": {}}, "probes_per_street must be >= 1"),
    ({"strategy": "u", "parameters": {}, "seconds": -1.0, "streets": {}}, "placement.seconds must be a finite number >= 0"),
    ({"strategy": "u", "parameters": {}, "seconds": 0, "streets": {"avenue": {}}}, r"names streets the set does not have: \['avenue'\]"),
    ({"strategy": "u", "parameters": {}, "streets": {}}, "missing key 'seconds'"),
    ({"strategy": "u", "parameters": {}, "seconds": 0, "streets": {}, "extra": 1}, "unknown key 'extra'"),
])
def test_bad_entries_are_one_line_naming_the_field(entry, msg):
    raw = json.loads(V1_FILE.read_text())
    raw["placement"] = entry
    with pytest.raises(ValueError, match=msg) as err:
        Manifest.from_json(raw)
    assert "\n" not in str(err.value) and "placement" in str(err.value)
    if not entry["streets"]:            # the schema says all but which streets the set has
        assert not jsonschema.Draft202012Validator(SCHEMA).is_valid(raw)


def test_the_sweep_of_a_placed_set_covers_the_whole_street(placed, canyon_probe_set):
    _, ps = placed
    a = [p.position[0] for p in sample_positions(ps.manifest, Sweep(per_street=20, seed=5))]
    # the jittered strata cover start + 2 .. end - 2, not the probes' span (-19 .. 5 m, plus half a gap)
    assert min(a) < -16.0 and max(a) > 16.0 and np.all(np.abs(a) <= 18.0)
    # a set at a uniform spacing keeps its sweep over its probes' span
    m = canyon_probe_set.manifest
    b = [p.position[0] for p in sample_positions(m, Sweep(per_street=20, seed=5))]
    xs = [p.position[0] for p in m.streets[0].probes]
    assert min(b) >= min(xs) - 50.0 and max(b) <= max(xs) + 50.0
