"""The typed manifest: byte-exact round trip of a version-1 file, the published JSON Schema
(validates a fresh bake; agrees with the dataclasses), strict errors that name the field."""

from __future__ import annotations

import copy
import dataclasses
import json
from pathlib import Path

import jsonschema
import pytest

from envcap.probeset.bake import bake_probe_set
from envcap.probeset.manifest import Manifest, dataclass_types, manifest_text, read_manifest, write_manifest
from envcap.scene import load_scene

ROOT = Path(__file__).resolve().parents[2]
SCHEMA = json.loads((ROOT / "docs/manifest.schema.json").read_text())
V1_FILE = Path(__file__).parent / "data/manifest_v1_canyon.json"
"""A manifest written by envcap before the typed manifest (canyon at 32^2, cut to 2 probes)."""


@pytest.fixture(scope="module")
def baked(gl_ctx, canyon_probe_set):
    """A fresh bake of the canyon (6 probes of 8^2), filtered (the session's) and unfiltered."""
    m = canyon_probe_set.manifest
    unfiltered = bake_probe_set(load_scene("canyon"), resolution=m.resolution, spacing=m.probe_spacing,
                                filter_levels=False, ctx=gl_ctx, progress=False)
    return m, unfiltered.manifest


def test_a_version_1_file_reads_and_writes_back_byte_for_byte(tmp_path):
    text = V1_FILE.read_text()
    m = read_manifest(V1_FILE)
    assert manifest_text(m) == text
    write_manifest(tmp_path / "m.json", m)
    assert (tmp_path / "m.json").read_bytes() == V1_FILE.read_bytes()
    # The typed view holds what the file says.
    raw = json.loads(text)
    st = m.streets[0]
    assert (st.name, st.axis, st.along_index, st.cross_index) == ("main", "x", 0, 2)
    assert st.probes[1].position == tuple(raw["streets"][0]["probes"][1]["position"])
    assert st.probes[0].fitted_planes.coverage_sr.ground == raw["streets"][0]["probes"][0]["fitted_planes"]["coverage_sr"]["ground"]
    assert m.timings.passes_s == {"sky_sh": 0.0107, "shadow_map": 0.0363, "render": 1.0555, "readback": 0.03}
    assert m.lobe_powers == tuple(raw["lobes"]["powers"]) and m.layer_count == 2
    assert m.sky.sun.illuminance == tuple(raw["sky"]["sun"]["illuminance"]) and m.sky.sun_baked_in_map is False


def test_a_set_baked_before_sun_in_map_existed_held_the_sun():
    raw = json.loads(V1_FILE.read_text())
    del raw["sky"]["sun_in_map"]
    m = Manifest.from_json(raw)
    assert m.sky.sun_in_map is None and m.sky.sun_baked_in_map is True
    assert "sun_in_map" not in m.to_json()["sky"]


def test_a_fresh_bake_validates_against_the_published_schema(baked):
    jsonschema.Draft202012Validator.check_schema(SCHEMA)
    for m in baked:
        obj = m.to_json()
        jsonschema.validate(obj, SCHEMA)
        assert Manifest.from_json(json.loads(json.dumps(obj))) == m
    filtered, unfiltered = baked
    assert unfiltered.to_json()["lobes"] == {} and unfiltered.levels[0].lobe_power is None
    assert len(filtered.levels) == 4 and filtered.lobe_powers == filtered.lobes.powers
    assert filtered.layer_count == 6 and filtered.scene.name == "canyon"


def test_the_schema_rejects_what_the_reader_rejects():
    v = jsonschema.Draft202012Validator(SCHEMA)
    raw = json.loads(V1_FILE.read_text())
    assert v.is_valid(raw)
    for mutate in (lambda m: m.update(version=2), lambda m: m["streets"][0].update(axis="y"),
                   lambda m: m["streets"][0]["probes"][0].update(position=[0, 1]), lambda m: m.update(extra=1),
                   lambda m: m["timings"].update(pass_s=1.0), lambda m: m["sky"].pop("sun")):
        bad = copy.deepcopy(raw)
        mutate(bad)
        assert not v.is_valid(bad)
        with pytest.raises(ValueError):
            Manifest.from_json(bad)


