"""envcap.latlong against hand-derived directions, float64 integrals, and OpenEXR's exrenvmap."""

import math
import shutil
import subprocess

import numpy as np
import OpenEXR
import pytest

from envcap.core import cube
from envcap.core.latlong import (cube_texel_average, cube_to_latlong, direction_to_latlong_xy, latlong_directions,
                            latlong_solid_angles, latlong_to_cube, load_latlong, read_latlong, sample_latlong)


@pytest.mark.parametrize("h,w", [(1, 2), (2, 4), (3, 6), (64, 128), (1000, 2000), (7, 3)])
def test_solid_angles_sum_to_4pi(h, w):
    assert abs(latlong_solid_angles(h, w).sum() - 4 * math.pi) < 1e-12


def test_solid_angle_of_a_pixel_matches_brute_force_integral():
    # Independent reference: midpoint rule of cos(lat) dlat dlon over pixel (x=3, y=5) of a 16x32 map.
    h, w, y = 16, 32, 5
    lat0, lat1 = math.pi / 2 - y * math.pi / h, math.pi / 2 - (y + 1) * math.pi / h
    m = 100000
    lat = lat1 + (np.arange(m) + 0.5) * (lat0 - lat1) / m
    ref = np.sum(np.cos(lat)) * (lat0 - lat1) / m * (2 * math.pi / w)
    assert abs(latlong_solid_angles(h, w)[y, 3] - ref) < 1e-12


def test_hand_derived_directions():
    # 2 x 4 map, texel centers: lon = -2 pi (u - 1/2) with u = 1/8, 3/8, 5/8, 7/8 -> 3pi/4, pi/4, -pi/4, -3pi/4.
    # lat = -pi (v - 1/2), v = 1/4, 3/4 -> +pi/4, -pi/4.
    d = latlong_directions(2, 4)
    s = math.sqrt(0.5)
    # top row, column 1: lat pi/4, lon pi/4 -> (sin lon cos lat, sin lat, cos lon cos lat) = (1/2, s, 1/2)
    np.testing.assert_allclose(d[0, 1], [0.5, s, 0.5], atol=1e-15)
    # bottom row, column 3: lat -pi/4, lon -3pi/4 -> (-1/2, -s, -1/2)
    np.testing.assert_allclose(d[1, 3], [-0.5, -s, -0.5], atol=1e-15)
    # Odd width/height: the middle pixel is exactly +Z; top row of a tall map is near +Y.
    e = latlong_directions(3, 5)
    np.testing.assert_allclose(e[1, 2], [0, 0, 1], atol=1e-15)
    # OpenEXR edge positions: row 0 is exactly +Y, the left column is lon = +pi (-Z), right column -pi.
    g = latlong_directions(5, 10, centers=False)
    np.testing.assert_allclose(g[0], np.broadcast_to([0, 1, 0], (10, 3)), atol=1e-15)
    np.testing.assert_allclose(g[2, 0], [0, 0, -1], atol=1e-15)
    # +X (lon = +pi/2) lies left of the middle: u = 1/4.
    np.testing.assert_allclose(latlong_directions(2, 4, centers=False)[0, 0], [0, 1, 0], atol=1e-15)
    x, y = direction_to_latlong_xy(np.array([1.0, 0, 0]), 10, 20)
    assert (float(x), float(y)) == pytest.approx((0.25 * 20 - 0.5, 0.5 * 10 - 0.5))


def test_direction_pixel_round_trip():
    h, w = 37, 74
    d = latlong_directions(h, w)
    x, y = direction_to_latlong_xy(d, h, w)
    X, Y = np.meshgrid(np.arange(w), np.arange(h))
    np.testing.assert_allclose(x, X, atol=1e-9)
    np.testing.assert_allclose(y, Y, atol=1e-9)


def test_poles_and_seam_are_finite_and_bad_directions_rejected():
    x, y = direction_to_latlong_xy(np.array([[0, 1, 0], [0, -1e-300, 0], [0, 0, -1], [-0.0, 0, -1]]), 4, 8)
    assert np.all(np.isfinite(x)) and np.all(np.isfinite(y))
    assert y[0] == -0.5 and y[1] == 3.5
    for bad in ([0, 0, 0], [np.nan, 0, 1], [np.inf, 0, 0]):
        with pytest.raises(ValueError):
            direction_to_latlong_xy(np.array(bad, float), 4, 8)
    for h, w in ((0, 2), (2, -1), (2.5, 5)):
        with pytest.raises(ValueError):
            latlong_solid_angles(h, w)


