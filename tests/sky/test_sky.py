"""envcap.sky: Preetham against the paper's formulas evaluated by hand (scalar math written here from
the paper, not from the module), sun energy conservation against the exact cube solid angles,
float32 safety, below-horizon rule, specs and bad inputs."""

import json
import math

import numpy as np
import OpenEXR
import pytest
from gl_sampling import SAMPLE_CUBE, sample_with_gl

from envcap.core import cube
from envcap.core.latlong import latlong_directions, latlong_solid_angles
from envcap.sky import (PreethamSky, Sun, UniformSky, direction_from_angles, preetham_sun, sky_from_spec,
                        splat_sun)

# sRGB / Rec.709 (D65) linear RGB -> XYZ, IEC 61966-2-1 (the inverse of the module's XYZ -> RGB).
RGB_TO_XYZ = np.array([[0.4124564, 0.3575761, 0.1804375],
                       [0.2126729, 0.7151522, 0.0721750],
                       [0.0193339, 0.1191920, 0.9503041]])


def _xyY(rgb):
    X, Y, Z = RGB_TO_XYZ @ np.asarray(rgb, float)
    return X / (X + Y + Z), Y / (X + Y + Z), Y


def _paper_zenith(T, ts):
    """Preetham et al. 1999, appendix A.2, written out term by term."""
    chi = (4 / 9 - T / 120) * (math.pi - 2 * ts)
    Yz = ((4.0453 * T - 4.9710) * math.tan(chi) - 0.2155 * T + 2.4192) * 1000  # kcd/m^2 -> cd/m^2
    xz = (T * T * (0.00166 * ts ** 3 - 0.00375 * ts ** 2 + 0.00209 * ts)
          + T * (-0.02903 * ts ** 3 + 0.06377 * ts ** 2 - 0.03202 * ts + 0.00394)
          + (0.11693 * ts ** 3 - 0.21196 * ts ** 2 + 0.06052 * ts + 0.25886))
    yz = (T * T * (0.00275 * ts ** 3 - 0.00610 * ts ** 2 + 0.00317 * ts)
          + T * (-0.04214 * ts ** 3 + 0.08970 * ts ** 2 - 0.04153 * ts + 0.00516)
          + (0.15346 * ts ** 3 - 0.26756 * ts ** 2 + 0.06670 * ts + 0.26688))
    return Yz, xz, yz


def test_paper_zenith_luminance_hand_values():
    # Hand evaluation, T = 2, sun at the zenith: chi = (4/9 - 1/60) pi = 1.343890 rad,
    # tan(chi) = cot(pi/2 - chi) = cot(0.226906) = 1 / (0.226906 + 0.226906^3/3 + 2 * 0.226906^5/15) = 4.3313;
    # Yz = (3.1196 * 4.3313 - 0.431 + 2.4192) kcd/m^2 = 15.50 kcd/m^2.  Sun on the horizon: chi = 0,
    # Yz = (-0.2155 T + 2.4192) kcd/m^2, i.e. 1.9882 (T=2) and 0.2642 (T=10).
    assert _paper_zenith(2, 0)[0] == pytest.approx(15_500.7, rel=2e-4)
    assert _paper_zenith(2, math.pi / 2)[0] == pytest.approx(1988.2, rel=1e-9)
    assert _paper_zenith(10, math.pi / 2)[0] == pytest.approx(264.2, rel=1e-9)


@pytest.mark.parametrize("T", [2, 3, 4, 6, 8, 10])
@pytest.mark.parametrize("elev", [0, 10, 35, 60, 90])
def test_zenith_radiance_is_paper_zenith_luminance_and_chromaticity(T, elev):
    # The Perez ratio F(0, ts) / F(0, ts) is 1 at the zenith: the zenith radiance must carry exactly
    # the paper's (Y_z, x_z, y_z), through xyY -> XYZ -> RGB.
    sky = PreethamSky(T, elev, 77.0)
    x, y, Y = _xyY(sky.radiance(np.array([0.0, 1.0, 0.0])))
    Yz, xz, yz = _paper_zenith(T, math.radians(90 - elev))
    assert Y == pytest.approx(Yz, rel=1e-6)
    assert x == pytest.approx(xz, abs=1e-6)
    assert y == pytest.approx(yz, abs=1e-6)


def _lum(sky, elev, az):
    return float(RGB_TO_XYZ[1] @ sky.radiance(direction_from_angles(elev, az)))


@pytest.mark.parametrize("T", [2, 3, 6, 10])
@pytest.mark.parametrize("elev", [10, 35, 60])
def test_perez_brighter_near_the_sun(T, elev):
    sky = PreethamSky(T, elev, 40.0)
    near = _lum(sky, elev + 5, 40.0)
    assert near > _lum(sky, elev, 40.0 + 90) and near > _lum(sky, elev, 40.0 + 180)
    assert near > _lum(sky, 90, 0)


