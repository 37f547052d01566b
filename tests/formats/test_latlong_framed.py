"""Lat-long maps of probes of a street at an angle are in the world's orientation, like the sky
they are composited over (review of issue 10: the frame-axis cube was unwrapped as if it were
world-axis, turning the street by its yaw against the sky)."""

import dataclasses
import math

import numpy as np

from envcap.core import cube, cube_sampling
from envcap.core.latlong import latlong_directions
from envcap.formats.latlong_exr import cube_to_latlong_seamless
from envcap.formats.latlong_writer import write_latlong_maps

YAW = 65.0


def hand_frame(d: np.ndarray, yaw: float) -> np.ndarray:
    """World directions in the frame of a street at ``yaw`` (x_f = c x + s z, z_f = -s x + c z)."""
    c, s = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    return np.stack([c * d[..., 0] + s * d[..., 2], d[..., 1], -s * d[..., 0] + c * d[..., 2]], axis=-1)


def test_a_turned_cube_unwraps_in_the_worlds_orientation():
    n = 16
    f = cube.texel_directions(n)                   # texel = its own (frame) direction
    img = cube_to_latlong_seamless(f, yaw_deg=YAW)
    d = latlong_directions(32, 64)
    np.testing.assert_allclose(img, hand_frame(d, YAW), atol=0.02)   # bilinear of a smooth field
    assert np.array_equal(cube_to_latlong_seamless(f, yaw_deg=0.0), cube_to_latlong_seamless(f))


def test_latlong_writer_turns_each_probe_by_its_streets_yaw(canyon_probe_set, tmp_path):
    ps = canyon_probe_set
    st = ps.manifest.streets[0]
    framed = dataclasses.replace(ps, manifest=dataclasses.replace(
        ps.manifest, streets=(dataclasses.replace(st, yaw_deg=YAW), *ps.manifest.streets[1:])))
    write_latlong_maps(tmp_path, framed)
    import OpenImageIO as oiio
    layer = st.probes[0].layer
    got = oiio.ImageInput.open(str(tmp_path / f"latlong/probe_{layer:03d}.exr")).read_image("float")[..., :3]
    h = got.shape[0]
    d = latlong_directions(h, 2 * h)
    street = cube_sampling.sample_cube_array(ps.levels[:1], hand_frame(d, YAW).reshape(-1, 3), layer).reshape(h, 2 * h, 4)
    sky = cube_sampling.sample_cube(ps.sky_levels[:1], d.reshape(-1, 3)).reshape(h, 2 * h, -1)[..., :3]
    want = street[..., :3] + (1 - np.clip(street[..., 3:], 0, 1)) * sky
    np.testing.assert_allclose(got, want, rtol=2e-3, atol=1e-3 * float(np.abs(want).max()))   # half floats
