"""HDR cube capture (envcap.capture) on real OpenGL (llvmpipe), checked against hand-derived cases.

References: envcap.core.cube (texel directions / direction_to_texel) for face orientation, analytic
ray-box distances, Lambert's law for the sun, the closed-form irradiance of a uniform sky
hemisphere, a slab-test shadow oracle, and a float64 brute-force irradiance integral.
"""

import math

import numpy as np
import pytest

from envcap.core import cube
from envcap.capture.culling import chunk_face_visibility, chunk_triangles
from envcap.capture.outputs import probe_inside_geometry
from envcap.capture.projection import FACE_ROWS, face_clip_matrix, face_clip_matrix_reversed
from envcap.capture.renderer import CubeCapture
from envcap.capture.sky_sh import sh9_basis, sky_irradiance_sh
from envcap.gpu import float_depth
from envcap.scene import load_scene
from envcap.scene.synthetic import box, quad
from envcap.scene.model import SceneMesh


class StandInSun:
    def __init__(self, direction, illuminance):
        d = np.asarray(direction, np.float64)
        self.direction = d / np.linalg.norm(d)
        self.illuminance = np.asarray(illuminance, np.float64)
        self.radiance = self.illuminance / (math.pi * 0.00465 ** 2)
        self.angular_radius = 0.00465


class StandInSky:
    """Same attributes as envcap.sky.Sky that the capture uses: ``sun`` and ``radiance(dirs)``."""

    def __init__(self, sun=None, radiance_fn=None, level=(1000.0, 1200.0, 1500.0)):
        self.sun = sun
        self._fn = radiance_fn
        self._level = np.asarray(level, np.float64)

    def radiance(self, dirs):
        dirs = np.asarray(dirs, np.float64)
        if self._fn is not None:
            return self._fn(dirs)
        return np.broadcast_to(self._level, dirs.shape).copy()


EMPTY = SceneMesh.concatenate([])


def _ray_box_exit(p, d, lo, hi):
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (hi - p) / d
        t0 = (lo - p) / d
    return np.min(np.maximum(t0, t1), axis=-1)


def test_face_orientation_marker_quads_light_the_expected_texels(gl_ctx):
    n = 16
    rng = np.random.default_rng(3)
    dirs = cube.texel_directions(n).reshape(-1, 3)
    pick = rng.choice(dirs.shape[0], size=60, replace=False)
    p = np.array([1.5, 2.0, -3.0])
    r = 5.0
    parts = []
    for d in dirs[pick]:
        a = np.cross(d, [0.3, 0.5, 0.8])
        a /= np.linalg.norm(a)
        b = np.cross(d, a)
        h = 0.1 * (2.0 / n) * r  # far smaller than a texel, even in a face corner
        c = p + r * d - h * a - h * b
        parts.append(quad(c, 2 * h * b, 2 * h * a, emission=(1, 1, 1)))  # b x a = -d: faces the probe
    mesh = SceneMesh.concatenate(parts)
    with CubeCapture(mesh, n, ctx=gl_ctx, effects={"emissive_windows"}) as cap:
        got = cap.capture(p)
    hit = np.argwhere(got.rgba[..., 3] > 0)
    want = np.stack(cube.direction_to_texel(dirs[pick], n), axis=-1)
    assert sorted(map(tuple, hit)) == sorted(map(tuple, want))
    # The marker faces the probe: front face, emission seen, distance ~ r.
    f, j, i = want.T
    np.testing.assert_allclose(got.rgba[f, j, i, :3], 1.0)
    np.testing.assert_allclose(got.distance[f, j, i], r, rtol=1e-4)
    assert not got.backfacing.any()


@pytest.mark.parametrize("n", [1, 7, 32])
def test_box_room_distance_is_the_analytic_wall_distance(gl_ctx, n):
    lo, hi = np.array([-100.0, -2.0, -150.0]), np.array([120.0, 80.0, 90.0])
    p = np.array([3.3, 1.7, -2.1])
    mesh = box(lo, hi, inward=True)
    with CubeCapture(mesh, n, ctx=gl_ctx) as cap:
        got = cap.capture(p)
    d = cube.texel_directions(n)
    want = _ray_box_exit(p, d, lo, hi)
    assert np.all(got.rgba[..., 3] == 1.0)
    assert not got.backfacing.any()
    # The goal is 1 cm at 100 m (1e-4); float32 perspective-correct interpolation gives ~1.5e-5.
    np.testing.assert_allclose(got.distance, want, rtol=3e-5)
    assert got.rgba.dtype == np.float32 and got.distance.dtype == np.float32
    assert got.rgba.shape == (6, n, n, 4) and got.distance.shape == (6, n, n)


