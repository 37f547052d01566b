"""The registry of placement strategies (docs/architecture.md, "Where to add"): a strategy
registered from this file alone (``ends_first``: one function + one PlacementStrategy line) is
found by ``place_scene`` and by ``envcap capture --placement``; ``uniform`` is today's placement
bit for bit; the hard inputs (one probe, a street shorter than the spacing, a count past the
limit, a count that is not a whole number) and a strategy that breaks the contract."""

import json

import numpy as np
import pytest

from envcap.cli import main
from envcap.core.budget import BudgetError
from envcap.placement import PlacementContext, PlacementStrategy, StreetPlacement, get, register, registered, unregister
from envcap.placement.place import check_probes_per_street, place_scene
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.placement import place_probes
from envcap.scene import load_scene
from envcap.scene.segment import street_segment


def ends_first(context, street, counts, power=2.0):
    """Probes crowded towards both ends: u in (-1, 1) uniform, placed at mid + half * sign(u) |u|^(1/power)."""
    mid, half = 0.5 * (street.start + street.end), 0.5 * street.length
    out = []
    for n in counts:
        u = (np.arange(n) + 0.5) / n * 2 - 1
        out.append(StreetPlacement(mid + half * np.sign(u) * np.abs(u) ** (1 / power), {"power": power}))
    return out


ENDS_FIRST = PlacementStrategy("ends_first", ends_first, "probes crowded towards the street's ends", {"power": 2.0})


@pytest.fixture
def registered_ends_first():
    register(ENDS_FIRST)
    yield ENDS_FIRST
    unregister(ENDS_FIRST.name)


@pytest.fixture(scope="module")
def crossing():
    return street_segment(load_scene("crossing"), 40.0)


def expected_ends_first(street, n, power):
    u = (np.arange(n) + 0.5) / n * 2 - 1
    return 0.5 * (street.start + street.end) + 0.5 * street.length * np.sign(u) * np.abs(u) ** (1 / power)


def test_a_strategy_registered_here_is_found_by_name(registered_ends_first, crossing):
    assert "ends_first" in registered() and get("ends_first") is ENDS_FIRST
    sp = place_scene(crossing, "ends_first", probes_per_street=5, parameters={"power": 3.0})
    for st in crossing.streets:
        np.testing.assert_allclose(sp.along[st.name], expected_ends_first(st, 5, 3.0), rtol=0, atol=1e-12)
    assert sp.table.strategy == "ends_first" and sp.table.probes_per_street == 5
    assert sp.table.parameters == {"power": 3.0}
    assert sp.table.streets == {st.name: {"power": 3.0} for st in crossing.streets}


def test_the_capture_command_finds_a_registered_strategy(registered_ends_first, tmp_path, capsys):
    out = tmp_path / "set"
    assert main(["capture", "asymmetric", "--out", str(out), "--resolution", "8", "--placement", "ends_first",
                 "--probes-per-street", "4", "--quiet"]) == 0
    m = json.loads((out / "manifest.json").read_text())
    assert m["placement"]["strategy"] == "ends_first" and m["placement"]["probes_per_street"] == 4
    street = load_scene("asymmetric").streets[0]
    got = [p["position"][street.along_index] for p in m["streets"][0]["probes"]]
    np.testing.assert_allclose(got, expected_ends_first(street, 4, 2.0), rtol=0, atol=1e-9)
    assert m["probe_spacing"] == pytest.approx(street.length / 4)


def test_registry_rules(registered_ends_first):
    with pytest.raises(ValueError, match="already registered"):
        register(ENDS_FIRST)
    with pytest.raises(ValueError, match="identifier"):
        PlacementStrategy("two words", ends_first, "")
    with pytest.raises(ValueError, match=r"unknown placement strategy 'nope'; known: uniform, density, min_error, ends_first"):
        get("nope")
    with pytest.raises(ValueError, match=r"no parameter\(s\) \['sharpness'\]; known: power"):
        ENDS_FIRST.settings({"sharpness": 1})


@pytest.mark.parametrize("bad,msg", [
    (lambda st, n: np.linspace(st.start, st.end, n + 1), "placed 4 probes on street 'main', asked for 3"),
    (lambda st, n: np.linspace(st.start - 1, st.end, n), "outside the street"),
    (lambda st, n: np.linspace(st.end, st.start, n), "must increase along the street"),
    (lambda st, n: np.full(n, np.nan), "outside the street"),
])
def test_a_strategy_that_breaks_the_contract_is_named(bad, msg):
    broken = PlacementStrategy("broken", lambda c, st, counts: [StreetPlacement(bad(st, n)) for n in counts], "")
    street = street_segment(load_scene("canyon"), 30.0).streets[0]
    with pytest.raises(ValueError, match=f"placement strategy 'broken'.*{msg}"):
        broken(PlacementContext(load_scene("canyon")), street, (3,))


