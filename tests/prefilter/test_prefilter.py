"""Cosine-lobe chains: the exact reference against hand-derived integrals, the GLSL filter
against the exact reference (real GL on llvmpipe), seams, premultiplied alpha, hard inputs."""

import math

import numpy as np
import pytest

from envcap.core import cube as cm
from envcap.core.color import luminance
from envcap.core.lobes import lobe_ladder
from envcap.prefilter import (check_finite_cube, convolve_exact, convolve_exact_dirs, footprint_rects,
                              omega_box_pyramid, prefilter_chain)


def _rel_rmse(fast, exact):
    om = cm.texel_solid_angles(exact.shape[1])
    yf, ye = luminance(fast), luminance(exact)
    return math.sqrt((om * (yf - ye) ** 2).sum() / (om * ye**2).sum())


def _street(n, sun=1e9):
    """Street-like RGBA (premultiplied): facades with sharp edges, alpha 0 sky above; a sun texel by a seam."""
    d = cm.texel_directions(n)
    geo = (d[..., 1] < 0.35 + 0.2 * (np.sin(7 * np.arctan2(d[..., 0], d[..., 2])) > 0)).astype(np.float64)
    rgb = np.stack([0.3 + 0.2 * (d[..., 0] > 0.2), 0.25 + 0.1 * (d[..., 2] > 0), 0.2 + 0.0 * d[..., 0]], -1) * 500
    street = np.concatenate([rgb * geo[..., None], geo[..., None]], -1)
    sky = np.concatenate([np.stack([2e3 + 1e3 * d[..., 1]] * 3, -1), np.ones_like(d[..., :1])], -1)
    f, r, c = cm.direction_to_texel(np.array([1.0, 0.999, 0.2]), n)  # next to the +X/+Y seam
    sky[f, r, c, :3] += sun
    return street, sky


