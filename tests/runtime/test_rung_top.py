"""The top of a rung ladder (envcap.runtime.rung_top, GLSL envcap_rung_top / envcap_rung_lod_of_w):
lookups from rung 0's power up to the mirror against the float64 exact cos^w filter of the same
level-0 cube, the mirror as the nearest texel centre, the lookup position, hard input, and GLSL
against the numpy twin."""

import numpy as np
import pytest

from envcap.core import cube, cube_sampling
from envcap.core.rungs import rung_ladder
from envcap.gpu.cube_array import CubeArrayTexture
from envcap.gpu.glsl_harness import run_glsl
from envcap.prefilter.exact import convolve_exact_dirs
from envcap.runtime.rung_top import MIRROR_POWER, top_power
from envcap.runtime.rungs import MAX_RUNGS, RungChains, rung_fetch, rung_lod_of_w, rung_position, rung_table

LAD = rung_ladder(16, "half_octave")          # sizes (16, 8); rung 0 at w = 766, rung 1 at 243


def _dirs(rng, m):
    d = rng.normal(size=(m, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _patched_cube(rng, n):
    c = rng.uniform(0.5, 1.5, (6, n, n, 4))
    c[0, :4, :4, :3] = 20.0                   # a bright patch at a cube corner, across two seams
    c[2, 5:9, 3:6, :3] = 8.0
    return c


def _chains(level0, lad):
    levels = [np.zeros((lad.per_level, 6, s, s, level0.shape[-1])) for s in lad.sizes]
    levels[0][0] = level0
    return RungChains(levels, lad)


def _rel(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2) / np.mean(b ** 2)))


def test_lookups_past_rung_0_hold_the_exact_lobe():
    # docs/lobes.md, "The top of the ladder": measured 3.8 / 0.75 / 0.36 / 0.04 / 0 / 0 % at
    # w = w_0, 3 w_0, 1e4, 1e5, 1e7, inf; the bilinear read of rung 0 (before) 8.8 .. 24 %
    rng = np.random.default_rng(4)
    c = _patched_cube(rng, 16)
    rc = _chains(c, LAD)
    d = _dirs(rng, 3000)
    w0 = LAD.powers[0]
    bounds = {w0: 0.045, 3 * w0: 0.01, 1e4: 0.006, 1e5: 0.002, 1e7: 1e-6, np.inf: 1e-6}
    for w, bound in bounds.items():
        truth = convolve_exact_dirs(c, min(w, 1e300), d)      # 1e300: the limit, the nearest centre
        after = _rel(rc.fetch(d, 0.0, np.full(len(d), w)), truth)
        before = _rel(cube_sampling.bilinear(c, d), truth)
        assert after < bound, (w, after)
        assert before > 2 * after and before > 0.08, (w, before, after)


@pytest.mark.parametrize("n", [2, 4, 16, 32])
def test_the_mirror_is_the_nearest_texel_centre(n):
    rng = np.random.default_rng(n)
    lad = rung_ladder(n, "half_octave")
    levels = [rng.uniform(0.2, 2.0, (lad.per_level, 6, s, s, 3)) for s in lad.sizes]
    d = _dirs(rng, 20000)
    got = RungChains(levels, lad).fetch(d, 0.0, np.full(len(d), np.inf))
    src = cube.texel_directions(n).reshape(-1, 3)
    want = levels[0][0].reshape(-1, 3)[np.argmax(d @ src.T, axis=1)]
    _, u, v = cube.direction_to_face_uv(d)
    corner = (np.abs(u) > 1 - 1 / n) & (np.abs(v) > 1 - 1 / n)    # the cube's corner cells: GL averages 3 faces
    np.testing.assert_allclose(got[~corner], want[~corner], rtol=1e-12)
    bad = np.abs(got - want).max(1) > 1e-9
    assert bad.mean() <= 0.3 * corner.mean()         # measured: 23 % of them at 2^2, 6 % at 4^2, none at 16^2


def test_lookup_position_runs_on_to_the_mirror():
    xr = rung_table(LAD.powers)
    w0 = LAD.powers[0]
    w = np.exp(np.linspace(np.log(0.1), np.log(1e30), 4000))
    u = rung_lod_of_w(w, xr)
    assert np.all(np.diff(u) <= 0) and np.all(np.diff(u)[(w[1:] > w0) & (w[1:] < 1e12)] < 0)  # strictly down past w_0
    np.testing.assert_allclose(u[w <= w0], rung_position(w[w <= w0], xr), atol=1e-15)  # the ladder below
    np.testing.assert_allclose(rung_lod_of_w([w0 * (1 - 1e-9), w0 * (1 + 1e-9)], xr), 0.0, atol=1e-8)
    np.testing.assert_allclose(u[w > w0], -(1 - (1 + w0) / (1 + w[w > w0])), rtol=1e-12)
    assert rung_lod_of_w(np.inf, xr) == -1.0
    np.testing.assert_array_equal(rung_lod_of_w([np.nan, -5.0, 0.0], xr), LAD.rungs - 1)
    # rung 0's power is the capture's texel power 3 N^2 - 2: top_power inverts the top segment
    hi = w[(w > w0) & (w < 1e7)]                 # (1 + u) ~ w_0 / w: float64 resolves it to 1e-9 there
    np.testing.assert_allclose(top_power(rung_lod_of_w(hi, xr), 16), hi, rtol=1e-9)
    assert top_power(0.0, 16) == pytest.approx(w0) and top_power(-1.0, 16) == pytest.approx(MIRROR_POWER)


