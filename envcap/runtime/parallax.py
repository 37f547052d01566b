"""Street geometry of the runtime (twin of ``shaders/runtime/envcap_street.glsl``): probe
selection along a street and three-plane parallax.

Every function is vectorized (inputs broadcast; vectors are ``(..., 3)``), float64 by default;
``dtype=np.float32`` evaluates in float32 in the GLSL operation order, to compare with the GPU.
Conventions: world right-handed, meters, +Y up; a street runs along world axis ``along``
(0 = x, 2 = z), its cross axis is ``2 - along``; ``planes = (facade_min, facade_max, ground)``
in absolute world coordinates (m).  Math and fallbacks: ``docs/runtime.md``.  Nothing here
returns NaN or Inf for finite inputs; the fallbacks are the GLSL ones.
"""

from __future__ import annotations

from typing import Any

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


def clamp_to_street(x: ArrayLike, planes: ArrayLike, along: int, dtype: Any = np.float64) -> NDArray:
    """``x`` moved into the street volume (cross coordinate into the facades, height >= ground)."""
    c = 2 - check_along(along)
    x = np.asarray(x, dtype=dtype).copy()
    pl = np.asarray(planes, dtype=dtype)
    x, pl = np.broadcast_arrays(x, pl)
    x = x.copy()
    x[..., c] = np.minimum(np.maximum(x[..., c], pl[..., 0]), pl[..., 1])
    x[..., 1] = np.maximum(x[..., 1], pl[..., 2])
    return x


def exit_distance(x: ArrayLike, d: ArrayLike, planes: ArrayLike, along: int, dtype: Any = np.float64) -> NDArray:
    """Distance (m) along unit ``d`` from ``x`` (inside the street) to the first plane, or FAR.

    +0.0 and -0.0 direction components mean "parallel" (no division happens for them).
    """
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
        tg = np.where(d[..., 1] < 0, (pl[..., 2] - x[..., 1]) / np.where(d[..., 1] < 0, d[..., 1], 1), far)
    return np.minimum(np.minimum(tc, tg), far)


def parallax(x: ArrayLike, d: ArrayLike, p: ArrayLike, planes: ArrayLike, along: int,
             dtype: Any = np.float64) -> tuple[NDArray, NDArray]:
    """Three-plane parallax: ``(r, ratio)`` for shading points ``x``, unit directions ``d``,
    probe positions ``p`` and planes (all broadcast; vectors ``(..., 3)``).

    ``r`` (``(..., 3)``) is the unit vector from the probe to the hit point; ``ratio`` = |hit - p|
    / |hit - x| clamped to [1/MAX_RATIO, MAX_RATIO].  Fallbacks: no hit -> ``(d, 1)``; hit within
    MIN_DIST of the probe -> ``(d, 1/MAX_RATIO)``; ``x`` on a plane -> |hit - x| taken as MIN_DIST.
    Points outside the street or below the ground are first clamped into it.
    """
    x, d, p, planes = (np.asarray(a, dtype=dtype) for a in (x, d, p, planes))
    shape = np.broadcast_shapes(x.shape, d.shape, p.shape, planes.shape)
    x, d, p, planes = (np.broadcast_to(a, shape) for a in (x, d, p, planes))
    xc = clamp_to_street(x, planes, along, dtype)
    t = exit_distance(xc, d, planes, along, dtype)
    hit = t < dtype(FAR)
    r = (xc - p) + t[..., None] * d
    dp = np.sqrt(dot3(r, r))
    ok = hit & (dp > dtype(MIN_DIST))
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = dp / np.maximum(t, dtype(MIN_DIST))
        ratio = np.minimum(np.maximum(ratio, dtype(1.0 / MAX_RATIO)), dtype(MAX_RATIO))
        rn = r / np.where(ok, dp, 1)[..., None]
    r_out = np.where(ok[..., None], rn, d)
    ratio_out = np.where(ok, ratio, np.where(hit, dtype(1.0 / MAX_RATIO), dtype(1.0))).astype(dtype)
    return r_out.astype(dtype), ratio_out
