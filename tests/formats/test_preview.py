"""Previews: tone mapping properties, cross layout (hand-derived), PNG files read back with PIL."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from PIL import Image

from envcap.formats.png_preview import (
    auto_exposure,
    contact_sheet_png,
    cross_image,
    cube_cross_png,
    heatmap_png,
    side_by_side_png,
    tonemap,
)


def test_tonemap_hand_values_and_hard_inputs():
    rgb = np.array([[[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [np.nan, -5.0, np.inf], [1e38, 1e30, 0.5]]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = tonemap(rgb, exposure=1.0)
    assert out.dtype == np.uint8 and out.shape == (1, 4, 3)
    assert np.all(out[0, 0] == 0)
    # ACES fit at x = 1: 2.54 / 3.16 = 0.80380; sRGB: 1.055 * 0.80380^(1/2.4) - 0.055 = 0.90823 -> 232.
    assert np.all(out[0, 1] == 232)
    assert list(out[0, 2]) == [0, 0, 255]  # NaN -> 0, negative -> 0, +Inf -> white
    assert list(out[0, 3][:2]) == [255, 255]
    with pytest.raises(ValueError, match="exposure"):
        tonemap(rgb, exposure=0.0)
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\)"):
        tonemap(np.zeros((4, 4, 2)))


def test_auto_exposure_is_scale_invariant_and_robust():
    rng = np.random.default_rng(0)
    img = rng.uniform(10, 1000, (32, 32, 3))
    a = tonemap(img)
    assert np.array_equal(a, tonemap(img * 1000.0))
    img2 = img.copy()
    img2[0, 0] = 1e9  # the sun barely moves the exposure (median, not mean)
    img2[0, 1] = np.nan
    assert abs(auto_exposure(img2) / auto_exposure(img) - 1.0) < 0.01
    assert np.all(np.abs(tonemap(img2)[5:].astype(int) - a[5:]) <= 2)
    assert auto_exposure(np.zeros((4, 4, 3))) == 1.0
    # The median luminance lands on middle gray 0.18 -> ACES(0.18) sRGB-encoded.
    gray = np.full((3, 3, 3), 42.0)
    x = 0.18
    aces = x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14)
    want = round((1.055 * aces ** (1 / 2.4) - 0.055) * 255)
    assert np.all(tonemap(gray) == want)


def test_cross_layout_inside_view():
    """Inside view (mirrored outside cross): middle row -Z, +X, +Z, -X; +Y above and -Y below +Z."""
    n = 4
    colors = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [0, 1, 1], [1, 0, 1]], float) * 0.5
    cube = np.broadcast_to(colors[:, None, None, :], (6, n, n, 3)).copy()
    img = cross_image(cube, exposure=1.0)
    assert img.shape == (3 * n, 4 * n, 3)
    cell = {(1, 0): 5, (1, 1): 0, (1, 2): 4, (1, 3): 1, (0, 2): 2, (2, 2): 3}
    ref = tonemap(colors, exposure=1.0)
    for (r, c), f in cell.items():
        assert np.array_equal(img[r * n + 1, c * n + 1], ref[f]), (r, c, f)
    assert np.all(img[0:n, 0:n] == img[0, 0]) and img[0, 0, 0] < 40  # empty cell: dark


def test_cross_alpha_checkerboard():
    n = 16
    cube = np.zeros((6, n, n, 4))
    cube[..., :3] = 100.0
    cube[..., 3] = 1.0
    cube[2, ..., :] = 0.0  # +Y: sky, alpha 0, premultiplied RGB 0
    img = cross_image(cube)
    top = img[0:n, 2 * n:3 * n]
    assert len(np.unique(top.reshape(-1, 3), axis=0)) == 2  # two checker grays
    img_nock = cross_image(cube, checker=False)
    assert np.all(img_nock[0:n, 2 * n:3 * n] == 0)


def test_pngs_written_and_readable(tmp_path):
    n = 8
    rng = np.random.default_rng(2)
    cubes = [rng.uniform(0, 100, (6, n, n, 4)) for _ in range(5)]
    p = cube_cross_png(tmp_path / "c.png", cubes[0])
    assert Image.open(p).size == (4 * n, 3 * n)
    p = contact_sheet_png(tmp_path / "s.png", cubes, [f"p{i}" for i in range(5)], cols=3)
    w, h = Image.open(p).size
    assert w == 3 * 4 * n + 2 * 4 and h > 2 * 3 * n
    p = side_by_side_png(tmp_path / "b.png", [rng.uniform(0, 1, (10, 12, 3)), np.zeros((10, 12, 3), np.uint8)], ["a", "b"])
    assert Image.open(p).size[0] == 2 * 12 + 4
    vals = rng.uniform(0, 1, (20, 30))
    vals[3, 4] = np.nan
    p = heatmap_png(tmp_path / "h.png", vals, 0.0, 1.0, "error (relative)")
    im = np.asarray(Image.open(p).convert("RGB"))
    assert im.shape[0] > 50 and np.any(np.all(im == 128, axis=-1) | np.all(im == 127, axis=-1))  # NaN gray
    assert sorted(x.name for x in tmp_path.iterdir()) == ["b.png", "c.png", "h.png", "s.png"]


def test_preview_bad_arguments(tmp_path):
    with pytest.raises(ValueError, match="labels"):
        contact_sheet_png(tmp_path / "s.png", [np.zeros((6, 2, 2, 3))], ["a", "b"])
    with pytest.raises(ValueError, match="nothing to show"):
        contact_sheet_png(tmp_path / "s.png", [], [])
    with pytest.raises(ValueError, match="vmin < vmax"):
        heatmap_png(tmp_path / "h.png", np.zeros((2, 2)), 1.0, 1.0, "x")
    with pytest.raises(ValueError, match=r"\(6, N, N, C\)"):
        cube_cross_png(tmp_path / "c.png", np.zeros((5, 2, 2, 3)))
    assert list(tmp_path.iterdir()) == []
