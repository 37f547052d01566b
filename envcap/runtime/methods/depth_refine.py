"""``depth_refine``: the fitted planes' hit, checked against the probe's distance and moved onto
the surface the probe saw where the planes are wrong; the oblique mip shift at the refined hit.

1. Three-plane hit of the ray ``x + t d`` with the probe's **fitted** planes (the parallax of
   ``planes_mip_oblique``): ``h = x_c + t d`` (``x_c``: ``x`` clamped into the street), seen from
   the probe at ``p`` along ``u = (h - p) / |h - p|`` (a ray that hits no plane: ``t`` = FAR).
2. **Check** (1 fetch of the inverse-distance texture, nearest texel): ``s = 1 / D(u)`` (1/m; 0
   where the probe sees the sky).  The planes are right there when ``| |h - p| s - 1 | <= TOL``
   (the probe sees a surface at the plane's distance), or when ``s = 0`` (the probe sees sky
   there: the planes keep the roof lines where they are; an infinite facade plane reprojects them).
3. Otherwise (a set-back, a gap, the open cross street, a street end), ``STEPS`` fixed-point
   steps: ``t`` becomes the ray's exit from the sphere of radius ``1 / s`` around the probe
   (``t = -b + sqrt(b^2 - |o|^2 + 1/s^2)``, ``o = x_c - p``, ``b = o . d``; kept where there is
   no positive root or ``s = 0``), then ``s`` is read again towards the new hit (``STEPS - 1``
   more fetches).  At the probe's own position (``o = 0``) the first step is exact.
4. The probe is sampled towards the (refined) hit ``r`` at ``w' = w q``,
   ``q = (|h - p| / t)^2 cos(alpha) / cos(beta)``: the oblique shift of ``planes_mip_oblique``
   with the normal of the plane the ray left through (the only normal at hand; exact where the
   planes were right), clamped to ``[1/MAX_RATIO^2, MAX_RATIO^2]``; unrefined rays that hit no
   plane: ``r = d``, ``q = 1``.  Street radiance composited over the sky as every method.

The distance is read **nearest texel** (GL ``NEAREST``): a bilinear read mixes a roof's distance
with the sky's 0 at every roof line and sends the check off there (measured: canyon w = 64 error
0.111 bilinear vs 0.101 nearest).  Stored as the inverse distance so that the sky is 0 (no Inf
in a texture) and far surfaces need no range.  Measured in docs/evaluation.md ("Narrow streets").

Cost: 1 probe fetch + 1 sky fetch (skipped where alpha = 1) + 1 distance fetch, + ``STEPS - 1``
distance fetches where the check fails (a branch: on a GPU only those pixels pay); a
single-channel nearest fetch of level 0.  Needs: the fitted plane set and the probe set's
distance channel (the runtime uploads :func:`inverse_distance` as a cube-map array, one layer per
probe, like the probes).  Parameters: ``steps`` = 2, ``tol`` = 0.1 (:data:`PARAMETERS`).  GLSL:
``envcap_sample_depth_refine`` (``shaders/runtime/envcap_depth_refine.glsl``; it takes the
distance texture as an extra sampler, so the registry's ``glsl`` field, whose functions take the
probes and the sky only, stays ``None``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core import cube
from envcap.core.inverse_distance import MAX_DISTANCE, inverse_distance  # noqa: F401 (MAX_DISTANCE: public here too)
from envcap.runtime.chains import ProbeChains
from envcap.runtime.footprint import MIN_COS, hit_normal
from envcap.runtime.glsl_math import dot3
from envcap.runtime.limits import FAR, MAX_RATIO, MIN_DIST
from envcap.runtime.methods.registry import ParallaxMethod
from envcap.runtime.mip import scale_power
from envcap.runtime.parallax import clamp_to_street, exit_distance
from envcap.runtime.street import RuntimeStreet

PARAMETERS = {"steps": 2, "tol": 0.1}
"""``steps``: distance reads (the check plus ``steps - 1`` refinement reads; ``steps`` sphere
steps); ``tol``: relative distance mismatch above which the planes' hit is refined.  GLSL
``ENVCAP_DEPTH_STEPS``, ``ENVCAP_DEPTH_TOL``."""

MIN_INV_DISTANCE = 1.0e-5
"""Inverse distances (1/m) at or below this count as sky (surfaces beyond 100 km).  GLSL
``ENVCAP_MIN_INV_DISTANCE``."""

def fetch_inverse(inv: NDArray, u: NDArray, layer: ArrayLike) -> NDArray[np.float64]:
    """Nearest-texel read of ``inv`` ``(L, 6, N, N)`` along unit ``u`` ``(M, 3)`` of ``layer``
    (GL ``NEAREST`` on a cube-map array: face by the major axis, texel ``floor(s N)``)."""
    f, j, i = cube.direction_to_texel(u, inv.shape[2])
    lay = np.broadcast_to(np.asarray(layer, np.int64).reshape(-1), f.shape)
    return inv[lay, f, j, i].astype(np.float64)


def depth_refine(x: ArrayLike, d: ArrayLike, p: ArrayLike, planes: ArrayLike, along: int, inv: NDArray,
                 layer: ArrayLike, steps: int = 2, tol: float = 0.1,
                 level_bias: float = 1.0) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(r, q)``: unit direction ``(M, 3)`` from the probe to the (refined) hit and the power
    multiplier ``(M,)`` (``w' = w q``), for shading points ``x`` (3,) or (M, 3), unit directions
    ``d`` (M, 3), probe positions ``p`` and ``planes`` (3,) / (M, 3) (or 4 columns with a ground
    slope), ``inv`` :func:`inverse_distance` ``(L, 6, N, N)``, ``layer`` (M,) or scalar.  Module
    docstring: the steps.  ``level_bias``: a finite factor > 0 on every ``q`` (``w' = w q
    level_bias``; > 1 reads a sharper level); 1 (the default, the GLSL's) leaves ``q`` bit for bit.
    Only a calibration knob (``envcap bench level_bias``, docs/evaluation.md): the runtime method
    does not set it.  Every output is finite for finite inputs."""
    if steps < 1:
        raise ValueError(f"steps must be >= 1, got {steps}")
    if not (math.isfinite(level_bias) and level_bias > 0):
        raise ValueError(f"level_bias must be a finite number > 0, got {level_bias}")
    d = np.asarray(d, np.float64).reshape(-1, 3)
    m = d.shape[0]
    x = np.broadcast_to(np.asarray(x, np.float64).reshape(-1, 3), (m, 3))
    p = np.broadcast_to(np.asarray(p, np.float64).reshape(-1, 3), (m, 3))
    pl = np.asarray(planes, np.float64)
    pl = np.broadcast_to(pl.reshape(-1, pl.shape[-1]), (m, pl.shape[-1]))
    lay = np.broadcast_to(np.asarray(layer, np.int64).reshape(-1), (m,))
    xc = clamp_to_street(x, pl, along)
    t = exit_distance(xc, d, pl, along)                 # FAR: no plane hit
    n = hit_normal(xc, d, pl, along)
    o = xc - p

    def towards(tt: NDArray) -> tuple[NDArray, NDArray]:
        h = o + tt[:, None] * d
        hl = np.sqrt(dot3(h, h))
        return np.where((hl > MIN_DIST)[:, None], h / np.where(hl > MIN_DIST, hl, 1.0)[:, None], d), hl

    u, hl = towards(t)
    s = fetch_inverse(inv, u, lay)
    refine = (s > MIN_INV_DISTANCE) & (np.abs(hl * s - 1.0) > tol)
    b = dot3(o, d)
    oo = dot3(o, o)
    tr = t.copy()
    for k in range(steps):
        sky = ~(s > MIN_INV_DISTANCE)
        with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
            rad = 1.0 / np.where(sky, 1.0, s)
            disc = b * b - (oo - rad * rad)
            tn = -b + np.sqrt(np.maximum(disc, 0.0))
        tr = np.where(~sky & (disc >= 0) & (tn > 0), tn, tr)
        if k + 1 < steps:
            s = fetch_inverse(inv, towards(tr)[0], lay)
    t = np.where(refine, tr, t)
    hit = t < FAR
    r, dp = towards(t)
    ok = hit & (dp > MIN_DIST)
    r = np.where(ok[:, None], r, d)
    ratio = np.clip(dp / np.maximum(t, MIN_DIST), 1.0 / MAX_RATIO, MAX_RATIO)
    ca = np.maximum(np.abs(dot3(n, d)), MIN_COS)
    cb = np.maximum(np.abs(dot3(n, r)), MIN_COS)
    lo, hi = 1.0 / (MAX_RATIO * MAX_RATIO), MAX_RATIO * MAX_RATIO
    q = np.clip(ratio * ratio * (ca / cb), lo, hi)
    q = np.where(ok, q, np.where(hit, lo, 1.0))
    return r, (q if level_bias == 1.0 else q * level_bias)


