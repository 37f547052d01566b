"""Runtime GLSL (shaders/runtime/envcap_*.glsl) against its numpy twin (envcap.runtime.parallax, .mip), plus hand checks.

References: the float32 numpy twin (same operation order) for GLSL; float64 geometry checks
(hit point on a plane, inside the street) and envcap.core.lobes.z_of_w for the twin itself.
"""

import numpy as np
import pytest

from envcap.runtime import limits, mip
from envcap.runtime import parallax as px
from envcap.runtime.street import RuntimeStreet
from envcap.gpu.glsl_harness import run_glsl
from envcap.core.lobes import z_of_w as z_ref

POWERS = np.array([16382.0, 4094.0, 1022.0, 254.0, 62.0, 14.0, 2.0, 1.0])
DECL = "uniform int along; uniform float xk[ENVCAP_MAX_LEVELS]; uniform int nlevels;"
BODY = """
vec4 r = envcap_parallax(x[i].xyz, d[i].xyz, p[i].xyz, pl[i].xyz, along);
vec3 xc = envcap_clamp_to_street(x[i].xyz, pl[i].xyz, along);
float t = envcap_exit_distance(xc, d[i].xyz, pl[i].xyz, along);
float ws = envcap_shift_power(w[i].x, r.w);
o_r[i] = r;
o_z[i] = vec4(t, ws, envcap_z_of_w(w[i].x, xk, nlevels), envcap_clamp_level(envcap_z_of_w(ws, xk, nlevels), nlevels));
"""
# Float32 tolerances of GLSL (llvmpipe) against the float32 twin, measured on 10^6 inputs:
# r 1.8e-7, ratio 2.4e-7 (relative), t exact, z 4.8e-7 (llvmpipe's log2 is a polynomial).
TOL_R, TOL_RATIO, TOL_T, TOL_Z = 1e-6, 1e-6, 1e-6, 3e-6


def _unit(a):
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


def random_inputs(n, along, seed):
    rng = np.random.default_rng(seed)
    c = 2 - along
    fmin = rng.uniform(-20, 0, n)
    width = rng.uniform(2, 30, n)
    g = rng.uniform(-1, 1, n)
    pl = np.stack([fmin, fmin + width, g], -1)
    x = np.zeros((n, 3))
    x[:, along] = rng.uniform(-50, 50, n)
    x[:, c] = fmin + width * rng.uniform(-0.1, 1.1, n)   # 10% outside each facade
    x[:, 1] = g + rng.uniform(-0.5, 20, n)               # some below the ground
    p = np.zeros((n, 3))
    p[:, along] = x[:, along] + rng.uniform(-10, 10, n)
    p[:, c] = fmin + width * rng.uniform(0.1, 0.9, n)
    p[:, 1] = g + rng.uniform(0.5, 3, n)
    d = _unit(rng.normal(size=(n, 3)))
    w = np.exp(rng.uniform(np.log(0.01), np.log(1e7), n))
    return x, d, p, pl, w


def run_gl(ctx, x, d, p, pl, w, along):
    f = lambda a: np.asarray(a, np.float32)
    return run_glsl(ctx, BODY, {"x": f(x), "d": f(d), "p": f(p), "pl": f(pl), "w": f(w)}, {"o_r": 4, "o_z": 4},
                    uniforms={"along": along, "xk": mip.lobe_table(POWERS, np.float32), "nlevels": POWERS.size},
                    declarations=DECL)


def twin32(x, d, p, pl, w, along):
    f = [np.asarray(a, np.float32) for a in (x, d, p, pl, w)]
    xk = mip.lobe_table(POWERS, np.float32)
    r, ratio = px.parallax(*f[:4], along, dtype=np.float32)
    xc = px.clamp_to_street(f[0], f[3], along, np.float32)
    t = px.exit_distance(xc, f[1], f[3], along, np.float32)
    ws = mip.shift_power(f[4], ratio, np.float32)
    z = mip.z_of_w(f[4], xk, np.float32)
    zs = mip.clamp_level(mip.z_of_w(ws, xk, np.float32), POWERS.size, np.float32)
    return r, ratio, t, ws, z, zs


def assert_agree(out, ref):
    r, ratio, t, ws, z, zs = ref
    g, gz = out["o_r"], out["o_z"]
    assert np.all(np.isfinite(g)) and np.all(np.isfinite(gz))
    np.testing.assert_allclose(g[:, :3], r, rtol=0, atol=TOL_R)
    np.testing.assert_allclose(g[:, 3], ratio, rtol=TOL_RATIO, atol=0)
    np.testing.assert_allclose(gz[:, 0], t, rtol=TOL_T, atol=1e-30)
    np.testing.assert_allclose(gz[:, 1], ws, rtol=4 * TOL_RATIO, atol=1e-30)
    np.testing.assert_allclose(gz[:, 2], z, rtol=0, atol=TOL_Z)
    np.testing.assert_allclose(gz[:, 3], zs, rtol=0, atol=TOL_Z)


