"""envcap.core.latlong against hand-derived directions, float64 integrals, brute-force resampling and OpenEXR's exrenvmap."""

import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import OpenEXR
import OpenImageIO as oiio
import pytest
from PIL import Image

from envcap.core import cube
from envcap.core.latlong import (cube_texel_average, cube_to_latlong, direction_to_latlong_xy, latlong_box_average,
                                 latlong_directions, latlong_solid_angles, latlong_to_cube, load_latlong, read_latlong,
                                 sample_latlong)
from envcap.formats.ktx2 import read_ktx2


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


# --------------------------------------------------------------- large images: tiles, bands, box average

def _brute_force_box_average(img, n):
    # float64, every pixel at once: the solid-angle-weighted mean of the pixels whose centers fall
    # in each texel (np.add.at, no bands).
    h, w, c = img.shape
    f, t, s = cube.direction_to_texel(latlong_directions(h, w), n)
    omega = latlong_solid_angles(h, w)
    num = np.zeros((6, n, n, c))
    den = np.zeros((6, n, n))
    np.add.at(num, (f, t, s), img.astype(np.float64) * omega[..., None])
    np.add.at(den, (f, t, s), omega)
    return num / den[..., None], den


def _spot_image(h, w, seed=5):
    rng = np.random.default_rng(seed)
    img = rng.random((h, w, 3)).astype(np.float32)
    img[h // 3, w // 7] = [1e6, 5e5, 2e5]  # a one-pixel sun
    return img


@pytest.mark.parametrize("n", [8, 64])
def test_box_average_in_bands_equals_float64_brute_force(n):
    img = _spot_image(256, 512)
    with np.errstate(invalid="ignore"):
        ref, den = _brute_force_box_average(img, n)
    got = latlong_box_average(img, n, band_pixels=3000)  # 5 rows a band: 52 bands
    assert got.dtype == np.float32 and got.shape == (6, n, n, 3)
    full = den > 0
    np.testing.assert_allclose(got[full], ref[full], rtol=2e-7, atol=0)  # float32 rounding of the float64 sums
    # 512 pixels around the equator: 16 a texel at n = 8, none empty; 2 a texel at n = 64, where
    # some corner texels hold no pixel center and get the bilinear lookup at their center.
    f, t, s = np.nonzero(~full)
    assert (f.size == 0) == (n == 8)
    np.testing.assert_allclose(got[~full], sample_latlong(img, cube.texel_directions(n)[f, t, s]), rtol=1e-6)


def _brute_force_supersampled(img, n, ss):
    # Independent of cube_texel_average: per texel, ss x ss sub-sample centers, direction by the
    # face table of docs/conventions.md, bilinear lookup written out here, weights (1+u^2+v^2)^-1.5.
    h, w, c = img.shape
    a = img.astype(np.float64)
    out = np.zeros((6, n, n, c))
    sub = (np.arange(ss) + 0.5) / ss
    for f in range(6):
        for t in range(n):
            for s in range(n):
                uu, vv = np.meshgrid((s + sub) / n * 2 - 1, (t + sub) / n * 2 - 1)
                one = np.ones_like(uu)
                x, y, z = [(one, -vv, -uu), (-one, -vv, uu), (uu, one, vv), (uu, -one, -vv), (uu, -vv, one),
                           (-uu, -vv, -one)][f]
                r = np.sqrt(x * x + y * y + z * z)
                lat = np.arcsin(np.clip(y / r, -1, 1))
                lon = np.arctan2(x, z)
                px = (0.5 - lon / (2 * math.pi)) * w - 0.5
                py = np.clip((0.5 - lat / math.pi) * h - 0.5, 0, h - 1)
                x0 = np.floor(px)
                y0 = np.minimum(np.floor(py), h - 1)
                fx, fy = (px - x0)[..., None], (py - y0)[..., None]
                x0 = x0.astype(int) % w
                x1 = (x0 + 1) % w
                y0 = y0.astype(int)
                y1 = np.minimum(y0 + 1, h - 1)
                val = ((a[y0, x0] * (1 - fx) + a[y0, x1] * fx) * (1 - fy) + (a[y1, x0] * (1 - fx) + a[y1, x1] * fx) * fy)
                wgt = (1 + uu * uu + vv * vv) ** -1.5
                out[f, t, s] = np.einsum("ijc,ij->c", val, wgt) / wgt.sum()
    return out


def test_tiled_supersampling_equals_brute_force_and_does_not_depend_on_tiles():
    img = _spot_image(64, 128)
    n, ss = 8, 4
    ref = _brute_force_supersampled(img, n, ss)
    whole = cube_texel_average(lambda d: sample_latlong(img, d), n, ss, tile_texels=10**6)
    for tile in (1, 7, 100):  # one row of one face per tile; rows split across faces
        np.testing.assert_array_equal(cube_texel_average(lambda d: sample_latlong(img, d), n, ss, tile_texels=tile),
                                      whole)
    np.testing.assert_allclose(whole, ref, rtol=1e-9)
    np.testing.assert_array_equal(latlong_to_cube(img, n, ss), whole.astype(np.float32))


def test_latlong_to_cube_picks_box_for_images_finer_than_the_cube():
    fine = _spot_image(256, 512)
    for n in (1, 8, 32):  # 512 / (4 n) = 128, 16, 4 pixels a texel along the equator: box average
        np.testing.assert_array_equal(latlong_to_cube(fine, n), latlong_box_average(fine, n))
    # Below 4 pixels a texel: supersampled bilinear with the default ss = ceil(W / 4n) (unchanged).
    for n, ss in ((33, 4), (64, 2)):
        np.testing.assert_array_equal(latlong_to_cube(fine, n),
                                      cube_texel_average(lambda d: sample_latlong(fine, d), n, ss).astype(np.float32))
    # An explicit supersample is always honoured.
    np.testing.assert_array_equal(latlong_to_cube(fine, 4, supersample=2),
                                  cube_texel_average(lambda d: sample_latlong(fine, d), 4, 2).astype(np.float32))


def test_box_average_keeps_the_energy_of_a_one_pixel_sun():
    # A single bright pixel anywhere: sum over texels of L * Omega against the pixel's L * omega.
    # The box average moves it whole into one texel (error: that texel's pixel-vs-texel area
    # mismatch, a few %); 16 x 16 bilinear lookups a texel (the old default at 16 pixels a texel)
    # weighed it by where lookups happened to fall: errors of 100 % and more.
    h, w, n = 256, 512, 8
    omega = latlong_solid_angles(h, w)
    rng = np.random.default_rng(11)
    box_err, ss_err = [], []
    for _ in range(12):
        img = np.zeros((h, w, 1), np.float32)
        y, x = rng.integers(0, h), rng.integers(0, w)
        img[y, x] = 1.0
        for out, c in ((box_err, latlong_to_cube(img, n)), (ss_err, latlong_to_cube(img, n, supersample=16))):
            out.append(abs(np.sum(c[..., 0].astype(np.float64) * cube.texel_solid_angles(n)) / omega[y, x] - 1))
    assert max(box_err) < 0.08 and max(ss_err) > 0.5, (max(box_err), max(ss_err))


# ------------------------------------------------------------------------- reading: LDR, bands, tiles

def test_ldr_png_is_decoded_from_srgb_with_one_warning_line(tmp_path, capfd):
    px = np.zeros((8, 16, 3), np.uint8)
    px[..., 0], px[..., 1], px[..., 2] = 128, 255, 10
    Image.fromarray(px).save(tmp_path / "sky.png")
    img = load_latlong(tmp_path / "sky.png")
    # IEC 61966-2-1: ((128/255 + 0.055) / 1.055)^2.4 = 0.2158605; 255 -> 1; 10/255 <= 0.04045 -> /12.92.
    np.testing.assert_allclose(img[..., 0], 0.2158605, rtol=1e-6)
    np.testing.assert_allclose(img[..., 1], 1.0, rtol=1e-7)
    np.testing.assert_allclose(img[..., 2], 10 / 255 / 12.92, rtol=1e-6)
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "sky.png" in err[0] and "sRGB" in err[0] and "uint8" in err[0], err
    _write_exr(tmp_path / "sky.exr", np.full((8, 16, 3), 0.5, np.float32))
    np.testing.assert_array_equal(load_latlong(tmp_path / "sky.exr"), 0.5)  # HDR: as stored, no warning
    assert capfd.readouterr().err == ""


def test_bands_and_tiles_read_the_same_pixels_and_find_the_first_bad_one(tmp_path):
    h, w = 768, 1536  # 1.18 M pixels: two bands of 682 rows (BAND_PIXELS = 2^20)
    rgb = np.random.default_rng(7).random((h, w, 3)).astype(np.float32)
    _write_exr(tmp_path / "scan.exr", rgb)
    np.testing.assert_array_equal(load_latlong(tmp_path / "scan.exr"), rgb)
    spec = oiio.ImageSpec(w, h, 3, "float")
    spec.tile_width = spec.tile_height = 64
    out = oiio.ImageOutput.create(str(tmp_path / "tiled.exr"))
    assert out.open(str(tmp_path / "tiled.exr"), spec) and out.write_image(rgb)
    out.close()
    np.testing.assert_array_equal(load_latlong(tmp_path / "tiled.exr"), rgb)
    rgb[700, 3, 1] = -1.0  # second band only
    rgb[750, 9, 0] = np.inf
    _write_exr(tmp_path / "bad.exr", rgb)
    with pytest.raises(ValueError, match=r"bad.exr has 2 bad texel\(s\) \(1 with NaN/Inf, the rest negative\); "
                                         r"first at pixel \(x=3, y=700\)"):
        load_latlong(tmp_path / "bad.exr")


def test_truncated_exr_is_one_line_naming_the_file(tmp_path, capfd):
    _write_exr(tmp_path / "ok.exr", np.random.default_rng(1).random((64, 128, 3)))
    data = (tmp_path / "ok.exr").read_bytes()
    (tmp_path / "cut.exr").write_bytes(data[: len(data) * 2 // 3])
    (tmp_path / "tiny.exr").write_bytes(data[:40])
    for name in ("cut.exr", "tiny.exr"):
        with pytest.raises(ValueError) as e:
            load_latlong(tmp_path / name)
        assert name in str(e.value) and "\n" not in str(e.value), str(e.value)
    assert capfd.readouterr().err == ""


def test_prefilter_of_a_png_uses_linear_radiance_and_warns_once(tmp_path):
    # Issue 9: a PNG given to `envcap prefilter` was read as linear (sRGB 128 -> 0.502).
    Image.fromarray(np.full((16, 32, 3), 128, np.uint8)).save(tmp_path / "sky.png")
    r = subprocess.run([sys.executable, "-m", "envcap", "prefilter", str(tmp_path / "sky.png"), "--out",
                        str(tmp_path / "o"), "--size", "4", "--quality", "fast"], capture_output=True, text=True,
                       timeout=120, cwd=Path(__file__).resolve().parents[2])
    assert r.returncode == 0, r.stderr
    err = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith("envcap: warning: ") and "sRGB" in err[0], r.stderr
    levels, _ = read_ktx2(tmp_path / "o" / "chain.ktx2")
    np.testing.assert_allclose(levels[0][..., :3], 0.2158605, rtol=1e-6)
