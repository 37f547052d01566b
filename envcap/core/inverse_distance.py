"""A probe's distance channel as the runtime reads it: inverse distance (1/m), 0 for the sky.

One definition for the bake side (the ``inverse_distance`` writer, ``inverse_distance.ktx2``) and
the runtime (method ``depth_refine``, GLSL ``ENVCAP_DISTANCE_FETCH``).  Storing 1/d rather than d
keeps the sky (d = infinity) a finite 0 and gives half floats their precision where it matters
(near surfaces).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

MAX_DISTANCE = 1.0e5
"""Distances (m) at or beyond this are stored as sky (0) by :func:`inverse_distance`."""


def inverse_distance(distance: ArrayLike) -> NDArray[np.float32]:
    """``1 / distance`` (1/m) as float32, shape unchanged (``(L, 6, N, N)`` or ``(6, N, N)``); 0
    where the probe sees the sky (distance 0), and for distances that are not positive and finite
    or are >= :data:`MAX_DISTANCE` (Inf, NaN, negative)."""
    D = np.asarray(distance, np.float64)
    ok = np.isfinite(D) & (D > 0) & (D < MAX_DISTANCE)
    return np.where(ok, 1.0 / np.where(ok, D, 1.0), 0.0).astype(np.float32)
