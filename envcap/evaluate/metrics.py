"""Error metrics on cube maps, weighted by exact texel solid angles.

All metrics compare luminance ``Y = 0.2126 R + 0.7152 G + 0.0722 B`` (Rec.709, linear) of cubes
``(..., 6, N, N, 3+)`` and weight every texel by its solid angle, so that the result is an
integral over the sphere and does not depend on how the cube parameterizes it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from envcap.core import cube

REC709_LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
"""Luminance weights of linear Rec.709 RGB."""


def luminance(rgb: NDArray[np.floating]) -> NDArray[np.float64]:
    """Luminance of linear Rec.709 colors ``(..., 3+)`` (extra channels ignored), float64."""
    a = np.asarray(rgb, dtype=np.float64)
    if a.shape[-1] < 3:
        raise ValueError(f"need at least 3 color channels, got shape {a.shape}")
    return a[..., :3] @ REC709_LUMINANCE


def relative_rmse(pred: NDArray[np.floating], truth: NDArray[np.floating]) -> float:
    """Solid-angle weighted relative RMSE of luminance between two cubes ``(6, N, N, C)``.

    ``sqrt(sum_i Omega_i (Y_pred,i - Y_truth,i)^2) / sqrt(sum_i Omega_i Y_truth,i^2)``: the L2
    error over the sphere relative to the L2 norm of the truth.  A black truth gives 0 when the
    prediction is black too and ``inf``-free 1.0 otherwise (the error is then 100 % of the
    prediction).  Leading batch dimensions are summed over.
    """
    p = np.asarray(pred)
    t = np.asarray(truth)
    if p.shape != t.shape:
        raise ValueError(f"prediction shape {p.shape} differs from truth shape {t.shape}")
    n = t.shape[-2]
    cube.check_cube(t.reshape((-1,) + t.shape[-4:])[0])
    w = cube.texel_solid_angles(n)
    yp, yt = luminance(p), luminance(t)
    if not (np.all(np.isfinite(yp)) and np.all(np.isfinite(yt))):
        raise ValueError("cubes contain NaN or Inf")
    num = float(np.sum(w * (yp - yt) ** 2))
    den = float(np.sum(w * yt**2))
    if den == 0.0:
        return 0.0 if num == 0.0 else 1.0
    return float(np.sqrt(num / den))


def relative_error_map(pred: NDArray[np.floating], truth: NDArray[np.floating], floor: float | None = None) -> NDArray[np.float64]:
    """Per-texel relative luminance error ``|Y_p - Y_t| / max(Y_t, floor)`` of ``(6, N, N, C)`` cubes.

    ``floor`` defaults to 1 % of the truth's solid-angle weighted mean luminance, so that black
    texels do not blow up the map.  Returns ``(6, N, N)``.
    """
    yp, yt = luminance(pred), luminance(truth)
    if floor is None:
        w = cube.texel_solid_angles(yt.shape[-1])
        floor = max(0.01 * float(np.sum(w * yt) / (4 * np.pi)), 1e-12)
    return np.abs(yp - yt) / np.maximum(yt, floor)