def test_uniform_is_todays_placement_bit_for_bit(crossing, gl_ctx):
    canyon = load_scene("canyon")
    for scene in (canyon, crossing):
        for spacing in (5.0, 7.3, 1000.0):
            sp = place_scene(scene, "uniform", spacing=spacing)
            for st in scene.streets:
                ref = [st.to_frame(np.array(p.position))[st.along_index] for p in place_probes(st, spacing)]
                np.testing.assert_array_equal(sp.along[st.name], ref)
        for n in (1, 4, 7):
            sp = place_scene(scene, "uniform", probes_per_street=n)
            for st in scene.streets:
                ref = [st.to_frame(np.array(p.position))[st.along_index] for p in place_probes(st, st.length / n)]
                np.testing.assert_array_equal(sp.along[st.name], ref)
    # and the bake at those coordinates is the default bake's probe for probe
    a = bake_probe_set(crossing, resolution=8, spacing=6.0, ctx=gl_ctx, progress=False)
    sp = place_scene(crossing, "uniform", spacing=6.0)
    b = bake_probe_set(crossing, resolution=8, ctx=gl_ctx, progress=False, along=sp.along, placement=sp.table)
    assert [s.probes for s in a.manifest.streets] == [s.probes for s in b.manifest.streets]
    assert b.manifest.placement.strategy == "uniform" and a.manifest.placement is None
    np.testing.assert_array_equal(a.levels[0], b.levels[0])


def test_hard_inputs(crossing):
    one = place_scene(crossing, "uniform", probes_per_street=1)
    for st in crossing.streets:
        np.testing.assert_array_equal(one.along[st.name], [0.5 * (st.start + st.end)])
    short = street_segment(load_scene("canyon"), 2.0)                         # shorter than the spacing
    np.testing.assert_array_equal(place_scene(short, "uniform", spacing=5.0).along["main"], [0.0])
    three = place_scene(short, "uniform", probes_per_street=3).along["main"]
    np.testing.assert_allclose(three, [-2 / 3, 0.0, 2 / 3], rtol=0, atol=1e-12)
    with pytest.raises(BudgetError, match=r"10000000 probes per street on 2 street\(s\) \(a bake of ~20,000,000 probes "
                                          r".*peak memory.*more than the limit of 100,000; change --probes-per-street"):
        place_scene(crossing, "uniform", probes_per_street=10_000_000)
    for bad in (0, -3, 2.5, "2.5", "1e3", True, None, "three"):
        with pytest.raises(ValueError, match="--probes-per-street must be a whole number of probes >= 1"):
            check_probes_per_street(bad)
    assert check_probes_per_street(" 12 ") == 12


def test_a_framed_street_on_terrain_places_like_the_default(tmp_path, gl_ctx):
    """A street at 30 deg that follows a ramp: uniform coordinates give the default bake's probes
    (positions, grounds, slopes); a strategy's coordinates stand on the terrain under them."""
    import dataclasses

    import trimesh

    from envcap.scene import scene_from_dict

    xs = np.arange(-100.0, 101.0, 20.0)
    gx, gz = np.meshgrid(xs, xs)
    n = len(xs)
    i = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    faces = np.concatenate([np.stack([i, i + n, i + 1], 1), np.stack([i + 1, i + n, i + n + 1], 1)])
    trimesh.Trimesh(np.stack([gx.ravel(), 0.05 * gx.ravel(), gz.ravel()], 1), faces, process=False).export(tmp_path / "r.ply")
    doc = {"name": "ramp", "effects": [], "sky": {"type": "uniform", "radiance": 1.0}, "ground": {"enabled": False},
           "mesh": {"file": "r.ply"},
           "streets": [{"name": "up", "axis": "x", "start": -30.0, "end": 30.0, "width": 12.0, "follow_terrain": True}]}
    scene = scene_from_dict(doc, base_dir=tmp_path)
    scene = dataclasses.replace(scene, streets=[dataclasses.replace(scene.streets[0], yaw_deg=30.0, origin_xz=(2.0, -3.0))])
    a = bake_probe_set(scene, resolution=4, spacing=12.0, filter_levels=False, ctx=gl_ctx, progress=False)
    sp = place_scene(scene, "uniform", spacing=12.0)
    b = bake_probe_set(scene, resolution=4, filter_levels=False, ctx=gl_ctx, progress=False, along=sp.along,
                       placement=sp.table)
    assert a.manifest.streets[0].probes == b.manifest.streets[0].probes
    c = bake_probe_set(scene, resolution=4, filter_levels=False, ctx=gl_ctx, progress=False,
                       along={"up": [-29.0, -20.0, 3.0]}, placement=sp.table)
    probes = c.manifest.streets[0].probes
    frame = c.manifest.streets[0].frame_positions()
    np.testing.assert_allclose(frame[:, 0], [-29.0, -20.0, 3.0], atol=1e-9)
    x = np.array([p.position[0] for p in probes])
    np.testing.assert_allclose([p.position[1] for p in probes], 0.05 * x + 2.0, atol=1e-4)