def test_empty_scene_is_all_sky(gl_ctx):
    sky = StandInSky(StandInSun((0.2, 1, 0.1), (1e5, 1e5, 1e5)))
    eff = {"sun_light", "sun_shadows", "sky_light", "emissive_windows"}
    with CubeCapture(EMPTY, 4, ctx=gl_ctx, sky=sky, effects=eff) as cap:
        got = cap.capture([0, 1, 0])
    assert np.all(got.rgba == 0) and np.all(got.distance == 0)
    assert "shadow_map" not in got.passes_run  # nothing to cast a shadow
    assert got.passes_run[-2:] == ["render", "readback"]


@pytest.mark.parametrize("bad", [0, -1, 2.5, 3.0, True, "8", None])
def test_bad_resolution_is_a_value_error(gl_ctx, bad):
    with pytest.raises(ValueError, match="resolution"):
        CubeCapture(EMPTY, bad, ctx=gl_ctx)


@pytest.mark.parametrize("pos", [[0, np.nan, 0], [np.inf, 0, 0], [0, 0], [[0, 0, 0]]])
def test_bad_position_is_a_value_error(gl_ctx, pos):
    with CubeCapture(box((0, 0, 0), (1, 1, 1)), 2, ctx=gl_ctx) as cap:
        with pytest.raises(ValueError, match="position"):
            cap.capture(pos)


def test_bad_effects_and_near_far(gl_ctx):
    with pytest.raises(ValueError, match="unknown effect"):
        CubeCapture(EMPTY, 2, ctx=gl_ctx, effects={"fog"})
    with pytest.raises(ValueError, match="needs 'sun_light'"):
        CubeCapture(EMPTY, 2, ctx=gl_ctx, effects={"sun_shadows"})
    for near, far in [(0.0, 10.0), (-1.0, 10.0), (5.0, 1.0), (math.nan, 10.0)]:
        with pytest.raises(ValueError, match="near"):
            CubeCapture(EMPTY, 2, ctx=gl_ctx, near=near, far=far)


def test_probe_inside_a_building_sees_back_faces(gl_ctx):
    building = box((-5, 0, -5), (5, 10, 5), albedo=(0.8, 0.8, 0.8), emission=(2, 2, 2))
    sky = StandInSky(StandInSun((0.3, 1, 0.2), (1e4, 1e4, 1e4)))
    eff = {"sun_light", "sky_light", "emissive_windows"}
    with CubeCapture(building, 8, ctx=gl_ctx, sky=sky, effects=eff) as cap:
        inside = cap.capture([1, 3, -2])
        outside = cap.capture([0, 3, -9])
    assert np.all(inside.rgba[..., 3] == 1) and inside.backfacing.all()
    assert np.all(inside.rgba[..., :3] == 0)  # the unlit side is black
    assert inside.inside_geometry and probe_inside_geometry(inside.backfacing)
    want = _ray_box_exit(np.array([1.0, 3, -2]), cube.texel_directions(8), np.array([-5.0, 0, -5]), np.array([5.0, 10, 5]))
    np.testing.assert_allclose(inside.distance, want, rtol=3e-5)
    assert not outside.inside_geometry and not outside.backfacing.any()
    assert outside.rgba[..., 3].any()


def test_sun_light_adds_lambert_term_to_a_wall(gl_ctx):
    # Wall at x = 4 facing -X toward the probe; the sun comes from -X, above.
    l = np.array([-0.6, 0.7, 0.2])
    l /= np.linalg.norm(l)
    e_sun = np.array([9e4, 8e4, 7e4])
    albedo = np.array([0.6, 0.4, 0.2])
    wall = quad((4, -10, 10), (0, 20, 0), (0, 0, -20), albedo)  # (0,20,0) x (0,0,-20) = -X
    sky = StandInSky(StandInSun(l, e_sun))
    p = [0, 0, 0]
    with CubeCapture(wall, 16, ctx=gl_ctx, sky=sky, effects=set()) as off_cap:
        off = off_cap.capture(p)
    with CubeCapture(wall, 16, ctx=gl_ctx, sky=sky, effects={"sun_light"}) as on_cap:
        on = on_cap.capture(p)
    assert on_cap.applied == {"sun_light"} and off_cap.applied == set()
    wall_px = on.rgba[0, ..., 3] == 1  # face +X sees the wall everywhere
    assert wall_px.all()
    want = albedo / math.pi * e_sun * max(0.0, -l[0])
    np.testing.assert_allclose(off.rgba[0, ..., :3], 0.0)
    np.testing.assert_allclose(on.rgba[0, ..., :3] - off.rgba[0, ..., :3], np.broadcast_to(want, (16, 16, 3)),
                               rtol=1e-5)
    # A sun behind the wall lights nothing.
    with CubeCapture(wall, 16, ctx=gl_ctx, sky=StandInSky(StandInSun(-l, e_sun)), effects={"sun_light"}) as c:
        np.testing.assert_array_equal(c.capture(p).rgba[0, ..., :3], 0.0)


