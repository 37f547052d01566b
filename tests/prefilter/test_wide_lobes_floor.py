"""The wide rungs of a rung ladder (:func:`envcap.prefilter.wide_lobes.filter_wide_lobes`) never
ring below zero beside a black region: a premultiplied probe is black (alpha 0) where it sees the
sky, and ``probes.ktx2`` refuses negative radiance (``envcap capture avenue --resolution 32
--spacing 40 --ladder half_octave`` failed at the write with -1.8e-4)."""

import numpy as np

from envcap.core import cube as cube_geometry
from envcap.prefilter.exact import convolve_exact
from envcap.prefilter.wide_lobes import filter_wide_lobes


def _edge_cube(n: int) -> np.ndarray:
    """A lit street (RGB 1, alpha 1) below a sharp sky edge (RGB 0, alpha 0) at y = 0.3."""
    d = cube_geometry.texel_directions(n)
    sky = d[..., 1] > 0.3
    c = np.zeros((6, n, n, 4))
    c[..., :3] = np.where(sky, 0.0, 1.0)[..., None]
    c[..., 3] = np.where(sky, 0.0, 1.0)
    return c


def test_no_negative_texel_from_truncated_harmonics():
    c = _edge_cube(16)
    powers, sizes = [30.0, 20.6, 1.0], [8, 8, 4]
    got = filter_wide_lobes(c[None], powers, sizes)
    again = filter_wide_lobes(np.asarray(convolve_exact(c, 45.0, 16))[None], [30.0], [8], source_power=45.0)
    for w, m, g in [*zip(powers, sizes, got), (30.0, 8, again[0])]:
        assert g.min() >= 0.0                                  # was -4e-7 .. -7e-7 at w = 30
        ref = convolve_exact(c, w, m)
        assert np.abs(g[0] - ref).max() < 1e-3                 # still the lobe average
    signed = c - 0.5                                           # signed data keeps its own floor
    low = filter_wide_lobes(signed[None], [30.0], [8])[0]
    assert low.min() < 0.0 and low.min() >= -0.5 - 1e-6
