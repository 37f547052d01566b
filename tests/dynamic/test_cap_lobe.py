"""envcap's form of the light a sphere blocks from a lobe (envcap.dynamic.cap_lobe): against the
float64 cap quadrature and a direction-grid quadrature (fraction and centroid), GLSL
(``envcap_cap_lobe_product`` on llvmpipe) against the numpy twin on 10^6 random inputs plus the
hard cases, and the form switch (numpy ``form=``, GLSL ``ENVCAP_DYNAMIC_PAPER_FORM``)."""

import math

import numpy as np
import pytest

from envcap.dynamic import cap_lobe_integral, lobe_product, sphere_lobe
from envcap.dynamic.cap_lobe import (CAP_NODES, EXPM1_SERIES_ABOVE, cap_half_angle, cap_lobe_fraction,
                                     cap_lobe_product, gauss_nodes, occlusion)
from envcap.gpu.glsl_harness import run_glsl
from envcap.runtime.lafortune import quadrature
from test_lobe_product import HARD

INCLUDES = ("runtime/envcap_dynamic.glsl",)


def gl_cap(ctx, D, C, t, w, defines=None):
    return run_glsl(ctx, "o[i] = envcap_occlusion(d[i].xyz, c[i].xyz, d[i].w, c[i].w);",
                    {"d": np.c_[D, t], "c": np.c_[C, w]}, {"o": 4}, includes=INCLUDES, defines=defines)["o"]


def test_fraction_against_quadrature():
    """Largest error of the 4-node form over caps 1-89.9 deg, w 0-10^7 and gamma from 0 to 20 theta
    (and past pi): <= 1.5e-3 of the lobe's light (measured 1.26e-3 on the benchmark's grid)."""
    rows = []
    for th_deg in (1.0, 10.0, 60.0, 89.9):
        th = math.radians(th_deg)
        for w in (0.0, 1.0, 100.0, 1e7):
            for m in (0.0, 0.5, 1.1, 1.5, 20.0):
                g = min(m * th, math.pi)
                rows.append((th, g, w, cap_lobe_integral(th, g, w) * (1 + w) / (2 * math.pi)))
    th, g, w, truth = np.array(rows).T
    f, _, _ = cap_lobe_fraction(th, g, w)
    assert np.all(np.abs(f - truth) <= 1.5e-3), np.abs(f - truth).max()
    f2, _, _ = cap_lobe_fraction(th, g, w, nodes=8)          # more nodes converge
    assert np.abs(f2 - truth).max() < 1e-4


def test_fraction_and_centroid_against_a_direction_grid():
    """Independent brute force: the lobe times the cap's indicator summed over cube texels
    (128^2 a face); the axis M is the normalized first moment of the blocked light."""
    dirs, dw = quadrature(128)
    for th, g, w in [(0.5, 0.3, 4.0), (0.3, 0.6, 20.0), (1.2, 2.0, 0.5), (0.2, 0.0, 2.0)]:
        D = np.array([0.0, 0.0, 1.0])
        C = np.array([math.sin(g), 0.0, math.cos(g)])
        lobe = np.maximum(dirs @ C, 0) ** w * (dirs @ D >= math.cos(th)) * dw
        t = math.cos(th) / (1 - math.cos(th))
        got = cap_lobe_product(D, C, t, w)
        assert abs(float(got.peak) - lobe.sum() * (1 + w) / (2 * math.pi)) < 3e-3
        moment = (lobe[:, None] * dirs).sum(axis=0)
        assert np.degrees(np.arccos(np.clip(got.axis @ moment / np.linalg.norm(moment), -1, 1))) < 0.5


def test_cap_from_power_is_the_sphere_lobes_inverse():
    s = np.array([1e-6, 0.01, 0.3, 0.9, 1 - 1e-9, 1.0])
    _, t = sphere_lobe(np.zeros((6, 3)), np.c_[np.zeros(6), np.zeros(6), np.ones(6)], s)
    np.testing.assert_allclose(np.sin(cap_half_angle(t)), s, rtol=1e-9)
    assert cap_half_angle(0.0) == pytest.approx(math.pi / 2) and cap_half_angle(np.inf) < 1e-14