def test_emissive_windows_only_when_listed(gl_ctx):
    em = np.array([5.0, 4.0, 3.0])
    win = quad((3, -1, 1), (0, 2, 0), (0, 0, -2), (0.5, 0.5, 0.5), em)  # faces -X
    with CubeCapture(win, 8, ctx=gl_ctx, effects={"emissive_windows"}) as cap:
        on = cap.capture([0, 0, 0])
    with CubeCapture(win, 8, ctx=gl_ctx) as cap:
        off = cap.capture([0, 0, 0])
    seen = on.rgba[..., 3] == 1
    assert seen.any()
    np.testing.assert_allclose(on.rgba[seen][:, :3], np.broadcast_to(em, (seen.sum(), 3)), rtol=1e-6)
    np.testing.assert_array_equal(off.rgba[..., :3], 0.0)
    np.testing.assert_array_equal(off.rgba[..., 3], on.rgba[..., 3])


def test_sky_light_uniform_hemisphere_matches_closed_form(gl_ctx):
    # Uniform sky L0 over the upper hemisphere: E(up) = pi L0, E(horizontal) = pi L0 / 2.
    level = np.array([1000.0, 1200.0, 1500.0])
    sky = StandInSky(None, level=level)
    albedo = np.array([0.5, 0.3, 0.7])
    floor = quad((-50, 0, 50), (100, 0, 0), (0, 0, -100), albedo)  # +Y
    wall = quad((5, 0, 50), (0, 50, 0), (0, 0, -100), albedo)  # faces -X, vertical
    mesh = SceneMesh.concatenate([floor, wall])
    with CubeCapture(mesh, 8, ctx=gl_ctx, sky=sky, effects={"sky_light"}) as cap:
        got = cap.capture([0, 1, 0])
        assert cap.passes_run == ["sky_sh"]
    np.testing.assert_allclose(got.rgba[3, ..., :3], np.broadcast_to(albedo * level, (8, 8, 3)), rtol=2e-3)
    # face +X: rows in the upper half see the wall (the floor is at y = 0, 1 m below the probe)
    d = cube.texel_directions(8)[0]
    t_wall = 5.0 / d[..., 0]
    sees_wall = (1.0 + t_wall * d[..., 1]) > 0.05
    np.testing.assert_allclose(got.rgba[0][sees_wall][:, :3],
                               np.broadcast_to(albedo * level / 2, (sees_wall.sum(), 3)), rtol=2e-3)


