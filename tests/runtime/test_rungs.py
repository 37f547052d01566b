"""Rung-ladder lookups (envcap.runtime.rungs, GLSL envcap_rung_fetch) and their filter
(envcap.prefilter.rungs): the blend against the ladder's own position rule on constant rungs,
GLSL against the numpy twin, and the filtered rungs against the exact float64 convolution."""

import numpy as np
import pytest

from envcap.core import cube_sampling
from envcap.core.rungs import rung_ladder
from envcap.gpu.cube_array import CubeArrayTexture
from envcap.gpu.glsl_harness import run_glsl
from envcap.prefilter.exact import convolve_exact
from envcap.prefilter.rungs import prefilter_rungs
from envcap.runtime.rung_top import top_fetch
from envcap.runtime.rungs import MAX_RUNGS, RungChains, rung_fetch, rung_table

LAD = rung_ladder(16, "half_octave")          # sizes (16, 8), 8 rungs


def _random_levels(rng, probes, per, sizes, smooth=True):
    out = []
    for s in sizes:
        a = rng.uniform(0.2, 2.0, (probes * per, 6, s, s, 4))
        out.append(a)
    return out


def _dirs(rng, m):
    d = rng.normal(size=(m, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_constant_rungs_return_the_rung_position():
    # rung i holds the constant i: a lookup returns the blended rung position itself
    per = LAD.per_level
    levels = [np.zeros((2 * per, 6, s, s, 1)) for s in LAD.sizes]
    for i in range(LAD.rungs):
        for p in range(2):
            levels[i // per][p * per + i % per] = i
    rng = np.random.default_rng(1)
    w = np.exp(rng.uniform(np.log(0.5), np.log(2e3), 400))
    got = RungChains(levels, LAD).fetch(_dirs(rng, 400), rng.integers(0, 2, 400), w)[:, 0]
    np.testing.assert_allclose(got, LAD.position(w), atol=1e-12)


def test_whole_rung_is_one_bilinear_fetch():
    rng = np.random.default_rng(2)
    levels = _random_levels(rng, 1, LAD.per_level, LAD.sizes)
    d = _dirs(rng, 50)
    for i in (0, 3, 5, 7):
        want = cube_sampling.bilinear(levels[i // LAD.per_level], d, np.full(50, i % LAD.per_level))
        got = rung_fetch(levels, d, 0.0, LAD.powers[i], rung_table(LAD.powers), LAD.per_level)
        if i == 0:      # rung 0, the capture, is read with its lobe's footprint kernel (one bilinear fetch)
            np.testing.assert_allclose(got, top_fetch(levels[0], d, np.zeros(50, int), LAD.powers[0]), rtol=1e-12)
            assert np.abs(got - want).max() > 0.05
        else:
            np.testing.assert_allclose(got, want, rtol=1e-12)


def test_glsl_rung_fetch_matches_numpy(gl_ctx):
    rng = np.random.default_rng(3)
    per, probes = LAD.per_level, 3
    levels = [a.astype(np.float32) for a in _random_levels(rng, probes, per, LAD.sizes)]
    m = 3000
    d = _dirs(rng, m)
    w = np.exp(rng.uniform(np.log(0.1), np.log(3e3), m))
    w[:6] = [0.0, -1.0, np.inf, 1e30, LAD.powers[3], LAD.powers[-1]]
    base = rng.integers(0, probes, m) * per
    xr = np.zeros(MAX_RUNGS, np.float32)
    xr[:LAD.rungs] = rung_table(LAD.powers, np.float32)
    pt = CubeArrayTexture(levels)
    try:
        got = run_glsl(gl_ctx, "o[i] = envcap_rung_fetch(probes, d[i].xyz, b[i].x, b[i].y, xr, nr, per);",
                       {"d": d, "b": np.c_[base, np.where(np.isfinite(w), w, 3e38)]}, {"o": 4},
                       uniforms={"xr": xr, "nr": LAD.rungs, "per": per},
                       declarations="uniform float xr[ENVCAP_MAX_RUNGS]; uniform int nr; uniform int per;",
                       probes=pt)["o"]
    finally:
        pt.release()
    want = rung_fetch(levels, d, base, np.where(w > 0, w, 0.0), rung_table(LAD.powers), per)
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got, want, rtol=2e-4, atol=2e-4)


def test_prefilter_rungs_match_exact_convolution(gl_ctx):
    rng = np.random.default_rng(4)
    lad = rung_ladder(8, "octave")             # one level of 8^2: the capture and w = 1
    lad16 = rung_ladder(16, "octave")          # (16, 8): rungs at both levels
    cube = rng.uniform(0.5, 1.5, (6, 16, 16, 4))
    cube[0, :4, :4, :3] = 20.0                  # a bright patch: the lobes' shapes matter
    levels = prefilter_rungs(cube, lad16, ctx=gl_ctx)
    assert [a.shape for a in levels] == [(2, 6, 16, 16, 4), (2, 6, 8, 8, 4)]
    np.testing.assert_array_equal(levels[0][0], cube.astype(np.float32))
    for i in range(1, lad16.rungs):
        j, r = divmod(i, lad16.per_level)
        ref = convolve_exact(cube, lad16.powers[i], lad16.sizes[j])
        np.testing.assert_allclose(levels[j][r], ref, rtol=3e-3, atol=1e-3 * float(np.abs(ref).max()))
    with pytest.raises(ValueError, match="16-texel faces"):
        prefilter_rungs(cube, lad, ctx=gl_ctx)


def test_rung_chains_of_probe_set_diffuse_term(canyon_probe_set, gl_ctx):
    from envcap.prefilter.exact import convolve_exact_dirs
    from envcap.runtime.rungs import rung_chains_of

    probes, sky = rung_chains_of(canyon_probe_set, "half_octave", ctx=gl_ctx)
    layers = canyon_probe_set.layer_count
    assert probes.levels[0].shape == (layers * 4, 6, 8, 8, 4) and sky.levels[0].shape == (4, 6, 8, 8, 4)
    rng = np.random.default_rng(5)
    d = _dirs(rng, 64)
    cap = np.asarray(canyon_probe_set.levels[0][1], np.float64)
    got = probes.fetch(d, 1, 1.0)                 # the widest rung: Eq. 3's diffuse term E_1
    ref = convolve_exact_dirs(cap, 1.0, d)
    assert np.sqrt(np.mean((got - ref) ** 2) / np.mean(ref ** 2)) < 0.02
