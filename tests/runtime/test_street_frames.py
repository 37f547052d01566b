"""Streets at any angle and sloped ground in the runtime (issue 10): GLSL against the numpy twin
with random yaws and slopes, today's code path bit for bit at yaw 0 and slope 0, a framed street
against the same street axis-aligned in the world turned by -yaw (hand-derived rotation), and the
tilted ground against a float64 point-normal ray-plane reference."""

import math

import numpy as np
import pytest
from runtime_fixtures import ARGS, DECL

from envcap.gpu.glsl_harness import run_glsl
from envcap.runtime import parallax as px
from envcap.runtime.chains import ProbeChains
from envcap.runtime.footprint import footprint
from envcap.runtime.limits import FAR
from envcap.runtime.methods import BUILTIN, get
from envcap.runtime.sampling import composite, sample_sky, sample_street
from envcap.runtime.street import RuntimeStreet

ORIGIN_XZ = (350.5, -820.25)
SLOPES = np.array([0.12, -0.07, 0.2])


def hand_frame(x, yaw_deg, origin_xz=(0.0, 0.0)):
    """World (x, y, z) -> street frame, written out: along = c dx + s dz, cross = -s dx + c dz."""
    a = math.radians(yaw_deg)
    c, s = math.cos(a), math.sin(a)
    x = np.asarray(x, np.float64)
    dx, dz = x[..., 0] - origin_xz[0], x[..., 2] - origin_xz[1]
    return np.stack([c * dx + s * dz, x[..., 1], -s * dx + c * dz], axis=-1)


def hand_world(f, yaw_deg, origin_xz=(0.0, 0.0)):
    """The inverse of :func:`hand_frame`."""
    a = math.radians(yaw_deg)
    c, s = math.cos(a), math.sin(a)
    f = np.asarray(f, np.float64)
    return np.stack([c * f[..., 0] - s * f[..., 2] + origin_xz[0], f[..., 1],
                     s * f[..., 0] + c * f[..., 2] + origin_xz[1]], axis=-1)


def framed(street, yaw, origin_xz=ORIGIN_XZ, slopes=None):
    return RuntimeStreet(0, street.positions, street.planes, street.layers, yaw, origin_xz, slopes)


def lookups(n, seed):
    """Frame points in and around the street (some below the ground, outside the facades), unit directions, powers."""
    rng = np.random.default_rng(seed)
    f = np.c_[rng.uniform(-5, 25, n), rng.uniform(-2, 12, n), rng.uniform(-7, 7, n)]
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return f, d, np.exp(rng.uniform(np.log(0.1), np.log(1e6), n))


def gl_sample(ctx, scene, street, fn, xw, dw, w):
    """GLSL lookups of ``street`` at world points (passed as ``to_local``) along world directions."""
    pt, st = scene[4], scene[5]
    uni = street.uniforms(scene[3])
    return run_glsl(ctx, f"o[i] = vec4({fn}(probes, sky, x[i].xyz, d[i].xyz, w[i].x, {ARGS}), 0);",
                    {"x": uni.to_local(xw), "d": dw, "w": w}, {"o": 3}, uniforms=uni.values(), declarations=DECL,
                    probes=pt, sky=st)["o"], uni


def twin_inputs(uni, street, xw, dw, w):
    """The numpy twin's inputs: exactly the float32 points and directions GLSL received, in float64."""
    xl = uni.to_local(xw).astype(np.float64)
    return (hand_world(xl + uni.origin, street.yaw_deg, street.origin_xz), np.asarray(dw, np.float32).astype(np.float64),
            np.asarray(w, np.float32).astype(np.float64))


CASES = [(m.name, 213.7) for m in BUILTIN if m.glsl] + [("planes_mip", 90.0), ("blend", 180.0), ("planes_mip_oblique", -90.0)]


@pytest.mark.parametrize("method,yaw", CASES, ids=[f"{m}-{y:g}" for m, y in CASES])
def test_framed_sloped_glsl_matches_twin(gl_ctx, scene, method, yaw):
    probes, sky, street, powers = scene[:4]
    st = framed(street, yaw, slopes=SLOPES)
    f, d, w = lookups(4000, 11)
    xw = hand_world(f, yaw, ORIGIN_XZ)
    got, uni = gl_sample(gl_ctx, scene, st, get(method).glsl, xw, d, w)
    x64, d64, w64 = twin_inputs(uni, st, xw, d, w)
    ref = sample_street(ProbeChains(probes, powers), sky, st, x64, d64, w64, method)
    assert np.all(np.isfinite(got))
    # as tests/runtime/test_parallax_sampling.py, plus float32 rounding of the frame rotation (~1e-7)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-5 * np.abs(ref).max())


