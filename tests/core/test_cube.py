"""envcap.core.cube against hand-derived cases and float64 references."""

import numpy as np
import pytest

from envcap.core import cube


@pytest.mark.parametrize("n", [1, 2, 3, 16, 255, 256])
def test_solid_angles_sum_to_4pi(n):
    assert abs(cube.texel_solid_angles(n).sum() - 4 * np.pi) < 1e-12


def test_solid_angle_one_texel_face_is_a_sixth_of_the_sphere():
    np.testing.assert_allclose(cube.texel_solid_angles(1), 4 * np.pi / 6, rtol=0, atol=1e-15)


def test_solid_angle_matches_numerical_integral():
    # Independent reference: integrate dA / (1 + x^2 + y^2)^(3/2) over one texel with a fine midpoint rule.
    n, j, i = 4, 0, 1
    x0, x1 = -1 + 2 * i / n, -1 + 2 * (i + 1) / n
    y0, y1 = -1 + 2 * j / n, -1 + 2 * (j + 1) / n
    m = 2000
    xs = x0 + (np.arange(m) + 0.5) * (x1 - x0) / m
    ys = y0 + (np.arange(m) + 0.5) * (y1 - y0) / m
    X, Y = np.meshgrid(xs, ys)
    ref = np.sum((1 + X**2 + Y**2) ** -1.5) * (x1 - x0) * (y1 - y0) / m**2
    assert abs(cube.texel_solid_angles(n)[0, j, i] - ref) < 1e-8


def test_face_centers_point_along_axes():
    d = cube.texel_directions(1)[:, 0, 0]
    want = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    np.testing.assert_allclose(d, want, atol=1e-15)


def test_direction_round_trip_through_face_uv():
    d = cube.texel_directions(7)
    f, u, v = cube.direction_to_face_uv(d)
    back = cube.face_uv_to_direction(f, u, v)
    back /= np.linalg.norm(back, axis=-1, keepdims=True)
    np.testing.assert_allclose(back, d, atol=1e-14)
    np.testing.assert_array_equal(f, np.arange(6)[:, None, None] * np.ones((1, 7, 7), int))


def test_signed_zero_components_pick_the_same_face():
    for d in ([1.0, 0.0, -0.0], [1.0, -0.0, 0.0]):
        f, s, t = cube.direction_to_face_st(np.array(d))
        assert f == 0 and s == 0.5 and t == 0.5


@pytest.mark.parametrize("bad", [[0.0, 0.0, 0.0], [np.nan, 1, 0], [np.inf, 0, 0]])
def test_invalid_directions_raise(bad):
    with pytest.raises(ValueError):
        cube.direction_to_face_uv(np.array(bad))


def test_bad_sizes_raise():
    for n in (0, -1, 2.5, True):
        with pytest.raises(ValueError):
            cube.texel_directions(n)


def test_horizontal_cross_edges_are_continuous_outside_view():
    n = 8
    d = cube.texel_directions(n)
    cross = cube.horizontal_cross(d, inside=False)
    # +Z (middle row, column 1) right edge meets +X (column 2) left edge: neighbouring texels nearly equal.
    left = cross[n:2 * n, 2 * n - 1]
    right = cross[n:2 * n, 2 * n]
    assert np.max(np.linalg.norm(left - right, axis=-1)) < 2.5 / n
    top = cross[n - 1, n:2 * n]  # +Y bottom row over +Z top row
    below = cross[n, n:2 * n]
    assert np.max(np.linalg.norm(top - below, axis=-1)) < 2.5 / n
    inside = cube.horizontal_cross(d)
    np.testing.assert_array_equal(inside, cross[:, ::-1])
