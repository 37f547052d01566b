"""Streets at any angle in the street map (issue 10 on issue 11's map): rotated rectangles
rasterize as the rectangles in plan (an independent reference from the end points, no angle),
crossings go to the nearest centre line; GLSL ``envcap_city_locate`` (street, probe range,
street-local position) equals its numpy twin :meth:`StreetTable.locate` on 10^6 positions
(oblique streets, cell boundaries, rectangle edges, outside every street, non-finite), and the
twin's position is the float64 frame transform."""

import math

import moderngl
import numpy as np
import pytest

from envcap.core.street_frame import frame_to_world, world_to_frame
from envcap.gpu.glsl_harness import run_glsl
from envcap.probeset.manifest import Street
from envcap.probeset.planes import Planes
from envcap.runtime.street_map import StreetMap, StreetTable, street_map, street_table
from envcap.scene.model import local_origin

from city_fixtures import framed_street, plan_coords

UNITS = (5, 6, 7)
DECL = (f"layout(binding = {UNITS[0]}) uniform usampler2D street_map;\n"
        f"layout(binding = {UNITS[1]}) uniform sampler2D frames;\n"
        f"layout(binding = {UNITS[2]}) uniform usampler2D ranges;\n"
        "uniform vec2 map_origin;\nuniform float map_inv_cell;")
BODY = """uvec4 range;
vec3 local;
uint id = envcap_city_locate(street_map, map_origin, map_inv_cell, frames, ranges, p[i].xyz, range, local);
o[i] = vec4(float(id), local);
r[i] = vec4(range);"""

# (name, p0, p1, width, cross): oblique streets crossing each other and two axis streets
OBLIQUE = (("d45", (-50.0, -50.0), (50.0, 50.0), 10.0, 0.0), ("d30", (-40.0, 30.0), (60.0, 87.7), 8.0, 1.0),
           ("d120", (30.0, -40.0), (0.0, 12.0), 9.0, 0.0), ("dm75", (-30.0, 60.0), (-10.0, -15.0), 6.0, -1.0),
           ("d90", (40.0, -50.0), (40.0, 60.0), 7.0, 0.0))


def streets() -> list[Street]:
    out = [framed_street(n, p0, p1, w, c) for n, p0, p1, w, c in OBLIQUE]
    out.append(Street("ax", "x", -60.0, 60.0, 0.0, Planes(-4.0, 4.0, 0.0), ()))
    out.append(Street("az", "z", -50.0, 70.0, 20.0, Planes(16.0, 24.0, 0.0), ()))
    # a frame whose origin is 1.4 km behind the street: its local origin is 1 km along its x
    a = math.radians(10.0)
    out.append(Street("far", "x", 1400.0, 1500.0, 0.0, Planes(-3.0, 3.0, 0.0), (), yaw_deg=10.0,
                      origin_xz=(-1400.0 * math.cos(a), -1400.0 * math.sin(a))))
    return out


