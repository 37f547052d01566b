"""Face atlases: a probe array's mip chains as a 2D texture array, for APIs without cube-map
arrays (WebGL2).

One atlas per probe face: layer ``probe * 6 + face`` (GL face order).  For a chain of ``K``
levels with face sizes ``N_k = max(1, N >> k)``, the atlas is ``W = (N + 2) + (N_1 + 2)`` texels
wide (``N_1 = max(1, N >> 1)``, also for ``K = 1``) and ``H = max(N + 2, sum_{k>=1} (N_k + 2))``
high.  Level 0 sits at texel ``(x, y) = (0, 0)``, level ``k >= 1`` at ``(N + 2, sum_{j=1}^{k-1}
(N_j + 2))``; each is its ``N_k x N_k`` face (rows t, columns s, as in envcap cubes) inside a
1-texel border.  A border texel is the texel of the adjacent face that seamless cube filtering
would read there (the texel containing the direction of its center on the extended face plane);
a border corner is the mean of the other three texels of its 2x2 footprint (the three texels
meeting at the cube corner: what llvmpipe does, see ``envcap.core.cube_sampling``).  The rest is
zero.  Bilinear filtering of one level with texture coordinate ``(o + 1 + (s, t) N_k) / (W, H)``
then equals the seamless cube lookup; ``shaders/runtime/envcap_face_atlas.glsl`` mixes two levels
for trilinear lookups.  ``N`` is recovered from ``W`` alone (:func:`face_size_of_width`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import DTypeLike, NDArray

from envcap.core import cube
from envcap.core.checks import positive_int


@dataclass(frozen=True)
class FaceAtlasLayout:
    """Where each level of an ``size``-texel, ``levels``-level chain sits in its face atlas:
    ``origins[k] = (x, y)``, the top-left texel of level ``k``'s bordered square of
    ``face_sizes[k] + 2`` texels; ``width`` x ``height`` the atlas."""

    size: int
    levels: int
    width: int
    height: int
    origins: tuple[tuple[int, int], ...]
    face_sizes: tuple[int, ...]


def face_atlas_layout(size: int, levels: int) -> FaceAtlasLayout:
    """The layout for level-0 face size ``size`` and ``levels`` levels (1 .. log2(size) + 1)."""
    n = positive_int(size, "face size")
    k_levels = positive_int(levels, "level count")
    if k_levels > n.bit_length():
        raise ValueError(f"{k_levels} levels given, but a {n}-texel face has at most {n.bit_length()}")
    sizes = tuple(max(1, n >> k) for k in range(k_levels))
    origins = [(0, 0)]
    y = 0
    for k in range(1, k_levels):
        origins.append((n + 2, y))
        y += sizes[k] + 2
    return FaceAtlasLayout(n, k_levels, n + 2 + max(1, n >> 1) + 2, max(n + 2, y), tuple(origins), sizes)


def face_size_of_width(width: int) -> int:
    """Level-0 face size ``N`` of an atlas ``width`` texels wide (``width - 4 = N + max(1, N >> 1)``),
    as ``envcap_face_atlas_size`` computes it in GLSL."""
    m = int(width) - 4
    n = 1 if m <= 2 else (2 * m + 2) // 3
    if face_atlas_layout(n, 1).width != width:
        raise ValueError(f"{width} texels is not the width of a face atlas")
    return n


def _border_sources(n: int) -> tuple[NDArray[np.int64], ...]:
    """For the 4n edge-border texels of each face of an n-texel cube: padded (row, column) and
    the source (face, row, column), each of shape (6, 4n)."""
    k = np.arange(n)
    rows = np.concatenate([k, k, np.full(n, -1), np.full(n, n)])    # left, right, top, bottom
    cols = np.concatenate([np.full(n, -1), np.full(n, n), k, k])
    face = np.repeat(np.arange(6), rows.size).reshape(6, -1)
    r = np.broadcast_to(rows, face.shape)
    c = np.broadcast_to(cols, face.shape)
    d = cube.face_uv_to_direction(face, (2.0 * c + 1.0) / n - 1.0, (2.0 * r + 1.0) / n - 1.0)
    sf, sr, sc = cube.direction_to_texel(d, n)
    return r + 1, c + 1, sf, sr, sc


def bordered_level(level: NDArray, dtype: DTypeLike | None = None) -> NDArray:
    """One level ``(L, 6, n, n, C)`` with its 1-texel seam border: ``(L, 6, n + 2, n + 2, C)``."""
    lv = np.asarray(level)
    if lv.ndim != 5 or lv.shape[1] != 6 or lv.shape[2] != lv.shape[3] or lv.shape[2] < 1:
        raise ValueError(f"a level must have shape (L, 6, n, n, C), got {lv.shape}")
    n = lv.shape[2]
    out = np.zeros(lv.shape[:2] + (n + 2, n + 2) + lv.shape[4:], dtype=dtype or lv.dtype)
    out[:, :, 1:-1, 1:-1] = lv
    pr, pc, sf, sr, sc = _border_sources(n)
    out[:, np.arange(6)[:, None], pr, pc] = lv[:, sf, sr, sc]
    for r, c, dr, dc in ((0, 0, 1, 1), (0, n + 1, 1, -1), (n + 1, 0, -1, 1), (n + 1, n + 1, -1, -1)):
        three = (out[:, :, r + dr, c].astype(np.float64) + out[:, :, r, c + dc] + out[:, :, r + dr, c + dc]) / 3.0
        out[:, :, r, c] = three.astype(out.dtype)
    return out


def face_atlas(levels: Sequence[NDArray], dtype: DTypeLike | None = None) -> NDArray:
    """The face atlases of a probe array's chain ``levels[k]`` ``(L, 6, N_k, N_k, C)``:
    ``(L * 6, H, W, C)`` in ``dtype`` (default: level 0's), layer ``probe * 6 + face``."""
    if not levels:
        raise ValueError("levels must be a non-empty list of (L, 6, N_k, N_k, C) arrays")
    first = np.asarray(levels[0])
    if first.ndim != 5:
        raise ValueError(f"level 0 must have shape (L, 6, N, N, C), got {first.shape}")
    lay = face_atlas_layout(first.shape[2], len(levels))
    n_layers, ch = first.shape[0] * 6, first.shape[4]
    out = np.zeros((n_layers, lay.height, lay.width, ch), dtype=dtype or first.dtype)
    for k, (lv, (x, y), nk) in enumerate(zip(levels, lay.origins, lay.face_sizes)):
        a = np.asarray(lv)
        if a.shape != (first.shape[0], 6, nk, nk, ch):
            raise ValueError(f"level {k} must have shape {(first.shape[0], 6, nk, nk, ch)}, got {a.shape}")
        out[:, y:y + nk + 2, x:x + nk + 2] = bordered_level(a, out.dtype).reshape(n_layers, nk + 2, nk + 2, ch)
    return out
