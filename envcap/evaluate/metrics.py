"""Error metrics on cube maps, weighted by exact texel solid angles, and the plane misfit of a position.

All metrics compare luminance ``Y = 0.2126 R + 0.7152 G + 0.0722 B`` (Rec.709, linear) of cubes
``(..., 6, N, N, 3+)`` and weight every texel by its solid angle, so that the result is an
integral over the sphere and does not depend on how the cube parameterizes it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core import cube
from envcap.core.color import luminance
from envcap.runtime.parallax import clamp_to_street, exit_distance
from envcap.runtime.street import RuntimeStreet


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


def plane_misfit(x: ArrayLike, distance: NDArray, alpha: NDArray, street: RuntimeStreet, rel: float = 0.2,
                 abs_m: float = 0.25) -> float:
    """Share of the sphere (solid-angle weighted, 0..1) seen from the world point ``x`` (``distance``
    captured with its axes along the street's frame) where the three nominal
    planes of the nearest probe are the wrong model: the true hit distance (``distance``
    ``(6, N, N)`` m from ``x``, geometry where ``alpha > 0.5``) and the planes' exit distance
    differ by more than ``rel`` (relative) + ``abs_m`` (m), or one of them sees the sky (no
    hit within 1 km) and the other does not.  Gaps, crossings, setbacks and open squares raise it.
    """
    x = street.to_frame(np.asarray(x, np.float64))      # the capture's axes are the street's frame
    n = distance.shape[1]
    d = cube.texel_directions(n)
    planes = street.lookup_planes[int(street.nearest(x))]
    xc = clamp_to_street(x, planes, street.along)
    t_model = exit_distance(xc, d, planes, street.along)
    geo = (np.asarray(alpha) > 0.5) & (np.asarray(distance) > 0)
    t_true = np.where(geo, np.asarray(distance, np.float64), np.inf)
    far = 1000.0
    sky_true, sky_model = ~(t_true < far), ~(t_model < far)
    with np.errstate(invalid="ignore"):
        close = np.abs(t_true - t_model) <= rel * np.minimum(t_true, t_model) + abs_m
    ok = (sky_true & sky_model) | (~sky_true & ~sky_model & close)
    om = cube.texel_solid_angles(n)
    return float(np.sum(om[~ok]) / (4.0 * np.pi))