_inverse_cache: dict[int, tuple[Any, NDArray[np.float32]]] = {}


def chains_inverse(chains: ProbeChains) -> NDArray[np.float32]:
    """:func:`inverse_distance` of ``chains.distance``, computed once per distance array."""
    key = id(chains.distance)
    hit = _inverse_cache.get(key)
    if hit is None or hit[0] is not chains.distance:
        _inverse_cache.clear()
        hit = (chains.distance, inverse_distance(chains.distance))
        _inverse_cache[key] = hit
    return hit[1]


def street_rgba(chains: ProbeChains, street: RuntimeStreet, x: NDArray, d: NDArray, w: NDArray,
                **parameters: Any) -> NDArray[np.float64]:
    """The nearest probe sampled towards the depth-refined hit at the oblique level."""
    i = street.nearest(x)
    shape = d.shape[:-1]
    layer = np.broadcast_to(street.layers[i], shape)
    r, q = depth_refine(x.reshape(-1, 3), d.reshape(-1, 3), street.positions[i].reshape(-1, 3),
                        street.lookup_planes[i].reshape(-1, street.lookup_planes.shape[-1]), street.along,
                        chains_inverse(chains), layer.reshape(-1), **parameters)
    return chains.fetch(r.reshape(d.shape), layer, scale_power(w, q.reshape(shape)))


METHOD = ParallaxMethod("depth_refine", street_rgba,
                        "fitted planes' hit checked against the probe's distance, refined where wrong; oblique shift",
                        planes="fitted", needs_distance=True, parameters=PARAMETERS)