def _hard_dirs():
    s = 1 / np.sqrt(3)
    hard = [(1, 0, 0), (0, -1, 0), (0, 0, 1), (s, s, s), (-s, s, -s), (1, 1, 0), (0.3, 1, 1), (1, -1e-7, 0.5),
            (1, 0.999999, 0.999999), (-1, 1e-30, 0), (1e-3, 1, 1e-3)]
    d = np.array(hard, np.float64)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


HARD_W = [0.0, -1.0, np.nan, 1.0, 1e7, 1e30, np.inf]


@pytest.mark.parametrize("n", [1, 2, 8])
def test_hard_input_stays_a_convex_mix_of_texels(n):
    # one-texel faces, face edges, cube corners, w = 0, 1e7, inf, NaN, < 0: finite, and (all weights
    # >= 0) within the texels' range
    rng = np.random.default_rng(9)
    lad = rung_ladder(n, "half_octave")
    levels = [rng.uniform(0.2, 2.0, (lad.per_level, 6, s, s, 4)) for s in lad.sizes]
    d = np.concatenate([_hard_dirs(), _dirs(rng, 200)])
    xr = rung_table(lad.powers)
    for w in HARD_W:
        got = rung_fetch(levels, d, 0.0, np.full(len(d), w), xr, lad.per_level)
        assert np.all(np.isfinite(got)) and got.min() >= 0.2 - 1e-12 and got.max() <= 2.0 + 1e-12, w


def _glsl_fetch(ctx, levels, lad, d, base, w):
    xr = np.zeros(MAX_RUNGS, np.float32)
    xr[:lad.rungs] = rung_table(lad.powers, np.float32)
    pt = CubeArrayTexture([np.asarray(a, np.float32) for a in levels])
    try:
        return run_glsl(ctx, "o[i] = envcap_rung_fetch(probes, d[i].xyz, b[i].x, b[i].y, xr, nr, per);"
                             "u[i] = vec4(envcap_rung_lod_of_w(b[i].y, xr, nr));",
                        {"d": d, "b": np.c_[base, np.where(np.isinf(w), 3e38, w)]}, {"o": 4, "u": 1},
                        uniforms={"xr": xr, "nr": lad.rungs, "per": lad.per_level},
                        declarations="uniform float xr[ENVCAP_MAX_RUNGS]; uniform int nr; uniform int per;",
                        probes=pt)
    finally:
        pt.release()


@pytest.mark.parametrize("n", [16, 1])
def test_glsl_top_matches_numpy(gl_ctx, n):
    # random directions, w log-uniform from below rung 1 to 1e9: the same numbers as the float64
    # twin (float32 directions and rung table; the kernel's -log cos is well conditioned, so the
    # steep weights agree); hard directions (axes, edges, corners: exact ties, where float32 may
    # break a tie the other way) at hard w: finite, within the texels' range
    rng = np.random.default_rng(10 + n)
    lad = rung_ladder(n, "half_octave")
    probes = 2
    levels = [rng.uniform(0.2, 2.0, (probes * lad.per_level, 6, s, s, 4)).astype(np.float32) for s in lad.sizes]
    hard = np.repeat(_hard_dirs(), len(HARD_W), axis=0)
    d = np.concatenate([hard, _dirs(rng, 3000)]).astype(np.float32).astype(np.float64)
    w = np.exp(rng.uniform(np.log(lad.powers[min(1, lad.rungs - 1)] * 0.5), np.log(1e9), len(d)))
    w[:len(hard)] = np.tile(HARD_W, len(_hard_dirs()))
    w[len(hard)] = lad.powers[0]
    w[len(hard) + 1] = np.inf
    w = w.astype(np.float32).astype(np.float64)
    base = rng.integers(0, probes, len(d)) * lad.per_level
    out = _glsl_fetch(gl_ctx, levels, lad, d, base, w)
    xr = rung_table(lad.powers)
    got, nh = out["o"], len(hard)
    assert np.all(np.isfinite(got)) and got.min() >= 0.2 - 1e-6 and got.max() <= 2.0 + 1e-6
    np.testing.assert_allclose(out["u"][:, 0], rung_lod_of_w(np.where(np.isinf(w), 3e38, w), xr), atol=2e-6)
    want = rung_fetch(levels, d[nh:], base[nh:], w[nh:], xr, lad.per_level)
    np.testing.assert_allclose(got[nh:], want, rtol=2e-4, atol=2e-4)
