"""Solid-angle weighted metrics against hand-derived values."""

import numpy as np
import pytest

from envcap.core import cube
from envcap.evaluate.metrics import luminance, relative_error_map, relative_rmse


def test_luminance_of_white_is_one():
    assert luminance(np.ones(3)) == pytest.approx(1.0, abs=1e-12)


def test_relative_rmse_of_a_uniform_scale_is_the_scale_error():
    rng = np.random.default_rng(0)
    t = rng.uniform(0.1, 2.0, size=(6, 8, 8, 3))
    assert relative_rmse(1.1 * t, t) == pytest.approx(0.1, rel=1e-12)


def test_relative_rmse_weights_by_solid_angle():
    # Error only in one texel: rmse^2 = Omega_i * e^2 / (4 pi * 1) for a truth of luminance 1.
    n = 4
    t = np.ones((6, n, n, 3))
    p = t.copy()
    p[2, 0, 0] += 0.5
    omega = cube.texel_solid_angles(n)[2, 0, 0]
    assert relative_rmse(p, t) == pytest.approx(np.sqrt(omega * 0.25 / (4 * np.pi)), rel=1e-12)


def test_black_truth_and_bad_input():
    z = np.zeros((6, 2, 2, 3))
    assert relative_rmse(z, z) == 0.0
    assert relative_rmse(z + 1, z) == 1.0
    with pytest.raises(ValueError):
        relative_rmse(z, np.zeros((6, 3, 3, 3)))
    bad = z.copy()
    bad[0, 0, 0, 0] = np.nan
    with pytest.raises(ValueError):
        relative_rmse(bad, z)


def test_error_map_has_no_inf_on_black_texels():
    t = np.zeros((6, 2, 2, 3))
    t[0] = 1.0
    m = relative_error_map(t * 0.5, t)
    assert np.all(np.isfinite(m)) and m[0].max() == pytest.approx(0.5)