def test_hard_inputs_on_a_tilted_ground_are_finite_and_agree(gl_ctx, scene):
    """Full lookups at yaw 90 and 180 from points on, below and above a tilted ground, along the
    axes and parallel to the ground: finite everywhere; GLSL == twin except for rays parallel to
    the ground (from a point on it, which side of the plane a float32 rounding lands on decides;
    the float32-exact case is the next test)."""
    probes, sky, street, powers = scene[:4]
    k = 0.2
    slopes = np.full(3, k)
    g = street.planes[0, 2]
    s_p = street.positions[:, 0]
    along = np.array([2.0, 7.5, 13.0])
    ground = g + k * (along - s_p[np.argmin(np.abs(along[:, None] - s_p), axis=1)])   # nearest probe's plane
    pts = np.concatenate([np.c_[along, ground, [0.5, -3.0, 4.0]],                    # on the ground
                          np.c_[along, ground - 0.7, [1.0, 2.0, -5.0]],              # below it (lifted onto it)
                          np.c_[along, ground + 1.5, [0.0, 5.9, -5.9]]])             # above it
    par = np.array([1.0, k, 0.0]) / math.hypot(1.0, k)                              # parallel to the ground
    e = np.eye(3)
    dirs = np.concatenate([e, -e, [par, -par]])
    f = np.repeat(pts, len(dirs), axis=0)
    df = np.tile(dirs, (len(pts), 1))
    grazing = np.abs(df[:, 1] - k * df[:, 0]) < 1e-6      # (blend: a point above one probe's ground is on the other's)
    for yaw in (90.0, 180.0):
        st = framed(street, yaw, slopes=slopes)
        xw, dw = hand_world(f, yaw, ORIGIN_XZ), hand_world(df, yaw)
        for w in (0.0, 50.0, 1e7):
            for m in ("planes_mip", "blend", "planes_mip_oblique", "planes_mip_footprint", "planes_mip_sigma"):
                got, uni = gl_sample(gl_ctx, scene, st, get(m).glsl, xw, dw, np.full(len(f), w))
                x64, d64, w64 = twin_inputs(uni, st, xw, dw, np.full(len(f), w))
                ref = sample_street(ProbeChains(probes, powers), sky, st, x64, d64, w64, m)
                assert np.all(np.isfinite(got)) and np.all(np.isfinite(ref))
                np.testing.assert_allclose(got[~grazing], ref[~grazing], rtol=0, atol=1e-5 * np.abs(ref).max())


