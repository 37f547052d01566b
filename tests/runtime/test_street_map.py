"""The top-down street-ID map (issue 11, item 3): the rasterization of two crossing streets
against a hand-derived grid, and the GLSL lookup ``envcap_street_map_id`` (an R16UI texture read
with texelFetch) against the numpy twin :meth:`StreetMap.lookup` on 10^6 positions, cell
boundaries, positions outside the grid and non-finite positions included."""

import moderngl
import numpy as np
import pytest

from envcap.gpu.glsl_harness import run_glsl
from envcap.probeset.manifest import Street
from envcap.probeset.planes import Planes
from envcap.runtime.street_map import StreetMap, street_map

MAP_UNIT = 5
DECL = f"layout(binding = {MAP_UNIT}) uniform usampler2D street_map;\nuniform vec2 map_origin;\nuniform float map_inv_cell;"
BODY = "o[i] = vec4(float(envcap_street_map_id(street_map, map_origin, map_inv_cell, p[i].xy)));"


def street(name, axis, start, end, lo, hi):
    return Street(name=name, axis=axis, start=start, end=end, center=0.5 * (lo + hi),
                  planes=Planes(facade_min=lo, facade_max=hi, ground=0.0), probes=())


# A along x (0..20 m, z in [-2, 2], centre line z = 0); B along z (-10..10 m, x in [8, 12], centre line x = 10).
CROSSING = (street("a", "x", 0.0, 20.0, -2.0, 2.0), street("b", "z", -10.0, 10.0, 8.0, 12.0))


def test_two_crossing_streets_rasterize_as_derived_by_hand():
    m = street_map(CROSSING, 1.0)
    # grid: x from 0 to 20, z from -10 to 10, 1 m cells; cell centres x = i + 0.5, z = j - 9.5
    assert m.origin == (0.0, -10.0) and m.size == (20, 20)
    want = np.zeros((20, 20), dtype=np.uint16)
    want[8:12, :] = 1                       # A: centres z = -1.5 .. 1.5
    want[:, 8:12] = 2                       # B: centres x = 8.5 .. 11.5
    # crossing (rows z = -1.5, -0.5, 0.5, 1.5; columns x = 8.5 .. 11.5): distances to A's line
    # |z| = 1.5, .5, .5, 1.5, to B's line |x - 10| = 1.5, .5, .5, 1.5; nearer wins, ties to A
    want[8:12, 8:12] = [[1, 2, 2, 1],
                        [1, 1, 1, 1],
                        [1, 1, 1, 1],
                        [1, 2, 2, 1]]
    np.testing.assert_array_equal(m.ids, want)
    # lookups on boundaries (floor: the cell above), on the far edge (outside) and off the map
    x = np.array([9.0, 8.0, 7.999, 0.0, 20.0, 19.999, -0.001, 10.0, np.nan, np.inf])
    z = np.array([-2.0, -2.0, -2.001, 0.0, 0.0, 0.0, 0.0, 10.0, 0.0, 0.0])
    np.testing.assert_array_equal(m.lookup(x, z), [2, 1, 0, 1, 0, 1, 0, 0, 0, 0])


def test_a_street_narrower_than_a_cell_is_an_error():
    with pytest.raises(ValueError, match="covers no cell centre"):
        street_map((street("thin", "x", 0.0, 20.0, 0.1, 0.4),), 1.0)


def city() -> tuple[Street, ...]:
    """A small grid of crossing streets (4 along x, 3 along z) with ragged widths and ends."""
    rng = np.random.default_rng(11)
    out = []
    for k in range(4):
        c = 30.0 * k + rng.uniform(-3, 3)
        w = rng.uniform(4, 9)
        out.append(street(f"x{k}", "x", rng.uniform(-10, 5), rng.uniform(80, 100), c - w, c + w))
    for k in range(3):
        c = 35.0 * k + rng.uniform(-3, 3)
        w = rng.uniform(4, 9)
        out.append(street(f"z{k}", "z", rng.uniform(-15, 0), rng.uniform(85, 95), c - w, c + w))
    return tuple(out)


def glsl_lookup(ctx: moderngl.Context, m: StreetMap, x: np.ndarray, z: np.ndarray) -> np.ndarray:
    tex = ctx.texture(m.size, 1, np.ascontiguousarray(m.ids).tobytes(), dtype="u2")
    tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    try:
        tex.use(MAP_UNIT)
        origin, inv_cell = m.glsl_arguments()
        out = run_glsl(ctx, BODY, {"p": np.stack([x, z], axis=1)}, {"o": 1},
                       uniforms={"map_origin": origin, "map_inv_cell": inv_cell}, declarations=DECL,
                       includes=("runtime/envcap_street_map.glsl",))["o"][:, 0]
    finally:
        tex.release()
    return out


@pytest.mark.parametrize("cell", [0.5, 0.7])
def test_glsl_matches_numpy_on_a_million_positions(gl_ctx, cell):
    m = street_map(city(), cell)
    w, h = m.size
    assert m.ids.max() == 7 and (m.ids == 0).any()
    rng = np.random.default_rng(3)
    n = 500_000
    ox, oz = m.origin
    span_x, span_z = w * cell, h * cell
    # uniform over the map and a 20 % margin outside it
    x = rng.uniform(ox - 0.2 * span_x, ox + 1.2 * span_x, n)
    z = rng.uniform(oz - 0.2 * span_z, oz + 1.2 * span_z, n)
    # a quarter exactly on cell boundaries (both coordinates, from one cell outside to one past the far edge)
    q = n // 4
    x[:q] = ox + rng.integers(-1, w + 2, q) * cell
    z[:q] = oz + rng.integers(-1, h + 2, q) * cell
    # footprint edges (facades, street ends) exactly
    edges = np.array([[s.start, s.end, s.planes.facade_min, s.planes.facade_max] for s in city()]).ravel()
    x[q:2 * q:2] = rng.choice(edges, len(x[q:2 * q:2]))
    z[q + 1:2 * q:2] = rng.choice(edges, len(z[q + 1:2 * q:2]))
    x[-4:] = [np.nan, np.inf, -np.inf, ox]
    z[-4:] = [oz, oz, oz, np.nan]
    x, z = x.astype(np.float32), z.astype(np.float32)
    got = glsl_lookup(gl_ctx, m, x, z)
    want = m.lookup(x, z)
    assert np.array_equal(got, want.astype(np.float32)), f"{np.count_nonzero(got != want)} of {n} differ"
    # the sample reaches every street, no street and off-map positions
    assert set(np.unique(want)) == set(range(8))
    # independent check of the twin where the cell is exact (power of two): a boundary position
    # ox + k * cell lies in cell k, and off the grid the id is 0
    if cell == 0.5:
        ki = np.round((x[:q].astype(np.float64) - ox) / cell).astype(int)
        kj = np.round((z[:q].astype(np.float64) - oz) / cell).astype(int)
        inside = (ki >= 0) & (kj >= 0) & (ki < w) & (kj < h)
        ref = np.zeros(q, dtype=np.uint16)
        ref[inside] = m.ids[kj[inside], ki[inside]]
        np.testing.assert_array_equal(want[:q], ref)
