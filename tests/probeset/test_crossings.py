"""Crossings (docs/crossings.md): where streets meet, found from the streets' centre lines and
corridors, against hand-derived centres (the bundled crossing, the generated city, a street at
45 degrees, T-junctions, parallel streets); the crossing region; a bake with ``crossings=True``
puts a probe at the centre, records it in the manifest (schema, round trip), and an older set
without the key still reads."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from envcap.probeset.bake import bake_probe_set
from envcap.probeset.crossing_table import Crossing
from envcap.probeset.crossings import corridor, crossing_of, detect_crossings
from envcap.probeset.manifest import Manifest, manifest_text, read_manifest
from envcap.scene import load_scene
from envcap.scene.model import Street
from envcap.scene.segment import street_segment

ROOT = Path(__file__).resolve().parents[2]
SCHEMA = json.loads((ROOT / "docs/manifest.schema.json").read_text())
V1_FILE = Path(__file__).parent / "data/manifest_v1_canyon.json"


def centres(streets):
    return sorted((round(m.centre[0], 9), round(m.centre[1], 9), m.streets) for m in detect_crossings(streets))


def test_the_bundled_crossing_meets_at_the_origin():
    sc = load_scene("crossing")
    assert [st.name for st in sc.streets] == ["east_west", "north_south"]
    assert centres(sc.streets) == [(0.0, 0.0, (0, 1))]


def test_the_generated_city_grid_meets_where_its_centre_lines_cross():
    sc = load_scene("generated_city")
    # u streets run along x at centre lines z = -27.5 (facades -34.5 .. -20.5) and 29 (23.5 .. 34.5),
    # x in -164 .. 164; v streets along z at x = -86, 1, 87, z in -77.5 .. 78.5 (city_scenes/generated_city)
    want = sorted((x, z, (u, v)) for u, z in ((0, -27.5), (1, 29.0)) for v, x in ((2, -86.0), (3, 1.0), (4, 87.0)))
    assert centres(sc.streets) == want


def st(name, axis, start, end, lo, hi, yaw=0.0, origin=(0.0, 0.0)):
    return Street(name, axis, start, end, lo, hi, yaw_deg=yaw, origin_xz=origin)


def test_hard_inputs_parallel_t_junctions_and_turned_streets():
    main = st("main", "x", -50.0, 50.0, -5.0, 5.0)
    # parallel streets never meet, not even overlapping ones
    assert detect_crossings([main, st("twin", "x", -20.0, 20.0, -3.0, 7.0), st("far", "x", -50.0, 50.0, 20.0, 30.0)]) == []
    # a side street (x in 10..14, centre 12) running into the main street's roadway up to its centre line: a T
    assert centres([main, st("side", "z", 0.0, 40.0, 10.0, 14.0)]) == [(12.0, 0.0, (0, 1))]
    # ... stopping at the facade (z = 5): the corridors touch along an edge only, no crossing
    assert detect_crossings([main, st("side", "z", 5.0, 40.0, 10.0, 14.0)]) == []
    # ... stopping at z = 0.5, inside the roadway but short of the centre line: no crossing
    assert detect_crossings([main, st("side", "z", 0.5, 40.0, 10.0, 14.0)]) == []
    # a street at 45 deg from (0, -30): its centre line (frame z = 0) is x = t cos45, z = -30 + t sin45,
    # so it crosses main's centre line z = 0 at x = 30
    diag = st("diag", "x", 0.0, 80.0, -4.0, 4.0, yaw=45.0, origin=(0.0, -30.0))
    (x, z, pair), = centres([main, diag])
    assert pair == (0, 1) and x == pytest.approx(30.0, abs=1e-9) and z == pytest.approx(0.0, abs=1e-9)
    # three streets through one point are one crossing
    assert centres([main, st("b", "z", -40.0, 40.0, -4.0, 4.0), st("c", "x", -40.0, 40.0, -3.0, 3.0, yaw=45.0)]) \
        == [(0.0, 0.0, (0, 1, 2))]


def test_the_crossing_region_is_the_overlap_of_the_corridors_edges_included():
    sc = load_scene("crossing")      # east_west z in [-7, 7], north_south x in [-6, 6]
    cors = [corridor(s) for s in sc.streets]
    ms = detect_crossings(sc.streets)
    pts = np.array([[0.0, 0.0], [6.0, 7.0], [-6.0, -7.0], [6.0 + 1e-9, 0.0], [0.0, -7.0 - 1e-9], [20.0, 0.0],
                    [0.0, 20.0], [np.nan, 0.0], [np.inf, 0.0]])
    np.testing.assert_array_equal(crossing_of(cors, ms, pts), [0, 0, 0, -1, -1, -1, -1, -1, -1])


@pytest.fixture(scope="module")
def crossed(gl_ctx):
    scene = street_segment(load_scene("crossing"), 20.0)       # -10 .. 10 on both streets
    return bake_probe_set(scene, resolution=8, spacing=5.0, ctx=gl_ctx, progress=False, crossings=True)


def test_a_bake_with_crossings_puts_a_shared_probe_at_the_centre(crossed, tmp_path):
    m = crossed.manifest
    ew, ns = m.streets
    # uniform probes at -7.5, -2.5, 2.5, 7.5 on each street, plus the centre on east_west (its first street)
    assert [p.position[0] for p in ew.probes] == [-7.5, -2.5, 0.0, 2.5, 7.5]
    assert [p.position[2] for p in ns.probes] == [-7.5, -2.5, 2.5, 7.5]
    assert m.crossings == (Crossing("east_west+north_south", (0.0, 2.0, 0.0), ("east_west", "north_south"), 2),)
    assert ew.probes[2].layer == 2 and ew.probes[2].position == (0.0, 2.0, 0.0)
    obj = m.to_json()
    jsonschema.validate(obj, SCHEMA)
    (tmp_path / "m.json").write_text(manifest_text(m))
    back = read_manifest(tmp_path / "m.json")
    assert back.crossings == m.crossings and manifest_text(back) == manifest_text(m)


def test_an_older_set_without_crossings_still_reads():
    raw = json.loads(V1_FILE.read_text())
    m = Manifest.from_json(raw)
    assert m.crossings is None and "crossings" not in m.to_json()


@pytest.mark.parametrize("entry,msg", [
    ({"name": "x", "centre": [0, 2, 0], "streets": ["east_west"], "probe_layer": 2}, "at least two distinct streets"),
    ({"name": "x", "centre": [0, 2, 0], "streets": ["east_west", "nowhere"], "probe_layer": 2}, "does not have"),
    ({"name": "x", "centre": [0, 2, 0], "streets": ["east_west", "north_south"], "probe_layer": 6},
     "not a probe of its first street"),
    ({"name": "x", "centre": [0, 2], "streets": ["east_west", "north_south"], "probe_layer": 2}, "centre"),
])
def test_bad_crossing_entries_are_one_line_naming_the_field(crossed, entry, msg):
    obj = copy.deepcopy(crossed.manifest.to_json())
    obj["crossings"] = [entry]
    with pytest.raises(ValueError, match=msg) as e:
        Manifest.from_json(obj)
    assert "crossings[0]" in str(e.value) and "\n" not in str(e.value)


def test_the_evaluator_resolves_a_crossing_to_its_probe(crossed):
    from envcap.evaluate.predict import Predictor
    centre = 2    # the crossing probe's layer; east_west layers 0..4, north_south 5..8 (z = -7.5, -2.5, 2.5, 7.5)
    inside, outside = np.array([0.5, 1.5, 1.0]), np.array([0.5, 1.5, 9.0])
    probe, shared, off = (Predictor(crossed, crossings=m) for m in ("probe", "shared", "off"))
    assert probe.crossing_at(inside) == 0 and probe.crossing_at(outside) == -1 and off.crossing_at(inside) == -1
    assert list(probe.local_street("north_south", inside).layers) == [centre]
    # shared: north_south's 4 nearest probes along it and the centre probe, sorted along z, with north_south's planes
    st = shared.local_street("north_south", inside, "fitted")
    assert list(st.layers) == [5, 6, centre, 7, 8] and st.positions[2].tolist() == [0.0, 2.0, 0.0]
    np.testing.assert_allclose(st.planes[2, :2], [-6.0, 6.0], atol=1e-3)    # its neighbour's fitted facades (x = -6, 6)
    assert list(shared.local_street("east_west", inside).layers) == list(off.local_street("east_west", inside).layers)
    # direction: each direction on the street it looks down (east_west along x, north_south along z)
    direction = Predictor(crossed, crossings="direction")
    d = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    w = np.full(3, 64.0)
    got = direction.street_rgba("planes_mip", "north_south", inside, d, w)
    want = [shared.street_rgba("planes_mip", "east_west", inside, d[:1], w[:1])[0],
            shared.street_rgba("planes_mip", "north_south", inside, d[1:2], w[:1])[0],
            shared.street_rgba("planes_mip", "east_west", inside, d[2:], w[:1])[0]]   # straight up: a tie, the owner
    np.testing.assert_array_equal(got, np.array(want))
    assert not np.array_equal(want[0], shared.street_rgba("planes_mip", "north_south", inside, d[:1], w[:1])[0])
    # a meeting street turned differently from the owner keeps its own probes in mode direction
    # (the crossing probe's cube is in the owner's frame)
    import dataclasses
    direction.streets["east_west"] = dataclasses.replace(direction.streets["east_west"], yaw_deg=0.5)   # the owner
    assert list(direction._direction_street("north_south", 0, inside, "nominal").layers) == [5, 6, 7, 8]
    assert centre in direction._direction_street("east_west", 0, inside, "nominal").layers
    for p in (probe, shared):      # outside the region: per street, as without crossings
        assert list(p.local_street("north_south", outside).layers) == list(off.local_street("north_south", outside).layers)
