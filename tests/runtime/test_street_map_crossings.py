"""The street map with crossings (docs/crossings.md): cells in a crossing's region get the
crossing's id (streets + 1 + k), against hand-derived grids (an X crossing, a T-junction, parallel
streets that never cross, a cell centre exactly on a corridor edge), and GLSL
``envcap_street_map_crossing`` of ``envcap_street_map_id`` against the numpy twin inside and
outside crossings, on cell boundaries and non-finite positions."""

import moderngl
import numpy as np

from envcap.gpu.glsl_harness import run_glsl
from envcap.probeset.crossings import Meeting, detect_crossings
from envcap.probeset.manifest import Street
from envcap.probeset.planes import Planes
from envcap.runtime.street_map import StreetMap, crossing_index, street_map

MAP_UNIT = 5
DECL = (f"layout(binding = {MAP_UNIT}) uniform usampler2D street_map;\nuniform vec2 map_origin;\n"
        "uniform float map_inv_cell;\nuniform uint street_count;")
BODY = ("uint id = envcap_street_map_id(street_map, map_origin, map_inv_cell, p[i].xy);\n"
        "o[i] = vec4(float(id), float(envcap_street_map_crossing(id, street_count)), 0.0, 0.0);")


def street(name, axis, start, end, lo, hi):
    return Street(name=name, axis=axis, start=start, end=end, center=0.5 * (lo + hi),
                  planes=Planes(facade_min=lo, facade_max=hi, ground=0.0), probes=())


# A along x (0..20, z in [-2, 2]); B along z (-10..10, x in [8, 12]): centre lines meet at (10, 0).
A, B = street("a", "x", 0.0, 20.0, -2.0, 2.0), street("b", "z", -10.0, 10.0, 8.0, 12.0)


def test_an_x_crossing_gets_its_own_id():
    ms = detect_crossings((A, B))
    assert ms == [Meeting((10.0, 0.0), (0, 1))]
    m = street_map((A, B), 1.0, crossings=ms)
    plain = street_map((A, B), 1.0)
    want = plain.ids.copy()
    want[8:12, 8:12] = 3                   # centres x = 8.5 .. 11.5, z = -1.5 .. 1.5: in both corridors
    np.testing.assert_array_equal(m.ids, want)
    np.testing.assert_array_equal(crossing_index(m.lookup(np.array([10.0, 9.0, 5.0, 10.0]), np.array([0.0, -2.0, 0.0, 5.0])), 2),
                                  [0, 0, -1, -1])


def test_edges_t_junctions_and_parallel_streets():
    # cell centres on integers (origin -0.5): the corridor edges x = 8, 12 and z = -2, 2 fall on centres; closed: in
    m = street_map((A, B), 1.0, crossings=detect_crossings((A, B)), origin=(-0.5, -10.5), size=(21, 21))
    rows, cols = np.nonzero(m.ids == 3)
    assert (cols.min(), cols.max(), rows.min(), rows.max()) == (8, 12, 8, 12)      # x 8..12, z -2..2
    assert m.ids[10, 7] == 1 and m.ids[7, 10] == 2                                  # one cell outside
    # a T: the side street (x in [8, 12]) runs from A's centre line z = 0 to z = 10
    side = street("side", "z", 0.0, 10.0, 8.0, 12.0)
    ms = detect_crossings((A, side))
    assert ms == [Meeting((10.0, 0.0), (0, 1))]
    t = street_map((A, side), 1.0, crossings=ms, origin=(-0.5, -10.5), size=(21, 21))
    rows, cols = np.nonzero(t.ids == 3)
    assert (cols.min(), cols.max(), rows.min(), rows.max()) == (8, 12, 10, 12)      # z 0..2 only
    # parallel streets, one overlapping A: no crossing, the map is the plain one
    twin = street("twin", "x", 5.0, 15.0, -1.0, 3.0)
    assert detect_crossings((A, twin)) == []
    np.testing.assert_array_equal(street_map((A, twin), 1.0, crossings=[]).ids, street_map((A, twin), 1.0).ids)


def grid() -> tuple[Street, ...]:
    """Three streets along x and two along z, all crossing (six crossings)."""
    xs = [street(f"x{k}", "x", -5.0, 95.0, 30.0 * k - 4.0, 30.0 * k + 5.0) for k in range(3)]
    zs = [street(f"z{k}", "z", -10.0, 70.0, 40.0 * k + 10.0 - 3.5, 40.0 * k + 10.0 + 6.0) for k in range(2)]
    return tuple(xs + zs)


def glsl_lookup(ctx: moderngl.Context, m: StreetMap, n_streets: int, x: np.ndarray, z: np.ndarray) -> np.ndarray:
    tex = ctx.texture(m.size, 1, np.ascontiguousarray(m.ids).tobytes(), dtype="u2")
    tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    try:
        tex.use(MAP_UNIT)
        origin, inv_cell = m.glsl_arguments()
        return run_glsl(ctx, BODY, {"p": np.stack([x, z], axis=1)}, {"o": 2},
                        uniforms={"map_origin": origin, "map_inv_cell": inv_cell, "street_count": n_streets},
                        declarations=DECL, includes=("runtime/envcap_street_map.glsl",))["o"][:, :2]
    finally:
        tex.release()


def test_glsl_matches_numpy_inside_and_outside_crossings(gl_ctx):
    streets = grid()
    ms = detect_crossings(streets)
    assert len(ms) == 6
    m = street_map(streets, 0.5, crossings=ms)
    assert set(np.unique(m.ids)) == set(range(12))          # none, 5 streets, 6 crossings
    rng = np.random.default_rng(4)
    n = 100_000
    ox, oz = m.origin
    w, h = m.size
    x = rng.uniform(ox - 10, ox + w * 0.5 + 10, n)
    z = rng.uniform(oz - 10, oz + h * 0.5 + 10, n)
    q = n // 4                                               # a quarter on cell boundaries
    x[:q] = ox + rng.integers(-1, w + 2, q) * 0.5
    z[:q] = oz + rng.integers(-1, h + 2, q) * 0.5
    x[-4:] = [np.nan, np.inf, -np.inf, ox]
    z[-4:] = [oz, oz, oz, np.nan]
    x, z = x.astype(np.float32), z.astype(np.float32)
    got = glsl_lookup(gl_ctx, m, len(streets), x, z)
    ids = m.lookup(x, z)
    k = crossing_index(ids, len(streets))
    assert np.array_equal(got[:, 0], ids.astype(np.float32)) and np.array_equal(got[:, 1], k.astype(np.float32))
    assert set(np.unique(k)) == set(range(-1, 6))


def test_crossings_naming_streets_the_map_lacks_are_an_error():
    import pytest
    with pytest.raises(ValueError, match=r"crossings name streets \(0, 5\) of a map of 2 streets"):
        street_map((A, B), 1.0, crossings=[Meeting((10.0, 0.0), (0, 5))])
