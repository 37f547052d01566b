"""``depth_reproject``: a reference method that marches the lookup ray through the nearest
probe's distance channel instead of three planes.

The ray ``x + t d`` is sampled at ``steps`` geometric ``t`` in ``[t_min, t_max]`` m; a sample is
*behind* when its distance from the probe exceeds the probe's stored distance towards it
(nearest texel).  The first behind sample within ``thickness`` (relative, + 0.1 m) of the surface
is the hit, refined by ``refine`` bisection steps; the probe is sampled towards it with the mip
shift of the hit distances.  Rays whose behind samples are all too deep (the hit is occluded from
the probe) fall back to three-plane parallax; rays that never pass behind anything see the sky
(``r = d``, no shift).  Numpy only (no GLSL): it shows what the three planes leave on the table.

Needs: the probe set's distance channel and the fitted plane set (its fallback).
Parameters: ``steps`` = 32, ``t_min`` = 0.05 m, ``t_max`` = 2000 m, ``thickness`` = 0.15,
``refine`` = 6 (:data:`PARAMETERS`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core import cube
from envcap.runtime.chains import ProbeChains
from envcap.runtime.limits import MAX_RATIO, MIN_DIST
from envcap.runtime.methods.registry import ParallaxMethod
from envcap.runtime.mip import shift_power
from envcap.runtime.parallax import parallax
from envcap.runtime.street import RuntimeStreet

PARAMETERS = {"steps": 32, "t_min": 0.05, "t_max": 2000.0, "thickness": 0.15, "refine": 6}
"""Ray-march parameters (see the module docstring)."""


def depth_reproject(x: ArrayLike, d: ArrayLike, p: ArrayLike, distance: NDArray, planes: ArrayLike, along: int,
                    layer: ArrayLike | None = None, steps: int = 32, t_min: float = 0.05, t_max: float = 2000.0,
                    thickness: float = 0.15, refine: int = 6) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Reprojection through a probe's distance channel: ``(r, ratio)`` like :func:`envcap.runtime.parallax.parallax`.

    ``x`` (3,) or (M, 3) shading points (m), ``d`` (M, 3) unit directions, ``p`` (3,) or (M, 3)
    probe positions, ``planes`` (3,) or (M, 3) the fallback planes; ``distance`` ``(6, N, N)``
    (one probe) or ``(L, 6, N, N)`` with ``layer`` (M,) the probe of each ray: radial distance
    (m, 0 = sky).  ``r`` ``(M, 3)`` points from the probe to the hit, ``ratio = |hit - p| /
    |hit - x|`` (clamped like the runtime).  Rays are independent: the result of each is the same
    whether it is marched alone or with others.
    """
    d = np.asarray(d, np.float64).reshape(-1, 3)
    m = d.shape[0]
    x = np.broadcast_to(np.asarray(x, np.float64).reshape(-1, 3), (m, 3))
    p = np.broadcast_to(np.asarray(p, np.float64).reshape(-1, 3), (m, 3))
    planes = np.asarray(planes, np.float64)
    planes = np.broadcast_to(planes.reshape(-1, planes.shape[-1]), (m, planes.shape[-1]))   # 3, or 4 with a slope
    D = np.asarray(distance, np.float64)
    if D.ndim == 3:
        D, layer = D[None], None
    lay = np.zeros(m, np.int64) if layer is None else np.broadcast_to(np.asarray(layer, np.int64).reshape(-1), (m,))
    n = D.shape[2]
    ts = np.geomspace(t_min, t_max, steps)

    def probe_depth(q: NDArray) -> tuple[NDArray, NDArray]:
        """Distance of points ``q`` ((M, 3) or (M, S, 3)) from the probe, and the probe's stored
        distance towards them (inf where it sees the sky)."""
        marched = q.ndim == 3
        v = q - (p[:, None, :] if marched else p)
        ln = np.linalg.norm(v, axis=-1)
        v = np.where((ln > 1e-9)[..., None], v, d[:, None, :] if marched else d)
        f, j, i = cube.direction_to_texel(v, n)
        stored = D[lay[:, None] if marched else lay, f, j, i]
        return ln, np.where(stored > 0, stored, np.inf)

    q = x[:, None, :] + ts[None, :, None] * d[:, None, :]          # (M, S, 3)
    ln, depth = probe_depth(q)
    behind = ln >= depth
    near = behind & (ln - depth <= thickness * depth + 0.1)
    any_behind = behind.any(axis=1)
    hit = near.any(axis=1)
    k = np.argmax(near, axis=1)
    t_hi = ts[k]
    t_lo = np.where(k > 0, ts[np.maximum(k - 1, 0)], 0.0)
    for _ in range(refine):
        tm = 0.5 * (t_lo + t_hi)
        lm, dm = probe_depth(x + tm[:, None] * d)
        b = lm >= dm
        t_hi = np.where(b, tm, t_hi)
        t_lo = np.where(b, t_lo, tm)
    t = t_hi
    h = x + t[:, None] * d
    rv = h - p
    dp = np.linalg.norm(rv, axis=1)
    ok = hit & (dp > MIN_DIST)
    r = np.where(ok[:, None], rv / np.where(ok, dp, 1.0)[:, None], d)
    ratio = np.clip(dp / np.maximum(t, MIN_DIST), 1.0 / MAX_RATIO, MAX_RATIO)
    ratio = np.where(ok, ratio, 1.0)
    # occluded from the probe: three planes; nothing behind at all: sky (r = d, ratio 1)
    fb = ~hit & any_behind
    if np.any(fb):
        r_pl, ratio_pl = parallax(x[fb], d[fb], p[fb], planes[fb], along)
        r[fb], ratio[fb] = r_pl, ratio_pl
    return r, ratio


def street_rgba(chains: ProbeChains, street: RuntimeStreet, x: NDArray, d: NDArray, w: NDArray,
                **parameters: float) -> NDArray[np.float64]:
    """The nearest probe sampled towards the ray's hit in its distance channel, shifted level."""
    i = street.nearest(x)
    layer = street.layers[i]
    r, ratio = depth_reproject(x, d, street.positions[i], chains.distance, street.lookup_planes[i], street.along,
                               layer=layer, **parameters)
    shape = d.shape[:-1]
    return chains.fetch(r.reshape(d.shape), layer, shift_power(w, ratio.reshape(shape)))


METHOD = ParallaxMethod("depth_reproject", street_rgba,
                        "nearest probe, the ray marched through its distance channel (reference)",
                        planes="fitted", needs_distance=True, parameters=PARAMETERS)
