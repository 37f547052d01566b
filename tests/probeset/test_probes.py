"""Probe placement and plane fitting, against hand-derived layouts and an analytic street."""

import numpy as np
import pytest

from envcap.core import cube
from envcap.probeset.placement import place_probes
from envcap.probeset.planes import Planes, fit_planes
from envcap.scene.model import Street


def test_probes_are_spaced_exactly_and_centered_on_the_street():
    st = Street("main", "x", 0.0, 100.0, -6.0, 10.0)
    probes = place_probes(st, spacing=5.0, height=2.0)
    along = [p.position[0] for p in probes]
    assert len(probes) == 20
    np.testing.assert_allclose(np.diff(along), 5.0)
    assert along[0] == pytest.approx(2.5) and along[-1] == pytest.approx(97.5)
    for p in probes:
        assert p.position[1] == 2.0 and p.position[2] == 2.0  # center of facades -6 and 10
        assert (p.planes.facade_min, p.planes.facade_max, p.planes.ground) == (-6.0, 10.0, 0.0)


def test_street_along_z_uses_x_as_cross_axis_and_short_street_gets_one_probe():
    st = Street("side", "z", 10.0, 13.0, 4.0, 8.0, ground=1.5)
    (p,) = place_probes(st, spacing=5.0, height=2.0)
    assert p.position == (6.0, 3.5, 11.5)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_spacing_and_height_raise(bad):
    st = Street("main", "x", 0.0, 100.0, -6.0, 10.0)
    with pytest.raises(ValueError, match="spacing"):
        place_probes(st, spacing=bad)
    with pytest.raises(ValueError, match="height"):
        place_probes(st, height=bad)


def analytic_capture(p, n, fmin, fmax, ground, height, gaps=()):
    """Distances from p to a street along z: facades x = fmin/fmax up to `height`, ground y = ground.

    `gaps` are (x_side_sign, z0, z1) intervals where the facade is missing (rays pass through,
    and hit a wall 30 m further back)."""
    d = cube.texel_directions(n)
    t = np.full(d.shape[:-1], np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        tg = (ground - p[1]) / d[..., 1]
        t = np.where((tg > 0), np.minimum(t, tg), t)
        for xf, sign in ((fmin, -1), (fmax, 1)):
            tf = (xf - p[0]) / d[..., 0]
            hit = p + d * tf[..., None]
            ok = (tf > 0) & (hit[..., 1] < height)
            for gs, z0, z1 in gaps:
                if gs == sign:
                    in_gap = (hit[..., 2] > z0) & (hit[..., 2] < z1)
                    tb = (xf + sign * 30.0 - p[0]) / d[..., 0]
                    t = np.where(ok & in_gap & (tb > 0), np.minimum(t, tb), t)
                    ok &= ~in_gap
            t = np.where(ok, np.minimum(t, tf), t)
    alpha = np.isfinite(t).astype(np.float32)
    return np.where(np.isfinite(t), t, 0.0), alpha


def test_fit_recovers_planes_of_an_analytic_street():
    p = np.array([1.0, 2.0, 0.0])
    dist, alpha = analytic_capture(p, 64, -7.0, 9.0, 0.0, 25.0)
    fit = fit_planes(p, dist, alpha, "z")
    assert fit.facade_min == pytest.approx(-7.0, abs=0.05)
    assert fit.facade_max == pytest.approx(9.0, abs=0.05)
    assert fit.ground == pytest.approx(0.0, abs=0.05)


def test_fit_is_robust_to_gaps_between_buildings():
    p = np.array([0.0, 2.0, 0.0])
    gaps = [(1, -4.0, 4.0), (-1, 6.0, 12.0)]  # a gap right in front of the probe on the + side
    dist, alpha = analytic_capture(p, 64, -6.0, 6.0, 0.0, 20.0, gaps)
    fit = fit_planes(p, dist, alpha, "z")
    assert fit.facade_min == pytest.approx(-6.0, abs=0.05)
    assert fit.facade_max == pytest.approx(6.0, abs=0.05)


def test_a_side_without_buildings_is_not_fitted_and_falls_back_to_nominal():
    p = np.array([0.0, 2.0, 0.0])
    dist, alpha = analytic_capture(p, 32, -6.0, 6.0, 0.0, 20.0)
    d = cube.texel_directions(32)
    open_side = d[..., 0] > 0  # no facade on +x: the ground still shows there, nothing else
    tg = np.where(d[..., 1] < 0, -2.0 / np.where(d[..., 1] < 0, d[..., 1], -1), 0.0)
    dist = np.where(open_side, tg, dist)
    alpha = np.where(open_side, (d[..., 1] < 0).astype(np.float32), alpha)
    fit = fit_planes(p, dist, alpha, "z", max_distance=50.0)
    assert fit.facade_max is None
    assert fit.coverage_sr.facade_max < 0.05 and fit.spread_m.facade_max == 0.0  # not seen: no spread
    assert fit.coverage_sr.ground > 1.0  # the lower hemisphere sees the ground almost everywhere
    merged = fit.merged(Planes(-6.0, 30.0, 0.0))
    assert merged.facade_max == 30.0 and merged.facade_min == pytest.approx(-6.0, abs=0.05)


def test_fit_rejects_bad_input():
    with pytest.raises(ValueError):
        fit_planes([0, 2, 0], np.zeros((6, 4, 4)), np.zeros((6, 4, 4)), "y")
    with pytest.raises(ValueError):
        fit_planes([0, 2, 0], np.zeros((6, 4, 4)), np.zeros((6, 5, 5)), "x")
    with pytest.raises(ValueError):
        fit_planes([0, np.nan, 0], np.zeros((6, 4, 4)), np.zeros((6, 4, 4)), "x")