def test_exactly_parallel_and_on_the_tilted_ground_glsl_matches_float32_twin(gl_ctx):
    """Float32-exact hard inputs (slope 1/4, ground 0.5 + s/4): rays exactly parallel to the
    ground (rise 0 in float32 too), points exactly on it and below it; GLSL parallax and exit
    distance against the float32 twin, and the parallel ray from above never hits the ground."""
    f32 = np.float32
    pl = np.array([-6.0, 6.0, 0.5, 0.25])
    s = np.array([-8.0, 0.0, 4.0, 12.0])
    on = np.c_[s, 0.5 + 0.25 * s, [0.0, 2.5, -4.0, 5.5]]
    pts = np.concatenate([on, on - [0.0, 1.0, 0.0], on + [0.0, 2.0, 0.0]])
    dirs = np.array([[0.8, 0.2, 0.6], [-0.8, -0.2, 0.6], [0.8, 0.2, -0.6], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0],
                     [-1.0, 0.0, 0.0], [0.6, -0.8, 0.0], [-0.0, 1.0, -0.0]])
    assert np.all((dirs[:3, 1] - 0.25 * dirs[:3, 0]).astype(f32) == 0)
    x = np.repeat(pts, len(dirs), axis=0).astype(f32)
    d = np.tile(dirs, (len(pts), 1)).astype(f32)
    p = np.tile([2.0, 3.0, 1.0], (len(x), 1)).astype(f32)
    o = run_glsl(gl_ctx, "vec4 pl = vec4(-6.0, 6.0, 0.5, 0.25); a[i] = envcap_parallax(x[i].xyz, d[i].xyz, p[i].xyz, pl, 0);"
                         "b[i] = vec4(envcap_exit_distance(envcap_clamp_to_street(x[i].xyz, pl, 0), d[i].xyz, pl, 0));",
                 {"x": x, "d": d, "p": p}, {"a": 4, "b": 4})
    r, ratio = px.parallax(x, d, p, pl.astype(f32), 0, dtype=f32)
    t = px.exit_distance(px.clamp_to_street(x, pl.astype(f32), 0, f32), d, pl.astype(f32), 0, f32)
    np.testing.assert_allclose(o["a"][:, :3], r, atol=1e-6)
    np.testing.assert_allclose(o["a"][:, 3], ratio, rtol=1e-6)
    np.testing.assert_allclose(o["b"][:, 0], t, rtol=1e-6)
    from_above = (np.repeat(np.arange(len(pts)), len(dirs)) >= 8) & (np.tile(np.arange(len(dirs)), len(pts)) < 3)
    assert np.all(t[from_above] > 0) and np.all(o["b"][from_above, 0] == t[from_above])
    assert np.all(px.plane_exits(x[from_above], d[from_above], pl.astype(f32), 0, f32)[1] == FAR)


# Today's GLSL (before issue 10), copied: the new code at yaw 0 and slope 0 must give its bits.
OLD_GLSL = """
vec3 old_clamp(vec3 x, vec3 planes, int along) {
    int cross = 2 - along;
    x[cross] = min(max(x[cross], planes.x), planes.y);
    x.y = max(x.y, planes.z);
    return x;
}
float old_exit(vec3 x, vec3 d, vec3 planes, int along) {
    int cross = 2 - along;
    float dc = d[cross];
    float tc = ENVCAP_FAR;
    if (dc > 0.0) tc = (planes.y - x[cross]) / dc;
    else if (dc < 0.0) tc = (planes.x - x[cross]) / dc;
    float tg = ENVCAP_FAR;
    if (d.y < 0.0) tg = (planes.z - x.y) / d.y;
    return min(min(tc, tg), ENVCAP_FAR);
}
vec4 old_parallax(vec3 x, vec3 d, vec3 p, vec3 planes, int along) {
    vec3 xc = old_clamp(x, planes, along);
    float t = old_exit(xc, d, planes, along);
    if (!(t < ENVCAP_FAR)) return vec4(d, 1.0);
    vec3 r = (xc - p) + t * d;
    float dp = length(r);
    if (!(dp > ENVCAP_MIN_DIST)) return vec4(d, 1.0 / ENVCAP_MAX_RATIO);
    float ratio = dp / max(t, ENVCAP_MIN_DIST);
    ratio = min(max(ratio, 1.0 / ENVCAP_MAX_RATIO), ENVCAP_MAX_RATIO);
    return vec4(r / dp, ratio);
}
vec4 old_oblique(vec3 x, vec3 d, vec3 p, vec3 planes, int along) {
    int cross = 2 - along;
    vec3 xc = old_clamp(x, planes, along);
    float dc = d[cross];
    float tc = ENVCAP_FAR;
    if (dc > 0.0) tc = (planes.y - xc[cross]) / dc;
    else if (dc < 0.0) tc = (planes.x - xc[cross]) / dc;
    float tg = ENVCAP_FAR;
    if (d.y < 0.0) tg = (planes.z - xc.y) / d.y;
    float t = min(min(tc, tg), ENVCAP_FAR);
    if (!(t < ENVCAP_FAR)) return vec4(d, 1.0);
    vec3 r = (xc - p) + t * d;
    float dp = length(r);
    if (!(dp > ENVCAP_MIN_DIST)) return vec4(d, 1.0 / (ENVCAP_MAX_RATIO * ENVCAP_MAX_RATIO));
    r = r / dp;
    float ratio = min(max(dp / max(t, ENVCAP_MIN_DIST), 1.0 / ENVCAP_MAX_RATIO), ENVCAP_MAX_RATIO);
    bool ground = tg < tc;
    float ca = max(abs(ground ? d.y : d[cross]), ENVCAP_MIN_COS);
    float cb = max(abs(ground ? r.y : r[cross]), ENVCAP_MIN_COS);
    float q = ratio * ratio * (ca / cb);
    return vec4(r, min(max(q, 1.0 / (ENVCAP_MAX_RATIO * ENVCAP_MAX_RATIO)), ENVCAP_MAX_RATIO * ENVCAP_MAX_RATIO));
}
vec3 old_sample_nearest(vec3 x, vec3 d, float w, EnvcapStreet street) {
    int i = envcap_nearest_probe(x[street.along], street.along_s, street.count);
    vec4 par = old_parallax(x, d, street.pos[i].xyz, street.planes[i].xyz, street.along);
    float zs = envcap_clamp_level(envcap_z_of_w(envcap_shift_power(w, par.w), street.xk, street.nlevels), street.nlevels);
    vec4 st = textureLod(probes, vec4(par.xyz, street.pos[i].w), zs);
    if (!(st.a < 1.0)) return st.rgb;
    float zk = envcap_clamp_level(envcap_z_of_w(w, street.xk, street.nlevels), street.nlevels);
    return envcap_composite(st, textureLod(sky, d, zk).rgb);
}
"""


