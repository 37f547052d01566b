"""The level-bias calibration (envcap.benchmarks.level_bias) and depth_refine's level_bias knob:
k = 1 is today's lookup bit for bit, k multiplies the power multiplier and nothing else, bad
factors fail with one line, and the fit / keep rules pick what a hand computation picks."""

import numpy as np
import pytest

from envcap.benchmarks.level_bias import choose_bias, helps_everywhere
from envcap.runtime.methods.depth_refine import depth_refine, inverse_distance
from envcap.runtime.parallax import exit_distance

PLANES = (-6.0, 9.0, 0.0)          # the +cross facade 3 m behind the lookup planes' +6


def _case():
    """A probe over a street whose +cross facade is set back (refined rays) and whose -cross one is
    where the planes say (kept rays); distances exact per texel centre of a 32^2 cube."""
    from envcap.core import cube
    p = np.array([10.0, 2.0, 0.0])
    dirs = cube.texel_directions(32).reshape(-1, 3)
    t = exit_distance(np.broadcast_to(p, dirs.shape), dirs, PLANES, 0)
    h = p + t[:, None] * dirs
    inv = inverse_distance(np.where((t < 1e5) & (h[:, 1] <= 12.0), t, 0.0).reshape(1, 6, 32, 32))
    rng = np.random.default_rng(3)
    x = np.c_[rng.uniform(8, 12, 500), rng.uniform(0.5, 3, 500), rng.uniform(-4, 4, 500)]
    d = rng.normal(size=(500, 3))
    return x, d / np.linalg.norm(d, axis=1, keepdims=True), p, inv


def test_level_bias_scales_q_only_and_one_is_identity():
    x, d, p, inv = _case()
    planes = (-6.0, 6.0, 0.0)
    r0, q0 = depth_refine(x, d, p, planes, 0, inv, 0)
    r1, q1 = depth_refine(x, d, p, planes, 0, inv, 0, level_bias=1.0)
    r2, q2 = depth_refine(x, d, p, planes, 0, inv, 0, level_bias=1.3)
    np.testing.assert_array_equal(r1, r0)
    np.testing.assert_array_equal(q1, q0)                    # bit for bit: today's lookup
    np.testing.assert_array_equal(r2, r0)                    # the hit does not move
    np.testing.assert_allclose(q2, 1.3 * q0, rtol=1e-15)    # every ray's power multiplier, refined or not
    assert q0.min() < q0.max()                               # a real mix of shifts, not a constant
    for bad in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(ValueError, match="level_bias"):
            depth_refine(x, d, p, planes, 0, inv, 0, level_bias=bad)


def test_fit_and_keep_rules():
    e = lambda one, k12, k14: {"1.0": one, "1.2": k12, "1.4": k14}
    fit = {"canyon": {"64": e(0.10, 0.08, 0.07), "1024": e(0.10, 0.10, 0.12)},
           "crossing": {"64": e(0.10, 0.09, 0.09), "1024": e(0.10, 0.10, 0.11)}}
    # mean ratios: 1.2 -> (0.8 + 1.0 + 0.9 + 1.0) / 4 = 0.925; 1.4 -> (0.7 + 1.2 + 0.9 + 1.1) / 4 = 0.975
    assert choose_bias(fit, [1.0, 1.2, 1.4]) == 1.2
    assert choose_bias({"a": {"64": e(0.1, 0.2, 0.3)}}, [1.4, 1.2, 1.0]) == 1.0
    assert not helps_everywhere(fit, 1.2)                    # 1024 does not improve
    assert helps_everywhere({"a": {"64": e(0.10, 0.09, 0.2)}, "b": {"256": e(0.2, 0.19, 0.1)}}, 1.2)
