"""Reading an image file as linear RGB radiance: the one door for envcap's input images.

Used by :func:`envcap.core.latlong.read_latlong` (lat-long skies and ``envcap prefilter`` inputs).

* Any format OpenImageIO reads; the first three channels are R, G, B in file order.
* **HDR** files (every one of R, G, B stored as float, half or double: EXR, Radiance HDR, float
  TIFF) are linear radiance as stored.
* **LDR** files (integer channels: 8/16-bit PNG, JPEG, TIFF) are display-referred: decoded from
  sRGB (IEC 61966-2-1) to linear, so sRGB 128/255 becomes 0.2158605 (not 0.502), with a one-line
  warning on stderr.  Their scale is relative (1.0 = display white), not absolute radiance.
* The image is read in bands of rows into one ``(H, W, 3)`` float32 array: memory is the image
  (checked first with :func:`envcap.core.budget.check_bytes`) plus one bounded band.
* A texel with NaN, Inf or a negative value in R, G or B is *bad*: by default the file is
  rejected (the count and the first bad pixel ``(x, y)``); ``sanitize=True`` sets those channel
  values to 0 and returns the count.
* Every error is one line naming the file (OpenImageIO's multi-line messages are joined).
"""

from __future__ import annotations

import os
import sys
from typing import Callable

import numpy as np
from numpy.typing import NDArray

from envcap.core import budget
from envcap.core.color import srgb_to_linear
from envcap.core.input_path import require_file

__all__ = ["BAND_PIXELS", "read_rgb_radiance", "one_line"]

BAND_PIXELS = 1 << 20
"""Pixels per band of rows read at once (a tiled file reads whole rows of tiles)."""


def one_line(message: str, limit: int = 300) -> str:
    """A library's multi-line (often repeated) error text as one line: distinct lines joined by ``; ``."""
    seen: list[str] = []
    for ln in str(message).splitlines():
        ln = " ".join(ln.split())
        if ln and ln not in seen:
            seen.append(ln)
    text = "; ".join(seen)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _is_float_format(fmt: object) -> bool:
    import OpenImageIO as oiio

    return getattr(fmt, "basetype", None) in (oiio.FLOAT, oiio.HALF, oiio.DOUBLE)


def read_rgb_radiance(
    path: str | os.PathLike[str],
    *,
    what: str = "image file",
    sanitize: bool = False,
    shape_check: Callable[[int, int], str | None] | None = None,
) -> tuple[NDArray[np.float32], int]:
    """Read ``path`` as ``(H, W, 3)`` float32 linear RGB; returns ``(image, bad_count)``.

    ``what`` names the file in messages (``"lat-long sky file"``).  ``shape_check(width, height)``
    may return an error text (raised as ``ValueError`` before any pixel is read).  Raises
    ``FileNotFoundError`` for a missing file, ``ValueError`` for an unreadable or truncated one,
    fewer than 3 channels, bad texels (unless ``sanitize``), and
    :class:`envcap.core.budget.BudgetError` when the image would not fit in memory.
    """
    import OpenImageIO as oiio

    p = require_file(path, what)
    inp = oiio.ImageInput.open(str(p))
    if inp is None:
        raise ValueError(f"cannot read {what} {p}: {one_line(oiio.geterror()) or 'unknown format'}")
    try:
        spec = inp.spec()
        wd, ht, nch = spec.width, spec.height, spec.nchannels
        if nch < 3:
            raise ValueError(f"{what} {p} has {nch} channel(s); need at least 3 (RGB)")
        problem = shape_check(wd, ht) if shape_check is not None else None
        if problem:
            raise ValueError(f"{what} {p} is {wd}x{ht}; {problem}")
        formats = list(spec.channelformats)[:3] or [spec.format] * 3
        ldr = not all(_is_float_format(f) for f in formats)
        tile_h = spec.tile_height if spec.tile_width > 0 else 0
        rows = max(1, BAND_PIXELS // max(wd, 1))
        if tile_h:
            rows = max(tile_h, rows // tile_h * tile_h)
        budget.check_bytes(f"{what} {p.name} ({wd}x{ht} RGB float32)", ht * wd * 12 + min(rows, ht) * wd * 40,
                           option="the input image size (downsample it)")
        img = np.empty((ht, wd, 3), dtype=np.float32)
        count = nonfinite = 0
        first: tuple[int, int, list[float]] | None = None
        for y0 in range(0, ht, rows):
            y1 = min(ht, y0 + rows)
            if tile_h:
                data = inp.read_tiles(0, 0, spec.x, spec.x + wd, spec.y + y0, spec.y + y1, spec.z, spec.z + 1,
                                      0, 3, "float")
            else:
                data = inp.read_scanlines(0, 0, spec.y + y0, spec.y + y1, spec.z, 0, 3, "float")
            if data is None or inp.has_error:
                raise ValueError(f"cannot read pixels of {what} {p} (truncated or corrupt?): "
                                 f"{one_line(inp.geterror()) or 'read failed'}")
            band = img[y0:y1]
            band[...] = np.asarray(data, dtype=np.float32).reshape(y1 - y0, wd, 3)
            if ldr:
                band[...] = srgb_to_linear(band)
            if band.size and np.min(band) >= 0 and np.max(band) < np.inf:  # NaN fails the first test
                continue
            bad_ch = ~np.isfinite(band) | (band < 0)
            bad = np.any(bad_ch, axis=-1)
            k = int(np.count_nonzero(bad))
            if k:
                if first is None:
                    by, bx = (int(i[0]) for i in np.nonzero(bad))
                    first = (bx, y0 + by, band[by, bx].tolist())
                count += k
                nonfinite += int(np.count_nonzero(np.any(~np.isfinite(band), axis=-1)))
                if sanitize:
                    band[bad_ch] = 0.0
    finally:
        inp.close()
    if count and not sanitize:
        assert first is not None
        raise ValueError(
            f"{what} {p} has {count} bad texel(s) ({nonfinite} with NaN/Inf, the rest negative); "
            f"first at pixel (x={first[0]}, y={first[1]}) = {first[2]}; fix the file or load it with sanitize=True "
            "(replaces them with 0)")
    if ldr:
        kinds = sorted({str(f) for f in formats})
        print(f"envcap: warning: {p} is a {'/'.join(kinds)} (not HDR) image: decoded as sRGB, display-referred "
              "(1.0 = display white, not scene radiance)", file=sys.stderr)
    return img, count