def test_sky_sh_irradiance_against_brute_force_integral():
    def rad(d):
        y = np.clip(d[..., 1], 0, None)
        lum = 800.0 * (1.0 + 2.0 * y * y + 0.5 * d[..., 0]) + 300.0 * np.exp(-4.0 * (1 - d[..., 2]))
        return np.stack([lum, 1.1 * lum, 1.3 * lum], axis=-1)

    sky = StandInSky(None, radiance_fn=rad)
    sh = sky_irradiance_sh(sky, 64)
    # Brute force: float64 sum over a finer cube (exact texel solid angles), clamped cosine.
    dirs = cube.texel_directions(128).reshape(-1, 3)
    w = cube.texel_solid_angles(128).reshape(-1)
    lr = rad(dirs) * (dirs[:, 1:2] >= 0)
    rng = np.random.default_rng(0)
    normals = rng.normal(size=(40, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    exact = np.stack([(lr * (w * np.clip(dirs @ nrm, 0, None))[:, None]).sum(0) for nrm in normals])
    approx = np.clip(sh9_basis(normals) @ sh, 0, None)
    scale = exact.max()
    # SH9 irradiance error bound for smooth skies (Ramamoorthi & Hanrahan: a few percent).
    assert np.max(np.abs(approx - exact)) < 0.05 * scale


def _slab_hits(o, l, lo, hi):
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (lo - o) / l
        t1 = (hi - o) / l
    tmin = np.nanmax(np.minimum(t0, t1), axis=-1)
    tmax = np.nanmin(np.maximum(t0, t1), axis=-1)
    return (tmax >= np.maximum(tmin, 0.0))


def test_sun_shadows_darken_exactly_the_shadowed_ground(gl_ctx):
    l = np.array([0.3, 1.0, 0.2])
    l /= np.linalg.norm(l)
    e_sun = np.array([1e5, 1e5, 1e5])
    albedo = 0.5
    ground = quad((-20, 0, 20), (40, 0, 0), (0, 0, -40), (albedo,) * 3)
    blo, bhi = np.array([-1.0, 3.0, -1.0]), np.array([1.0, 4.0, 1.0])
    mesh = SceneMesh.concatenate([ground, box(blo, bhi)])
    sky = StandInSky(StandInSun(l, e_sun))
    p = np.array([0.5, 1.5, 2.5])
    n = 64
    with CubeCapture(mesh, n, ctx=gl_ctx, sky=sky, effects={"sun_light", "sun_shadows"}) as cap:
        sh = cap.capture(p)
        assert cap.passes_run == ["shadow_map"]
    with CubeCapture(mesh, n, ctx=gl_ctx, sky=sky, effects={"sun_light"}) as cap:
        lit = cap.capture(p)
        assert cap.passes_run == []
    d = cube.texel_directions(n)
    with np.errstate(divide="ignore"):
        t_ground = np.where(d[..., 1] < 0, -p[1] / d[..., 1], np.inf)
    g = p + t_ground[..., None] * d
    on_ground = np.isfinite(t_ground) & (np.abs(g[..., 0]) < 19) & (np.abs(g[..., 2]) < 19)
    on_ground &= np.abs(sh.distance - t_ground) < 1e-3 * t_ground  # not hidden by the box
    # Shadow oracle: slab test toward the sun, robust to +-0.15 m (PCF and bias blur the edge).
    votes = [_slab_hits(g + np.array(o), l, blo, bhi) for o in
             [(0, 0, 0), (0.15, 0, 0), (-0.15, 0, 0), (0, 0, 0.15), (0, 0, -0.15)]]
    shadowed = on_ground & np.all(votes, axis=0)
    sunny = on_ground & ~np.any(votes, axis=0)
    assert shadowed.sum() > 50 and sunny.sum() > 1000
    full = albedo / math.pi * e_sun[0] * l[1]
    np.testing.assert_allclose(sh.rgba[..., 0][sunny], full, rtol=1e-5)  # no shadow acne
    np.testing.assert_array_equal(sh.rgba[..., 0][shadowed], 0.0)
    np.testing.assert_allclose(lit.rgba[..., 0][shadowed], full, rtol=1e-5)  # no shadows without the pass


def test_capture_many_and_pass_records(gl_ctx):
    mesh = box((-10, 0, -10), (10, 8, 10), inward=True)
    sky = StandInSky(StandInSun((0.3, 1, 0.2), (1e4, 1e4, 1e4)))
    eff = {"sun_light", "sun_shadows", "sky_light", "emissive_windows"}
    with CubeCapture(mesh, 4, ctx=gl_ctx, sky=sky, effects=eff) as cap:
        pos = np.array([[0, 1, 0], [2, 2, 2], [-3, 1, 4]], float)
        s = cap.capture_many(pos, progress=False)
        one = cap.capture(pos[1])
    assert s.rgba.shape == (3, 6, 4, 4, 4) and s.distance.shape == (3, 6, 4, 4)
    np.testing.assert_array_equal(s.rgba[1], one.rgba)
    np.testing.assert_array_equal(s.distance[1], one.distance)
    assert s.passes_run == ["sky_sh", "shadow_map", "render", "readback"]
    assert set(s.pass_times_s) == set(s.passes_run) and all(v >= 0 for v in s.pass_times_s.values())
    with pytest.raises(ValueError, match="positions"):
        CubeCapture(mesh, 2, ctx=gl_ctx).capture_many(np.zeros((3, 2)))


def test_face_clip_matrix_maps_texel_centers_to_pixel_centers():
    n = 5
    c = cube.texel_centers(n)
    v, u = np.meshgrid(c, c, indexing="ij")
    for f in range(6):
        d = cube.face_uv_to_direction(f, u, v) * 7.0
        clip = np.concatenate([d, np.ones(d.shape[:-1] + (1,))], axis=-1) @ face_clip_matrix(f).T
        np.testing.assert_allclose(clip[..., 0] / clip[..., 3], u, atol=1e-12)
        np.testing.assert_allclose(clip[..., 1] / clip[..., 3], v, atol=1e-12)
        assert np.all(np.abs(clip[..., 2] / clip[..., 3]) < 1)


# -- per-face chunk culling ---------------------------------------------------------------------

def _canyon():
    sc = load_scene("canyon")
    return sc, sc.sky.build()


def test_culled_capture_equals_drawing_everything_on_canyon(gl_ctx):
    """Culling and nearest-first order change nothing: bit-exact against the one-draw path."""
    sc, sky = _canyon()
    positions = [
        [10.3, 1.7, 0.4],      # mid street
        [8.0, 1.7, 0.0],       # on a chunk-cell boundary (8 m cells) in x and z
        [16.0, 1.7, 7.99],     # a cell corner, 1 cm from the facade plane
        [299.5, 1.7, 0.0],     # street end
        [305.0, 1.7, 0.0],     # beyond the end, looking back into the canyon
        [0.0, 60.0, 0.0],      # above the roofs
        [0.0, 10.0, -15.0],    # inside a building
    ]
    with CubeCapture.from_scene(sc, 32, sky=sky, ctx=gl_ctx) as fast, \
            CubeCapture.from_scene(sc, 32, sky=sky, ctx=gl_ctx, cull_chunks=False) as full:
        assert fast.chunks is not None and fast.chunks.first.size > 20
        for p in positions:
            a, b = fast.capture(p), full.capture(p)
            np.testing.assert_array_equal(a.rgba, b.rgba, err_msg=f"rgba at {p}")
            np.testing.assert_array_equal(a.distance, b.distance, err_msg=f"distance at {p}")
            np.testing.assert_array_equal(a.backfacing, b.backfacing, err_msg=f"backfacing at {p}")
            assert b.draw_stats["triangles"] == 6 * sc.mesh.triangle_count
            assert a.draw_stats["triangles"] < 0.5 * b.draw_stats["triangles"], p  # it does cull
            assert a.rgba[..., 3].any()
        s = fast.capture_many(np.array(positions[:3]), progress=False)
        np.testing.assert_array_equal(s.rgba[1], full.capture(positions[1]).rgba)


def test_chunk_visibility_never_rejects_a_box_the_frustum_reaches():
    """Reference: exact feasibility (scipy linprog) of {r in box, inside the face frustum}."""
    from scipy.optimize import linprog

    rng = np.random.default_rng(7)
    c0 = rng.uniform(-20, 20, (200, 3))
    size = rng.uniform(0.0, 6.0, (200, 3)) * (rng.random((200, 3)) > 0.1)  # some flat boxes
    lo, hi = c0, c0 + size
    lo[:10] = [[0.0, 0.0, 0.0]] * 10  # boxes touching the probe
    probe = np.zeros(3)
    near = 0.05
    vis = chunk_face_visibility(lo, hi, probe, near=near)
    assert vis.shape == (6, 200) and vis.dtype == bool
    rejected = 0
    for f in range(6):
        r = FACE_ROWS[f]
        a_ub = np.stack([r[0] - r[2], -r[0] - r[2], r[1] - r[2], -r[1] - r[2], -r[2]])  # a r <= b
        b_ub = np.array([0, 0, 0, 0, -near])
        for c in range(200):
            res = linprog(np.zeros(3), A_ub=a_ub, b_ub=b_ub, bounds=list(zip(lo[c], hi[c])), method="highs")
            if res.status == 0:
                assert vis[f, c], (f, lo[c], hi[c])
            rejected += not vis[f, c]
    assert rejected > 6 * 200 * 0.5  # most boxes miss most faces


def test_chunk_visibility_far_plane_and_box_around_probe():
    lo = np.array([[-1.0, -1, -1], [50.0, -1, -1]])
    hi = np.array([[1.0, 1, 1], [60.0, 1, 1]])
    vis = chunk_face_visibility(lo, hi, np.zeros(3), near=0.05, far=40.0)
    assert vis[:, 0].all()                     # a box around the probe reaches every face
    assert not vis[:, 1].any()                 # beyond far on +X, outside the other faces
    assert chunk_face_visibility(lo, hi, np.zeros(3))[0, 1]  # infinite far: +X sees it


def test_chunk_triangles_partition_and_bounds(gl_ctx):
    sc, _ = _canyon()
    m = sc.mesh
    ch = chunk_triangles(m.positions, m.indices, 8.0)
    assert np.array_equal(np.sort(ch.order), np.arange(m.triangle_count))  # each triangle once
    assert ch.first[0] == 0 and np.array_equal(ch.first[1:], np.cumsum(ch.count)[:-1])
    tri = m.positions[m.indices[ch.order]].astype(np.float64)
    chunk_of = np.repeat(np.arange(ch.first.size), ch.count)
    assert np.all(tri.min(axis=1) >= ch.lo[chunk_of]) and np.all(tri.max(axis=1) <= ch.hi[chunk_of])
    # Loose grid: a box is at most about twice its cell, so the huge ground does not bloat the rest.
    ext = (ch.hi - ch.lo)[:, [0, 2]].max(axis=1)
    assert ch.count[ext <= 2 * 8.0 + 1e-3].sum() > 0.95 * m.triangle_count  # windows, frames: 8 m cells
    assert ch.count[ext > 2 * 32.0 + 1e-3].sum() < 10  # only the ground is in a huge box
    empty = chunk_triangles(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint32))
    assert empty.first.size == 0
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="chunk cell size"):
            chunk_triangles(m.positions, m.indices, bad)
        with pytest.raises(ValueError, match="chunk cell size"):
            CubeCapture(box((0, 0, 0), (1, 1, 1)), 2, chunk_size=bad, ctx=gl_ctx)


