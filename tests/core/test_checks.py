"""envcap.core.checks: the shared number, size, direction and table-key checkers."""

import math

import numpy as np
import pytest

from envcap.core.checks import (check_table_keys, finite_directions, finite_float, float_in_range, positive_int,
                                unit_directions)


def test_finite_float():
    assert finite_float(np.float32(2.5), "x") == 2.5 and type(finite_float(3, "x")) is float
    for bad, words in ((True, "x must be a number"), ("1", "x must be a number"), (None, "number"),
                       (float("nan"), "x must be finite"), (-math.inf, "finite")):
        with pytest.raises(ValueError, match=words):
            finite_float(bad, "x")


def test_float_in_range_is_closed_and_names_range_and_unit():
    assert float_in_range(0, "e", 0.0, 90.0) == 0.0 and float_in_range(np.float32(90), "e", 0.0, 90.0) == 90.0
    assert float_in_range(-360, "az", -360.0, 360.0, "degrees") == -360.0
    with pytest.raises(ValueError, match=r"^az must be in \[-360, 360\] degrees, got 360\.5$"):
        float_in_range(360.5, "az", -360.0, 360.0, "degrees")
    with pytest.raises(ValueError, match=r"^t must be in \[2, 10\], got 1\.99$"):
        float_in_range(1.99, "t", 2.0, 10.0)
    for bad in (math.nan, math.inf, True, "5"):
        with pytest.raises(ValueError, match="^t must be"):
            float_in_range(bad, "t", 2.0, 10.0)


def test_positive_int():
    assert positive_int(np.int64(7), "cube face size") == 7 and type(positive_int(np.int8(1), "n")) is int
    for bad in (0, -3, 2.0, True, "4", None):
        with pytest.raises(ValueError, match="cube face size must be a positive integer"):
            positive_int(bad, "cube face size")


def test_finite_directions_keeps_lengths_and_rejects_zero_and_nonfinite():
    d = np.array([[0.0, 3.0, 0.0], [1e-200, 0.0, 0.0], [-2.0, 1.0, 5.0]])
    out = finite_directions(d)
    np.testing.assert_array_equal(out, d)
    assert out.dtype == np.float64 and finite_directions([1, 2, 3]).shape == (3,)
    for bad, words in (([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], "zero-length"), ([1.0, np.nan, 0.0], "NaN or Inf"),
                       ([np.inf, 0.0, 0.0], "NaN or Inf"), (np.ones((4, 2)), r"shape \(\.\.\., 3\)")):
        with pytest.raises(ValueError, match=words):
            finite_directions(bad, "dirs")


def test_unit_directions_against_per_row_lengths():
    rng = np.random.default_rng(1)
    d = rng.normal(size=(50, 3)) * 10.0 ** rng.uniform(-100, 100, size=(50, 1))
    out = unit_directions(d)
    for row, u in zip(d, out):
        length = math.sqrt(math.fsum(float(c) ** 2 for c in row / np.abs(row).max())) * np.abs(row).max()
        np.testing.assert_allclose(u, row / length, rtol=1e-15, atol=1e-300)
    # zero, or a length float64 cannot hold: no direction can be normalized from these
    for bad in ([0.0, 0.0, 0.0], [1e-170, 0.0, 0.0], [1e170, 1e170, 0.0]):
        with pytest.raises(ValueError, match="zero-length"):
            unit_directions(bad)


def test_check_table_keys():
    check_table_keys({"a": 1, "b": 2}, {"a"}, ("b", "c"), "sky")
    with pytest.raises(ValueError, match=r"sky: unknown key\(s\) \['z'\]; allowed: \['a', 'b'\]"):
        check_table_keys({"a": 1, "z": 0}, {"a"}, {"b"}, "sky")
    with pytest.raises(ValueError, match=r"sky.sun: missing key\(s\) \['a'\]"):
        check_table_keys({"b": 1}, {"a"}, {"b"}, "sky.sun")
    with pytest.raises(ValueError, match="sky must be a table, got list"):
        check_table_keys([1], {"a"}, set(), "sky")