def test_sample_latlong_is_exact_at_centers_and_wraps_longitude():
    rng = np.random.default_rng(3)
    img = rng.random((8, 16, 2))
    d = latlong_directions(8, 16)
    np.testing.assert_allclose(sample_latlong(img, d), img, atol=1e-12)
    # Halfway between the last and the first column (lon = -pi = +pi, i.e. -Z): average of both.
    lat = -math.pi * ((2 + 0.5) / 8 - 0.5)
    seam = np.array([0.0, math.sin(lat), -math.cos(lat)])
    np.testing.assert_allclose(sample_latlong(img, seam), 0.5 * (img[2, 0] + img[2, 15]), atol=1e-12)
    # A linear function of direction is reproduced within bilinear error; poles clamp (finite).
    v = sample_latlong(img, np.array([[0, 1, 0], [0, -1, 0]]))
    assert np.all(np.isfinite(v))


def test_latlong_to_cube_preserves_constant_and_mean_radiance():
    # Texel averages: a constant map gives the constant; the solid-angle integral of a smooth map
    # (L = 1 + y, whose integral over the sphere is 4 pi) is preserved.
    h, w = 64, 128
    d = latlong_directions(h, w)
    img = np.concatenate([np.full((h, w, 1), 2.5), 1.0 + d[..., 1:2]], axis=-1)
    c = latlong_to_cube(img, 8)
    assert c.shape == (6, 8, 8, 2) and c.dtype == np.float32
    np.testing.assert_allclose(c[..., 0], 2.5, rtol=1e-6)
    integral = np.sum(c[..., 1].astype(np.float64) * cube.texel_solid_angles(8))
    assert abs(integral - 4 * math.pi) < 2e-3 * 4 * math.pi
    one = latlong_to_cube(img, 1)
    assert one.shape == (6, 1, 1, 2)
    np.testing.assert_allclose(one[..., 0], 2.5, rtol=1e-6)
    # One texel per face: +Y holds more than 1, -Y less, the side faces about 1 (symmetry).
    assert one[2, 0, 0, 1] > 1.5 and one[3, 0, 0, 1] < 0.5
    np.testing.assert_allclose(one[[0, 1, 4, 5], 0, 0, 1], 1.0, atol=1e-3)


def test_cube_texel_average_matches_exact_integral_of_y():
    # Hand-derived: over the +Y face (plane y = 1, |x|, |z| <= 1), integral of cos(theta) d(omega)
    # = integral dA / (1 + x^2 + z^2)^2 = 4 * 2 * (1 / (2 sqrt 2)) atan(1 / sqrt 2) = 2 sqrt(2) atan(1/sqrt 2);
    # the face's solid angle is 4 pi / 6, so the mean of y over the face is their ratio (0.83119).
    ref = 2 * math.sqrt(2) * math.atan(1 / math.sqrt(2)) / (4 * math.pi / 6)
    got = cube_texel_average(lambda d: d[..., 1:2], 1, supersample=64)
    assert abs(got[2, 0, 0, 0] - ref) < 1e-5
    assert abs(got[3, 0, 0, 0] + ref) < 1e-5
    np.testing.assert_allclose(got[[0, 1, 4, 5], 0, 0, 0], 0.0, atol=1e-12)


def test_cube_to_latlong_of_a_face_index_cube():
    n = 8
    c = np.broadcast_to(np.arange(6, dtype=np.float32)[:, None, None, None], (6, n, n, 1))
    ll = cube_to_latlong(c, 32, 64)
    fc, u, v = cube.direction_to_face_uv(latlong_directions(32, 64))
    inner = (np.abs(u) < 1) & (np.abs(v) < 1)
    np.testing.assert_array_equal(ll[..., 0][inner], fc[inner])


