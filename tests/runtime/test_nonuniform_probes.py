"""The runtime's probe choice with probes at any spacing (a placement strategy's, docs/placement.md):
the GLSL nearest probe and bracketing pair against a brute-force reference in float32, and the
full nearest (``planes_mip``) and blended lookups, GLSL against the numpy twin, on a street whose
probes are crowded in one place and sparse in another."""

import numpy as np
import pytest

from envcap.core.lobes import lobe_ladder
from envcap.gpu.cube_array import CubeArrayTexture, cube_texture
from envcap.gpu.glsl_harness import run_glsl
from envcap.runtime import synthetic_street as ss
from envcap.runtime.chains import ProbeChains
from envcap.runtime.sampling import sample_street
from envcap.runtime.street import RuntimeStreet

from runtime_fixtures import ARGS, DECL

ALONG = np.array([-7.0, -6.2, -5.9, -1.0, 0.25, 0.5, 9.0, 23.0])
"""Probe coordinates (m) along x: a crowd near -6 and 0.4, gaps of 4.9, 8.5 and 14 m."""
PLANES = (-6.0, 6.0, 0.0)


@pytest.fixture(scope="module")
def uneven(gl_ctx):
    n = 16
    pos = np.c_[ALONG, np.full(ALONG.size, 1.6), np.zeros(ALONG.size)]
    pl = np.tile(np.asarray(PLANES), (ALONG.size, 1))
    lad = lobe_ladder(n)
    probes = ss.box_mips(ss.probe_cubes(pos, pl, 0, n), lad.levels)
    sky = ss.box_mips(ss.sky_cube(n), lad.levels)
    street = RuntimeStreet(0, pos, pl, np.arange(ALONG.size))
    pt, st = CubeArrayTexture(probes), cube_texture(gl_ctx, sky)
    yield probes, sky, street, np.asarray(lad.powers, np.float64), pt, st
    pt.release()
    st.release()


def along_points(rng, count, ties=True):
    """Along coordinates (float32): random over and beyond the probes, each probe, and each midpoint
    exactly (``ties``: the float32 midpoint and the next float up, where the choice flips) or 1 mm
    either side of it (a float64 twin and float32 GLSL then pick the same probe)."""
    a32 = ALONG.astype(np.float32)
    mids = (a32[:-1] + a32[1:]) / np.float32(2)
    near = [mids, np.nextafter(mids, np.float32(np.inf)), [-1e6, 1e6]] if ties else [mids - 1e-3, mids + 1e-3]
    return np.concatenate([rng.uniform(-12, 30, count), a32, *near]).astype(np.float32)


def test_glsl_nearest_and_pair_on_uneven_probes(gl_ctx, uneven):
    street, powers = uneven[2], uneven[3]
    uni = street.uniforms(powers)
    s = along_points(np.random.default_rng(1), 5000)
    x = np.c_[s, np.full(s.size, 1.0), np.zeros(s.size)]
    xl = uni.to_local(x).astype(np.float32)
    out = run_glsl(gl_ctx, "o[i] = vec4(float(envcap_nearest_probe(x[i].x, envcap_street.along_s, envcap_street.count)), "
                           "envcap_probe_pair(x[i].x, envcap_street.along_s, envcap_street.count));",
                   {"x": xl}, {"o": 4}, uniforms=uni.values(), declarations=DECL)["o"]
    # reference, by brute force in the uniforms' float32: nearest (ties to the lower index) and the bracket
    a = uni.along_s[:ALONG.size].astype(np.float32)
    q = xl[:, 0]
    dist = np.abs(q[:, None] - a[None, :])
    nearest = np.array([np.flatnonzero(row == row.min())[0] for row in dist])
    np.testing.assert_array_equal(out[:, 0].astype(int), nearest)
    i0 = np.clip(np.searchsorted(a, q, side="right") - 1, 0, a.size - 2)
    inside = (q > a[0]) & (q < a[-1])
    t = np.where(inside, (q - a[i0]) / (a[i0 + 1] - a[i0]), 0.0)
    ref0 = np.where(inside, i0, np.where(q <= a[0], 0, a.size - 1))
    ref1 = np.where(inside, i0 + 1, ref0)
    np.testing.assert_array_equal(out[:, 1].astype(int), ref0)
    np.testing.assert_array_equal(out[:, 2].astype(int), ref1)
    np.testing.assert_allclose(out[:, 3], t, rtol=0, atol=2e-6)   # float32 division
    # the numpy twin (float64) picks the same probes away from the float32 ties
    away = np.abs(s) < 1e5
    away[5000 + ALONG.size:] = False
    np.testing.assert_array_equal(street.nearest(x.astype(np.float64))[away], nearest[away])


@pytest.mark.parametrize("fn,method", [("envcap_sample_nearest", "planes_mip"), ("envcap_sample_blended", "blend")])
def test_glsl_lookups_match_the_twin_on_uneven_probes(gl_ctx, uneven, fn, method):
    probes, sky, street, powers, pt, st = uneven
    rng = np.random.default_rng(9)
    s = along_points(rng, 20_000, ties=False).astype(np.float64)
    n = s.size
    x = np.c_[s, rng.uniform(-1, 12, n), rng.uniform(-7, 7, n)]
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    w = np.exp(rng.uniform(np.log(0.1), np.log(1e6), n))
    uni = street.uniforms(powers)
    got = run_glsl(gl_ctx, f"o[i] = vec4({fn}(probes, sky, x[i].xyz, d[i].xyz, w[i].x, {ARGS}), 0);",
                   {"x": uni.to_local(x), "d": d, "w": w}, {"o": 3}, uniforms=uni.values(), declarations=DECL,
                   probes=pt, sky=st)["o"]
    f32 = lambda a: np.asarray(a, np.float32).astype(np.float64)  # noqa: E731
    ref = sample_street(ProbeChains(probes, powers), sky, street, f32(x), f32(d), f32(w), method)
    assert np.all(np.isfinite(got))
    # the tolerance of tests/runtime/test_parallax_sampling.py (float32 lookup vectors and levels)
    np.testing.assert_allclose(got, ref, rtol=0, atol=4e-6 * np.abs(ref).max())
