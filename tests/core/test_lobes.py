"""Lobe ladder and z(w): hand-derived cases and independent quadrature."""

import math

import numpy as np
import pytest
from scipy import integrate

from envcap.core.lobes import LobeLadder, lobe_half_angle, lobe_ladder, lobe_sigma, texel_power, z_of_w


@pytest.mark.parametrize("n", [1, 2, 3, 4, 16, 96, 256, 1024])
def test_ladder_shapes_and_strictly_decreasing(n):
    lad = lobe_ladder(n)
    assert lad.sizes == tuple(max(n >> k, 1) for k in range(n.bit_length()))
    assert all(a > b for a, b in zip(lad.powers, lad.powers[1:]))
    assert lad.powers[0] == texel_power(n)


def test_levels_resolve_their_lobe():
    lad = lobe_ladder(256)
    for k in range(1, lad.levels):
        if lad.powers[k] > 1.0:  # above the floor: RMS angle >= half a face-center texel
            assert lobe_sigma(lad.powers[k]) >= 0.5 * 2.0 / lad.sizes[k] - 1e-12


def test_z_at_nodes_clamps_and_inf():
    lad = lobe_ladder(256)
    np.testing.assert_allclose(lad.z(np.array(lad.powers)), np.arange(lad.levels), atol=1e-12)
    assert lad.z(1e9) == 0 and lad.z(np.inf) == 0
    assert lad.z(0.0) == lad.levels - 1 and lad.z(0.5) == lad.levels - 1
    w = np.logspace(0, 6, 200)
    z = lad.z(w)
    assert np.all(np.diff(z) <= 0) and np.all((z >= 0) & (z <= lad.levels - 1))
    # linear in log2(1 + w) between nodes: midpoint in x gives k + 0.5
    x = 0.5 * (math.log2(1 + lad.powers[3]) + math.log2(1 + lad.powers[4]))
    assert lad.z(2.0**x - 1.0) == pytest.approx(3.5, abs=1e-12)
    assert lad.z(np.zeros((2, 3))).shape == (2, 3)


@pytest.mark.parametrize("bad", [-1.0, -1e-9, np.nan])
def test_z_rejects_negative_and_nan(bad):
    with pytest.raises(ValueError):
        lobe_ladder(16).z(bad)
    with pytest.raises(ValueError):
        z_of_w(np.array([1.0, bad]), [10.0, 1.0])


def test_bad_tables_and_sizes():
    with pytest.raises(ValueError):
        z_of_w(1.0, [1.0, 2.0])
    with pytest.raises(ValueError):
        LobeLadder((4, 2), (10.0, 10.0))
    with pytest.raises(ValueError):
        LobeLadder((4, 3), (10.0, 1.0))
    for bad in (0, -3, 2.5, True):
        with pytest.raises(ValueError):
            lobe_ladder(bad)


def test_manifest_round_trip_and_single_level():
    lad = lobe_ladder(64)
    m = lad.to_manifest()
    assert m["z_of_w"] == "piecewise-linear in log2(1+w) over powers"
    assert LobeLadder.from_manifest(m) == lad
    one = lobe_ladder(1)
    assert one.z([0.0, 1.0, 1e6]).tolist() == [0.0, 0.0, 0.0]


@pytest.mark.parametrize("w", [0.0, 1.0, 7.0, 100.0])
def test_lobe_moments_against_quadrature(w):
    # normalization 2 pi / (w + 1) and E[1 - cos] = 1 / (w + 2), by scipy quadrature over theta
    norm = 2 * math.pi * integrate.quad(lambda t: math.cos(t) ** w * math.sin(t), 0, math.pi / 2)[0]
    assert norm == pytest.approx(2 * math.pi / (w + 1), rel=1e-9)
    m1 = 2 * math.pi * integrate.quad(lambda t: (1 - math.cos(t)) * math.cos(t) ** w * math.sin(t), 0, math.pi / 2)[0]
    assert m1 / norm == pytest.approx(1 / (w + 2), rel=1e-9)
    if w > 0:
        assert math.cos(float(lobe_half_angle(w))) ** w == pytest.approx(0.5, rel=1e-12)
