"""Wide cosine lobes filtered in spherical harmonics (Funk-Hecke): the rungs of a rung ladder with
``w <= SH_MAX_POWER`` (``docs/lobes.md``, "Bake cost of a rung ladder").

A normalized zonal lobe acts on the degree-``l`` band of the environment as multiplication by its
Legendre coefficient; for the normalized ``max(0, d.u)^w`` lobe ``lambda_0 = 1``, ``lambda_1 = (w +
1) / (w + 2)`` and ``lambda_l = lambda_{l-2} (w - l + 2) / (w + l + 1)``.  So the cold part of a
cube (hot texels removed, :mod:`envcap.prefilter.hot`) is projected once on the real SH of degree
``<= SH_DEGREE`` (solid-angle weighted texel-centre quadrature, on a solid-angle box reduction to
at most :data:`SH_SOURCE_SIZE` texels per face), every rung is one diagonal scaling of the
coefficients and one synthesis at its texel centres, and the hot texels are added exactly with
the rung's own lobe.  This is the exact filter of :mod:`envcap.prefilter.exact` with the kernel
truncated at degree ``SH_DEGREE`` (``lambda_25(32) = 1.2e-5``), the continuum normalizer
``2 pi / (w + 1)`` (the quadrature sum differs by < 1e-5 for these lobes) and the source box-reduced
(a box of ``2 / SH_SOURCE_SIZE``: 0.3 % of the variance of a ``w = 32`` lobe).  float64 throughout.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from envcap.core import cube as cube_geometry
from envcap.prefilter.exact import check_cosine_power
from envcap.prefilter.hot import hot_texels, luminance_weight

__all__ = ["SH_DEGREE", "SH_MAX_POWER", "SH_SOURCE_SIZE", "lobe_band_factors", "real_sh", "filter_wide_lobes"]

SH_DEGREE = 24
"""Highest SH degree kept ((SH_DEGREE + 1)^2 = 625 coefficients per channel)."""
SH_MAX_POWER = 32.0
"""The widest lobes (``w <= SH_MAX_POWER``) are filtered here: their ``lambda_l`` is below 1.2e-5 past
``SH_DEGREE``."""
SH_SOURCE_SIZE = 64
"""Sources larger than this are box-reduced (solid-angle weighted) to this face size first."""


def lobe_band_factors(w: float, degree: int = SH_DEGREE) -> NDArray[np.float64]:
    """``lambda_l(w)``, ``l = 0..degree``, of the normalized ``max(0, cos)^w`` lobe, ``(degree + 1,)``."""
    w = check_cosine_power(w)
    lam = [1.0, (w + 1.0) / (w + 2.0)]
    for l in range(2, degree + 1):
        lam.append(lam[l - 2] * (w - l + 2.0) / (w + l + 1.0))
    return np.asarray(lam[:degree + 1], np.float64)


def real_sh(d: NDArray[np.float64], degree: int = SH_DEGREE) -> NDArray[np.float64]:
    """Orthonormal real SH ``Y_lm`` (row ``l^2 + l + m``) of unit directions ``d`` ``(M, 3)`` ->
    ``((degree + 1)^2, M)`` float64 (z is the polar axis; fully normalized Legendre recurrence)."""
    d = np.asarray(d, np.float64)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    s = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    phi = np.arctan2(y, x)
    out = np.empty(((degree + 1) ** 2, d.shape[0]))
    pmm = np.full_like(z, math.sqrt(1.0 / (4.0 * math.pi)))
    p = np.empty_like(z)
    for m in range(degree + 1):
        if m:
            pmm = pmm * (math.sqrt((2.0 * m + 1.0) / (2.0 * m)) * s)
            cm, sm = np.cos(m * phi) * math.sqrt(2.0), np.sin(m * phi) * math.sqrt(2.0)
        p_prev, p = np.zeros_like(z), pmm
        for l in range(m, degree + 1):
            if l == m + 1:
                p_prev, p = p, (math.sqrt(2.0 * m + 3.0) * z) * pmm
            elif l > m + 1:
                a = math.sqrt((4.0 * l * l - 1.0) / (l * l - m * m))
                b = math.sqrt(((l - 1.0) ** 2 - m * m) / (4.0 * (l - 1.0) ** 2 - 1.0))
                p_prev, p = p, a * (z * p - b * p_prev)
            if m == 0:
                out[l * l + l] = p
            else:
                np.multiply(p, cm, out=out[l * l + l + m])
                np.multiply(p, sm, out=out[l * l + l - m])
    return out


def _box_reduce(v: NDArray[np.float64], size: int) -> NDArray[np.float64]:
    """The sums of ``v`` ``(M, 6, n, n, C)`` (``Omega L``) over the texels of ``size``-texel faces."""
    m, _, n, _, c = v.shape
    k = n // size
    return v.reshape(m, 6, size, k, size, k, c).sum(axis=(3, 5))


def _lowest(a: NDArray[np.floating]) -> NDArray[np.float64]:
    """``min(0, min over the texels)`` of each cube and channel of ``a`` ``(M, 6, N, N, C)``, as ``(M, 1, 1, 1, C)``."""
    return np.minimum(np.asarray(a).min(axis=(1, 2, 3), keepdims=True).astype(np.float64), 0.0)


def _floor(res: NDArray[np.floating], low: NDArray[np.float64]) -> NDArray[np.float32]:
    """``res`` as float32, raised to ``low`` where the truncated harmonics undershoot it: a lobe
    average of a cube without negative texels has none (a black sky region beside a lit facade
    rings to ~-1e-6 of the facade at ``w = 30``, which ``probes.ktx2`` refuses); other texels
    keep their bits."""
    return np.maximum(np.asarray(res, np.float32), low.astype(np.float32))


def filter_wide_lobes(cubes: NDArray[np.floating], powers: Sequence[float], sizes: Sequence[int],
                      degree: int = SH_DEGREE, source_power: float = 0.0) -> list[NDArray[np.float32]]:
    """The normalized ``cos^powers[i]`` filter of ``M`` finite cubes ``(M, 6, N, N, C)`` on
    ``sizes[i]``-texel faces: ``[(M, 6, sizes[i], sizes[i], C)]`` float32 (each normalized by the
    same sum over ``Omega``: a constant cube stays constant).

    For wide lobes only (``w <= SH_MAX_POWER``: accurate to ~1e-5 there, module docstring).  Hot
    texels are found per cube as :mod:`envcap.prefilter.composed` does (luminance of RGB, only RGB
    split off; every channel when ``C < 3``) and summed exactly.  ``source_power > 0``: the cubes
    are already the ``cos^source_power`` filter of the environment (``source_power`` above every
    ``powers[i]``, RMS angle over a texel: smooth on their texels, so no hot texels and no
    normalizer), and band ``l`` is scaled by ``lambda_l(w) / lambda_l(source_power)`` (<= 1).
    The ringing of the truncated harmonics below ``min(0, min of each cube and channel)`` is cut
    there: a cube without negative texels filters to none.
    """
    a = np.asarray(cubes)
    m, _, n, _, nch = a.shape
    if len(powers) != len(sizes):
        raise ValueError(f"one size per power, got {len(powers)} powers and {len(sizes)} sizes")
    if source_power > 0.0:
        if any(float(w) >= source_power for w in powers):
            raise ValueError(f"source_power {source_power} must exceed every power, got {list(powers)}")
        low = _lowest(a)
        return [_floor(r, low) for r in _from_filtered(a, powers, sizes, degree, source_power)]
    lum = 3 if nch >= 3 else nch
    low = _lowest(a)
    src = SH_SOURCE_SIZE if n > SH_SOURCE_SIZE and n % SH_SOURCE_SIZE == 0 else n
    om = cube_geometry.texel_solid_angles(n)
    d0 = cube_geometry.texel_directions(n).reshape(-1, 3)
    v = np.empty((m, 6, src, src, nch))
    hot: list[tuple[NDArray[np.int64], NDArray[np.float64]]] = []
    for i in range(m):   # one cube at a time in float64: hot texels out, box-reduced Omega L
        ci = np.asarray(a[i], np.float64) * om[..., None]
        idx = hot_texels(luminance_weight(np.asarray(a[i], np.float64)))[0]
        flat = ci.reshape(-1, nch)
        vals = flat[idx].copy()
        vals[:, lum:] = 0.0
        flat[idx, :lum] = 0.0
        hot.append((idx, vals))
        v[i] = ci if src == n else _box_reduce(ci[None], src)[0]
    ys = real_sh(cube_geometry.texel_directions(src).reshape(-1, 3), degree)
    # coefficients of every cube and channel, and of Omega (the quadrature's normalizer): (K, M C + 1)
    om_s = om.reshape(-1) if src == n else _box_reduce(om[None, ..., None], src).reshape(-1)
    cols = np.concatenate([np.moveaxis(v.reshape(m, -1, nch), 1, 0).reshape(-1, m * nch), om_s[:, None]], axis=1)
    coef = ys @ cols
    out: list[NDArray[np.float32]] = []
    bases: dict[int, tuple[NDArray[np.float64], NDArray[np.float64]]] = {}
    for w, size in zip(powers, sizes):
        w = check_cosine_power(w)
        if size not in bases:
            d_out = cube_geometry.texel_directions(size).reshape(-1, 3)
            bases[size] = (d_out, real_sh(d_out, degree).T)
        d_out, y = bases[size]
        lam = np.repeat(lobe_band_factors(w, degree), 2 * np.arange(degree + 1) + 1)
        res = (y * lam[None]) @ coef                               # (6 s^2, M C + 1)
        nu = res[:, -1:]                                           # sum_u Omega K_L(d.u): ~1
        res = np.moveaxis(res[:, :-1].reshape(-1, m, nch), 1, 0)  # (M, 6 s^2, C)
        norm = (w + 1.0) / (2.0 * math.pi)
        for i, (idx, vals) in enumerate(hot):
            if idx.size:
                cos = np.clip(d_out @ d0[idx].T, 0.0, None)        # (6 s^2, H)
                res[i] += (cos ** w * norm) @ vals
        out.append(_floor((res / nu[None]).reshape(m, 6, size, size, nch), low))
    return out


def _from_filtered(a: NDArray[np.floating], powers: Sequence[float], sizes: Sequence[int], degree: int,
                   source_power: float) -> list[NDArray[np.float32]]:
    """:func:`filter_wide_lobes` of cubes already filtered with ``cos^source_power``."""
    m, _, n, _, nch = a.shape
    om = cube_geometry.texel_solid_angles(n).reshape(-1)
    ys = real_sh(cube_geometry.texel_directions(n).reshape(-1, 3), degree)
    v = np.moveaxis(np.asarray(a, np.float64).reshape(m, -1, nch), 1, 0).reshape(-1, m * nch)
    coef = ys @ np.concatenate([v * om[:, None], om[:, None]], axis=1)   # and of Omega: the normalizer
    lam_src = lobe_band_factors(source_power, degree)
    out: list[NDArray[np.float32]] = []
    bases: dict[int, NDArray[np.float64]] = {}
    for w, size in zip(powers, sizes):
        if size not in bases:
            bases[size] = real_sh(cube_geometry.texel_directions(size).reshape(-1, 3), degree).T
        ratio = np.repeat(lobe_band_factors(float(w), degree) / lam_src, 2 * np.arange(degree + 1) + 1)
        res = (bases[size] * ratio[None]) @ coef
        res = res[:, :-1] / res[:, -1:]                            # a constant stays constant
        out.append(np.moveaxis(res.reshape(-1, m, nch), 1, 0).reshape(m, 6, size, size, nch).astype(np.float32))
    return out