def reference_ids(sts: list[Street], m: StreetMap, tol: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Ids by the rule from the plan geometry alone (end points, widths), and a mask of the cells
    where that is ambiguous in float64 (a centre within ``tol`` of an edge, or a near tie)."""
    w, h = m.size
    X, Z = np.meshgrid(m.origin[0] + (np.arange(w) + 0.5) * m.cell, m.origin[1] + (np.arange(h) + 0.5) * m.cell)
    best, ids, amb = np.full((h, w), np.inf), np.zeros((h, w), np.uint16), np.zeros((h, w), bool)
    for k, st in enumerate(sts):
        if st.framed:   # end points of the centre line from the frame's own definition (origin p0, along its x)
            p0 = st.frame_origin_xz
            a = math.radians(st.frame_yaw_deg)
            p1 = (p0[0] + math.cos(a), p0[1] + math.sin(a))
            along, across = plan_coords(p0, p1, X, Z)
        else:
            along, across = (X, Z) if st.axis == "x" else (Z, X)
        lo, hi = st.planes.facade_min, st.planes.facade_max
        margin = np.minimum.reduce([np.abs(along - st.start), np.abs(along - st.end), np.abs(across - lo),
                                    np.abs(across - hi)])
        inside = (along > st.start) & (along < st.end) & (across > lo) & (across < hi)
        amb |= margin < tol
        d = np.abs(across - st.center)
        amb |= inside & (np.abs(d - best) < tol)
        take = inside & (d < best)
        best[take], ids[take] = d[take], k + 1
    return ids, amb


def test_a_45_degree_street_rasterizes_as_derived_by_hand():
    # centre line (-0.2, -0.2) -> (10.2, 10.2), 2 m wide: a cell centre (x, z) is in when
    # |z - x| / sqrt(2) <= 1 and 0 <= (x + z + 0.4) / sqrt(2) <= 10.4 sqrt(2) (no centre on an edge)
    m = street_map([framed_street("d", (-0.2, -0.2), (10.2, 10.2), 2.0)], 1.0)
    assert m.origin == (-1.0, -1.0) and m.size == (12, 12)       # world box: corners +- 1/sqrt(2) m
    # cell (row j, column i) has centre (i - 0.5, j - 0.5): on the line (x = 0.5 .. 9.5), one cell
    # off (0.707 m: z = x + 1 for x = -0.5 .. 9.5, z = x - 1 for x = 0.5 .. 10.5), two off (1.41 m) out
    ids = m.ids
    assert ids[6, 6] == 1 and ids[6, 7] == 1 and ids[7, 6] == 1 and ids[6, 8] == 0 and ids[8, 6] == 0
    assert ids[1, 1] == 1 and ids[1, 0] == 1 and ids[0, 1] == 1 and ids[0, 0] == 0 and ids[11, 11] == 0
    assert ids[10, 11] == 1 and ids[11, 10] == 1 and ids[11, 9] == 0
    assert ids.sum() == 10 + 11 + 11


def test_oblique_streets_and_their_crossings_rasterize_as_the_rectangles_in_plan():
    sts = streets()
    m = street_map(sts, 0.5)
    want, amb = reference_ids(sts, m)
    assert amb.mean() < 0.005 and len(np.unique(want)) == len(sts) + 1
    differ = (m.ids != want) & ~amb
    assert not differ.any(), f"{differ.sum()} cells differ from the plan reference"
    # the world box of each street holds all its cells (the rasterizer tests only that window)
    from envcap.probeset.city_index import street_bounds
    for k, st in enumerate(sts):
        j, i = np.nonzero(m.ids == k + 1)
        x0, x1, z0, z1 = street_bounds(st)
        cx, cz = m.origin[0] + (i + 0.5) * m.cell, m.origin[1] + (j + 0.5) * m.cell
        assert cx.min() >= x0 and cx.max() <= x1 and cz.min() >= z0 and cz.max() <= z1


def table_of(sts: list[Street], m: StreetMap) -> tuple[StreetTable, np.ndarray]:
    lo = []
    for st in sts:
        a0, a1, c0, c1 = st.start, st.end, st.planes.facade_min, st.planes.facade_max
        box = np.array([[a0, 0, c0], [a1, 30, c1]]) if st.axis == "x" else np.array([[c0, 0, a0], [c1, 30, a1]])
        lo.append(local_origin(box[0], box[1]))
    ranges = [(k // 2, 7 * k, 100 + 7 * k, 3 + k) for k in range(len(sts))]
    return street_table([st.frame_yaw_deg for st in sts], [st.frame_origin_xz for st in sts], lo, ranges,
                        m.origin), np.array(lo)


def glsl_locate(ctx: moderngl.Context, m: StreetMap, tab: StreetTable, p: np.ndarray):
    frames, ranges = tab.textures(width=8)              # several rows: the row-major fetch is exercised
    texs = [ctx.texture(m.size, 1, np.ascontiguousarray(m.ids).tobytes(), dtype="u2"),
            ctx.texture(frames.shape[1::-1], 4, frames.tobytes(), dtype="f4"),
            ctx.texture(ranges.shape[1::-1], 4, ranges.tobytes(), dtype="u4")]
    try:
        for t, unit in zip(texs, UNITS):
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
            t.use(unit)
        origin, inv_cell = m.glsl_arguments()
        return run_glsl(ctx, BODY, {"p": p}, {"o": 4, "r": 4}, uniforms={"map_origin": origin, "map_inv_cell": inv_cell},
                        declarations=DECL, includes=("runtime/envcap_street_map.glsl",))
    finally:
        for t in texs:
            t.release()


def test_glsl_locate_matches_numpy_on_a_million_positions(gl_ctx):
    sts = streets()
    cell = 0.5
    m = street_map(sts, cell)
    tab, lo = table_of(sts, m)
    rng = np.random.default_rng(5)
    n = 1_000_000
    w, h = m.size
    ox, oz = m.origin
    x = rng.uniform(ox - 0.2 * w * cell, ox + 1.2 * w * cell, n)
    z = rng.uniform(oz - 0.2 * h * cell, oz + 1.2 * h * cell, n)
    y = rng.uniform(-5.0, 30.0, n)
    q = n // 5
    x[:q] = ox + rng.integers(-1, w + 2, q) * cell                 # cell boundaries
    z[:q] = oz + rng.integers(-1, h + 2, q) * cell
    # rectangle edges: a point on a random edge of a random street, taken to the world in float64
    e = slice(q, 3 * q)
    k = rng.integers(0, len(sts), 2 * q)
    side = rng.integers(0, 4, 2 * q)
    t = rng.uniform(0, 1, 2 * q)
    for s, st in enumerate(sts):
        sel = k == s
        a0, a1, c0, c1 = st.start, st.end, st.planes.facade_min, st.planes.facade_max
        ss, tt = side[sel], t[sel]
        along = np.where(ss == 0, a0, np.where(ss == 1, a1, a0 + tt * (a1 - a0)))
        across = np.where(ss == 2, c0, np.where(ss == 3, c1, c0 + tt * (c1 - c0)))
        loc = np.zeros((sel.sum(), 3))
        loc[:, st.along_index], loc[:, st.cross_index] = along, across
        wp = frame_to_world(loc, st.frame_yaw_deg, st.frame_origin_xz)
        x[e][sel], z[e][sel] = wp[:, 0], wp[:, 2]
    x[-4:], z[-4:] = [np.nan, np.inf, -np.inf, ox], [oz, oz, oz, np.nan]
    p = np.stack([x, y, z], axis=1).astype(np.float32)
    out = glsl_locate(gl_ctx, m, tab, p)
    ids, rng_, local = tab.locate(m, p[:, 0], p[:, 1], p[:, 2])
    got_id, got_local, got_range = out["o"][:, 0], out["o"][:, 1:], out["r"]
    assert np.array_equal(got_id, ids.astype(np.float32)), f"{np.count_nonzero(got_id != ids)} ids differ"
    assert np.array_equal(got_range, rng_.astype(np.float32))
    # the sample reaches every street and no street, on and off the map
    assert set(np.unique(ids)) == set(range(len(sts) + 1)) and (ids[q:3 * q] == 0).mean() > 0.2
    # street-local positions: the same float32 operations (a fused multiply-add may move an ulp)
    fin = np.all(np.isfinite(local), axis=1)
    assert np.array_equal(np.isfinite(got_local), np.isfinite(local)) and fin.sum() == n - 4
    scale = 256.0                                                     # |c dx| + |s dz| + |t| <= 256 m here
    assert np.max(np.abs(got_local[fin] - local[fin])) <= 2 * np.spacing(np.float32(scale))
    # the twin is the float64 transform R (p - O) - L of the float32 inputs, rounded like float32
    ref = np.zeros((n, 3))
    p64 = p.astype(np.float64)
    for s, st in enumerate(sts, start=1):
        sel = ids == s
        ref[sel] = world_to_frame(p64[sel], st.frame_yaw_deg, st.frame_origin_xz) - lo[s - 1]
    sel = (ids > 0) & fin
    err = np.abs(local[sel] - ref[sel])
    assert err.max() <= 4 * np.spacing(np.float32(scale)), err.max()
    # no street: relative to the map's origin, y kept
    none = (ids == 0) & fin
    np.testing.assert_allclose(local[none], np.stack([p64[none, 0] - ox, p64[none, 1], p64[none, 2] - oz], 1),
                               atol=np.spacing(np.float32(scale)))
    assert np.all(rng_[ids == 0] == 0)


def test_bad_tables_are_named():
    with pytest.raises(ValueError, match="frames must be"):
        StreetTable(np.zeros((2, 4), np.float32), np.zeros((2, 4), np.uint32))
    with pytest.raises(ValueError, match="non-negative 32-bit"):
        street_table([0.0], [(0.0, 0.0)], [(0.0, 0.0, 0.0)], [(-1, 0, 0, 1)], (0.0, 0.0))
    with pytest.raises(ValueError, match="width must be an integer >= 2"):
        street_table([0.0], [(0.0, 0.0)], [(0.0, 0.0, 0.0)], [(0, 0, 0, 1)], (0.0, 0.0)).textures(width=0)
