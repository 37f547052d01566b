"""Mip levels of a cosine-lobe chain (twin of ``shaders/runtime/envcap_lobes.glsl`` and the mip
shift of ``envcap_street.glsl``): the lobe table, z(w), the mip shift in lobe-power space and
level clamping.

A chain's level ``k`` holds the environment convolved with the normalized ``cos^powers[k]``
lobe; ``powers`` (the manifest's lobe table) is strictly decreasing.  Every function is
vectorized and float64 by default; ``dtype=np.float32`` evaluates in float32 in the GLSL
operation order.  Derivations and fallbacks: ``docs/runtime.md``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.runtime.limits import MAX_LEVELS


def lobe_table(powers: ArrayLike, dtype: Any = np.float64, most: int = MAX_LEVELS) -> NDArray:
    """``x_k = log2(1 + powers[k])`` for the GLSL uniform ``xk`` (computed in float64).

    ``powers`` is the manifest's strictly decreasing table of lobe powers (>= 0), at most
    ``most`` long (``MAX_LEVELS``; a rung table: ``MAX_RUNGS``).  Raises ``ValueError`` otherwise.
    """
    p = np.asarray(powers, dtype=np.float64)
    if p.ndim != 1 or not 1 <= p.size <= most:
        raise ValueError(f"powers must be a 1-D table of 1..{most} values, got shape {p.shape}")
    if not np.all(np.isfinite(p)) or np.any(p < 0) or np.any(np.diff(p) >= 0):
        raise ValueError(f"powers must be finite, >= 0 and strictly decreasing, got {p.tolist()}")
    return np.log2(1.0 + p).astype(dtype)


def z_of_w(w: ArrayLike, xk: ArrayLike, dtype: Any = np.float64) -> NDArray:
    """Continuous mip level of power(s) ``w`` from the table ``xk = lobe_table(powers)``.

    Same rule as :func:`envcap.core.lobes.z_of_w` (piecewise linear in log2(1 + w), clamped to
    [0, L-1]), written as the GLSL loop.  Unlike ``envcap.core.lobes.z_of_w`` it does not raise:
    ``w < 0`` and NaN count as 0 (as in GLSL), ``+inf`` gives 0.
    """
    xk = np.asarray(xk, dtype=dtype)
    w = np.asarray(w, dtype=dtype)
    n = xk.size
    with np.errstate(invalid="ignore", over="ignore"):
        x = np.log2(dtype(1.0) + np.where(w > 0, w, dtype(0.0)))
    z = np.full(x.shape, dtype(n - 1), dtype=dtype)
    done = ~(x < xk[0])
    z[done] = 0.0
    for k in range(1, n):
        m = ~done & (x >= xk[k])
        z[m] = dtype(k - 1) + (xk[k - 1] - x[m]) / (xk[k - 1] - xk[k])
        done |= m
    return z


def shift_power(w: ArrayLike, ratio: ArrayLike, dtype: Any = np.float64) -> NDArray:
    """Lobe power seen from the probe: ``max(w, 0) * ratio**2`` with ``ratio = d_probe / d_shade``
    (the mip shift, docs/runtime.md)."""
    w = np.asarray(w, dtype=dtype)
    ratio = np.asarray(ratio, dtype=dtype)
    return np.maximum(w, dtype(0)) * (ratio * ratio)


def scale_power(w: ArrayLike, q: ArrayLike, dtype: Any = np.float64) -> NDArray:
    """Lobe power seen from the probe for a power multiplier ``q`` (the oblique shift's
    ``ratio^2 cos(alpha) / cos(beta)``, :mod:`envcap.runtime.footprint`): ``max(w, 0) * q``."""
    w = np.asarray(w, dtype=dtype)
    return np.maximum(w, dtype(0)) * np.asarray(q, dtype=dtype)


def clamp_level(z: ArrayLike, n: int, dtype: Any = np.float64) -> NDArray:
    """Mip level clamped to [0, n - 1]; NaN -> 0."""
    z = np.asarray(z, dtype=dtype)
    return np.where(z > 0, np.minimum(z, dtype(max(n, 1) - 1)), dtype(0))


def level_of_power(w: ArrayLike, xk: ArrayLike) -> NDArray[np.float64]:
    """The clamped level ``clamp_level(z_of_w(w, xk), len(xk))`` a lookup of power ``w`` samples (float64)."""
    return clamp_level(z_of_w(w, xk), np.asarray(xk).size)