def hard_inputs():
    """The Eq. 4-7 hard cases plus spheres touching / containing the point through sphere_lobe."""
    D, C, t, w = (np.array([h[i] for h in HARD], dtype=np.float64) for i in range(4))
    x = np.zeros((4, 3))
    sph = np.array([[0, 0, 2, 2], [0, 0, 2, 3], [0, 0, 0, 1], [2, 0, 0, 2]], dtype=np.float64)
    Ds, ts = sphere_lobe(x, sph[:, :3], sph[:, 3])
    Cs = np.array([[0, 0, 1], [0.6, 0, 0.8], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
    ws = np.array([1e7, 0.0, 7.0, 3.0])
    return np.r_[D, Ds], np.r_[C, Cs], np.r_[t, ts], np.r_[w, ws]


def test_hard_cases_closed_forms():
    D, C, t, w = hard_inputs()
    ref = cap_lobe_product(D, C, t, w)
    assert np.all(np.isfinite(ref.integral)) and np.all(np.isfinite(ref.axis))
    np.testing.assert_allclose(np.linalg.norm(ref.axis, axis=1), 1, atol=1e-12)
    n = len(HARD)
    # D = C, t = 5 (cos theta = 5/6): 1 - (5/6)^(w+1); opposite: 0; powers 0, same axis: the hemisphere
    assert math.isclose(ref.peak[0], 1 - (5 / 6) ** 8, rel_tol=1e-12)
    assert ref.peak[1] == 0 and ref.peak[3] == 1 and ref.peak[4] == 0
    assert ref.peak[10] == 1 and ref.peak[11] == 1                      # sphere contains the point
    assert ref.peak[n + 0] == 1                                         # touching, lobe towards it
    assert ref.peak[n + 1] == 1 and ref.peak[n + 2] == 1                # containing spheres
    # touching sphere at 90 degrees from a power-3 lobe: the half of the lobe on its side
    assert math.isclose(ref.peak[n + 3], 0.5, rel_tol=1e-12)


def test_glsl_matches_twin_on_1e6_random_and_hard(gl_ctx):
    rng = np.random.default_rng(15)
    n = 1_000_000
    D, C = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    t = np.exp(rng.uniform(np.log(1e-3), np.log(1e7), n))
    w = np.exp(rng.uniform(np.log(1e-3), np.log(1e7), n))
    Dh, Ch, th, wh = hard_inputs()
    D, C, t, w = np.r_[D, Dh], np.r_[C, Ch], np.r_[t, th], np.r_[w, wh]
    got = gl_cap(gl_ctx, D, C, t, w)
    ref = cap_lobe_product(D, C, t, w)
    assert np.all(np.isfinite(got))
    wc = np.minimum(np.where(w > 0, w, 0), 1e30)
    f_gl = got[:, 3].astype(np.float64) * (1 + wc) / (2 * np.pi)
    err = np.abs(f_gl - ref.peak)
    # float32 angles (llvmpipe's atan: ~3.5e-6 rad) times the fraction's slopes in theta and gamma
    big = err > 2e-6
    theta, gamma, h = cap_half_angle(t[big]), ref.gamma[big], 1e-7
    slope = sum(np.abs(cap_lobe_fraction(*a, w[big])[0] - cap_lobe_fraction(*b, w[big])[0]) / (2 * h)
                for a, b in [((theta + h, gamma), (theta - h, gamma)), ((theta, gamma + h), (theta, np.maximum(gamma - h, 0)))])
    assert np.all(err[big] <= 2e-6 + 4e-6 * slope), (err[big] / (2e-6 + 4e-6 * slope)).max()
    ok = ref.peak > 1e-30
    assert np.linalg.norm(got[ok, :3] - ref.axis[ok], axis=1).max() < 2e-5
    np.testing.assert_allclose(np.linalg.norm(got[:, :3], axis=1), 1, atol=1e-5)
    # the float32 twin (GLSL order) is as close
    k = slice(0, 100_000)
    f32 = cap_lobe_product(*(np.asarray(a[k], np.float32) for a in (D, C, t, w)), dtype=np.float32)
    assert np.abs(f32.peak - ref.peak[k]).max() < 2e-4


def test_form_switch(gl_ctx):
    rng = np.random.default_rng(2)
    D, C = rng.normal(size=(500, 3)), rng.normal(size=(500, 3))
    t, w = np.exp(rng.uniform(0, 8, 500)), np.exp(rng.uniform(0, 8, 500))
    Dh, Ch, th, wh = hard_inputs()                 # the paper's form through the switch, hard cases too
    D, C, t, w = np.r_[D, Dh], np.r_[C, Ch], np.r_[t, th], np.r_[w, wh]
    paper = gl_cap(gl_ctx, D, C, t, w, defines={"ENVCAP_DYNAMIC_PAPER_FORM": 1})
    assert np.all(np.isfinite(paper))
    np.testing.assert_allclose(paper[:, 3], lobe_product(D, C, t, w).integral, rtol=1e-3, atol=1e-30)
    np.testing.assert_array_equal(occlusion(D, C, t, w, form="paper").integral, lobe_product(D, C, t, w).integral)
    np.testing.assert_array_equal(occlusion(D, C, t, w).integral, cap_lobe_product(D, C, t, w).integral)
    with pytest.raises(ValueError, match="occlusion form"):
        occlusion(D, C, t, w, form="exact")


def test_glsl_constants_match_the_twin(gl_ctx):
    got = run_glsl(gl_ctx, "o[i] = vec4(ENVCAP_CAP_NODES, ENVCAP_EXPM1_SERIES_ABOVE, ENVCAP_CAP_U[i], ENVCAP_CAP_W[i]);",
                   {"x": np.zeros(CAP_NODES)}, {"o": 4}, includes=INCLUDES)["o"]
    u, wk = gauss_nodes(CAP_NODES)
    np.testing.assert_array_equal(got[:, :2], np.float32([[CAP_NODES, EXPM1_SERIES_ABOVE]] * CAP_NODES))
    np.testing.assert_allclose(got[:, 2], u, rtol=1e-7)
    np.testing.assert_allclose(got[:, 3], wk, rtol=1e-7)
    with pytest.raises(ValueError, match="nodes"):
        gauss_nodes(9)
