"""envcap.core.color: the one Rec.709 luminance, checked against the primaries it comes from, and
the one sRGB decoder, checked against the standard's encoding curve and published values."""

import pathlib
import re

import numpy as np
import pytest

from envcap.core.color import REC709_LUMINANCE, luminance, srgb_to_linear
from envcap.sky.preetham import XYZ_TO_RGB

PACKAGE = pathlib.Path(__file__).resolve().parents[2] / "envcap"


def _y_row_from_chromaticities():
    """Y row of linear RGB -> XYZ from the Rec.709 primaries and the D65 white (SMPTE RP 177)."""
    prim = {"r": (0.64, 0.33), "g": (0.30, 0.60), "b": (0.15, 0.06)}
    xyz = np.array([[x / y, 1.0, (1 - x - y) / y] for x, y in prim.values()]).T  # columns: primaries at Y = 1
    wx, wy = 0.3127, 0.3290
    scale = np.linalg.solve(xyz, [wx / wy, 1.0, (1 - wx - wy) / wy])  # white = R + G + B at Y = 1
    return xyz[1] * scale


def test_weights_are_the_primaries_y_row_rounded_to_four_digits():
    derived = _y_row_from_chromaticities()
    np.testing.assert_array_equal(REC709_LUMINANCE, np.round(derived, 4))
    assert REC709_LUMINANCE.sum() == pytest.approx(1.0, abs=1e-12)


def test_skys_colorimetric_y_row_agrees_within_the_documented_bound():
    exact = np.linalg.inv(XYZ_TO_RGB)[1]  # the sky's own RGB -> Y
    assert np.max(np.abs(exact - REC709_LUMINANCE) / REC709_LUMINANCE) < 3.5e-4


def test_luminance_by_hand():
    rgba = np.array([[1.0, 0.0, 0.0, 0.5], [0.0, 2.0, 0.0, 1.0], [0.0, 0.0, 4.0, 0.0], [3.0, 3.0, 3.0, 9.0]])
    np.testing.assert_allclose(luminance(rgba), [0.2126, 1.4304, 0.2888, 3.0], rtol=1e-15)
    y = luminance(rgba.astype(np.float32).reshape(2, 2, 4))
    assert y.shape == (2, 2) and y.dtype == np.float64
    with pytest.raises(ValueError, match="3 color channels"):
        luminance(np.ones((4, 2)))
    with pytest.raises(ValueError, match="3 color channels"):
        luminance(1.0)


def test_no_other_copy_of_the_weights_in_the_package():
    hits = [f"{p.relative_to(PACKAGE)}:{i}" for p in PACKAGE.rglob("*.py") if p.name != "color.py"
            for i, line in enumerate(p.read_text().splitlines(), 1)
            if re.search(r"0\.2126\d*\s*,|0\.7152\s*,|0\.71515", line) and not line.lstrip().startswith(("#", "``", "*"))]
    assert not hits, f"luminance weights defined outside envcap/core/color.py: {hits}"


def test_srgb_decoding_inverts_the_standards_encoding_and_matches_published_values():
    # IEC 61966-2-1 encoding (linear -> sRGB), written independently of the decoder.
    lin = np.linspace(0.0, 1.0, 10001)
    enc = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055)
    np.testing.assert_allclose(srgb_to_linear(enc), lin, rtol=1e-12, atol=1e-15)
    # 8-bit codes from the published table: 0 -> 0, 10 -> 0.00303527, 128 -> 0.2158605, 255 -> 1.
    got = srgb_to_linear(np.array([0, 10, 128, 255], np.uint8) / 255.0)
    np.testing.assert_allclose(got, [0.0, 0.00303527, 0.2158605, 1.0], rtol=2e-6, atol=1e-12)
    assert srgb_to_linear(np.float32(0.5)).dtype == np.float64
    assert srgb_to_linear([[-0.01]])[0, 0] < 0  # not clipped: the caller checks the range



def test_no_other_srgb_decoder_in_the_package():
    hits = [f"{p.relative_to(PACKAGE)}:{i}" for p in PACKAGE.rglob("*.py") if p.name != "color.py"
            for i, line in enumerate(p.read_text().splitlines(), 1) if re.search(r"0\.04045|/\s*1\.055", line)]
    assert not hits, f"an sRGB decoder outside envcap/core/color.py: {hits}"