def test_exact_linear_function_matches_closed_form():
    # L(u) = a.u  =>  normalized cos^w average = (a.d) (w + 1) / (w + 2)  (hand-derived)
    n = 32
    a = np.array([0.3, -0.5, 0.8])
    cube = (cm.texel_directions(n) @ a)[..., None]
    dirs = np.random.default_rng(0).normal(size=(50, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    for w, tol in ((0.0, 2e-2), (1.0, 2e-3), (20.0, 2e-3)):
        got = convolve_exact_dirs(cube, w, dirs)[:, 0]
        np.testing.assert_allclose(got, (dirs @ a) * (w + 1) / (w + 2), atol=tol)


def test_exact_constant_and_huge_power_gives_nearest_texel():
    rng = np.random.default_rng(1)
    cube = rng.uniform(0, 10, size=(6, 4, 4, 2))
    for w in (0.0, 1.0, 62.0):
        np.testing.assert_allclose(convolve_exact(np.full((6, 4, 4, 1), 3.5), w, 2), 3.5, rtol=1e-13)
    out = convolve_exact(cube, 1e7, 4)
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out, cube, rtol=1e-12)


def test_bad_inputs_are_rejected_with_clear_errors():
    cube = np.ones((6, 4, 4, 3))
    cube[0, 1, 1, 0] = np.nan
    cube[2, 0, 0, :] = np.inf
    with pytest.raises(ValueError, match="2 texel"):
        check_finite_cube(cube)
    with pytest.raises(ValueError, match="2 texel"):
        prefilter_chain(cube)
    with pytest.raises(ValueError, match=">= 0"):
        convolve_exact(np.ones((6, 4, 4, 1)), -1.0, 2)
    with pytest.raises(ValueError, match="shape"):
        prefilter_chain(np.ones((5, 4, 4, 4)))
    with pytest.raises(ValueError, match="quality"):
        prefilter_chain(np.ones((6, 4, 4, 4)), quality="ultra")


def test_footprint_rects_hold_every_texel_in_the_cap():
    rng = np.random.default_rng(2)
    n = 24
    src = cm.texel_directions(n)
    for theta in (0.02, 0.1, 0.4, 0.9):
        d = rng.normal(size=(60, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        rects = footprint_rects(d, theta, n)
        for o in range(d.shape[0]):
            inside = np.argwhere(src @ d[o] >= math.cos(theta))
            for f, r, c in inside:
                c0, c1, r0, r1 = rects[o, f]
                assert c0 <= c < c1 and r0 <= r < r1, (theta, o, f, r, c)


def test_box_pyramid_conserves_energy():
    rng = np.random.default_rng(3)
    cube = rng.uniform(0, 1, (6, 16, 16, 2))
    pyr = omega_box_pyramid(cube, 5)
    e0 = (cube * cm.texel_solid_angles(16)[..., None]).sum((0, 1, 2))
    for lv in pyr:
        np.testing.assert_allclose((lv * cm.texel_solid_angles(lv.shape[1])[..., None]).sum((0, 1, 2)), e0, rtol=1e-12)


@pytest.fixture(scope="module")
def street_chain(gl_ctx):
    street, sky = _street(32)
    lad = lobe_ladder(32)
    env = street + (1 - street[..., 3:4]) * sky
    return street, sky, env, lad, prefilter_chain(env, lad, ctx=gl_ctx), prefilter_chain(street, lad, ctx=gl_ctx)


def test_gl_chain_matches_exact_reference_with_sun_by_seam(street_chain):
    _, _, env, lad, chain, _ = street_chain
    assert chain[0].dtype == np.float32 and np.array_equal(chain[0], env.astype(np.float32))
    for k in range(1, lad.levels):
        exact = convolve_exact(env, lad.powers[k], lad.sizes[k])
        assert chain[k].shape == exact.shape and np.all(np.isfinite(chain[k]))
        assert _rel_rmse(chain[k], exact) < 1e-4, k  # target is 5e-3; measured ~1e-6
        np.testing.assert_allclose(chain[k], exact, rtol=2e-4, atol=1e-6 * np.abs(exact).max())


def test_seams_continuous_like_the_exact_reference(street_chain, gl_ctx):
    # smooth input: texels adjacent across the +X / +Z edge (+X column 0 meets +Z last column)
    n = 32
    d = cm.texel_directions(n)
    smooth = np.stack([1 + d[..., 0] * d[..., 2], 2 + d[..., 1], np.exp(d[..., 2]), np.ones_like(d[..., 0])], -1)
    lad = lobe_ladder(n)
    chain = prefilter_chain(smooth, lad, ctx=gl_ctx)
    for k in range(1, lad.levels):
        exact = convolve_exact(smooth, lad.powers[k], lad.sizes[k])
        jump_fast = chain[k][0, :, 0] - chain[k][4, :, -1]
        jump_exact = exact[0, :, 0] - exact[4, :, -1]
        np.testing.assert_allclose(jump_fast, jump_exact, atol=2e-5)


def test_premultiplied_alpha_composite_identity(street_chain):
    # street_k + (1 - alpha_k) sky_k == filter(street + (1 - alpha) sky) holds exactly for a sky that is
    # constant over the lobe (linearity); for a varying sky it is the covariance of alpha and sky.
    street, _, _, lad, _, street_chain_k = street_chain
    const_sky = np.concatenate([np.full(street.shape[:3] + (3,), 1500.0), np.ones(street.shape[:3] + (1,))], -1)
    env = street + (1 - street[..., 3:4]) * const_sky
    for k in range(1, lad.levels):
        w, m = lad.powers[k], lad.sizes[k]
        s_ex = convolve_exact(street, w, m)
        comp_ex = s_ex[..., :3] + (1 - s_ex[..., 3:4]) * 1500.0
        want = convolve_exact(env, w, m)[..., :3]
        np.testing.assert_allclose(comp_ex, want, rtol=1e-5)
        comp_fast = street_chain_k[k][..., :3] + (1 - street_chain_k[k][..., 3:4]) * 1500.0
        np.testing.assert_allclose(comp_fast, want, rtol=1e-3)
        assert np.all((street_chain_k[k][..., 3] > -1e-6) & (street_chain_k[k][..., 3] < 1 + 1e-6))


def test_single_sun_texel_by_seam_is_finite_and_conserves_energy(gl_ctx):
    # Normalized filtering with a symmetric kernel conserves sum(Omega * value) in the continuum
    # (integrate m(d) over d, swap integrals); texel quadrature keeps it to discretization error.
    n = 32
    cube = np.full((6, n, n, 4), 1.0)
    f, r, c = cm.direction_to_texel(np.array([1.0, 0.999, 0.2]), n)
    cube[f, r, c, :3] = 1e9
    lad = lobe_ladder(n)
    chain = prefilter_chain(cube, lad, ctx=gl_ctx)
    e0 = (cube[..., 0] * cm.texel_solid_angles(n)).sum()
    for k in range(1, lad.levels):
        assert np.all(np.isfinite(chain[k]))
        ek = (chain[k][..., 0].astype(np.float64) * cm.texel_solid_angles(lad.sizes[k])).sum()
        assert ek == pytest.approx(e0, rel=0.05), k
        np.testing.assert_allclose(chain[k][..., 3], 1.0, rtol=1e-5)


@pytest.mark.parametrize("n", [1, 2])
def test_tiny_faces(gl_ctx, n):
    rng = np.random.default_rng(4)
    cube = rng.uniform(0, 1, (6, n, n, 3))
    lad = lobe_ladder(n)
    chain = prefilter_chain(cube, lad, ctx=gl_ctx)
    assert [c.shape for c in chain] == [(6, s, s, 3) for s in lad.sizes]
    for k in range(1, lad.levels):
        np.testing.assert_allclose(chain[k], convolve_exact(cube, lad.powers[k], lad.sizes[k]), rtol=1e-5)
