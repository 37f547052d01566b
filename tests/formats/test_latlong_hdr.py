"""The lat-long Radiance ``.hdr`` maps (``envcap capture --latlong-hdr``, Unreal's cubemap import):
read back by an independent reader (OpenImageIO's HDR plugin), they hold the ``.exr`` maps of the
same name to RGBE precision, in the same orientation; the encoder keeps every width (run-length
chunks over 128 bytes, flat scanlines under 8 pixels) and an HDR range."""

import json

import numpy as np
import OpenImageIO as oiio
import pytest

from envcap.formats.latlong_hdr_writer import write_hdr
from envcap.probeset.store import write_probe_set

RGBE_REL = 2.0 ** -7
"""RGBE keeps 8-bit mantissas of the largest channel: a channel is within 2^-8 of that channel's
value (floor), 2^-7 with readers that add half a step."""


def oiio_read(path):
    buf = oiio.ImageBuf(str(path))
    assert not buf.has_error, buf.geterror()
    return np.asarray(buf.get_pixels(oiio.FLOAT), np.float64)[..., :3]


def within_rgbe(got, want):
    top = np.abs(want).max(axis=-1, keepdims=True)
    return np.abs(got - np.maximum(want, 0.0)) <= RGBE_REL * top + 1e-30


@pytest.mark.parametrize("shape", [(3, 5), (16, 300), (7, 8)])
def test_oiio_reads_what_was_written(tmp_path, shape):
    rng = np.random.default_rng(sum(shape))
    img = np.exp(rng.normal(0.0, 4.0, size=shape + (3,)))   # radiance over ~20 stops
    img[0, 0] = 0.0
    img[-1, -1] = [70000.0, 3.0, 0.0]                       # a sun: beyond half floats
    path = write_hdr(tmp_path / "a.hdr", img)
    got = oiio_read(path)
    assert got.shape == img.shape
    assert within_rgbe(got, img).all(), np.abs(got - img).max()
    assert not within_rgbe(got, img[::-1]).all() and not within_rgbe(got, img[:, ::-1]).all()   # the check can fail


def test_hdr_maps_are_the_exr_maps(canyon_probe_set, tmp_path):
    out = write_probe_set(tmp_path / "set", canyon_probe_set, exr=False, previews=False,
                          writers=["ktx2", "latlong", "latlong_hdr"])
    files = json.loads((out / "manifest.json").read_text())["files"]
    assert files["latlong_hdr_sky"] == "latlong/sky.hdr"
    assert files["latlong_hdr"] == [p.replace(".exr", ".hdr") for p in files["latlong"]]
    for exr in [files["latlong_sky"], *files["latlong"]]:
        want, got = oiio_read(out / exr), oiio_read(out / exr.replace(".exr", ".hdr"))
        assert got.shape == want.shape == (2 * canyon_probe_set.resolution, 4 * canyon_probe_set.resolution, 3)
        assert within_rgbe(got, want).all(), (exr, np.abs(got - want).max())


def test_bad_image_is_refused(tmp_path):
    with pytest.raises(ValueError, match="NaN or Inf"):
        write_hdr(tmp_path / "b.hdr", np.full((2, 8, 3), np.nan))
    with pytest.raises(ValueError, match="shape"):
        write_hdr(tmp_path / "b.hdr", np.zeros((2, 8, 4)))
    assert list(tmp_path.iterdir()) == []
