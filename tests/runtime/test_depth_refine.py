"""The depth-refined lookup (envcap.runtime.methods.depth_refine): it finds the surface the probe
saw where the planes are wrong (against the analytic hit of a set-back facade), keeps the planes'
hit where they are right, and GLSL on llvmpipe matches the numpy twin, hard inputs included."""

import numpy as np
import pytest
from runtime_fixtures import ARGS, DECL, probe_set

from envcap.core import cube
from envcap.gpu.cube_array import CubeArrayTexture, cube_texture
from envcap.gpu.glsl_harness import run_glsl
from envcap.runtime.chains import ProbeChains
from envcap.runtime.footprint import footprint
from envcap.runtime.methods.depth_refine import METHOD, depth_refine, inverse_distance
from envcap.runtime.parallax import exit_distance
from envcap.runtime.sampling import sample_street

TRUE_PLANES = (-6.0, 9.0, 0.0)   # the +cross facade is set back 3 m behind the uploaded plane (+6)
ROOF = 12.0                      # facades end at this height: above it the probes see the sky
DIST_UNIT = 5
DIST_DECL = DECL + f"\nlayout(binding = {DIST_UNIT}) uniform samplerCubeArray dist;\n"
INCLUDES = ("runtime/envcap_depth_refine.glsl",)


def true_distance(p, n):
    """Distance (m) from probe ``p`` to the true street for every texel centre of an ``n`` cube;
    0 (sky) above the roofs and where no plane is hit."""
    d = cube.texel_directions(n).reshape(-1, 3)
    t = exit_distance(np.broadcast_to(p, d.shape), d, TRUE_PLANES, 0)
    h = p + t[:, None] * d
    return np.where((t < 1e5) & (h[:, 1] <= ROOF), t, 0.0).reshape(6, n, n)


@pytest.fixture(scope="module")
def world(gl_ctx):
    probes, sky, street, powers = probe_set()
    dist = np.stack([true_distance(p, 32) for p in street.positions])
    dist[0, 0, 0, :4] = np.inf          # hard texels: Inf and NaN distances read as sky
    dist[1, 0, 0, :4] = np.nan
    inv = inverse_distance(dist)
    tex = CubeArrayTexture([np.concatenate([inv[..., None], np.zeros(inv.shape + (3,), np.float32)], axis=-1)],
                           filter="nearest")
    pt, st = CubeArrayTexture(probes), cube_texture(gl_ctx, sky)
    yield probes, sky, street, powers, dist, inv, pt, st, tex
    for t in (pt, st, tex):
        t.release()


def f32(a):
    return np.asarray(a, np.float32).astype(np.float64)


def lookups(rng, n):
    x = np.c_[rng.uniform(-2, 22, n), rng.uniform(0.2, 8, n), rng.uniform(-5.5, 5.5, n)]
    d = rng.normal(size=(n, 3))
    return x, d / np.linalg.norm(d, axis=1, keepdims=True)


def hard_lookups(street):
    e = np.eye(3)
    dirs = np.concatenate([e, -e, np.array([[-0.0, 1.0, -0.0], [0.6, -0.0, 0.8], [-0.0, -0.6, -0.8]])])
    pts = np.concatenate([street.positions, [[5.0, 0.0, 6.0], [5.0, -3.0, -9.0], [-100.0, 1.0, 0.0],
                                             [1e4, 1.0, 1.0], [10.0, 20.0, 6.0]]])
    return np.repeat(pts, len(dirs), axis=0), np.tile(dirs, (len(pts), 1))