@pytest.mark.parametrize("along,n", [(0, 1_000_000), (2, 200_000)])
def test_glsl_math_matches_float32_twin_on_random_inputs(gl_ctx, along, n):
    inp = random_inputs(n, along, seed=along + 1)
    assert_agree(run_gl(gl_ctx, *inp, along), twin32(*inp, along))


def test_float64_twin_geometry_hand_checked():
    along, c = 0, 2
    x, d, p, pl, w = random_inputs(200_000, along, seed=7)
    xc = px.clamp_to_street(x, pl, along)
    assert np.all((xc[:, c] >= pl[:, 0]) & (xc[:, c] <= pl[:, 1]) & (xc[:, 1] >= pl[:, 2]))
    t = px.exit_distance(xc, d, pl, along)
    hit = t < limits.FAR
    h = xc + t[:, None] * d
    # The hit point lies on one of the three planes and inside (or on) the street.
    on = np.minimum.reduce([np.abs(h[:, c] - pl[:, 0]), np.abs(h[:, c] - pl[:, 1]), np.abs(h[:, 1] - pl[:, 2])])
    assert np.all(on[hit] < 1e-9 * np.maximum(1, t[hit]))
    assert np.all(h[hit, c] >= pl[hit, 0] - 1e-9) and np.all(h[hit, c] <= pl[hit, 1] + 1e-9)
    assert np.all(h[hit, 1] >= pl[hit, 2] - 1e-9)
    # No hit only for rays going up (no ground) that are parallel to the facades or ~so.
    assert np.all(d[~hit, 1] >= 0)
    r, ratio = px.parallax(x, d, p, pl, along)
    vec = h - p
    dp = np.linalg.norm(vec, axis=1)
    ok = hit & (dp > 1e-3)
    np.testing.assert_allclose(r[ok], vec[ok] / dp[ok, None], atol=1e-12)
    want = np.clip(dp / np.maximum(t, limits.MIN_DIST), 1 / limits.MAX_RATIO, limits.MAX_RATIO)
    np.testing.assert_allclose(ratio[ok], want[ok], rtol=1e-12)
    # z(w) twin loop equals the lobes module's interpolation (independent implementation)
    np.testing.assert_allclose(mip.z_of_w(w, mip.lobe_table(POWERS)), z_ref(w, POWERS), atol=1e-12)


def hard_cases(along):
    """Adversarial inputs: zero components of both signs, no-hit rays, points on/outside planes,
    hit point at the probe, extreme w."""
    c = 2 - along
    pl = np.array([-5.0, 5.0, 0.0])
    e = np.eye(3)
    rows = []
    base = np.zeros(3)
    base[along] = 3.0
    base[1] = 1.5
    probe = np.zeros(3)
    probe[1] = 1.6
    dirs = [e[0], -e[0], e[1], -e[1], e[2], -e[2]]
    # directions with exact +0.0 / -0.0 components: (a, +-0, b) etc.
    for sgn in (0.0, -0.0):
        for k in range(3):
            o1, o2 = [j for j in range(3) if j != k]
            for a, b in ((0.6, 0.8), (-0.6, 0.8), (0.6, -0.8), (-0.6, -0.8)):
                v = np.empty(3)
                v[k], v[o1], v[o2] = sgn, a, b
                dirs.append(v)
        for k in range(3):                                           # axis rays with -0.0 elsewhere
            for sg in (1.0, -1.0):
                v = np.full(3, -0.0)
                v[k] = sg
                dirs.append(v)
    points = [base.copy()]
    for plane_val in (pl[0], pl[1]):
        q = base.copy(); q[c] = plane_val; points.append(q)           # on a facade
        q = base.copy(); q[c] = plane_val * 3; points.append(q)       # outside the street
    q = base.copy(); q[1] = 0.0; points.append(q)                     # on the ground
    q = base.copy(); q[1] = -2.0; points.append(q)                    # below the ground
    q = base.copy(); q[c] = pl[1]; q[1] = 0.0; points.append(q)       # on the edge facade/ground
    ws = [0.0, 1.0, 1e7, -1.0]
    for x in points:
        for d in dirs:
            for w in ws:
                rows.append((x, d, probe, pl, w))
    # hit point exactly at the probe: probe on the max facade, ray toward it along the cross axis
    pf = probe.copy(); pf[c] = pl[1]
    xh = pf.copy(); xh[c] = pl[1] - 2.0
    dh = np.zeros(3); dh[c] = 1.0
    rows.append((xh, dh, pf, pl, 5.0))
    # probe exactly at the shading point on a facade
    rows.append((pf, dh, pf, pl, 5.0))
    x, d, p, q, w = (np.array(col, dtype=np.float64) for col in zip(*rows))
    return x, d, p, q, w


