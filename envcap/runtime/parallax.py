"""Street geometry of the runtime (twin of ``shaders/runtime/envcap_street.glsl``): probe
selection along a street and three-plane parallax.

Every function is vectorized (inputs broadcast; vectors are ``(..., 3)``), float64 by default;
``dtype=np.float32`` evaluates in float32 in the GLSL operation order, to compare with the GPU.
Conventions: right-handed, meters, +Y up, in the street's frame (the world for a street along
x or z; frame coordinates for a street at any angle, :mod:`envcap.core.street_frame`); a street
runs along axis ``along`` (0 = x, 2 = z), its cross axis is ``2 - along``; ``planes =
(facade_min, facade_max, ground)`` in absolute coordinates (m), or ``(facade_min, facade_max,
ground0, slope)`` for a tilted ground (GLSL ``planes.w``): the ground's height at a point is
``ground0 + slope * s``, ``s`` its along-street coordinate (``ground0``: the height at ``s = 0``),
normal ``(-slope, 1, 0) / sqrt(1 + slope^2)`` in (along, y, cross).  ``slope = 0`` gives exactly
the three-component numbers.  Math and fallbacks: ``docs/runtime.md``.  Nothing here returns
NaN or Inf for finite inputs; the fallbacks are the GLSL ones.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.runtime.glsl_math import dot3
from envcap.runtime.limits import FAR, MAX_PROBES, MAX_RATIO, MIN_DIST


def check_along(along: int) -> int:
    """``along`` if it is a street axis index (0 = x, 2 = z), else ``ValueError``."""
    if along not in (0, 2):
        raise ValueError(f"street axis index must be 0 (x) or 2 (z), got {along!r}")
    return along


def nearest_probe(s: ArrayLike, along_coords: ArrayLike) -> NDArray[np.int64]:
    """Index of the probe nearest to along-street coordinate(s) ``s`` (ties: lower index).

    ``along_coords`` (m) sorted ascending, 1..MAX_PROBES of them.
    """
    a = np.asarray(along_coords, dtype=np.float64)
    if a.ndim != 1 or not 1 <= a.size <= MAX_PROBES:
        raise ValueError(f"need 1..{MAX_PROBES} probe coordinates, got shape {a.shape}")
    s = np.asarray(s, dtype=np.float64)
    return np.argmin(np.abs(s[..., None] - a), axis=-1)


def probe_pair(s: ArrayLike, along_coords: ArrayLike, dtype: Any = np.float64) -> tuple[NDArray, NDArray, NDArray]:
    """The two probes bracketing ``s`` and the weight ``t`` of the second (blend ``(1-t), t``).

    Linear in ``s`` between probes, so continuous; outside the probe range both indices are the
    end probe and ``t = 0``.  Returns ``(i0, i1, t)``.
    """
    a = np.asarray(along_coords, dtype=dtype)
    if a.ndim != 1 or not 1 <= a.size <= MAX_PROBES:
        raise ValueError(f"need 1..{MAX_PROBES} probe coordinates, got shape {a.shape}")
    s = np.asarray(s, dtype=dtype)
    n = a.size
    i = np.clip(np.searchsorted(a, s, side="right") - 1, 0, max(n - 2, 0))
    i0 = i.copy()
    i1 = np.minimum(i + 1, n - 1)
    span = a[i1] - a[i0]
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(span > 0, np.clip((s - a[i0]) / np.where(span > 0, span, 1), 0, 1), 0).astype(dtype)
    lo = ~(s > a[0])
    hi = ~lo & ~(s < a[n - 1])
    i0 = np.where(lo, 0, np.where(hi, n - 1, i0))
    i1 = np.where(lo, 0, np.where(hi, n - 1, i1))
    t = np.where(lo | hi, dtype(0), t)
    return i0, i1, t


def tilted(planes: ArrayLike) -> bool:
    """Whether ``planes`` ``(..., 3 | 4)`` carry a ground slope (a fourth component)."""
    n = np.shape(planes)[-1]
    if n not in (3, 4):
        raise ValueError(f"planes must have 3 or 4 components (facade_min, facade_max, ground[, slope]), got {n}")
    return n == 4


def ground_height(x: NDArray, planes: NDArray, along: int, dtype: Any = np.float64) -> NDArray:
    """Height (m) of the ground under points ``x`` (GLSL ``planes.z + planes.w * x[along]``)."""
    if not tilted(planes):
        return planes[..., 2]
    return (planes[..., 2] + planes[..., 3] * x[..., along]).astype(dtype)


def ground_rate(d: NDArray, planes: NDArray, along: int, dtype: Any = np.float64) -> NDArray:
    """Rate (m per m) at which direction ``d`` rises above the ground: ``d_y - slope d_along``
    (negative: towards the ground; 0: parallel to it)."""
    if not tilted(planes):
        return d[..., 1]
    return (d[..., 1] - planes[..., 3] * d[..., along]).astype(dtype)


def clamp_to_street(x: ArrayLike, planes: ArrayLike, along: int, dtype: Any = np.float64) -> NDArray:
    """``x`` moved into the street volume (cross coordinate into the facades, height >= the ground
    under it; the along coordinate is kept)."""
    c = 2 - check_along(along)
    x = np.asarray(x, dtype=dtype)
    pl = np.asarray(planes, dtype=dtype)
    shape = np.broadcast_shapes(x.shape, pl.shape[:-1] + (3,))
    x = np.broadcast_to(x, shape).copy()
    pl = np.broadcast_to(pl, shape[:-1] + pl.shape[-1:])
    x[..., c] = np.minimum(np.maximum(x[..., c], pl[..., 0]), pl[..., 1])
    x[..., 1] = np.maximum(x[..., 1], ground_height(x, pl, along, dtype))
    return x


def plane_exits(x: ArrayLike, d: ArrayLike, planes: ArrayLike, along: int,
                dtype: Any = np.float64) -> tuple[NDArray, NDArray]:
    """``(t_c, t_g)``: distances (m) along ``d`` from ``x`` to the facade it runs towards and to the
    ground (FAR when parallel to it or moving away; may overflow to inf).  +0.0 and -0.0 rates
    mean "parallel" (no division happens for them)."""
    c = 2 - check_along(along)
    x = np.asarray(x, dtype=dtype)
    d = np.asarray(d, dtype=dtype)
    pl = np.asarray(planes, dtype=dtype)
    far = dtype(FAR)
    dc = d[..., c]
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        tpos = (pl[..., 1] - x[..., c]) / np.where(dc > 0, dc, 1)
        tneg = (pl[..., 0] - x[..., c]) / np.where(dc < 0, dc, 1)
        tc = np.where(dc > 0, tpos, np.where(dc < 0, tneg, far))
        dg = ground_rate(d, pl, along, dtype)
        tg = np.where(dg < 0, (ground_height(x, pl, along, dtype) - x[..., 1]) / np.where(dg < 0, dg, 1), far)
    return tc, tg


def exit_distance(x: ArrayLike, d: ArrayLike, planes: ArrayLike, along: int, dtype: Any = np.float64) -> NDArray:
    """Distance (m) along unit ``d`` from ``x`` (inside the street) to the first plane, or FAR
    (a ray parallel to a plane never hits it; a point on the ground going down: 0)."""
    tc, tg = plane_exits(x, d, planes, along, dtype)
    return np.minimum(np.minimum(tc, tg), dtype(FAR))


class PlaneHit(NamedTuple):
    """Where the lookup ray from ``x`` along ``d`` leaves the street (:func:`plane_hit`); arrays
    broadcast to one shape ``(..., 3)`` (``planes``: ``(..., 3)`` or ``(..., 4)``)."""

    x: NDArray       # the shading points, clamped into the street
    d: NDArray       # the unit directions
    p: NDArray       # the probe positions
    planes: NDArray  # the planes
    t: NDArray       # (...,) distance from x to the hit (m), FAR where none
    hit: NDArray     # (...,) t < FAR
    r: NDArray       # hit - p (m), not normalized
    dp: NDArray      # (...,) |hit - p| (m)
    ok: NDArray      # (...,) a hit at least MIN_DIST from the probe


def plane_hit(x: ArrayLike, d: ArrayLike, p: ArrayLike, planes: ArrayLike, along: int,
              dtype: Any = np.float64) -> PlaneHit:
    """The first plane hit of the rays from ``x`` along ``d`` seen from probes at ``p``: the
    common start of :func:`parallax` and the footprint (:mod:`envcap.runtime.footprint`)."""
    x, d, p, planes = (np.asarray(a, dtype=dtype) for a in (x, d, p, planes))
    shape = np.broadcast_shapes(x.shape, d.shape, p.shape, planes.shape[:-1] + (3,))
    x, d, p = (np.broadcast_to(a, shape) for a in (x, d, p))
    planes = np.broadcast_to(planes, shape[:-1] + planes.shape[-1:])
    xc = clamp_to_street(x, planes, along, dtype)
    t = exit_distance(xc, d, planes, along, dtype)
    hit = t < dtype(FAR)
    r = (xc - p) + t[..., None] * d
    dp = np.sqrt(dot3(r, r))
    return PlaneHit(xc, d, p, planes, t, hit, r, dp, hit & (dp > dtype(MIN_DIST)))


def parallax(x: ArrayLike, d: ArrayLike, p: ArrayLike, planes: ArrayLike, along: int,
             dtype: Any = np.float64) -> tuple[NDArray, NDArray]:
    """Three-plane parallax: ``(r, ratio)`` for shading points ``x``, unit directions ``d``,
    probe positions ``p`` and planes (all broadcast; vectors ``(..., 3)``).

    ``planes`` ``(..., 3)`` or ``(..., 4)`` with the ground slope (module docstring).
    ``r`` (``(..., 3)``) is the unit vector from the probe to the hit point; ``ratio`` = |hit - p|
    / |hit - x| clamped to [1/MAX_RATIO, MAX_RATIO].  Fallbacks: no hit -> ``(d, 1)``; hit within
    MIN_DIST of the probe -> ``(d, 1/MAX_RATIO)``; ``x`` on a plane -> |hit - x| taken as MIN_DIST.
    Points outside the street or below the ground are first clamped into it.
    """
    _, d, _, _, t, hit, r, dp, ok = plane_hit(x, d, p, planes, along, dtype)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = dp / np.maximum(t, dtype(MIN_DIST))
        ratio = np.minimum(np.maximum(ratio, dtype(1.0 / MAX_RATIO)), dtype(MAX_RATIO))
        rn = r / np.where(ok, dp, 1)[..., None]
    r_out = np.where(ok[..., None], rn, d)
    ratio_out = np.where(ok, ratio, np.where(hit, dtype(1.0 / MAX_RATIO), dtype(1.0))).astype(dtype)
    return r_out.astype(dtype), ratio_out


def frame_direction(d: ArrayLike, frame: ArrayLike, dtype: Any = np.float64) -> NDArray:
    """World directions ``d`` ``(..., 3)`` in a street's frame, ``frame = (cos yaw, sin yaw)``
    (:mod:`envcap.core.street_frame`), in GLSL ``envcap_frame_dir``'s operation order:
    ``(c d_x + s d_z, d_y, c d_z - s d_x)``.  ``frame = (1, 0)`` returns ``d`` (up to the sign of zeros)."""
    d = np.asarray(d, dtype=dtype)
    c, s = (dtype(v) for v in np.asarray(frame, dtype=dtype).reshape(2))
    return np.stack([c * d[..., 0] + s * d[..., 2], d[..., 1], c * d[..., 2] - s * d[..., 0]], axis=-1)
