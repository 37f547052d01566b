"""Streets turned by a multiple of 90 degrees use exact frames: cos/sin are 0 and +-1 there (not
the 6e-17 of ``cos(radians(90))``), so a direction exactly along such a street stays parallel to
its facades, as in the same street without a frame (the no-hit fallback, not a hit at t = 0 with
the sharpest level for points within 1e-10 m of a facade)."""

import math

import numpy as np
import pytest

from envcap.core.street_frame import frame_to_world, plan_rotation, to_frame, world_to_frame, yaw_cos_sin
from envcap.runtime.chains import ProbeChains
from envcap.runtime.methods import BUILTIN
from envcap.runtime.sampling import composite, sample_sky, sample_street
from envcap.runtime.street import RuntimeStreet

QUARTERS = {0.0: (1, 0), 90.0: (0, 1), -90.0: (0, -1), 180.0: (-1, 0), -180.0: (-1, 0), 270.0: (0, -1),
            450.0: (0, 1), -270.0: (0, 1), 360.0: (1, 0), 720.0: (1, 0)}
"""Multiples of 90 degrees and their (cos, sin), derived by hand."""


@pytest.mark.parametrize("yaw", list(QUARTERS))
def test_cos_sin_are_exact_at_multiples_of_90_degrees(yaw):
    c, s = yaw_cos_sin(yaw)
    assert (float(c), float(s)) == QUARTERS[yaw]
    r = plan_rotation(yaw)
    assert set(np.unique(r)) <= {-1.0, 0.0, 1.0}
    assert np.array_equal(r @ r.T, np.eye(3))
    # vectorised, the same values
    cv, sv = yaw_cos_sin(np.array([yaw, yaw]))
    assert np.array_equal(cv, [QUARTERS[yaw][0]] * 2) and np.array_equal(sv, [QUARTERS[yaw][1]] * 2)


@pytest.mark.parametrize("yaw", [30.0, -33.3, 1e-10, -1e-10, 89.99999999, 213.7, 135.0])
def test_cos_sin_elsewhere_are_the_plain_functions(yaw):
    c, s = yaw_cos_sin(yaw)
    assert abs(float(c) - math.cos(math.radians(yaw))) <= 1e-15
    assert abs(float(s) - math.sin(math.radians(yaw))) <= 1e-15
    if abs(yaw) < 1e-6:                                          # small angles keep their precision
        assert float(s) == math.sin(math.radians(yaw))


def test_non_finite_yaw_is_nan_and_refused_by_the_rotation():
    c, s = yaw_cos_sin(np.array([np.nan, np.inf, -np.inf]))
    assert np.isnan(c).all() and np.isnan(s).all()
    for bad in (math.nan, math.inf):
        with pytest.raises(ValueError, match="finite"):
            plan_rotation(bad)


@pytest.mark.parametrize("yaw", [90.0, -90.0, 180.0, 270.0])
def test_points_and_directions_turn_exactly(yaw):
    pts = np.array([[3.25, 1.5, -2.0], [-7.0, 0.0, 12.5]])
    f = world_to_frame(pts, yaw, (100.0, -50.0))
    assert np.array_equal(frame_to_world(f, yaw, (100.0, -50.0)), pts)
    along = frame_to_world(np.array([[1.0, 0.0, 0.0]]), yaw) - frame_to_world(np.zeros((1, 3)), yaw)
    assert np.count_nonzero(along) == 1                          # a world axis, exactly
    assert np.array_equal(to_frame(along, yaw), [[1.0, 0.0, 0.0]])


@pytest.mark.parametrize("yaw", [90.0, -90.0, 180.0, 270.0])
def test_a_direction_along_a_quarter_turned_street_is_parallel_to_its_facades(scene, yaw):
    """Every method without a distance channel returns, bit for bit, the street RGBA the same street
    without a frame returns for the hand-turned inputs: directions exactly along the street, points on,
    within 1e-10 m of and between the facades."""
    probes, sky, street, powers = scene[:4]
    chains = ProbeChains(probes, powers)
    c, s = QUARTERS[yaw]
    framed = RuntimeStreet(0, street.positions, street.planes, street.layers, yaw, (0.0, 0.0))
    assert np.array_equal(framed.frame, [c, s])
    lo, hi = (float(v) for v in street.planes[0, :2])
    z = np.array([lo, lo + 1e-10, hi - 1e-10, hi, 0.5 * (lo + hi)])
    f = np.stack([np.full(z.size, 7.25), np.full(z.size, 1.5), z], axis=-1)
    f = np.concatenate([f, f])
    df = np.repeat(np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]), z.size, axis=0)
    # world = R^T f: (c fx - s fz, fy, s fx + c fz), exact with c, s in {0, +-1}
    xw = np.stack([c * f[:, 0] - s * f[:, 2], f[:, 1], s * f[:, 0] + c * f[:, 2]], axis=-1)
    dw = np.stack([c * df[:, 0] - s * df[:, 2], df[:, 1], s * df[:, 0] + c * df[:, 2]], axis=-1)
    assert np.array_equal(framed.to_frame(xw), f) and np.array_equal(framed.direction_to_frame(dw), df)
    w = np.full(len(f), 64.0)
    for m in BUILTIN:
        if m.needs_distance:
            continue
        got, want = m(chains, framed, xw, dw, w), m(chains, street, f, df, w)
        assert np.array_equal(got, want), m.name
        full = sample_street(chains, sky, framed, xw, dw, w, m)     # the sky along the world direction
        assert np.array_equal(full, composite(want, sample_sky(sky, dw, w, chains.xk))), m.name
