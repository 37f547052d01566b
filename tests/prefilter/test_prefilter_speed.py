"""The batched / coarse-source GL filter: prefilter_many vs per-cube chains, the sun in `fast`
and `default` on a real Preetham sky against the float64 exact reference, huge powers."""

import math

import numpy as np
import pytest

from envcap.core import cube as cm
from envcap.core.color import luminance
from envcap.core.lobes import lobe_ladder
from envcap.prefilter import convolve_exact, prefilter_chain, prefilter_level, prefilter_many


def _rel_rmse(fast, exact):
    om = cm.texel_solid_angles(exact.shape[1])
    yf, ye = luminance(fast), luminance(exact)
    return math.sqrt((om * (yf - ye) ** 2).sum() / (om * ye**2).sum())


@pytest.fixture(scope="module")
def sun_sky():
    from envcap.scene import load_scene

    scene = load_scene("canyon")
    rgb = np.asarray(scene.sky.build().cube(64), np.float64)
    sky = np.concatenate([rgb, np.ones(rgb.shape[:-1] + (1,))], -1)
    assert sky[..., :3].max() > 1e4 * np.median(sky[..., :3])  # the sun is in it
    return sky


@pytest.mark.parametrize("quality", ["fast", "default"])
def test_sun_sky_meets_half_percent_at_every_level(gl_ctx, sun_sky, quality):
    lad = lobe_ladder(64)
    chain = prefilter_chain(sun_sky, lad, quality=quality, ctx=gl_ctx)
    for k in range(2, lad.levels):  # level 1 (6x32^2 x 6x64^2 weights) is the reference's own quadrature
        exact = convolve_exact(sun_sky, lad.powers[k], lad.sizes[k])
        assert np.all(np.isfinite(chain[k]))
        assert _rel_rmse(chain[k], exact) < 5e-3, (quality, k)
        # energy of the sun is where it should be: the brightest texel of each level agrees
        f = np.unravel_index(np.argmax(exact[..., 1]), exact.shape[:3])
        assert chain[k][f][1] == pytest.approx(exact[f][1], rel=2e-2), (quality, k)


def test_many_equals_one_by_one(gl_ctx, sun_sky):
    rng = np.random.default_rng(5)
    n = 16
    cubes = np.stack([rng.uniform(0, 1, (6, n, n, 5)), np.asarray(sun_sky[:, ::4, ::4, :].repeat(2, -1)[..., :5])])
    lad = lobe_ladder(n)
    many = prefilter_many(cubes, lad, ctx=gl_ctx)
    assert [m.shape for m in many] == [(2, 6, s, s, 5) for s in lad.sizes]
    for p in range(2):
        one = prefilter_chain(cubes[p], lad, ctx=gl_ctx)
        # the footprint truncation follows the batch's dynamic range: equal up to that (eps ~ 1e-4)
        for k in range(lad.levels):
            np.testing.assert_allclose(many[k][p], one[k], rtol=2e-4, atol=1e-6 * np.abs(one[k]).max())
    # small batches (one probe per dispatch) give the same numbers
    small = prefilter_many(cubes, lad, ctx=gl_ctx, batch_bytes=1)
    for k in range(lad.levels):
        np.testing.assert_allclose(small[k], many[k], rtol=1e-6, atol=1e-6 * np.abs(many[k]).max())


def test_many_rejects_bad_batches(gl_ctx):
    with pytest.raises(ValueError, match="P, 6, N, N, C"):
        prefilter_many(np.ones((6, 4, 4, 4)), ctx=gl_ctx)
    with pytest.raises(ValueError, match="P >= 1"):
        prefilter_many(np.ones((0, 6, 4, 4, 4)), ctx=gl_ctx)
    bad = np.ones((3, 6, 4, 4, 4))
    bad[2, 1, 0, 0, 0] = np.inf
    with pytest.raises(ValueError, match="cube 2 has 1 texel"):
        prefilter_many(bad, ctx=gl_ctx)


def test_level_huge_power_is_nearest_texel_and_zero_power_is_hemisphere_mean(gl_ctx):
    rng = np.random.default_rng(6)
    cube = rng.uniform(0.5, 2.0, (6, 8, 8, 4))
    out = prefilter_level(cube, 1e7, 8, ctx=gl_ctx)
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out, cube, rtol=1e-5)
    np.testing.assert_allclose(prefilter_level(cube, 0.0, 2, ctx=gl_ctx), convolve_exact(cube, 0.0, 2), rtol=1e-5)
    with pytest.raises(ValueError, match=">= 0"):
        prefilter_level(cube, -1.0, 2, ctx=gl_ctx)
