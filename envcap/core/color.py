"""Color: luminance of linear Rec.709 RGB (the one set of weights envcap uses) and the sRGB
decoding curve (the one decoder of display-referred colors: LDR images, mesh vertex colors).

envcap's colors are linear, scene-referred Rec.709 (sRGB primaries, D65 white); luminance is
``Y = 0.2126 R + 0.7152 G + 0.0722 B`` (the four-digit coefficients of ITU-R BT.709).
It drives the error metrics, the PNG previews' exposure, the prefilter's hot-texel detection and
the benchmarks' errors.

The sky's colorimetry (``envcap.sky``: xyY -> XYZ -> RGB with a seven-digit sRGB matrix) does not
need these weights: the Y row of that matrix's inverse (0.2126729, 0.7151522, 0.0721750) is the same
quantity (it agrees to 3.5e-4 relative for any non-negative color), and nothing in the pipeline
computes luminance from it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

REC709_LUMINANCE: NDArray[np.float64] = np.array([0.2126, 0.7152, 0.0722])
"""Luminance weights of linear Rec.709 RGB (R, G, B); they sum to 1, so grey ``(v, v, v)`` has ``Y = v``."""
REC709_LUMINANCE.setflags(write=False)


def luminance(rgb: ArrayLike) -> NDArray[np.float64]:
    """Luminance ``Y`` of linear Rec.709 colors ``(..., C)`` with ``C >= 3`` (channels after the
    third, e.g. alpha, are ignored), as float64 of shape ``(...)``; units those of ``rgb``."""
    a = np.asarray(rgb, dtype=np.float64)
    if a.ndim == 0 or a.shape[-1] < 3:
        raise ValueError(f"luminance needs at least 3 color channels in the last axis, got shape {a.shape}")
    return a[..., :3] @ REC709_LUMINANCE


def srgb_to_linear(c: ArrayLike) -> NDArray[np.float64]:
    """Decode sRGB-encoded values ``c`` (any shape; 1.0 = display white) to linear, as float64 of
    the same shape: IEC 61966-2-1, ``c / 12.92`` for ``c <= 0.04045``, else
    ``((c + 0.055) / 1.055) ** 2.4``.  Meant for ``[0, 1]``; a value outside it is not clipped
    (the caller checks the range: a negative value stays negative, NaN stays NaN)."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
