"""The product of two cosine lobes, Eq. 4-7 of the seed paper (numpy twin of
``envcap_lobe_product`` in ``shaders/runtime/envcap_dynamic.glsl``).

An occluder lobe ``max(0, u.D)^t`` (a sphere seen from the shading point, :mod:`sphere_lobe`) times
a BRDF lobe ``max(0, u.C)^w`` (unit axis ``C``, ``|Cv| = 1``: the caller multiplies by
``|Cv|^w``) is approximated by one lobe along the unit vector ``M``:

* Eq. 4 (``D.C >= 0``): ``M = normalize(D t^k + C w^k)``, ``k = LOBE_EXPONENT = 0.7``;
* Eq. 5 (``D.C < 0``): ``M`` on the great circle from ``D`` to ``C`` at the fraction
  ``w^k / (t^k + w^k)`` of the angle ``gamma`` between them (built with the in-plane
  perpendicular, the cross-product construction; the issue does not quote Eq. 5, see
  ``docs/dynamic.md``);
* Eq. 6: ``peak = h(M.C)^w h(M.D)^t``, ``h = max(0, .)``;
* Eq. 7: ``integral = pi peak (D.C + 1) / (1 + w + t)``, computed as
  ``2 pi peak cos^2(gamma / 2) / (1 + w + t)``.

Everything is evaluated through angles (``gamma = atan2(|D x C|, D.C)``, ``alpha`` = angle from
``D`` to ``M``) so that it stays accurate for sharp lobes: ``cos(x)^p = exp(p ln cos x)`` with
``ln cos x`` accurate at small ``x``.  Limits (all finite): ``t, w`` NaN or < 0 -> 0, > MAX_POWER
(also +inf) -> MAX_POWER; ``t = w = 0`` -> equal weights (the bisector); ``C = 0`` -> ``(0, 0, 1)``;
``D = 0`` -> ``D = C`` (the sphere contains the point: with ``t = 0`` the whole lobe is blocked,
``2 pi / (1 + w)``); ``D`` opposite to ``C`` -> a fixed perpendicular (integral 0);
``0^0 = 0`` for ``h``: a power-0 lobe is its hemisphere.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.runtime.glsl_math import dot3

LOBE_EXPONENT = 0.7
"""The paper's empirical exponent ``k`` of the weights ``t^k``, ``w^k`` (Eq. 4-5).  GLSL ``ENVCAP_LOBE_EXPONENT``."""
MAX_POWER = 1.0e30
"""Lobe powers are clamped to this (a sphere of radius 0 maps to it: it blocks ~nothing).  GLSL ``ENVCAP_MAX_POWER``."""
LN_COS_SERIES_BELOW = 0.25
"""Below this angle (rad) ``ln cos x`` is its Taylor series (4 terms, relative error < 1e-7)."""


@dataclass(frozen=True)
class LobeProduct:
    """Eq. 4-7 for ``(...)`` pairs of lobes: ``axis`` ``(..., 3)`` unit ``M``; ``peak`` (Eq. 6);
    ``integral`` (Eq. 7, sr, for ``|Cv| = 1``); ``gamma`` the angle between ``D`` and ``C`` (rad).
    envcap's form (:func:`envcap.dynamic.cap_lobe.cap_lobe_product`) puts the blocked fraction in ``peak``."""

    axis: NDArray
    peak: NDArray
    integral: NDArray
    gamma: NDArray


def clean_power(p: NDArray, dtype: Any) -> NDArray:
    """``p`` NaN or < 0 -> 0; above MAX_POWER (+inf included) -> MAX_POWER."""
    return np.where(p > 0, np.minimum(p, dtype(MAX_POWER)), dtype(0)).astype(dtype)