@pytest.mark.parametrize("T", [2, 3])
def test_clear_sky_horizon_brightening(T):
    sky = PreethamSky(T, 35, 0.0)
    for az in (90, 180):
        assert _lum(sky, 2, az) > _lum(sky, 30, az) > 0


def test_sun_direction_and_azimuth_convention():
    np.testing.assert_allclose(direction_from_angles(0, 0), [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(direction_from_angles(0, 90), [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(direction_from_angles(90, 123), [0, 1, 0], atol=1e-15)
    sky = PreethamSky(3, 35, 120)
    np.testing.assert_allclose(sky.sun.direction, direction_from_angles(35, 120))
    assert sky.sun.elevation_deg == pytest.approx(35) and sky.sun.azimuth_deg == pytest.approx(120)
    # The brightest texel of the cube holds the sun.
    c = sky.cube(16, supersample=1)
    f, r, col = np.unravel_index(np.argmax(c[..., 1]), c.shape[:3])
    assert (f, r, col) == tuple(int(v) for v in cube.direction_to_texel(sky.sun.direction, 16))


def test_preetham_sun_hand_value():
    # T = 3, sun at the zenith: m = 1 / (1 + 0.15 * 93.885^-1.253) = 0.99917; beta = 0.04608*3 - 0.04586.
    # Green (550 nm): tau = exp(-m (0.008735 * 0.55^-4.08 + beta * 0.55^-1.3)); E = 128000 tau.
    m = 1 / (1 + 0.15 * 93.885 ** -1.253)
    beta = 0.04608 * 3 - 0.04586
    tau = math.exp(-m * (0.008735 * 0.55 ** -4.08 + beta * 0.55 ** -1.3))
    sun = preetham_sun(3, 90, 0)
    assert sun.illuminance[1] == pytest.approx(128000 * tau, rel=1e-9)
    assert 70_000 < sun.illuminance[1] < 110_000  # clear-sky direct normal illuminance, order of magnitude
    # Redder at low elevation: more blue is lost through the longer air mass.
    low = preetham_sun(3, 5, 0)
    assert low.illuminance[2] / low.illuminance[0] < sun.illuminance[2] / sun.illuminance[0]
    # Disk radiance = E / (2 pi (1 - cos r)), r = 0.2665 deg.
    omega = 2 * math.pi * (1 - math.cos(math.radians(0.2665)))
    np.testing.assert_allclose(sun.radiance * omega, sun.illuminance, rtol=1e-9)


@pytest.mark.parametrize("n", [1, 2, 7, 64, 256])
@pytest.mark.parametrize("direction", [(0.3, 0.8, -0.5), (1, 1, 1), (0, 1, 0), (1, 0, 1e-9), (-0.2, 0.05, 1)])
def test_sun_splat_conserves_energy_in_float32(n, direction):
    # Independent reference: the exact texel solid angles of envcap.core.cube; the stored float32 cube
    # minus the sun-less cube, integrated, must equal the sun's illuminance at any resolution.
    sun = Sun.from_illuminance(np.array(direction, float), [95_000.0, 90_000.0, 70_000.0])
    sky = UniformSky([1000.0, 2000.0, 3000.0], sun)
    with_sun = sky.cube(n).astype(np.float64)
    without = sky.cube(n, include_sun=False).astype(np.float64)
    omega = cube.texel_solid_angles(n)[..., None]
    got = np.sum((with_sun - without) * omega, axis=(0, 1, 2))
    np.testing.assert_allclose(got, sun.illuminance, rtol=1e-6)
    total = np.sum(with_sun * omega, axis=(0, 1, 2))
    np.testing.assert_allclose(total, 4 * math.pi * np.array([1000, 2000, 3000]) + sun.illuminance, rtol=1e-6)


def test_sun_beyond_half_float_is_finite_in_float32_cube():
    sky = PreethamSky(2, 90, 0)
    assert np.all(sky.sun.illuminance > 65504) and np.all(sky.sun.radiance > 1e8)
    for n in (1, 256):
        c = sky.cube(n, supersample=1)
        assert c.dtype == np.float32 and np.all(np.isfinite(c))
        assert c.max() > 65504  # the sun is there, not clipped to half range
    # At 256^2 the disk (6.8e-5 sr) is about one texel: the peak is within a factor ~4 of the disk radiance.
    assert sky.sun.radiance[1] / 4 < c[..., 1].max() < sky.sun.radiance[1] * 4


def test_splat_centroid_is_the_sun_direction():
    sun = Sun.from_illuminance(direction_from_angles(20, 200), 1e5)
    n = 1024
    s = splat_sun(sun, n)
    nz = np.nonzero(s[..., 1])
    omega = cube.texel_solid_angles(n)[0][nz[1:]]  # every face has the same solid angles
    u = (nz[2] + 0.5) / n * 2 - 1
    v = (nz[1] + 0.5) / n * 2 - 1
    d = cube.face_uv_to_direction(nz[0], u, v)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    c = np.sum(d * (s[..., 1][nz] * omega)[:, None], axis=0)
    assert np.degrees(np.arccos(np.dot(c / np.linalg.norm(c), sun.direction))) < 0.01
    assert len(nz[0]) > 10  # the disk covers many texels at this size


@pytest.mark.parametrize("T,elev", [(2, 0), (2, 90), (10, 0), (10, 90), (3, 35)])
def test_radiance_finite_everywhere_and_ground_rule(T, elev):
    sky = PreethamSky(T, elev, 33)
    rng = np.random.default_rng(5)
    d = np.concatenate([rng.normal(size=(20000, 3)), [[0, 1, 0], [0, -1, 0], [1, 0, 0], [0, 0, -1], [1, -1e-300, 0]],
                        [sky.sun.direction, -sky.sun.direction], latlong_directions(32, 64).reshape(-1, 3)])
    r = sky.radiance(d)
    assert r.shape == d.shape and np.all(np.isfinite(r)) and np.all(r >= 0)
    below = d[:, 1] < 0
    np.testing.assert_array_equal(r[below], np.broadcast_to(sky.ground_radiance, r[below].shape))
    # Ground = albedo * E_h / pi, E_h from an independent lat-long quadrature of the upper dome + the sun.
    h, w = 256, 512
    dl = latlong_directions(h, w)
    up = dl[..., 1] > 0
    E = np.einsum("ijc,ij->c", sky.radiance(dl) * up[..., None], latlong_solid_angles(h, w) * dl[..., 1])
    E = E + sky.sun.illuminance * math.sin(math.radians(elev))
    np.testing.assert_allclose(sky.ground_radiance, 0.2 * E / math.pi, rtol=2e-3)


@pytest.mark.parametrize("kwargs,match", [
    (dict(turbidity=1.9, sun_elevation_deg=30), "turbidity"),
    (dict(turbidity=10.5, sun_elevation_deg=30), "turbidity"),
    (dict(turbidity=float("nan"), sun_elevation_deg=30), "turbidity"),
    (dict(turbidity=3, sun_elevation_deg=-0.1), "elevation"),
    (dict(turbidity=3, sun_elevation_deg=90.5), "elevation"),
    (dict(turbidity=3, sun_elevation_deg=float("inf")), "elevation"),
    (dict(turbidity=3, sun_elevation_deg=30, scale=-1), "scale"),
    (dict(turbidity=3, sun_elevation_deg=30, ground_albedo=2), "albedo"),
])
def test_invalid_preetham_parameters_rejected(kwargs, match):
    with pytest.raises(ValueError, match=match):
        PreethamSky(**kwargs)


def test_bad_directions_rejected():
    sky = UniformSky(1.0)
    for bad in ([0, 0, 0], [np.nan, 1, 0], [np.inf, 0, 0]):
        with pytest.raises(ValueError):
            sky.radiance(np.array(bad, float))
    with pytest.raises(ValueError):
        sky.cube(0)


@pytest.mark.parametrize("spec,match", [
    ({"type": "hosek"}, "unknown type 'hosek'"),
    ({"type": "preetham", "turbidity": 3, "sun_elevation_deg": 30, "sun_azimuth": 1}, r"unknown key.*sun_azimuth"),
    ({"type": "preetham", "turbidity": 3}, r"missing key.*sun_elevation_deg"),
    ({"type": "uniform", "radiance": [1, 2]}, "radiance"),
    ({"type": "uniform", "radiance": [1, -2, 3]}, "non-negative"),
    ({"type": "uniform", "radiance": 1, "sun": {"elevation_deg": 10, "illuminance": 1, "size": 2}}, r"sky.sun.*size"),
    ({"type": "uniform", "radiance": 1, "sun": {"elevation_deg": 100, "illuminance": 1}}, "elevation"),
    ({"type": "uniform", "radiance": 1, "sun": {"elevation_deg": 10, "illuminance": float("inf")}}, "illuminance"),
    ({"type": "latlong"}, r"missing key.*file"),
    ({"type": "preetham", "turbidity": "3", "sun_elevation_deg": 30}, "turbidity"),
    ("preetham", "table"),
])
def test_bad_specs_rejected_with_named_problem(spec, match):
    with pytest.raises(ValueError, match=match):
        sky_from_spec(spec)


def test_spec_round_trip_is_json_and_sun_light_is_checked():
    for spec in ({"type": "preetham", "turbidity": 3.0, "sun_elevation_deg": 35, "sun_azimuth_deg": 120, "scale": 0.5},
                 {"type": "uniform", "radiance": [1, 2, 3],
                  "sun": {"elevation_deg": 40, "azimuth_deg": 10, "illuminance": [9e4, 8e4, 7e4]}},
                 {"type": "uniform", "radiance": 0.5}):
        sky = sky_from_spec(spec)
        out = json.loads(json.dumps(sky.spec()))
        again = sky_from_spec(out)
        assert again.spec() == out
    out = sky_from_spec({"type": "preetham", "turbidity": 3.0, "sun_elevation_deg": 35}).spec()
    assert out["sun_light"]["illuminance"][1] == pytest.approx(out["sun_light"]["radiance"][1] *
                                                               2 * math.pi * (1 - math.cos(math.radians(0.2665))))
    out["sun_light"]["illuminance"] = [1, 1, 1]
    with pytest.raises(ValueError, match="sun_light"):
        sky_from_spec(out)


def _write_exr(path, rgb):
    h, w, _ = rgb.shape
    rgba = np.concatenate([rgb.astype(np.float32), np.ones((h, w, 1), np.float32)], -1)
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, {"RGBA": rgba}).write(str(path))


def test_latlong_sky_from_file_with_analytic_sun(tmp_path):
    h, w = 16, 32
    rgb = np.zeros((h, w, 3), np.float32)
    rgb[: h // 2] = [100, 200, 400]  # sky above, dark ground below
    _write_exr(tmp_path / "sky.exr", rgb)
    spec = {"type": "latlong", "file": "sky.exr", "scale": 2.0,
            "sun": {"elevation_deg": 30, "azimuth_deg": 90, "illuminance": 1e5}}
    sky = sky_from_spec(spec, base_dir=tmp_path)
    np.testing.assert_allclose(sky.radiance(np.array([0, 1, 0.0])), [200, 400, 800])
    np.testing.assert_allclose(sky.radiance(np.array([0, -1, 0.0])), 0)
    n = 8
    c = sky.cube(n).astype(np.float64)
    omega = cube.texel_solid_angles(n)[..., None]
    # Upper half 2 pi * radiance, plus the sun, integrated over the stored float32 cube.
    np.testing.assert_allclose(np.sum(c * omega, axis=(0, 1, 2)),
                               2 * math.pi * np.array([200, 400, 800]) + 1e5, rtol=2e-3)
    assert sky.spec()["file"] == "sky.exr" and sky_from_spec(sky.spec(), tmp_path).spec() == sky.spec()


def test_latlong_sky_file_with_nan_rejected_with_clear_message(tmp_path):
    rgb = np.ones((8, 16, 3), np.float32)
    rgb[3, 7, 2] = np.nan
    _write_exr(tmp_path / "nan.exr", rgb)
    with pytest.raises(ValueError, match=r"nan.exr has 1 bad texel.*x=7, y=3"):
        sky_from_spec({"type": "latlong", "file": "nan.exr"}, base_dir=tmp_path)
    sky = sky_from_spec({"type": "latlong", "file": "nan.exr", "sanitize": True}, base_dir=tmp_path)
    assert np.all(np.isfinite(sky.cube(2)))
    with pytest.raises(FileNotFoundError, match="missing.exr"):
        sky_from_spec({"type": "latlong", "file": "missing.exr"}, base_dir=tmp_path)


def test_sky_cube_uploads_as_is_and_gl_returns_the_sun_unclipped(gl_ctx):
    # The GL sampler as reference: the float32 cube (with a sun ~1e9 cd/m^2) uploaded as-is returns, with
    # nearest filtering, the splatted sun texel at the sun direction and the sky at the zenith.
    from envcap.gpu.cube_array import cube_texture

    sky = PreethamSky(3, 35, 120)
    n = 32
    c = sky.cube(n, supersample=1)
    rgba = np.concatenate([c, np.ones(c.shape[:3] + (1,), np.float32)], -1)
    tex = cube_texture(gl_ctx, [rgba])
    tex.filter = (0x2600, 0x2600)  # GL_NEAREST
    dirs = np.array([list(sky.sun.direction) + [0], [0, 1, 0, 0], [0.1, -1, 0.2, 0]], np.float32)
    got = sample_with_gl(gl_ctx, SAMPLE_CUBE, dirs, tex.use)[:, :3]
    tex.release()
    f, r, col = cube.direction_to_texel(sky.sun.direction, n)
    np.testing.assert_array_equal(got[0], c[f, r, col])
    assert got[0, 1] > 1e6 and np.all(np.isfinite(got))
    np.testing.assert_array_equal(got[1], c[(2,) + tuple(int(v) for v in cube.direction_to_texel([0, 1, 0], n)[1:])])
    np.testing.assert_allclose(got[2], sky.ground_radiance, rtol=1e-6)