@pytest.mark.skipif(shutil.which("exrenvmap") is None, reason="OpenEXR's exrenvmap not installed")
def test_latlong_convention_agrees_with_exrenvmap_cube_face_centers(tmp_path):
    # A lat-long EXR whose pixels hold their own direction; exrenvmap turns it into an OpenEXR cube
    # (faces stacked +X,-X,+Y,-Y,+Z,-Z).  With an odd face size the middle pixel of each face is
    # its center, i.e. the face's axis whatever the per-face orientation.
    h, w, n = 64, 128, 33
    d = latlong_directions(h, w, centers=False).astype(np.float32)
    rgba = np.concatenate([d, np.ones((h, w, 1), np.float32)], -1)
    hdr = {"compression": OpenEXR.NO_COMPRESSION, "type": OpenEXR.scanlineimage, "envmap": OpenEXR.ENVMAP_LATLONG}
    OpenEXR.File(hdr, {"RGBA": rgba}).write(str(tmp_path / "ll.exr"))
    subprocess.run(["exrenvmap", "-c", "-li", "-w", str(n), "-z", "none", str(tmp_path / "ll.exr"),
                    str(tmp_path / "cube.exr")], check=True, capture_output=True)
    px = OpenEXR.File(str(tmp_path / "cube.exr")).channels()["RGBA"].pixels
    assert px.shape[:2] == (6 * n, n)
    axes = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    for f in range(6):
        got = px[f * n + n // 2, n // 2, :3].astype(np.float64)
        assert np.dot(got / np.linalg.norm(got), axes[f]) > 0.9999, (cube.FACE_NAMES[f], got)


@pytest.mark.skipif(shutil.which("exrenvmap") is None, reason="OpenEXR's exrenvmap not installed")
def test_every_exrenvmap_latlong_pixel_is_where_our_directions_say(tmp_path):
    # A cube whose faces are constant (= face index) needs no per-face orientation.  exrenvmap writes
    # the lat-long map; every pixel must hold the face that contains OUR direction for that pixel
    # (OpenEXR's edge-to-edge positions, centers=False).  Texel-center positions would not match.
    n = 33
    cb = np.zeros((6 * n, n, 4), np.float32)
    for k in range(6):
        cb[k * n:(k + 1) * n] = [k, 0, 0, 1]
    hdr = {"compression": OpenEXR.NO_COMPRESSION, "type": OpenEXR.scanlineimage, "envmap": OpenEXR.ENVMAP_CUBE}
    OpenEXR.File(hdr, {"RGBA": cb}).write(str(tmp_path / "c.exr"))
    subprocess.run(["exrenvmap", "-l", "-ci", "-w", "128", "-f", "0.01", "1", "-z", "none", str(tmp_path / "c.exr"),
                    str(tmp_path / "ll.exr")], check=True, capture_output=True)
    ll = OpenEXR.File(str(tmp_path / "ll.exr")).channels()["RGBA"].pixels[..., 0]
    assert ll.shape == (64, 128)
    face, _, _ = cube.direction_to_face_uv(latlong_directions(64, 128, centers=False))
    np.testing.assert_array_equal(ll, face)
    face_c, _, _ = cube.direction_to_face_uv(latlong_directions(64, 128, centers=True))
    assert np.any(ll != face_c)


def _write_exr(path, rgb):
    h, w, _ = rgb.shape
    rgba = np.concatenate([rgb.astype(np.float32), np.ones((h, w, 1), np.float32)], -1)
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                 {"RGBA": rgba}).write(str(path))


def test_load_latlong_reads_real_exr(tmp_path):
    rgb = np.random.default_rng(0).random((8, 16, 3)).astype(np.float32) * 1e4
    _write_exr(tmp_path / "sky.exr", rgb)
    img = load_latlong(tmp_path / "sky.exr")
    assert img.shape == (8, 16, 3) and img.dtype == np.float32
    np.testing.assert_array_equal(img, rgb)


def test_load_latlong_rejects_nan_with_count_and_first_pixel_or_sanitizes(tmp_path):
    rgb = np.ones((8, 16, 3), np.float32)
    rgb[2, 5, 1] = np.nan
    rgb[6, 1, 0] = np.inf
    _write_exr(tmp_path / "bad.exr", rgb)
    with pytest.raises(ValueError, match=r"bad.exr has 2 bad texel.*x=5, y=2"):
        load_latlong(tmp_path / "bad.exr")
    img, count = read_latlong(tmp_path / "bad.exr", sanitize=True)
    assert count == 2 and np.all(np.isfinite(img))
    assert img[2, 5, 1] == 0 and img[6, 1, 0] == 0 and img[2, 5, 0] == 1


def test_load_latlong_errors_name_the_problem(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.exr"):
        load_latlong(tmp_path / "nope.exr")
    (tmp_path / "junk.exr").write_bytes(b"not an image at all")
    with pytest.raises(ValueError, match="junk.exr"):
        load_latlong(tmp_path / "junk.exr")
    _write_exr(tmp_path / "square.exr", np.ones((8, 8, 3)))
    with pytest.raises(ValueError, match="2:1"):
        load_latlong(tmp_path / "square.exr")
    OpenEXR.File({"type": OpenEXR.scanlineimage}, {"Y": np.ones((4, 8), np.float32)}).write(str(tmp_path / "y.exr"))
    with pytest.raises(ValueError, match="channel"):
        load_latlong(tmp_path / "y.exr")
