"""Numpy twin of OpenGL ``textureLod`` on a seamless, trilinear cube map or cube-map array.

GL rules followed (OpenGL 4.5 core, sections 8.13 "Cube Map Texture Selection" and 8.14
"Texture Minification" with ``TEXTURE_CUBE_MAP_SEAMLESS``):

* face and (s, t) from the major axis of the direction (``envcap.core.cube.direction_to_face_st``;
  ties X before Y before Z, as Mesa);
* bilinear within a face: ``u = s N - 1/2``, texels ``floor(u)`` and ``floor(u) + 1`` with weights
  ``1 - frac(u)``, ``frac(u)`` (same for t);
* seamless: a texel of the 2x2 footprint that lies one texel beyond a face edge is read from the
  adjacent face (the texel containing the direction of its center on the extended face plane);
  one beyond a corner (outside both edges) is the average of the other three texels of the
  footprint, which are the three texels meeting at the cube corner (GL allows this; llvmpipe
  does it -- checked in ``tests/core/test_cube_sampling.py``);
* explicit lod: clamped to [0, levels - 1]; levels ``floor(lod)`` and the next, linear in
  ``frac(lod)`` (``LINEAR_MIPMAP_LINEAR``);
* cube-map array layer ``clamp(floor(layer + 0.5), 0, layers - 1)``.

Everything is evaluated in float64.  Residual differences from llvmpipe: llvmpipe computes
(s, t) and weights in float32 (relative error ~1e-7 of the texel spacing); see
``docs/runtime.md`` for the measured agreement.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core import cube


def _corner_texels(face: NDArray, i: NDArray, j: NDArray, n: int) -> tuple[NDArray, NDArray, NDArray]:
    """Face, row, column of texel (column i, row j) of ``face``, with i or j one beyond an edge
    remapped to the adjacent face (not for both beyond: the caller handles corners)."""
    u = (2.0 * i + 1.0) / n - 1.0
    v = (2.0 * j + 1.0) / n - 1.0
    inside = (i >= 0) & (i < n) & (j >= 0) & (j < n)
    f2, r2, c2 = face.copy(), j.copy(), i.copy()
    out = ~inside
    if np.any(out):
        d = cube.face_uv_to_direction(face[out], u[out], v[out])
        f2[out], r2[out], c2[out] = cube.direction_to_texel(d, n)
    return f2, r2, c2


def bilinear(level: ArrayLike, d: ArrayLike, layer: ArrayLike | None = None) -> NDArray[np.float64]:
    """Seamless bilinear lookup of one mip level.

    ``level``: ``(6, N, N, C)`` cube or ``(L, 6, N, N, C)`` cube array; ``d``: ``(..., 3)``
    directions (non-zero, finite); ``layer``: integer layer index per direction (cube arrays).
    Returns ``(..., C)`` float64.
    """
    lv = np.asarray(level)
    if lv.ndim == 4:
        lv = lv[None]
        layer = None
    if lv.ndim != 5 or lv.shape[1] != 6 or lv.shape[2] != lv.shape[3]:
        raise ValueError(f"level must have shape (6, N, N, C) or (L, 6, N, N, C), got {lv.shape}")
    d = np.asarray(d, dtype=np.float64)
    shape = d.shape[:-1]
    d = d.reshape(-1, 3)
    lay = np.zeros(d.shape[0], dtype=np.int64) if layer is None else np.broadcast_to(
        np.asarray(layer, dtype=np.int64), shape).reshape(-1)
    n = lv.shape[2]
    face, s, t = cube.direction_to_face_st(d)
    u = s * n - 0.5
    v = t * n - 0.5
    i0 = np.floor(u).astype(np.int64)
    j0 = np.floor(v).astype(np.int64)
    a = u - i0
    b = v - j0
    acc = np.zeros((d.shape[0], lv.shape[4]), dtype=np.float64)
    corner_w = np.zeros(d.shape[0], dtype=np.float64)
    others = np.zeros_like(acc)
    for di, dj, wt in ((0, 0, (1 - a) * (1 - b)), (1, 0, a * (1 - b)), (0, 1, (1 - a) * b), (1, 1, a * b)):
        i = i0 + di
        j = j0 + dj
        corner = ((i < 0) | (i >= n)) & ((j < 0) | (j >= n))
        f2, r2, c2 = _corner_texels(face, np.where(corner, 0, i), np.where(corner, 0, j), n)
        val = lv[lay, f2, r2, c2].astype(np.float64)
        val = np.where(corner[:, None], 0.0, val)
        acc += wt[:, None] * val
        others += val
        corner_w += np.where(corner, wt, 0.0)
    acc += corner_w[:, None] * others / 3.0   # a corner texel = mean of the footprint's other three
    return acc.reshape(shape + (lv.shape[4],))


def _check_levels(levels: Sequence[ArrayLike], ndim: int) -> list[NDArray]:
    lv = [np.asarray(x) for x in levels]
    if not lv:
        raise ValueError("need at least one mip level")
    n0 = lv[0].shape[-2]
    for k, x in enumerate(lv):
        nk = max(n0 >> k, 1)
        if x.ndim != ndim or x.shape[-4] != 6 or x.shape[-3] != nk or x.shape[-2] != nk or x.shape[:-4] != lv[0].shape[:-4]:
            raise ValueError(f"level {k} must have {ndim} dims with faces of {nk} texels, got {x.shape}")
    return lv


def _trilinear(lv: list[NDArray], d: NDArray, lod: ArrayLike, layer: NDArray | None) -> NDArray[np.float64]:
    d = np.asarray(d, dtype=np.float64)
    lod = np.broadcast_to(np.asarray(lod, dtype=np.float64), d.shape[:-1])
    if np.any(np.isnan(lod)):
        raise ValueError("lod contains NaN")
    lod = np.clip(lod, 0.0, len(lv) - 1)
    k0 = np.floor(lod).astype(np.int64)
    k1 = np.minimum(k0 + 1, len(lv) - 1)
    f = lod - k0
    out = np.zeros(d.shape[:-1] + (lv[0].shape[-1],), dtype=np.float64)
    for k in np.unique(np.concatenate([k0.ravel(), k1.ravel()])):
        w = np.where(k0 == k, 1.0 - f, 0.0) + np.where((k1 == k) & (k1 != k0), f, 0.0)
        w = np.where((k0 == k) & (k1 == k0), 1.0, w)
        m = w > 0
        if np.any(m):
            out[m] += w[m][:, None] * bilinear(lv[k], d[m], None if layer is None else layer[m])
    return out


def sample_cube(levels: Sequence[ArrayLike], d: ArrayLike, lod: ArrayLike = 0.0) -> NDArray[np.float64]:
    """``textureLod(samplerCube, d, lod)``: ``levels[k]`` is ``(6, N_k, N_k, C)``, ``N_k = N_0 >> k``.

    ``d``: ``(..., 3)`` non-zero finite directions; ``lod`` broadcast to ``d.shape[:-1]``.
    Returns ``(..., C)`` float64.
    """
    lv = _check_levels(levels, 4)
    return _trilinear(lv, d, lod, None)


def sample_cube_array(levels: Sequence[ArrayLike], d: ArrayLike, layer: ArrayLike, lod: ArrayLike = 0.0) -> NDArray[np.float64]:
    """``textureLod(samplerCubeArray, vec4(d, layer), lod)``; ``levels[k]`` is ``(L, 6, N_k, N_k, C)``.

    ``layer`` (float, broadcast to ``d.shape[:-1]``) selects ``clamp(floor(layer + 0.5), 0, L-1)``.
    """
    lv = _check_levels(levels, 5)
    d = np.asarray(d, dtype=np.float64)
    lay = np.broadcast_to(np.asarray(layer, dtype=np.float64), d.shape[:-1])
    if np.any(~np.isfinite(lay)):
        raise ValueError("layer contains NaN or Inf")
    li = np.clip(np.floor(lay + 0.5), 0, lv[0].shape[0] - 1).astype(np.int64)
    return _trilinear(lv, d, lod, li)