@pytest.mark.parametrize("along", [0, 2])
def test_yaw_0_slope_0_is_todays_code_bit_for_bit(gl_ctx, along):
    rng = np.random.default_rng(21 + along)
    n = 20_000
    c = 2 - along
    x = np.zeros((n, 3))
    x[:, along] = rng.uniform(-20, 20, n)
    x[:, c] = rng.uniform(-8, 8, n)
    x[:, 1] = rng.uniform(-1, 10, n)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[:300] = np.eye(3)[rng.integers(0, 3, 300)] * rng.choice([-1.0, 1.0], (300, 1))   # axis directions
    p = np.c_[rng.uniform(-5, 5, n), rng.uniform(0.5, 3, n), rng.uniform(-5, 5, n)]
    pl = np.c_[rng.uniform(-7, -2, n), rng.uniform(2, 7, n), rng.uniform(-0.5, 0.5, n)]
    o = run_glsl(gl_ctx, """
        vec4 P = pl[i];
        vec4 pl4 = vec4(P.xyz, 0.0);
        a[i] = envcap_parallax(x[i].xyz, d[i].xyz, p[i].xyz, pl4, along) - old_parallax(x[i].xyz, d[i].xyz, p[i].xyz, P.xyz, along);
        b[i] = envcap_parallax_oblique(x[i].xyz, d[i].xyz, p[i].xyz, pl4, along)
             - old_oblique(x[i].xyz, d[i].xyz, p[i].xyz, P.xyz, along);
        vec3 xc = envcap_clamp_to_street(x[i].xyz, pl4, along);
        c[i] = vec4(xc - old_clamp(x[i].xyz, P.xyz, along),
                    envcap_exit_distance(xc, d[i].xyz, pl4, along) - old_exit(xc, d[i].xyz, P.xyz, along));
        e[i] = vec4(envcap_frame_dir(d[i].xyz, vec2(1.0, 0.0)) - d[i].xyz, 0.0);""",
                 {"x": x, "d": d, "p": p, "pl": pl}, {"a": 4, "b": 4, "c": 4, "e": 4}, uniforms={"along": along},
                 declarations="uniform int along;\nuniform samplerCubeArray probes; uniform samplerCube sky;\n" + OLD_GLSL)
    for k, v in o.items():
        assert np.array_equal(v, np.zeros_like(v)), k


def test_yaw_0_slope_0_full_lookup_is_todays_code_bit_for_bit(gl_ctx, scene):
    street = scene[2]
    assert np.array_equal(street.uniforms(scene[3]).frame, [1.0, 0.0])
    f, d, w = lookups(20_000, 31)
    uni = street.uniforms(scene[3])
    o = run_glsl(gl_ctx, f"o[i] = vec4(envcap_sample_nearest(probes, sky, x[i].xyz, d[i].xyz, w[i].x, {ARGS})"
                         f" - old_sample_nearest(x[i].xyz, d[i].xyz, w[i].x, {ARGS}), 0);",
                 {"x": uni.to_local(f), "d": d, "w": w}, {"o": 4}, uniforms=uni.values(), declarations=DECL + OLD_GLSL,
                 probes=scene[4], sky=scene[5])["o"]
    assert np.array_equal(o, np.zeros_like(o))


