"""Full runtime lookups (parallax + mip shift + sky composite, nearest and blended probes):
GLSL on llvmpipe against the numpy twin, the analytic street as ground truth, and no popping."""

import numpy as np
import pytest

from envcap.core import cube_sampling as cs
from envcap.runtime.chains import ProbeChains
from envcap.runtime.methods import BUILTIN
from envcap.runtime.sampling import composite, sample_street
from envcap.runtime import synthetic_street as ss
from envcap.gpu.glsl_harness import run_glsl

from runtime_fixtures import ARGS, DECL, probe_set


def gl_sample(ctx, scene, fn, x, d, w):
    """GLSL lookups at world points ``x``, passed in the street-local frame of the uniforms."""
    probes, sky, street, powers, pt, st = scene
    uni = street.uniforms(powers)
    return run_glsl(ctx, f"o[i] = vec4({fn}(probes, sky, x[i].xyz, d[i].xyz, w[i].x, {ARGS}), 0);",
                    {"x": uni.to_local(x), "d": d, "w": w}, {"o": 3}, uniforms=uni.values(), declarations=DECL,
                    probes=pt, sky=st)["o"]


def f32(a):
    return np.asarray(a, np.float32).astype(np.float64)


@pytest.mark.parametrize("method", [m for m in BUILTIN if m.glsl], ids=lambda m: m.name)
def test_sampled_values_glsl_match_twin(gl_ctx, scene, method):
    """Every registered method that names a GLSL function: GLSL against the numpy method."""
    probes, sky, street, powers = scene[:4]
    rng = np.random.default_rng(4 if method.name == "blend" else 3)
    # the methods beyond the paper's (planes_mip_oblique, _footprint, _aniso, _sigma): 5x10^4 lookups each (CI time)
    n = 50_000 if method.name.startswith("planes_mip_") else 200_000
    x = np.c_[rng.uniform(-5, 25, n), rng.uniform(-1, 15, n), rng.uniform(-7, 7, n)]
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    w = np.exp(rng.uniform(np.log(0.1), np.log(1e6), n))
    got = gl_sample(gl_ctx, scene, method.glsl, x, d, w)
    ref = sample_street(ProbeChains(probes, powers), sky, street, f32(x), f32(d), f32(w), method)
    # Filtering tolerance: float32 differences in the lookup vector (~2e-7) and level (~5e-7)
    # move a bilinear/trilinear result by at most (gradient x step); measured max 2.2e-5 for
    # values up to 20 (1.1e-6 relative).  Stated bound: 4e-6 x the largest value.
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got, ref, rtol=0, atol=4e-6 * np.abs(ref).max())


def test_hard_inputs_through_full_lookup_are_finite(gl_ctx, scene):
    probes, sky, street, powers = scene[:4]
    e = np.eye(3)
    dirs = np.concatenate([e, -e, np.full((1, 3), -0.0) + e[1], np.array([[0.6, -0.0, 0.8], [-0.0, -0.6, -0.8]])])
    pts = np.array([[5.0, 1.5, 0.0], [5.0, 0.0, 6.0], [5.0, -3.0, -9.0], [0.0, 1.6, 0.0],  # on probe 0
                    [-100.0, 1.0, 0.0], [1e4, 1.0, 1.0], [10.0, 1.6, 6.0]])
    x = np.repeat(pts, len(dirs), axis=0)
    d = np.tile(dirs, (len(pts), 1))
    for w in (0.0, 1e7, -1.0):
        for fn, method in (("envcap_sample_nearest", "planes_mip"), ("envcap_sample_blended", "blend"),
                           ("envcap_sample_oblique", "planes_mip_oblique"), ("envcap_sample_footprint", "planes_mip_footprint"),
                           ("envcap_sample_aniso", "planes_mip_aniso"), ("envcap_sample_sigma", "planes_mip_sigma")):
            got = gl_sample(gl_ctx, scene, fn, x, d, np.full(len(x), w))
            ref = sample_street(ProbeChains(probes, powers), sky, street, x, d, max(w, 0.0), method)
            assert np.all(np.isfinite(got)) and np.all(np.isfinite(ref))
            np.testing.assert_allclose(got, ref, rtol=0, atol=4e-6 * np.abs(ref).max())


def test_parallax_is_closer_to_the_analytic_street_than_no_parallax():
    """Level-0 lookups from points 2-5 m away from the probe: with parallax the result matches
    the analytic radiance seen from the point far better than the plain lookup along d."""
    probes, sky, street, powers = probe_set(n=64, count=1, start=0.0, end=0.0)
    rng = np.random.default_rng(5)
    n = 20_000
    p = street.positions[0]
    x = p + np.c_[rng.uniform(-5, 5, n), rng.uniform(-1, 1, n), rng.uniform(-4, 4, n)]
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    truth = ss.environment_radiance(x, d, street.planes[0], 0)
    w = np.full(n, 1e9)   # level 0
    with_px = sample_street(ProbeChains(probes, powers), sky, street, x, d, w)
    st = cs.sample_cube_array(probes, d, 0, 0.0)
    without = composite(st, cs.sample_cube(sky, d, 0.0))
    e_px = np.abs(with_px - truth).mean()
    e_no = np.abs(without - truth).mean()
    assert e_px < 0.35 * e_no, (e_px, e_no)


@pytest.mark.parametrize("d,w", [((0.3, 0.2, 1.0), 20.0), ((0.3, -0.5, 0.8), 200.0), ((-1.0, 0.1, 0.3), 5.0)])
def test_blending_removes_popping_at_the_midpoint(gl_ctx, scene, d, w):
    """Along-street sweep across the midpoint (s = 5 m) between probes at 0 and 10 m, step 1 mm:
    the nearest probe jumps there, the blended result moves by at most 10 per meter."""
    probes, sky, street, powers = scene[:4]
    s = np.linspace(3.0, 7.0, 4001)
    x = np.c_[s, np.full_like(s, 1.2), np.full_like(s, 1.0)]
    dv = np.tile(np.array(d) / np.linalg.norm(d), (s.size, 1))
    wv = np.full(s.size, w)
    near = gl_sample(gl_ctx, scene, "envcap_sample_nearest", x, dv, wv)
    blend = gl_sample(gl_ctx, scene, "envcap_sample_blended", x, dv, wv)
    step_n = np.abs(np.diff(near, axis=0)).max(axis=1)
    step_b = np.abs(np.diff(blend, axis=0)).max(axis=1)
    assert np.argmax(step_n) == 2000 and step_n[2000] > 0.04       # the pop, at the midpoint
    assert step_b.max() <= 10.0 * 1e-3                              # bounded finite differences
    assert step_b[1995:2005].max() < 0.1 * step_n[2000]
    twin = sample_street(ProbeChains(probes, powers), sky, street, f32(x), f32(dv), f32(wv), "blend")
    assert np.abs(np.diff(twin, axis=0)).max() <= 10.0 * 1e-3
