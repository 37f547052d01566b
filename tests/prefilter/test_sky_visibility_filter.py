"""The bake side of the sky-visibility correction (envcap.prefilter.sky_visibility): the SH basis
against quadrature and the capture's own l <= 2 basis, the lobe's band factors against scipy
quadrature, the filtered V = filter(alpha Y_lm) against the float64 brute-force convolution, the
packed layout, and hard inputs (alpha all 0 / all 1, one-texel faces, NaN alpha)."""

import numpy as np
import pytest

from envcap.capture.sky_sh import sh9_basis
from envcap.core import cube as cube_geometry
from envcap.core.rungs import rung_ladder
from envcap.prefilter.exact import convolve_exact
from envcap.prefilter.sky_visibility import (
    band_factors,
    first_stored_level,
    prefilter_sky_visibility,
    sh_basis,
    visibility_bytes_per_probe,
)


def test_sh_basis_is_orthonormal_and_extends_the_capture_basis():
    d = cube_geometry.texel_directions(48)
    om = cube_geometry.texel_solid_angles(48)
    y = sh_basis(d, 4)
    gram = np.einsum("fija,fijb,fij->ab", y, y, om)
    np.testing.assert_allclose(gram, np.eye(25), atol=2e-3)
    np.testing.assert_array_equal(y[..., :9], sh9_basis(d))
    with pytest.raises(ValueError, match="SH order"):
        sh_basis(d, 5)


def test_band_factors_match_quadrature():
    from numpy.polynomial import legendre

    x, g = legendre.leggauss(300)                # Gauss-Legendre on mu in [0, 1]
    mu, g = 0.5 * (x + 1.0), 0.5 * g
    for w in (0.0, 1.0, 3.7, 50.0):
        lobe = g * mu ** w / np.sum(g * mu ** w)
        ref = [np.sum(lobe * legendre.legval(mu, [0] * l + [1])) for l in range(5)]
        np.testing.assert_allclose(band_factors(w, 4), ref, atol=1e-7)
    assert np.all(band_factors(np.inf, 4) == 1.0)


def _canyon_alpha(n):
    d = cube_geometry.texel_directions(n)
    return (((np.abs(d[..., 0]) > 0.45) & (d[..., 1] < 0.5)) | (d[..., 1] < -0.1)).astype(np.float64)


@pytest.mark.parametrize("quality, atol", [("harmonics", 5e-5), ("default", 2e-4)])
def test_visibility_matches_exact_convolution(gl_ctx, quality, atol):
    lad = rung_ladder(16, "half_octave")        # sizes (16, 8): level 1 stored (w = 6 .. 1)
    alpha = _canyon_alpha(16)
    vis = prefilter_sky_visibility(alpha, lad, 2, quality=quality, ctx=gl_ctx)
    assert vis.first_level == 1 and [a.shape for a in vis.levels] == [(4, 6, 8, 8, 9)]
    basis = sh_basis(cube_geometry.texel_directions(16), 2)
    for r in (0, 3):                             # w = 6, 1
        ref = convolve_exact(alpha[..., None] * basis, lad.powers[4 + r], 8)
        np.testing.assert_allclose(vis.levels[0][r], ref, atol=atol)
    assert vis.bytes_per_probe() == visibility_bytes_per_probe(lad, 2) == 9 * 6 * 8 ** 2 * 8


def test_harmonics_refuse_a_lobe_past_their_reach():
    with pytest.raises(ValueError, match="quality='default'"):
        prefilter_sky_visibility(_canyon_alpha(256), rung_ladder(256, "half_octave"), 1, max_power=5000.0)   # w = 2046 stored


def test_alpha_all_zero_and_all_one(gl_ctx):
    lad = rung_ladder(16, "half_octave")
    zero = prefilter_sky_visibility(np.zeros((6, 16, 16)), lad, 3, ctx=gl_ctx)
    assert all(np.all(a == 0.0) for a in zero.levels)
    one = prefilter_sky_visibility(np.ones((2, 6, 16, 16)), lad, 3, ctx=gl_ctx)
    d = cube_geometry.texel_directions(8)
    for r, w in enumerate(lad.level_powers(1)):  # filter(Y_lm) = lambda_l(w) Y_lm (zonal lobe)
        want = band_factors(w, 3)[np.repeat(np.arange(4), [1, 3, 5, 7])] * sh_basis(d, 3)
        for p in range(2):
            np.testing.assert_allclose(one.levels[0][p * 4 + r], want, atol=3e-3)


def test_packed_layout_and_hard_inputs(gl_ctx):
    lad = rung_ladder(1, "half_octave")          # one-texel faces: one level, stored whole
    alpha = np.array([1.0, 0.0, 1.0, 0.0, 0.0, 1.0]).reshape(6, 1, 1)
    vis = prefilter_sky_visibility(alpha, lad, 2, ctx=gl_ctx)
    assert vis.first_level == 0 and vis.levels[0].shape == (4, 6, 1, 1, 9) and np.isfinite(vis.levels[0]).all()
    np.testing.assert_allclose(vis.levels[0][0], alpha[..., None] * sh_basis(cube_geometry.texel_directions(1), 2))
    packed = vis.packed_levels()[0]               # 4 rungs x 9 = 36 channels = 9 RGBA layers
    assert packed.shape == (9, 6, 1, 1, 4)
    flat = np.moveaxis(packed, 0, -2).reshape(6, 1, 1, 36)
    for r in range(4):
        np.testing.assert_array_equal(flat[..., 9 * r:9 * r + 9], vis.levels[0][r])
    with pytest.raises(ValueError, match="NaN"):
        prefilter_sky_visibility(np.full((6, 1, 1), np.nan), lad, 2, ctx=gl_ctx)
    with pytest.raises(ValueError, match="starts at 1"):
        prefilter_sky_visibility(np.zeros((6, 2, 2)), lad, 2, ctx=gl_ctx)
    assert first_stored_level(rung_ladder(64, "half_octave")) == 1
    assert first_stored_level(rung_ladder(256, "half_octave")) == 3