def test_numpy_slope_0_and_yaw_0_are_todays_numbers_bit_for_bit(scene):
    probes, sky, street, powers = scene[:4]
    f, d, w = lookups(300, 41)
    chains = ProbeChains(probes, powers)
    flat4 = np.c_[street.planes, np.zeros(3)]            # the tilted-ground path at slope 0
    for i in range(3):
        for a, b in zip(px.parallax(f, d, street.positions[i], flat4[i], 0), px.parallax(f, d, street.positions[i], street.planes[i], 0)):
            assert np.array_equal(a, b)
    same = RuntimeStreet(0, street.positions, street.planes, street.layers, 0.0, (0.0, 0.0), np.zeros(3))
    for m in BUILTIN:
        if not m.needs_distance:
            assert np.array_equal(sample_street(chains, sky, same, f, d, w, m), sample_street(chains, sky, street, f, d, w, m))


@pytest.mark.parametrize("yaw", [90.0, 180.0, -33.3])
def test_framed_street_equals_axis_aligned_street_in_the_turned_world(scene, yaw):
    """The framed street at world (x, d) fetches what the same street along x fetches at the
    hand-rotated (x_f, d_f); the sky is looked up along the world d (not turned)."""
    probes, sky, street, powers = scene[:4]
    chains = ProbeChains(probes, powers)
    st = framed(street, yaw, slopes=SLOPES)
    axis = RuntimeStreet(0, street.positions, street.planes, street.layers, slopes=SLOPES)
    f, df, w = lookups(200, 51)
    xw, dw = hand_world(f, yaw, ORIGIN_XZ), hand_world(df, yaw)
    np.testing.assert_allclose(hand_frame(xw, yaw, ORIGIN_XZ), f, atol=1e-9)
    for m in BUILTIN:
        if m.needs_distance:
            continue
        a = m(chains, st, xw, dw, w)
        b = m(chains, axis, f, df, w)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * np.abs(b).max())
        full = sample_street(chains, sky, st, xw, dw, w, m)
        np.testing.assert_allclose(full, composite(b, sample_sky(sky, dw, w, chains.xk)), atol=1e-9)
    # the sky is the world's: lookups that see no street return the sky along the world d, and the
    # sky along the turned direction differs (the synthetic sky is not symmetric about +y)
    up = hand_world(np.array([[0.6, 0.8, 0.0]]), yaw)         # up along the street: no facade in the way
    got = sample_street(chains, sky, st, hand_world([10.0, 1.5, 0.0], yaw, ORIGIN_XZ), up, 1e9, "planes_mip")
    np.testing.assert_allclose(got, sample_sky(sky, up, 1e9, chains.xk)[..., :3], atol=1e-12)
    assert not np.allclose(got, sample_sky(sky, hand_frame(up, yaw), 1e9, chains.xk)[..., :3])


