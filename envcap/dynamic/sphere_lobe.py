"""A sphere seen from a shading point as a cosine lobe ``max(0, u.D)^t`` (numpy twin of
``envcap_sphere_lobe`` in ``shaders/runtime/envcap_dynamic.glsl``).

A sphere of radius ``r`` whose center is at distance ``l`` covers the spherical cap of half-angle
``theta``, ``sin theta = s = r / l``, solid angle ``Omega = 2 pi (1 - cos theta)``.  The lobe
``max(0, u.D)^t`` integrates to ``2 pi / (1 + t)``; equal integrals (the solid-angle match, the
paper's size-over-distance power) give

    t = cos theta / (1 - cos theta) = c (1 + c) / s^2,   c = cos theta = sqrt((1 - s)(1 + s)),

written without the cancellation of ``1 - cos theta``.  ``D`` is the unit vector to the center.
Limits: ``r`` NaN or <= 0 (no sphere) -> ``t = MAX_POWER``; ``s < 1e-15`` -> ``MAX_POWER``;
touching (``l = r``) -> ``t = 0`` (a hemisphere, exactly the cap); containing (``l < r``) ->
``D = 0``, ``t = 0``, which :func:`envcap.dynamic.lobe_product.lobe_product` reads as "blocks the
whole BRDF lobe".  Distances in meters; only ``r / l`` matters.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.dynamic.lobe_product import MAX_POWER
from envcap.runtime.glsl_math import dot3

MIN_SINE = 1.0e-15
"""Below this ``r / l`` the sphere maps to ``MAX_POWER`` (its ``t`` would overflow float32)."""


def sphere_lobe(x: ArrayLike, center: ArrayLike, radius: ArrayLike, dtype: Any = np.float64) -> tuple[NDArray, NDArray]:
    """``(D, t)``: unit direction ``(..., 3)`` from ``x`` to the sphere's center (``0`` when the
    sphere contains ``x``) and the lobe power ``(...)`` of equal solid angle.  ``x``, ``center``:
    ``(..., 3)`` meters; ``radius``: ``(...)`` meters.  ``dtype=np.float32``: GLSL order."""
    x, center = (np.asarray(a, dtype=dtype) for a in (x, center))
    r = np.asarray(radius, dtype=dtype)
    v = center - x
    ell = np.sqrt(dot3(v, v))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        D = np.where((ell > 0)[..., None], v / np.where(ell > 0, ell, dtype(1))[..., None],
                     np.array([0, 0, 1], dtype=dtype))
        s = r / ell
        c = np.sqrt(np.maximum((dtype(1) - s) * (dtype(1) + s), dtype(0)))
        t = np.where(s > dtype(MIN_SINE), np.minimum(c * (dtype(1) + c) / (s * s), dtype(MAX_POWER)), dtype(MAX_POWER))
    present = r > 0
    inside = present & (ell < r)
    t = np.where(present, np.where(inside, dtype(0), t), dtype(MAX_POWER))
    D = np.where(inside[..., None], dtype(0), D)
    return D.astype(dtype), t.astype(dtype)


def cap_solid_angle(sin_theta: ArrayLike) -> NDArray[np.float64]:
    """Solid angle (sr) of the cap of a sphere with ``r / l = sin_theta`` (``>= 1``: 4 pi, inside)."""
    s = np.asarray(sin_theta, dtype=np.float64)
    inner = 2 * np.pi * s * s / (1 + np.sqrt(np.maximum(1 - s * s, 0)))
    return np.where(s < 1, inner, np.where(s == 1, 2 * np.pi, 4 * np.pi))


def lobe_power_matched(sin_theta: ArrayLike, w: ArrayLike) -> NDArray[np.float64]:
    """A per-BRDF-lobe power ``t_w`` that makes Eq. 7 exact when ``D = C`` (float64, the candidate
    improvement measured by ``envcap bench dynamic``): the cap integral of ``cos^w`` about its axis
    is ``2 pi (1 - c^(w+1)) / (w + 1)`` and Eq. 7 gives ``2 pi / (1 + w + t)``, so
    ``t_w = (w + 1) c^(w+1) / (1 - c^(w+1))`` (``w = 0``: the solid-angle match)."""
    s = np.asarray(sin_theta, dtype=np.float64)
    w = np.maximum(np.asarray(w, dtype=np.float64), 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        log_cw = (w + 1) * 0.5 * np.log1p(-np.minimum(s * s, 1.0))
        t = (w + 1) * np.exp(log_cw) / -np.expm1(log_cw)
    return np.where(s >= 1, 0.0, np.minimum(np.nan_to_num(t, nan=MAX_POWER, posinf=MAX_POWER), MAX_POWER))