def test_refined_hit_lands_on_the_set_back_facade():
    """Rays towards the set-back facade: the planes' hit is 3 m short; two steps land within a
    small fraction of that error of the analytic hit (float64, exact distances per texel centre)."""
    _, _, street, _ = probe_set()
    p = street.positions[1]
    n = 256                                                   # fine texels: the read error is small
    inv = inverse_distance(true_distance(p, n))[None]
    rng = np.random.default_rng(1)
    x = np.c_[rng.uniform(8, 12, 400), rng.uniform(0.5, 3, 400), rng.uniform(-4, 4, 400)]
    d = np.c_[rng.uniform(-0.3, 0.3, 400), rng.uniform(-0.1, 0.3, 400), np.ones(400)]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t_true = exit_distance(x, d, TRUE_PLANES, 0)
    h = x + t_true[:, None] * d
    on_facade = (h[:, 2] > TRUE_PLANES[1] - 0.01) & (h[:, 1] < ROOF - 1)
    want = (h - p) / np.linalg.norm(h - p, axis=1, keepdims=True)
    r_planes = footprint(x, d, p, street.planes[1], 0).r
    r, q = depth_refine(x, d, p, street.planes[1], 0, inv, 0, steps=2)
    r3, _ = depth_refine(x, d, p, street.planes[1], 0, inv, 0, steps=3)
    err = lambda a: np.degrees(np.arccos(np.clip(np.sum(a * want, axis=1), -1, 1)))[on_facade]
    assert on_facade.sum() > 200
    assert np.median(err(r_planes)) > 3.0                     # the wrong plane: degrees off
    assert np.median(err(r)) < 0.02 * np.median(err(r_planes))           # measured 0.0027 vs 3.9 deg
    assert np.median(err(r3)) <= np.median(err(r)) + 1e-9
    assert np.all(np.isfinite(q)) and np.all(q > 0)


def test_planes_kept_where_right_and_exact_at_the_probe():
    """Towards the true -cross facade the planes are right: r and q are planes_mip_oblique's.  At
    the probe's own position the lookup direction is d itself (the first sphere step is exact)."""
    _, _, street, _ = probe_set()
    p = street.positions[1]
    inv = inverse_distance(true_distance(p, 64))[None]
    rng = np.random.default_rng(2)
    x = np.c_[rng.uniform(8, 12, 300), rng.uniform(0.5, 3, 300), rng.uniform(-4, 4, 300)]
    d = np.c_[rng.uniform(-0.3, 0.3, 300), rng.uniform(-0.2, 0.1, 300), -np.ones(300)]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    r, q = depth_refine(x, d, p, street.planes[1], 0, inv, 0)
    fp = footprint(x, d, p, street.planes[1], 0)
    h = x + exit_distance(x, d, street.planes[1], 0)[:, None] * d
    low = h[:, 1] < ROOF - 2                                  # away from the roof line (nearest texel)
    np.testing.assert_allclose(r[low], fp.r[low], atol=1e-12)
    np.testing.assert_allclose(q[low], fp.q_iso[low], rtol=1e-12)
    dd = lookups(rng, 2000)[1]
    r0, _ = depth_refine(p, dd, p, street.planes[1], 0, inv, 0)
    seen = inv[0][cube.direction_to_texel(dd, 64)] > 0
    np.testing.assert_allclose(r0[seen], dd[seen], atol=1e-9)


def gl_refine(ctx, world, x, d):
    street, powers, tex = world[2], world[3], world[8]
    uni = street.uniforms(powers)
    i = street.nearest(x)
    tex.use(DIST_UNIT)
    out = run_glsl(ctx, "int k = envcap_nearest_probe(x[i].xyz[envcap_street.along], envcap_street.along_s, "
                        "envcap_street.count);\n"
                        "o[i] = envcap_depth_refine(dist, envcap_street.pos[k].w, x[i].xyz, d[i].xyz, "
                        "envcap_street.pos[k].xyz, envcap_street.planes[k], envcap_street.along);",
                   {"x": uni.to_local(x), "d": d}, {"o": 4}, uniforms=uni.values(), declarations=DIST_DECL,
                   includes=INCLUDES)["o"]
    return out, i


