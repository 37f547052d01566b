"""Previews as PNG: tone mapping, cube crosses, contact sheets, heatmaps, side-by-side images.

Inputs are linear scene-referred HDR (Rec.709, cd/m^2-scaled).  Tone mapping: a linear
exposure multiplier (automatic: the median luminance of the finite positive pixels is mapped to
0.18), then the ACES filmic fit of Narkowicz (2015), then the sRGB transfer function.  NaN
becomes 0 (black), +Inf becomes white, negative values are clamped to 0.  Every PNG is written
atomically.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from envcap.outputs import atomic_output_file
from envcap.core.color import luminance
from envcap.core.cube import check_cube, horizontal_cross

MIDDLE_GRAY = 0.18


def auto_exposure(rgb: NDArray, percentile: float = 50.0) -> float:
    """Linear exposure multiplier mapping the ``percentile`` luminance of the finite, positive
    pixels of ``rgb`` (``(..., 3)``) to middle gray 0.18; 1.0 when there are none."""
    y = luminance(rgb)
    y = y[np.isfinite(y) & (y > 0)]
    if y.size == 0:
        return 1.0
    key = float(np.percentile(y, percentile))
    return MIDDLE_GRAY / key if key > 0 and math.isfinite(MIDDLE_GRAY / key) else 1.0


def _aces(x: NDArray) -> NDArray:
    return np.clip(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)


def _srgb(x: NDArray) -> NDArray:
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(np.maximum(x, 0.0031308), 1 / 2.4) - 0.055)


def tonemap(rgb: NDArray, exposure: float | None = None) -> NDArray[np.uint8]:
    """Tone-map linear HDR ``rgb`` of shape ``(H, W, 3)`` (or ``(..., 3)``) to sRGB uint8.

    ``exposure`` is a linear multiplier; ``None`` picks :func:`auto_exposure`.  NaN -> 0,
    +Inf -> 255, negatives -> 0.
    """
    a = np.asarray(rgb, dtype=np.float64)
    if a.ndim < 1 or a.shape[-1] != 3:
        raise ValueError(f"tonemap expects (..., 3) RGB, got shape {a.shape}")
    if exposure is None:
        exposure = auto_exposure(a)
    if not (math.isfinite(exposure) and exposure > 0):
        raise ValueError(f"exposure must be a finite positive multiplier, got {exposure}")
    with np.errstate(invalid="ignore", over="ignore"):
        x = np.nan_to_num(a * exposure, nan=0.0, posinf=1e30, neginf=0.0)
    x = np.clip(x, 0.0, 1e30)
    # ACES fit is x^2-dominated for large x: evaluate on a capped input to avoid overflow.
    x = np.minimum(x, 1e6)
    return np.round(_srgb(_aces(x)) * 255.0).astype(np.uint8)


def _checker(h: int, w: int, cell: int = 8) -> NDArray[np.float64]:
    y, x = np.mgrid[0:h, 0:w]
    return np.where(((y // cell) + (x // cell)) % 2 == 0, 0.55, 0.75)


def cross_image(cube: NDArray, *, exposure: float | None = None, checker: bool = True) -> NDArray[np.uint8]:
    """Tone-mapped inside-view horizontal cross ``(3N, 4N, 3)`` uint8 of a cube ``(6, N, N, 3|4)``.

    With 4 channels the RGB is taken as premultiplied by alpha and composited over a gray
    checkerboard where alpha < 1 (the sky) when ``checker``; cells outside the cross are dark.
    """
    a = check_cube(cube).astype(np.float64)
    if a.shape[-1] not in (3, 4):
        raise ValueError(f"cube must have 3 or 4 channels, got {a.shape[-1]}")
    n = a.shape[1]
    cross = horizontal_cross(a[..., :3], inside=True)
    mask = horizontal_cross(np.ones((6, n, n, 1)), inside=True)[..., 0] > 0
    if exposure is None:
        exposure = auto_exposure(cross[mask])
    img = tonemap(cross, exposure).astype(np.float64) / 255.0
    if a.shape[-1] == 4 and checker:
        alpha = np.clip(np.nan_to_num(horizontal_cross(a[..., 3:], inside=True)[..., 0], nan=1.0), 0.0, 1.0)
        bg = _checker(*alpha.shape, cell=max(2, n // 8))
        img = img + (1.0 - alpha)[..., None] * bg[..., None]
    img[~mask] = 0.12
    return np.round(np.clip(img, 0, 1) * 255).astype(np.uint8)


def _save_png(path: str | os.PathLike[str], img: NDArray[np.uint8]) -> Path:
    from PIL import Image

    final = Path(path)
    with atomic_output_file(final) as tmp:
        Image.fromarray(np.ascontiguousarray(img)).save(tmp, format="PNG")
    return final


def cube_cross_png(
    path: str | os.PathLike[str], cube: NDArray, *, exposure: float | None = None, checker: bool = True
) -> Path:
    """Write the inside-view cross of ``cube`` ``(6, N, N, 3|4)`` as a PNG (see :func:`cross_image`)."""
    return _save_png(path, cross_image(cube, exposure=exposure, checker=checker))


def _label_strip(text: str, width: int, height: int = 16) -> NDArray[np.uint8]:
    from PIL import Image, ImageDraw

    im = Image.new("RGB", (width, height), (20, 20, 20))
    ImageDraw.Draw(im).text((3, 2), text, fill=(235, 235, 235))
    return np.asarray(im)


def _pad_to(img: NDArray[np.uint8], h: int, w: int) -> NDArray[np.uint8]:
    out = np.full((h, w, 3), 20, np.uint8)
    out[: img.shape[0], : img.shape[1]] = img
    return out


def _grid(tiles: Sequence[NDArray[np.uint8]], labels: Sequence[str], cols: int) -> NDArray[np.uint8]:
    th = max(t.shape[0] for t in tiles)
    tw = max(t.shape[1] for t in tiles)
    cells = [np.concatenate([_label_strip(lab, tw), _pad_to(t, th, tw)], axis=0) for t, lab in zip(tiles, labels)]
    rows = math.ceil(len(cells) / cols)
    blank = np.full_like(cells[0], 20)
    cells += [blank] * (rows * cols - len(cells))
    gap = 4
    out_rows = []
    for r in range(rows):
        row = []
        for c in range(cols):
            row.append(cells[r * cols + c])
            if c < cols - 1:
                row.append(np.full((cells[0].shape[0], gap, 3), 0, np.uint8))
        out_rows.append(np.concatenate(row, axis=1))
        if r < rows - 1:
            out_rows.append(np.full((gap, out_rows[-1].shape[1], 3), 0, np.uint8))
    return np.concatenate(out_rows, axis=0)


def _check_labels(n: int, labels: Sequence[str] | None, what: str) -> list[str]:
    if n == 0:
        raise ValueError(f"{what}: nothing to show")
    if labels is None:
        return [str(i) for i in range(n)]
    if len(labels) != n:
        raise ValueError(f"{what}: {n} images but {len(labels)} labels")
    return [str(x) for x in labels]


def contact_sheet_png(
    path: str | os.PathLike[str],
    cubes: Sequence[NDArray],
    labels: Sequence[str] | None = None,
    *,
    exposure: float | None = None,
    cols: int | None = None,
) -> Path:
    """Grid of labeled inside-view crosses, one per cube ``(6, N, N, 3|4)``, as a PNG.

    One exposure for all cubes (automatic over all of them unless given) so they compare.
    """
    labels = _check_labels(len(cubes), labels, "contact sheet")
    if exposure is None:
        ys = [np.asarray(c, dtype=np.float64)[..., :3].reshape(-1, 3) for c in cubes]
        exposure = auto_exposure(np.concatenate(ys))
    tiles = [cross_image(c, exposure=exposure) for c in cubes]
    cols = cols or min(len(tiles), max(1, math.ceil(math.sqrt(len(tiles)))))
    return _save_png(path, _grid(tiles, labels, cols))


def side_by_side_png(
    path: str | os.PathLike[str],
    images: Sequence[NDArray],
    labels: Sequence[str] | None = None,
    *,
    exposure: float | None = None,
) -> Path:
    """Images side by side with labels.  uint8 ``(H, W, 3)`` images are used as-is; float
    ``(H, W, 3)`` images are linear HDR, tone-mapped with one shared exposure."""
    labels = _check_labels(len(images), labels, "side by side")
    floats = [np.asarray(im, dtype=np.float64) for im in images if np.asarray(im).dtype != np.uint8]
    if exposure is None and floats:
        exposure = auto_exposure(np.concatenate([f[..., :3].reshape(-1, 3) for f in floats]))
    tiles = []
    for im in images:
        a = np.asarray(im)
        if a.ndim == 2:
            a = np.repeat(a[..., None], 3, axis=-1)
        if a.ndim != 3 or a.shape[-1] not in (3, 4):
            raise ValueError(f"side by side: images must be (H, W, 3), got {a.shape}")
        tiles.append(a[..., :3] if a.dtype == np.uint8 else tonemap(a[..., :3], exposure))
    return _save_png(path, _grid(tiles, labels, len(tiles)))


def heatmap_png(
    path: str | os.PathLike[str],
    values: NDArray,
    vmin: float,
    vmax: float,
    label: str,
    *,
    title: str | None = None,
    cmap: str = "viridis",
) -> Path:
    """Heatmap of ``values`` ``(H, W)`` with a colorbar labeled ``label`` (units belong in it).

    Values outside ``[vmin, vmax]`` saturate; NaN/Inf show as gray.  Row 0 is at the top.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 2 or v.size == 0:
        raise ValueError(f"heatmap values must be a non-empty (H, W) array, got {v.shape}")
    if not (math.isfinite(vmin) and math.isfinite(vmax) and vmax > vmin):
        raise ValueError(f"heatmap needs finite vmin < vmax, got {vmin}, {vmax}")
    cm = plt.get_cmap(cmap).with_extremes(bad=(0.5, 0.5, 0.5))
    h, w = v.shape
    fig_w = 6.0
    fig, ax = plt.subplots(figsize=(fig_w, max(2.0, fig_w * h / w * 0.85)), dpi=100)
    try:
        im = ax.imshow(np.ma.masked_invalid(v), vmin=vmin, vmax=vmax, cmap=cm, interpolation="nearest")
        fig.colorbar(im, ax=ax, label=label)
        if title:
            ax.set_title(title)
        final = Path(path)
        with atomic_output_file(final) as tmp:
            fig.savefig(tmp, format="png", bbox_inches="tight")
    finally:
        plt.close(fig)
    return final
