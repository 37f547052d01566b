"""Rung ladders (envcap.core.rungs): the rule of docs/lobes.md "Ladder modes" checked by hand."""

import math

import numpy as np
import pytest

from envcap.core.lobes import texel_power
from envcap.core.rungs import RungLadder, ladder_bytes_per_probe, rung_ladder


@pytest.mark.parametrize("mode,per", [("half_octave", 4), ("octave", 2)])
def test_rung_ladder_rule(mode, per):
    lad = rung_ladder(64, mode)
    assert lad.sizes == (64, 32, 16, 8) and lad.per_level == per and lad.rungs == 4 * per
    p = np.array(lad.powers)
    assert p[0] == texel_power(64) and p[-1] == pytest.approx(1.0)
    assert np.all(np.diff(p) < 0)
    # middle levels: first rung at an RMS angle of sqrt(2) face-centre texels, then (w + 2) / 2^(2/R)
    for j in (1, 2):
        v = np.array(lad.level_powers(j)) + 2.0
        assert v[0] == pytest.approx((lad.sizes[j] / (2 * math.sqrt(2))) ** 2)
        np.testing.assert_allclose(v[1:] / v[:-1], 2.0 ** (-2.0 / per))
    # the widest lobes (w <= 16) live on faces of >= 8 texels
    for i, w in enumerate(p):
        if w <= 16:
            assert lad.sizes[i // per] >= 8


def test_rung_position_and_manifest():
    lad = rung_ladder(16, "half_octave")
    np.testing.assert_allclose(lad.position(np.array(lad.powers)), np.arange(lad.rungs), atol=1e-12)
    x = 0.5 * (np.log2(1 + lad.powers[2]) + np.log2(1 + lad.powers[3]))
    assert lad.position(2.0 ** x - 1.0) == pytest.approx(2.5)
    assert lad.position(np.inf) == 0 and lad.position(0.0) == lad.rungs - 1
    assert RungLadder.from_manifest(lad.to_manifest()) == lad
    with pytest.raises(ValueError, match="mode"):
        rung_ladder(16, "paper")
    with pytest.raises(ValueError, match="NaN"):
        lad.position(float("nan"))
    with pytest.raises(ValueError, match="strictly decreasing"):
        RungLadder((8,), (1.0, 2.0), 2)


def test_bytes_per_probe_by_hand():
    # rgba16f: 8 bytes a texel, 6 faces
    assert ladder_bytes_per_probe("paper", 64) == 6 * 8 * sum(s * s for s in (64, 32, 16, 8, 4, 2, 1))
    assert ladder_bytes_per_probe("half_octave", 64) == 4 * 6 * 8 * sum(s * s for s in (64, 32, 16, 8))
    assert ladder_bytes_per_probe("octave", 256) == 2 * 6 * 8 * sum(s * s for s in (256, 128, 64, 32, 16, 8))