def test_tilted_ground_against_a_float64_point_normal_reference():
    """exit_distance, parallax and the oblique cosines on a tilted ground against the plane in
    point-normal form (through (s_p, ground) with normal (-k, 1, 0)/|.|), and the first exit
    checked by marching the inside test along the ray."""
    rng = np.random.default_rng(61)
    n = 4000
    k = rng.uniform(-0.3, 0.3, n)
    s_p, g = rng.uniform(-10, 10, n), rng.uniform(-1, 1, n)
    fmin, fmax = rng.uniform(-8, -2, n), rng.uniform(2, 8, n)
    planes4 = np.c_[fmin, fmax, g - k * s_p, k]
    x = np.c_[rng.uniform(-20, 20, n), np.zeros(n), rng.uniform(-1.9, 1.9, n)]
    x[:, 1] = g + k * (x[:, 0] - s_p) + rng.uniform(0.01, 6, n)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    nrm = np.c_[-k, np.ones(n), np.zeros(n)] / np.sqrt(1 + k * k)[:, None]
    p0 = np.c_[s_p, g, np.zeros(n)]
    dn = np.sum(d * nrm, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        tg = np.where(dn < 0, np.sum((p0 - x) * nrm, axis=1) / dn, np.inf)
        tc = np.where(d[:, 2] > 0, (fmax - x[:, 2]) / d[:, 2], np.where(d[:, 2] < 0, (fmin - x[:, 2]) / d[:, 2], np.inf))
    t_ref = np.minimum(np.minimum(tg, tc), FAR)
    t = px.exit_distance(x, d, planes4, 0)
    np.testing.assert_allclose(t, t_ref, rtol=1e-10, atol=1e-12)
    inside = lambda q: (np.sum((q - p0) * nrm, axis=-1) >= -1e-9) & (q[..., 2] >= fmin - 1e-9) & (q[..., 2] <= fmax + 1e-9)
    hit = t < FAR
    for u in np.linspace(0.0, 0.999, 40):                # every point before the exit is inside
        assert np.all(inside(x + (u * np.where(hit, t, 50.0))[:, None] * d))
    beyond = x + (np.where(hit, t, 0) * 1.001 + 1e-6)[:, None] * d
    assert np.all(~inside(beyond[hit]))                  # and just after it, outside
    p = np.c_[rng.uniform(-5, 5, n) + s_p, g + rng.uniform(0.5, 3, n), rng.uniform(-1.5, 1.5, n)]
    r, ratio = px.parallax(x, d, p, planes4, 0)
    h = x + t_ref[:, None] * d
    ok = hit & (np.linalg.norm(h - p, axis=1) > 1e-3)
    r_ref = (h - p) / np.linalg.norm(h - p, axis=1, keepdims=True)
    np.testing.assert_allclose(r[ok], r_ref[ok], atol=1e-9)
    fp = footprint(x, d, p, planes4, 0)
    on_ground = ok & (tg < tc)
    q_ref = (np.linalg.norm(h - p, axis=1) / t_ref) ** 2 * np.abs(dn) / np.abs(np.sum(r_ref * nrm, axis=1))
    good = on_ground & (np.abs(dn) > 1e-3) & (np.abs(np.sum(r_ref * nrm, axis=1)) > 1e-3) & (q_ref < 6e4) & (q_ref > 2e-5)
    assert good.sum() > 500
    np.testing.assert_allclose(fp.q_iso[good], q_ref[good], rtol=1e-8)
    # a ray parallel to the tilted ground never hits it; a point below it is lifted onto it
    par = np.c_[np.ones(n), k, np.zeros(n)] / np.sqrt(1 + k * k)[:, None]
    assert np.all(px.plane_exits(x, par, planes4, 0)[1] >= FAR)   # rise 0 up to rounding: no hit within FAR
    below = x.copy()
    below[:, 1] = g + k * (x[:, 0] - s_p) - 1.0
    np.testing.assert_allclose(px.clamp_to_street(below, planes4, 0)[:, 1], g + k * (x[:, 0] - s_p), atol=1e-12)


def test_to_local_of_a_framed_street_far_from_the_origin(scene):
    """A framed street 10^6 m out: its uniforms are those of the same street with its frame at the
    world origin (frame coordinates), and ``to_local`` turns world points in float64 before the one
    float32 rounding (hand-derived frame coordinates)."""
    street, powers = scene[2], scene[3]
    far = (1.0e6 + 0.5, -2.0e6 + 0.25)
    u_far, u_near = framed(street, 33.0, far, SLOPES).uniforms(powers), framed(street, 33.0, (0.0, 0.0), SLOPES).uniforms(powers)
    for f in u_far.glsl_fields():
        assert np.array_equal(getattr(u_far, f.name), getattr(u_near, f.name)), f.name
    f, _, _ = lookups(500, 71)
    x = hand_world(f, 33.0, far)
    assert np.array_equal(u_far.to_local(x), (hand_frame(x, 33.0, far) - u_far.origin).astype(np.float32))
    np.testing.assert_allclose(u_far.to_local(x), f, atol=2e-6)
    np.testing.assert_allclose(u_far.frame, [math.cos(math.radians(33.0)), math.sin(math.radians(33.0))], rtol=1e-7)
    assert u_far.planes[1, 3] == np.float32(SLOPES[1])
    np.testing.assert_allclose(u_far.planes[:3, 2] + SLOPES * street.positions[:, 0], street.planes[:, 2], atol=1e-6)