def test_window_1p5cm_in_front_of_its_wall_wins_at_300m(gl_ctx):
    """Float32 reversed depth: a 24-bit standard depth buffer ties these two planes at 300 m
    (resolution ~10 cm there) and would show the wall drawn first."""
    d = 300.0
    wall = quad((d + 0.015, -150, -150), (0, 0, 300), (0, 300, 0), emission=(0, 1, 0))   # faces -x
    window = quad((d, -120, -120), (0, 0, 240), (0, 240, 0), emission=(1, 0, 0))        # in front
    mesh = SceneMesh.concatenate([wall, window])  # the wall first: a depth tie keeps the wall
    with CubeCapture(mesh, 64, ctx=gl_ctx, effects={"emissive_windows"}) as cap:
        got = cap.capture([0.0, 0.0, 0.0])
        gl = float_depth.FloatDepthGL()
        assert gl.get(float_depth.GL_CLIP_DEPTH_MODE) == 0x935E  # NEGATIVE_ONE_TO_ONE restored
        assert gl.get(float_depth.GL_DEPTH_FUNC) != float_depth.GL_GREATER
    seen = got.rgba[0, ..., 3] > 0
    dirs = cube.texel_directions(64)[0]
    inside = np.all(np.abs(dirs[..., 1:] / dirs[..., :1]) * d < 119.0, axis=-1)  # rays hitting the window
    assert inside.sum() > 500 and np.all(seen[inside])
    np.testing.assert_array_equal(got.rgba[0][inside][:, :3], np.tile([1.0, 0.0, 0.0], (inside.sum(), 1)))
    np.testing.assert_allclose(got.distance[0][inside], d / dirs[inside][:, 0], rtol=3e-5)


def test_reversed_face_clip_matrix_depth_and_xy():
    """Hand-derived: z/w = 1 at ma = near, 0 at ma = far (near / ma when far is infinite);
    x, y, w rows equal face_clip_matrix's."""
    near, far = 0.05, 400.0
    for f in range(6):
        ma_dir = np.linalg.inv(face_clip_matrix(f)[[0, 1, 3], :3])[:, 2]  # direction with sc = tc = 0
        for ma in (near, 1.0, 100.0, far):
            r = np.append(ma_dir * ma, 1.0)
            fin = face_clip_matrix_reversed(f, near, far) @ r
            inf = face_clip_matrix_reversed(f, near) @ r
            np.testing.assert_allclose(fin[[0, 1, 3]], (face_clip_matrix(f, near, far) @ r)[[0, 1, 3]], atol=1e-12)
            np.testing.assert_allclose(fin[2] / fin[3], (far - ma) / (far - near) * near / ma, rtol=1e-12, atol=1e-15)
            np.testing.assert_allclose(inf[2] / inf[3], near / ma, rtol=1e-12)
    with pytest.raises(ValueError, match="near"):
        face_clip_matrix_reversed(0, 0.0)