@pytest.mark.parametrize("along", [0, 2])
def test_hard_cases_finite_and_documented_fallbacks(gl_ctx, along):
    x, d, p, pl, w = hard_cases(along)
    out = run_gl(gl_ctx, x, d, p, pl, w, along)
    ref = twin32(x, d, p, pl, w, along)
    assert_agree(out, ref)
    r64, ratio64 = px.parallax(x, d, p, pl, along)
    assert np.all(np.isfinite(r64)) and np.all(np.isfinite(ratio64))
    # zero components keep their sign through the SSBO: -0.0 really was tested
    assert np.any(np.signbit(np.asarray(d, np.float32)) & (np.asarray(d, np.float32) == 0))
    # rays with no plane ahead (up, or straight along the street): no parallax, ratio 1
    up_or_along = (d[:, 1] >= 0) & (d[:, 2 - along] == 0)
    np.testing.assert_array_equal(out["o_r"][up_or_along, :3], d[up_or_along].astype(np.float32))
    np.testing.assert_array_equal(out["o_r"][up_or_along, 3], 1.0)
    np.testing.assert_array_equal(out["o_z"][up_or_along, 0], np.float32(limits.FAR))
    # unit results and bounded ratio everywhere
    np.testing.assert_allclose(np.linalg.norm(out["o_r"][:, :3], axis=1), 1.0, atol=1e-6)
    assert np.all((out["o_r"][:, 3] >= 1 / limits.MAX_RATIO) & (out["o_r"][:, 3] <= limits.MAX_RATIO))
    # hit at the probe (second-to-last row): direction falls back to d, ratio clamps low
    np.testing.assert_array_equal(out["o_r"][-2, :3], d[-2].astype(np.float32))
    assert out["o_r"][-2, 3] == np.float32(1 / limits.MAX_RATIO)
    assert out["o_z"][-2, 3] == POWERS.size - 1  # widest level (clamped)
    # levels stay inside the chain; w = 1e7 -> sharpest level, w <= 0 -> widest
    assert np.all((out["o_z"][:, 2:] >= 0) & (out["o_z"][:, 2:] <= POWERS.size - 1))
    assert np.all(out["o_z"][w == 1e7, 2] == 0) and np.all(out["o_z"][w <= 0, 2] == POWERS.size - 1)


def test_clamp_level_and_z_outside_chain(gl_ctx):
    z = np.array([-5.0, -0.0, 0.0, 3.3, 7.0, 7.5, 100.0, np.inf, -np.inf, np.nan], dtype=np.float32)
    w = np.array([np.inf, 1e30, 1e7, 0.0, -3.0, np.nan, 1.0, 2.0, 1.5, 16382.0], dtype=np.float32)
    out = run_glsl(gl_ctx, "o[i] = vec4(envcap_clamp_level(z[i].x, nlevels), envcap_z_of_w(w[i].x, xk, nlevels), 0, 0);",
                   {"z": z, "w": w}, {"o": 2}, uniforms={"xk": mip.lobe_table(POWERS, np.float32), "nlevels": POWERS.size},
                   declarations=DECL)["o"]
    want_z = np.array([0, 0, 0, 3.3, 7, 7, 7, 7, 0, 0], dtype=np.float32)
    np.testing.assert_allclose(out[:, 0], want_z, atol=1e-6)
    np.testing.assert_allclose(mip.clamp_level(z, POWERS.size, np.float32), want_z, atol=1e-6)
    want_w = np.array([0, 0, 0, 7, 7, 7, 7, 6, z_ref(1.5, POWERS), 0], dtype=np.float32)
    np.testing.assert_allclose(out[:, 1], want_w, atol=TOL_Z)
    np.testing.assert_allclose(mip.z_of_w(w, mip.lobe_table(POWERS, np.float32), np.float32), want_w, atol=TOL_Z)


def test_bad_arguments_raise():
    with pytest.raises(ValueError, match="axis"):
        px.parallax(np.zeros(3), np.array([1.0, 0, 0]), np.zeros(3), [-1, 1, 0], along=1)
    with pytest.raises(ValueError, match="decreasing"):
        mip.lobe_table([1.0, 2.0])
    with pytest.raises(ValueError, match="facade_max"):
        RuntimeStreet(0, np.zeros((1, 3)), np.array([[1.0, 1.0, 0.0]]), np.zeros(1, np.int64))