def cos_power(x: NDArray, p: NDArray, dtype: Any = np.float64) -> NDArray:
    """``h(cos x)^p`` for angles ``x`` (rad, ``|x|`` used) and powers ``p >= 0``: 0 for
    ``|x| >= pi/2`` (also when ``p = 0``: the lobe's hemisphere), 1 for ``p = 0`` inside it,
    else ``exp(p ln cos x)``; ``ln cos x = log1p(-2 sin^2(x/2))`` in float64, the GLSL form
    (4-term series below LN_COS_SERIES_BELOW, else ``log(cos x)``) in float32."""
    x = np.abs(np.asarray(x, dtype=dtype))
    p = np.asarray(p, dtype=dtype)
    x2 = x * x
    series = -x2 * (dtype(0.5) + x2 * (dtype(1 / 12) + x2 * (dtype(1 / 45) + x2 * dtype(17 / 2520))))
    cx = np.cos(x)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        if np.dtype(dtype) == np.float64:   # the accurate form; float32: the GLSL form
            sx = np.sin(0.5 * x)
            lc = np.log1p(np.maximum(-2.0 * sx * sx, -1.0))
        else:
            lc = np.where(x < dtype(LN_COS_SERIES_BELOW), series, np.log(np.where(cx > 0, cx, dtype(1))))
        val = np.where(p > 0, np.exp(p * lc), dtype(1))
    inside = (x < dtype(np.pi / 2)) & (cx > 0)
    return np.where(inside, val, dtype(0)).astype(dtype)


def any_perpendicular(d: NDArray, dtype: Any = np.float64) -> NDArray:
    """A unit vector perpendicular to unit ``d`` (``(..., 3)``), Duff et al. 2017's basis."""
    s = np.where(d[..., 2] >= 0, dtype(1), dtype(-1))
    a = dtype(-1) / (s + d[..., 2])
    b = d[..., 0] * d[..., 1] * a
    return np.stack([dtype(1) + s * d[..., 0] * d[..., 0] * a, s * b, -s * d[..., 0]], axis=-1).astype(dtype)


def unit_or(v: NDArray, fallback: NDArray, dtype: Any) -> tuple[NDArray, NDArray]:
    """``(v / |v|, |v|)``, with ``fallback`` where ``|v|`` is 0 (or NaN)."""
    ln = np.sqrt(dot3(v, v))
    ok = ln > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        u = v / np.where(ok, ln, dtype(1))[..., None]
    return np.where(ok[..., None], u, fallback).astype(dtype), ln


def lobe_product(D: ArrayLike, C: ArrayLike, t: ArrayLike, w: ArrayLike, exponent: float = LOBE_EXPONENT,
                 dtype: Any = np.float64) -> LobeProduct:
    """Eq. 4-7 for the occluder lobe ``(D, t)`` and the BRDF lobe ``(C, w)``.

    ``D``, ``C``: ``(..., 3)`` directions (any length; world or local frame, the same for both);
    ``t``, ``w``: ``(...)`` powers.  ``dtype=np.float32`` evaluates in the GLSL order.
    """
    D, C = (np.asarray(a, dtype=dtype) for a in (D, C))
    t, w = (clean_power(np.asarray(a, dtype=dtype), dtype) for a in (t, w))
    D, C = np.broadcast_arrays(D, C)
    c, _ = unit_or(C, np.array([0, 0, 1], dtype=dtype), dtype)
    d, _ = unit_or(D, c, dtype)
    cos_g = dot3(d, c)
    dxc = np.cross(d, c).astype(dtype)
    sin_g = np.sqrt(dot3(dxc, dxc))
    gamma = np.arctan2(sin_g, cos_g).astype(dtype)
    p, _ = unit_or(c - cos_g[..., None] * d, any_perpendicular(d, dtype), dtype)
    k = dtype(exponent)
    with np.errstate(divide="ignore", invalid="ignore"):
        a = np.where(t > 0, np.power(t, k), dtype(0)).astype(dtype)
        b = np.where(w > 0, np.power(w, k), dtype(0)).astype(dtype)
    none = (a + b) == 0
    a, b = np.where(none, dtype(1), a), np.where(none, dtype(1), b)
    alpha = np.where(cos_g >= 0, np.arctan2(b * sin_g, a + b * cos_g), gamma * (b / (a + b))).astype(dtype)
    M = np.cos(alpha)[..., None] * d + np.sin(alpha)[..., None] * p
    peak = cos_power(gamma - alpha, w, dtype) * cos_power(alpha, t, dtype)
    half = np.cos(dtype(0.5) * gamma)
    integral = dtype(2 * np.pi) * peak * (half * half) / (dtype(1) + w + t)
    return LobeProduct(M.astype(dtype), peak.astype(dtype), integral.astype(dtype), gamma)
