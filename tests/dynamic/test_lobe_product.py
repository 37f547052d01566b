"""Eq. 4-7 (envcap.dynamic.lobe_product) and the sphere -> lobe mapping: GLSL
(shaders/runtime/envcap_dynamic.glsl on llvmpipe) against the numpy twin on 10^6 random inputs and
the hard cases, and the closed forms each limit must give."""

import math

import numpy as np

from envcap.dynamic import MAX_POWER, cap_solid_angle, lobe_product, sphere_lobe
from envcap.dynamic.lobe_product import LN_COS_SERIES_BELOW, LOBE_EXPONENT
from envcap.dynamic.sphere_lobe import MIN_SINE
from envcap.gpu.glsl_harness import run_glsl

INCLUDES = ("runtime/envcap_dynamic.glsl",)


def gl_product(ctx, D, C, t, w):
    return run_glsl(ctx, "o[i] = envcap_lobe_product(d[i].xyz, c[i].xyz, d[i].w, c[i].w);",
                    {"d": np.c_[D, t], "c": np.c_[C, w]}, {"o": 4}, includes=INCLUDES)["o"]


def gl_sphere(ctx, x, sphere):
    return run_glsl(ctx, "o[i] = envcap_sphere_lobe(x[i].xyz, s[i]);", {"x": x, "s": sphere}, {"o": 4},
                    includes=INCLUDES)["o"]


def tolerance(ref, D, t, w):
    """Relative tolerance of a float32 Eq. 7 against float64: 3e-6 (1 + |ln peak|) (exp/log
    polynomials) + 1e-5 rad x the condition number kappa = w tan|gamma - alpha| + t tan alpha +
    tan(gamma/2) (llvmpipe's atan is good to ~3e-6 rad; each angle enters the exponent or the
    cos^2(gamma/2) factor with these slopes; measured max 6e-6 rad)."""
    d = D / np.linalg.norm(D, axis=1, keepdims=True)
    alpha = np.arctan2(np.linalg.norm(np.cross(ref.axis, d), axis=1), np.einsum("ij,ij->i", ref.axis, d))
    x = np.abs(ref.gamma - alpha)

    def tan(a):
        return np.where(a < np.pi / 2, np.tan(np.minimum(a, np.pi / 2)), 0.0)

    kappa = np.minimum(w, MAX_POWER) * tan(x) + np.minimum(t, MAX_POWER) * tan(alpha) + np.tan(ref.gamma / 2)
    return 3e-6 * (1 + np.abs(np.log(np.maximum(ref.peak, 1e-300)))) + 1e-5 * kappa, alpha


def check_against_float64(got, D, C, t, w):
    ref = lobe_product(D, C, t, w)
    assert np.all(np.isfinite(got))
    tol, alpha = tolerance(ref, D, t, w)
    ok = ref.integral > 1e-30
    rel = np.abs(got[ok, 3] - ref.integral[ok]) / ref.integral[ok]
    assert np.all(rel <= tol[ok]), (rel / tol[ok]).max()
    assert np.all(np.abs(got[~ok, 3]) <= 1e-30)                      # float32 underflow
    # the axis: ~1e-5 (atan), and ill-conditioned near D = -C (the perpendicular p is then
    # c - cos(gamma) d over |sin gamma|): 2e-7 sin(alpha) / sin(gamma)
    dm = np.linalg.norm(got[:, :3] - ref.axis, axis=1)
    assert np.all(dm <= 1.2e-5 + 2e-7 * np.sin(alpha) / np.maximum(np.sin(ref.gamma), 1e-30))


def test_glsl_matches_twin_on_1e6_random(gl_ctx):
    rng = np.random.default_rng(14)
    n = 1_000_000
    D, C = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    t = np.exp(rng.uniform(np.log(1e-3), np.log(1e7), n))
    w = np.exp(rng.uniform(np.log(1e-3), np.log(1e7), n))
    got = gl_product(gl_ctx, D, C, t, w)
    check_against_float64(got, D, C, t, w)
    # the float32 twin rounds like the GPU up to the same bound
    f32 = lobe_product(*(np.asarray(a, np.float32) for a in (D, C, t, w)), dtype=np.float32)
    check_against_float64(np.c_[f32.axis, f32.integral], D, C, t, w)


