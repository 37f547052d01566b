"""Validation of sky parameters: RGB radiance / illuminance triples, sun elevations, scale factors.

Built on :mod:`envcap.core.checks` (numbers, directions, table keys, used directly by the sky
modules).  Every checker returns the cleaned value or raises ``ValueError`` whose message names
the parameter, so a scene file's error points at the offending key.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.core.checks import float_in_range

RGB_LIMIT = 1.0e12
"""Largest radiance (cd/m^2-scaled) or illuminance (lux) a scene key may give: ``[sky] radiance``,
``sun.illuminance`` (window ``emission`` has its own, smaller limit,
:data:`envcap.scene.limits.EMISSION_LIMIT`).  500 times the sun's disk radiance (~2e9 cd/m^2),
10^7 times its illuminance: larger is a unit mistake, and every value derived from it (texel
averages, the splatted sun, prefiltered sums) stays far inside float32 range."""

SCALE_LIMIT = 1.0e6
"""Largest ``[sky] scale``: a lat-long file in relative units (1 = white) becomes cd/m^2 with
scales up to ~10^5; the scaled radiance must also stay below :data:`RGB_LIMIT`."""

AZIMUTH_LIMIT_DEG = 360.0
"""Largest absolute azimuth (degrees): ``sun_azimuth_deg``, ``sun.azimuth_deg``."""


def rgb_triple(value: Any, name: str, limit: float | None = None) -> NDArray[np.float64]:
    """A non-negative finite RGB triple, shape ``(3,)`` float64, from a number (grey) or a 3-sequence;
    each channel at most ``limit`` if given (scene keys pass :data:`RGB_LIMIT`)."""
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        arr = np.full(3, float(value))
    else:
        try:
            arr = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be a number or [r, g, b], got {value!r}") from None
        if arr.shape != (3,):
            raise ValueError(f"{name} must be a number or [r, g, b], got {value!r}")
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise ValueError(f"{name} must be finite and non-negative, got {value!r}")
    if limit is not None and np.any(arr > limit):
        raise ValueError(f"{name} must be at most {limit:g} per channel, got {value!r}")
    return arr


def check_elevation(e: Any, name: str = "sun elevation") -> float:
    """A sun elevation in [0, 90] degrees."""
    return float_in_range(e, name, 0.0, 90.0, "degrees")


def check_azimuth(value: Any, name: str) -> float:
    """An azimuth in degrees within [-:data:`AZIMUTH_LIMIT_DEG`, +:data:`AZIMUTH_LIMIT_DEG`]."""
    return float_in_range(value, name, -AZIMUTH_LIMIT_DEG, AZIMUTH_LIMIT_DEG, "degrees")


def check_scale(value: Any, name: str = "scale") -> float:
    """A radiance scale factor in [0, :data:`SCALE_LIMIT`]."""
    return float_in_range(value, name, 0.0, SCALE_LIMIT)

