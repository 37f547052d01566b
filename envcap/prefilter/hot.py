"""Hot texels: the few level-0 texels (a sun) that the GL filters sum exactly at full resolution
instead of through a coarse or composed source (``docs/prefilter.md``)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from envcap.core.color import luminance

__all__ = ["HOT_FACTOR", "MAX_HOT", "hot_texels", "luminance_weight"]

HOT_FACTOR = 1e3
"""Level-0 texels brighter than this x the median positive luminance are summed exactly (the sun)."""
MAX_HOT = 256
"""At most this many hot texels per cube (the brightest); the rest stay in the source levels."""


def luminance_weight(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Non-negative luminance weight of each texel of ``(..., C)``: Rec.709 Y of the first three
    channels when ``C >= 3``, else the sum of the positive channels."""
    if a.shape[-1] >= 3:
        y = luminance(a)
    else:
        y = np.maximum(a, 0.0).sum(axis=-1)
    return np.maximum(y, 0.0)


def hot_texels(y: NDArray[np.float64]) -> tuple[NDArray[np.int64], float]:
    """``(indices, median)`` of one cube's luminance weights ``y`` (any shape, flattened C-order).

    ``indices``: the texels brighter than :data:`HOT_FACTOR` x the median positive weight (at
    most :data:`MAX_HOT`, the brightest); ``median``: that median (0 when no weight is positive).
    """
    yi = y.reshape(-1)
    pos = yi[yi > 0]
    med = float(np.median(pos)) if pos.size else 0.0
    cand = np.flatnonzero(yi > HOT_FACTOR * med) if pos.size else np.zeros(0, np.int64)
    if cand.size > MAX_HOT:
        cand = cand[np.argsort(yi[cand])[-MAX_HOT:]]
    return cand, med
