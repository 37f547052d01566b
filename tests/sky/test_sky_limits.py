"""Issue 9, sky side: every number of a ``[sky]`` table has its documented range
(``envcap.sky.checks``: RGB_LIMIT, SCALE_LIMIT, AZIMUTH_LIMIT_DEG), and an integer too large for a
float is one line naming the key, not an ``OverflowError``.  Through real scene files."""

from __future__ import annotations

import numpy as np
import OpenEXR
import pytest

from envcap.scene import load_scene
from envcap.sky import sky_from_spec
from envcap.sky.checks import RGB_LIMIT

STREET = '[[streets]]\naxis = "x"\nstart = 0.0\nend = 10.0\nwidth = 10.0\n'


def _load(tmp_path, sky: str):
    path = tmp_path / "scene.toml"
    path.write_text(f"effects = []\nsky = {sky}\n{STREET}")
    with pytest.raises(ValueError) as ei:
        load_scene(path)
    msg = str(ei.value)
    assert msg.startswith(str(path)) and "\n" not in msg, msg
    return msg


BIG = "1" + "0" * 400  # a TOML integer past float range (10**400)


@pytest.mark.parametrize("sky, words", [
    # old: OverflowError from float() in core.checks.finite_float (a traceback)
    (f'{{ type = "preetham", turbidity = {BIG}, sun_elevation_deg = 30 }}', ["sky.turbidity", "1329 bits"]),
    (f'{{ type = "preetham", turbidity = 3, sun_elevation_deg = 30, ground_albedo = {BIG} }}',
     ["sky.ground_albedo", "1329 bits"]),
    # old: accepted; sin/cos of 1e300 degrees is noise, and a scale of 1e30 overflowed float32 later
    ('{ type = "preetham", turbidity = 3, sun_elevation_deg = 30, sun_azimuth_deg = 1e300 }',
     ["sky.sun_azimuth_deg", "[-360, 360]"]),
    ('{ type = "preetham", turbidity = 3, sun_elevation_deg = 30, scale = 1e30 }', ["sky.scale", "1e+06"]),
    ('{ type = "uniform", radiance = 1e13 }', ["sky.radiance", "1e+12"]),
    ('{ type = "uniform", radiance = 1, sun = { elevation_deg = 30, illuminance = [1, 1e300, 1] } }',
     ["sky.sun.illuminance", "1e+12"]),
    ('{ type = "uniform", radiance = 1, sun = { elevation_deg = 30, illuminance = 1, azimuth_deg = 400 } }',
     ["sky.sun.azimuth_deg"]),
])
def test_each_sky_number_is_checked_against_its_range(tmp_path, sky, words):
    msg = _load(tmp_path, sky)
    for w in words:
        assert w in msg, (w, msg)


def test_the_limits_themselves_are_accepted():
    sky = sky_from_spec({"type": "uniform", "radiance": RGB_LIMIT,
                         "sun": {"elevation_deg": 30, "azimuth_deg": -360, "illuminance": RGB_LIMIT}})
    c = sky.cube(4)
    assert c.dtype == np.float32 and np.all(np.isfinite(c))
    # the splatted sun conserves its illuminance even at the limit (float32 cube, float64 sum)
    assert float(np.max(c)) >= RGB_LIMIT


def test_a_latlong_scale_that_pushes_the_image_past_the_radiance_limit_is_named(tmp_path):
    rgb = np.ones((8, 16, 3), np.float32)
    rgb[2, 3] = 1e7
    channels = {c: np.ascontiguousarray(rgb[..., i]) for i, c in enumerate("RGB")}
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels).write(
        str(tmp_path / "sky.exr"))
    ok = sky_from_spec({"type": "latlong", "file": "sky.exr", "scale": 1e5}, base_dir=tmp_path)  # peak 1e12
    assert float(np.max(ok.image)) * ok.scale == RGB_LIMIT
    msg = _load(tmp_path, '{ type = "latlong", file = "sky.exr", scale = 1e6 }')
    assert "sky.scale" in msg and "sky.exr peaks at 1e+07" in msg, msg