HARD = [  # D, C, t, w
    ((0, 0, 1), (0, 0, 1), 5, 7),            # parallel
    ((0, 0, 1), (0, 0, -1), 5, 7),           # opposite
    ((1, 0, 0), (-1, 1e-7, 0), 5, 7),        # nearly opposite
    ((0, 0, 1), (0, 0, 1), 0, 0),            # both powers 0: hemispheres
    ((0, 0, 1), (0, 0, -1), 0, 0),
    ((0, 1, 0), (1, 0, 0), 0, 0),            # right angle, powers 0
    ((0, 0, 1), (0.6, 0, 0.8), 1e7, 1e7),
    ((0, 0, 1), (0.6, 0, 0.8), 0, 1e7),
    ((0, 0, 1), (0.6, 0, 0.8), 1e7, 0),
    ((0, 0, 1), (0, 0, 1), 1e7, 1e7),
    ((0, 0, 0), (0.6, 0, 0.8), 0, 20),       # sphere contains the point
    ((0, 0, 0), (0.6, 0, 0.8), 0, 0),
    ((0.6, 0, 0.8), (0, 0, 0), 3, 3),        # C = 0
    ((0.6, 0, 0.8), (0.6, 0, 0.8), np.inf, 3),
    ((0.6, 0, 0.8), (0.0, 0.8, 0.6), np.nan, -1),
    ((1, 0, 0), (0, 0, 1), MAX_POWER, 1e7),
    ((0, 0, 1), (1, 0, 1e-4), 1e7, 1e7),
]


def test_hard_cases_are_finite_and_match(gl_ctx):
    D, C, t, w = (np.array([h[i] for h in HARD], dtype=np.float64) for i in range(4))
    got = gl_product(gl_ctx, D, C, t, w)
    ref = lobe_product(D, C, t, w)
    assert np.all(np.isfinite(got)) and np.all(np.isfinite(ref.integral)) and np.all(np.isfinite(ref.axis))
    np.testing.assert_allclose(np.linalg.norm(got[:, :3], axis=1), 1, atol=1e-6)
    np.testing.assert_allclose(got[:, 3], ref.integral, rtol=1e-4, atol=1e-30)
    two_pi = 2 * np.pi
    assert math.isclose(ref.integral[0], two_pi / 13, rel_tol=1e-12)      # D = C: 2 pi / (1 + w + t)
    assert ref.integral[1] == 0 and ref.integral[2] < 1e-20 and ref.integral[4] == 0
    assert math.isclose(ref.integral[3], two_pi, rel_tol=1e-12)          # hemisphere x hemisphere
    assert math.isclose(ref.integral[5], two_pi * 0.5, rel_tol=1e-12)    # pi (D.C + 1) at 90 degrees
    assert math.isclose(ref.integral[10], two_pi / 21, rel_tol=1e-12)    # contained: whole lobe
    assert math.isclose(ref.integral[11], two_pi, rel_tol=1e-12)
    assert math.isclose(ref.integral[12], two_pi / 7 * np.cos(np.arccos(0.8) / 2) ** 2 * ref.peak[12], rel_tol=1e-12)
    assert math.isclose(ref.integral[13], two_pi / (4 + MAX_POWER), rel_tol=1e-12)   # t = inf -> MAX_POWER
    assert math.isclose(ref.integral[14], np.pi * (1 + 0.48), rel_tol=1e-12)        # NaN, -1 -> 0: hemispheres
    assert ref.integral[15] == 0                                       # t = MAX_POWER at 90 degrees
    np.testing.assert_allclose(ref.axis[0], (0, 0, 1))


def test_eq4_axis_is_the_weighted_sum_and_eq6_its_peak():
    """Independent of the angle form: Eq. 4 as the paper writes it (normalized weighted sum),
    Eq. 6 as the product of the two lobes at M, Eq. 7 as pi peak (D.C + 1) / (1 + w + t)."""
    rng = np.random.default_rng(4)
    D, C = rng.normal(size=(2000, 3)), rng.normal(size=(2000, 3))
    d, c = (v / np.linalg.norm(v, axis=1, keepdims=True) for v in (D, C))
    acute = np.einsum("ij,ij->i", d, c) >= 0
    t, w = np.exp(rng.uniform(0, 6, 2000)), np.exp(rng.uniform(0, 6, 2000))
    ref = lobe_product(D, C, t, w)
    m = d * t[:, None] ** 0.7 + c * w[:, None] ** 0.7
    m /= np.linalg.norm(m, axis=1, keepdims=True)
    np.testing.assert_allclose(ref.axis[acute], m[acute], atol=1e-12)
    # Eq. 5: on the great circle of D and C, at the fraction w^k / (t^k + w^k) of the angle
    frac = np.arccos(np.clip(np.einsum("ij,ij->i", ref.axis, d), -1, 1)) / ref.gamma
    np.testing.assert_allclose(frac[~acute], (w ** 0.7 / (t ** 0.7 + w ** 0.7))[~acute], atol=1e-9)
    np.testing.assert_allclose(np.einsum("ij,ij->i", np.cross(d, c), ref.axis), 0, atol=1e-12)
    h = lambda x: np.maximum(x, 0)
    peak = h(np.einsum("ij,ij->i", ref.axis, c)) ** w * h(np.einsum("ij,ij->i", ref.axis, d)) ** t
    np.testing.assert_allclose(ref.peak, peak, rtol=1e-9, atol=1e-300)
    eq7 = np.pi * peak * (np.einsum("ij,ij->i", d, c) + 1) / (1 + w + t)
    np.testing.assert_allclose(ref.integral, eq7, rtol=1e-9, atol=1e-300)


