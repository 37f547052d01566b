"""Sky-weighted alpha of rung textures (envcap.prefilter.rungs.sky_weighted_alpha): the runtime's
composite after filtering, street_w + (1 - alpha_w) sky_w, against the exact filter of the
composited cube (float64 brute force)."""

import numpy as np
import pytest

from envcap.core.color import luminance
from envcap.core.rungs import rung_ladder
from envcap.prefilter.exact import convolve_exact
from envcap.prefilter.rungs import prefilter_rungs


def _street_and_sky(rng, n):
    sky = np.ones((6, n, n, 4))
    sky[..., :3] = rng.uniform(0.5, 1.0, 3)
    sky[2, ..., :3] *= 6.0                     # a bright zenith face: alpha and the sky correlate
    st = np.zeros((6, n, n, 4))
    st[[0, 1, 3, 4, 5], n // 2:] = [0.2, 0.15, 0.1, 1.0]   # facades below the horizon, opaque
    st[0, : n // 2, :2] = [0.3, 0.3, 0.3, 1.0]
    return st, sky


def test_sky_weighted_alpha_makes_the_composite_exact(gl_ctx):
    rng = np.random.default_rng(7)
    n = 8
    st, sky = _street_and_sky(rng, n)
    lad = rung_ladder(n, "octave")             # (capture, w = 1) on 8^2 faces
    plain = prefilter_rungs(st, lad, ctx=gl_ctx)
    weighted = prefilter_rungs(st, lad, ctx=gl_ctx, sky=sky)
    np.testing.assert_array_equal(weighted[0][0], plain[0][0])          # rung 0 untouched
    np.testing.assert_array_equal(weighted[0][1, ..., :3], plain[0][1, ..., :3])
    w = lad.powers[1]
    truth = luminance(convolve_exact(st[..., :3] + (1 - st[..., 3:]) * sky[..., :3], w, n))
    sky_w = convolve_exact(sky, w, n)[..., :3]

    def composite(level):
        return luminance(level[..., :3] + (1 - level[..., 3:4]) * sky_w)

    err_plain = np.abs(composite(plain[0][1]) - truth).max() / truth.max()
    err_weighted = np.abs(composite(weighted[0][1]) - truth).max() / truth.max()
    assert err_plain > 0.03                      # the covariance the plain composite misses
    assert err_weighted < 3e-3
    with pytest.raises(ValueError, match="positive luminance"):
        prefilter_rungs(st, lad, ctx=gl_ctx, sky=np.zeros_like(sky))