def _json_fields(cls: type) -> tuple[set[str], set[str], list[dataclasses.Field]]:
    """(JSON keys, keys that must be present, fields that hold the object's other keys)."""
    named = [f for f in dataclasses.fields(cls) if f.metadata.get("json") != "rest"]
    rest = [f for f in dataclasses.fields(cls) if f.metadata.get("json") == "rest"]
    return {f.name for f in named}, {f.name for f in named if f.metadata.get("json") != "omit_none"}, rest


def test_the_schema_and_the_dataclasses_agree():
    types = dataclass_types()
    defs = dict(SCHEMA["$defs"], Manifest=SCHEMA)
    assert set(defs) == set(types)
    for name, cls in types.items():
        s = defs[name]
        keys, required, rest = _json_fields(cls)
        assert set(s["properties"]) == keys, name
        assert set(s.get("required", ())) == required, name
        if rest:  # the other keys are described by a pattern or by additionalProperties
            for f in rest:
                pattern = f.metadata.get("pattern")
                assert (s["patternProperties"] if pattern else s["additionalProperties"]), (name, f.name)
                if pattern:
                    assert list(s["patternProperties"]) == [f"^{pattern.replace('(.+)', '.+')}$"]
        else:
            assert s["additionalProperties"] is False, name


@pytest.mark.parametrize(
    "mutate,msg",
    [
        (lambda m: m.update(format="other"), "format is 'other'"),
        (lambda m: m.update(version=2), "version 2 not supported"),
        (lambda m: m.update(units="feet"), "units is 'feet'"),
        (lambda m: m.update(resolution=0), "resolution: must be positive"),
        (lambda m: m.update(resolution=32.5), "resolution: must be an integer"),
        (lambda m: m["levels"][1].update(size=3), r"levels\[1\] must be"),
        (lambda m: m["levels"][0].update(lobe_power=-1), r"levels\[0\].lobe_power: must be positive"),
        (lambda m: m["streets"][0].update(axis="y"), r"streets\[0\].axis: must be 'x' or 'z'"),
        (lambda m: m["streets"][0]["probes"][1].update(layer=0), "layers must be 0..1"),
        (lambda m: m["streets"][0]["probes"][0].update(position=[0, 1]),
         r"streets\[0\].probes\[0\].position: must be an array of 3 entries"),
        (lambda m: m["streets"][0]["probes"][0]["position"].__setitem__(1, True),
         r"streets\[0\].probes\[0\].position\[1\]: must be a finite number"),
        (lambda m: m["streets"][0]["planes"].update(facade_max=-20.0), r"streets\[0\].planes: facade_max -20.0 must exceed"),
        (lambda m: m["streets"][0]["probes"][1]["fitted_planes"].pop("spread_m"),
         r"streets\[0\].probes\[1\].fitted_planes: missing key 'spread_m'"),
        (lambda m: m["streets"][0]["probes"][1].update(planes_fitted=None), r"probes\[1\]: unknown key 'planes_fitted'"),
        (lambda m: m.update(probe_spacing=0), "probe_spacing: must be positive"),
        (lambda m: m["sky"].update(format="RGBA16F"), "sky.format is 'RGBA16F'"),
        (lambda m: m["sky"]["sun"].update(radiance="bright"), "sky.sun.radiance: must be an array"),
        (lambda m: m["timings"].update(pass_render_s="fast"), "timings.pass_render_s: must be a finite number"),
        (lambda m: m["files"].update(layers=3), "files.layers: must be a path or a list of paths"),
        (lambda m: m["streets"].append(copy.deepcopy(m["streets"][0])), r"streets\[1\].name: 'main' is not unique"),
        (lambda m: m.pop("effects"), "missing key 'effects'"),
    ],
)
def test_errors_are_one_line_and_name_the_field(mutate, msg):
    raw = json.loads(V1_FILE.read_text())
    mutate(raw)
    with pytest.raises(ValueError, match=msg) as err:
        Manifest.from_json(raw, "manifest.json")
    assert str(err.value).startswith("manifest.json: ") and "\n" not in str(err.value)


def test_reader_errors_name_the_file(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_manifest(tmp_path / "nope.json")
    (tmp_path / "bad.json").write_text("{ not json")
    with pytest.raises(ValueError, match="bad.json: not valid JSON"):
        read_manifest(tmp_path / "bad.json")