def test_sphere_lobe_matches_the_cap_solid_angle_and_glsl(gl_ctx):
    rng = np.random.default_rng(7)
    n = 200_000
    x = rng.uniform(-50, 50, (n, 3))
    center = x + rng.normal(size=(n, 3)) * np.exp(rng.uniform(np.log(1e-3), np.log(1e3), n))[:, None]
    r = np.exp(rng.uniform(np.log(1e-4), np.log(1e2), n))
    D, t = sphere_lobe(x, center, r)
    ell = np.linalg.norm(center - x, axis=1)
    out = ell > r
    # the lobe's integral 2 pi / (1 + t) equals the cap's solid angle 2 pi (1 - cos theta)
    np.testing.assert_allclose(2 * np.pi / (1 + t[out]), cap_solid_angle(r[out] / ell[out]), rtol=1e-12)
    np.testing.assert_allclose(D[out], (center - x)[out] / ell[out, None], atol=1e-15)
    assert np.all(t[~out] == 0) and np.all(D[~out] == 0)
    got = gl_sphere(gl_ctx, x, np.c_[center, r])
    assert np.all(np.isfinite(got))
    # float32 positions: l and r / l carry ~1e-7 relative, and t ~ 2 l^2 / r^2 doubles it; near
    # touching (s -> 1) t = c (1 + c) / s^2 with c = sqrt(1 - s^2) amplifies by 1 / (2 c^2)
    s = np.minimum(r / ell, 1)
    c2 = np.maximum(1 - s * s, 1e-12)
    far = out & (c2 > 1e-3)
    rel = np.abs(got[far, 3] - t[far]) / t[far]
    assert np.all(rel <= 2e-6 * (1 + 1 / c2[far]) * (1 + 50 / np.minimum(ell[far], 50))), rel.max()
    # D = (center - x) / l: float32 rounding of coordinates up to ~90 m, relative to l
    dd = np.linalg.norm(got[far, :3] - D[far], axis=1)
    assert np.all(dd <= 1e-6 + 2e-5 / ell[far]), (dd * ell[far]).max()


def test_sphere_lobe_hard_cases(gl_ctx):
    x = np.zeros((7, 3))
    sph = np.array([[0, 0, 2, 2], [0, 0, 2, 3], [0, 0, 0, 1], [0, 0, 5, 0], [0, 0, 5, -1], [0, 0, 1e30, 1],
                    [3, 0, 0, np.nan]], dtype=np.float64)
    D, t = sphere_lobe(x, sph[:, :3], sph[:, 3])
    got = gl_sphere(gl_ctx, x, sph)
    assert np.all(np.isfinite(got)) and np.all(np.isfinite(t))
    assert t[0] == 0 and got[0, 3] == 0 and np.allclose(D[0], (0, 0, 1))       # touching: a hemisphere
    assert t[1] == 0 and np.all(D[1] == 0) and np.all(got[1] == 0)              # containing
    assert t[2] == 0 and np.all(D[2] == 0) and np.all(got[2] == 0)              # center at the point
    assert np.all(t[3:] == MAX_POWER) and np.all(got[3:, 3] == np.float32(MAX_POWER))   # no sphere / far
    # the containing sphere blocks the whole BRDF lobe: Eq. 7 = 2 pi / (1 + w)
    prod = lobe_product(D[1], (0.3, 0.4, 0.866), t[1], 12.0)
    assert math.isclose(float(prod.integral), 2 * np.pi / 13, rel_tol=1e-12)


def test_glsl_constants_match_the_twin(gl_ctx):
    got = run_glsl(gl_ctx, "o[i] = vec4(ENVCAP_LOBE_EXPONENT, ENVCAP_MAX_POWER, ENVCAP_MIN_SINE, ENVCAP_LN_COS_SERIES_BELOW);",
                   {"x": np.zeros(1)}, {"o": 4}, includes=INCLUDES)["o"][0]
    np.testing.assert_array_equal(got, np.float32([LOBE_EXPONENT, MAX_POWER, MIN_SINE, LN_COS_SERIES_BELOW]))
