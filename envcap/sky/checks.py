"""Validation of sky parameters: RGB radiance / illuminance triples, sun elevations, scale factors.

Built on :mod:`envcap.core.checks` (numbers, directions, table keys, used directly by the sky
modules).  Every checker returns the cleaned value or raises ``ValueError`` whose message names
the parameter, so a scene file's error points at the offending key.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.core.checks import finite_float


def rgb_triple(value: Any, name: str) -> NDArray[np.float64]:
    """A non-negative finite RGB triple, shape ``(3,)`` float64, from a number (grey) or a 3-sequence."""
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
    return arr


def check_elevation(e: Any, name: str = "sun elevation") -> float:
    """A sun elevation in [0, 90] degrees."""
    e = finite_float(e, name)
    if not 0.0 <= e <= 90.0:
        raise ValueError(f"{name} must be in [0, 90] degrees, got {e:g}")
    return e


def check_scale(value: Any) -> float:
    """A non-negative finite radiance scale factor."""
    s = finite_float(value, "scale")
    if s < 0:
        raise ValueError(f"scale must be non-negative, got {s:g}")
    return s