def test_glsl_matches_twin(gl_ctx, world):
    """envcap_depth_refine and envcap_sample_depth_refine against the numpy twin: random lookups
    and hard ones (axis and -0.0 directions, points at the probes, on and outside the planes, far
    away).  A float32 step across a texel edge reads the neighbouring texel; at most 0.5 % of the
    lookups may differ beyond the float32 tolerance, and every value is finite."""
    probes, sky, street, powers, dist, inv, pt, st, tex = world
    rng = np.random.default_rng(3)
    x, d = lookups(rng, 20_000)
    hx, hd = hard_lookups(street)
    x, d = np.concatenate([x, hx]), np.concatenate([d, hd])
    got, i = gl_refine(gl_ctx, world, x, d)
    r, q = depth_refine(f32(x), f32(d), street.positions[i], street.planes[i], 0, inv, street.layers[i])
    assert np.all(np.isfinite(got))
    bad = (np.abs(got[:, :3] - r).max(axis=1) > 2e-4) | (np.abs(np.log(got[:, 3] / q)) > 2e-3)
    assert bad.mean() < 0.005, bad.mean()
    assert not bad[-len(hx):].any()
    w = np.exp(rng.uniform(np.log(1.0), np.log(1e5), len(x)))
    uni = street.uniforms(powers)
    tex.use(DIST_UNIT)
    rgb = run_glsl(gl_ctx, f"o[i] = vec4(envcap_sample_depth_refine(probes, sky, dist, x[i].xyz, d[i].xyz, w[i].x, "
                           f"{ARGS}), 0);", {"x": uni.to_local(x), "d": d, "w": w}, {"o": 3}, uniforms=uni.values(),
                   declarations=DIST_DECL, includes=INCLUDES, probes=pt, sky=st)["o"]
    ref = sample_street(ProbeChains(probes, powers, distance=dist), sky, street, f32(x), f32(d), f32(w), METHOD)
    assert np.all(np.isfinite(rgb)) and np.all(np.isfinite(ref))
    close = np.abs(rgb - ref).max(axis=1) <= 4e-6 * np.abs(ref).max() + 1e-5 * np.abs(ref).max(axis=1)
    assert close.mean() > 0.995 and close[-len(hx):].all()


def test_inverse_distance_and_parameters():
    inv = inverse_distance(np.array([0.0, 2.0, np.inf, np.nan, -1.0, 1e6]))
    np.testing.assert_array_equal(inv, np.array([0.0, 0.5, 0.0, 0.0, 0.0, 0.0], np.float32))
    with pytest.raises(ValueError, match="steps"):
        depth_refine(np.zeros(3), np.array([[1.0, 0, 0]]), np.zeros(3), (-1.0, 1.0, -1.0), 0, np.zeros((1, 6, 4, 4)),
                     0, steps=0)
    assert METHOD.needs_distance and METHOD.planes == "fitted"


def test_glsl_matches_twin_on_a_framed_street(gl_ctx, world):
    """A street turned by 37 deg in plan (frame origin far from 0): the GLSL lookup takes world
    directions, refines the hit in the street's frame and reads the sky along the world direction,
    like the numpy twin (which turns x and d through the method registry)."""
    import dataclasses

    from envcap.core.street_frame import frame_to_world, from_frame
    probes, sky, street, powers, dist, inv, pt, st, tex = world
    framed = dataclasses.replace(street, yaw_deg=37.0, origin_xz=(350.5, -820.25))
    rng = np.random.default_rng(5)
    xf, df = lookups(rng, 4_000)
    x, d = frame_to_world(xf, 37.0, (350.5, -820.25)), from_frame(df, 37.0)
    w = np.exp(rng.uniform(np.log(1.0), np.log(1e4), len(x)))
    uni = framed.uniforms(powers)
    tex.use(DIST_UNIT)
    rgb = run_glsl(gl_ctx, f"o[i] = vec4(envcap_sample_depth_refine(probes, sky, dist, x[i].xyz, d[i].xyz, w[i].x, "
                           f"{ARGS}), 0);", {"x": uni.to_local(x), "d": d, "w": w}, {"o": 3}, uniforms=uni.values(),
                   declarations=DIST_DECL, includes=INCLUDES, probes=pt, sky=st)["o"]
    ref = sample_street(ProbeChains(probes, powers, distance=dist), sky, framed, x, f32(d), f32(w), METHOD)
    close = np.abs(rgb - ref).max(axis=1) <= 1e-4 * np.abs(ref).max() + 1e-4 * np.abs(ref).max(axis=1)
    assert close.mean() > 0.99, close.mean()
