"""Per-face culling of the capture: triangles grouped into spatial chunks, and the chunks each
cube face's frustum can reach, as indirect draw commands.

llvmpipe transforms, clips and sets up every triangle of every draw on the CPU, so the capture
draws, for each of the six faces, only the chunks whose bounding box can reach that face's
frustum, nearest first (``docs/capture.md``, "Per-face chunk culling").  Culling never changes
the image: a rejected chunk lies wholly outside one clip plane.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from envcap.capture.projection import FACE_ROWS


@dataclass(frozen=True)
class TriangleChunks:
    """Triangles grouped into spatial chunks: contiguous ranges of a reordered index buffer.

    ``order`` (T,) int64: triangle ``k`` of the reordered buffer is input triangle ``order[k]``.
    ``first``, ``count`` (C,) int64: chunk ``c`` is reordered triangles ``first[c] ..
    first[c] + count[c] - 1``.  ``lo``, ``hi`` (C, 3) float64: the chunk's axis-aligned bounding
    box in meters (exact bounds of its float32 vertices, in their frame: the capture's is
    relative to the mesh origin, and so are the probe positions it culls for).  Chunks are stored in the order of
    their keys (level, x cell, z cell); within a chunk triangles keep their input order.
    """

    order: NDArray[np.int64]
    first: NDArray[np.int64]
    count: NDArray[np.int64]
    lo: NDArray[np.float64]
    hi: NDArray[np.float64]


def chunk_triangles(positions: NDArray[np.floating], indices: NDArray[np.integer],
                    cell: float = 8.0) -> TriangleChunks:
    """Sort triangles into chunks of a loose grid in x-z with cells of ``cell`` meters.

    A triangle whose x-z extent is ``e`` goes to level ``k``, the smallest with
    ``e <= cell * 4**k``, and to the level-``k`` cell (side ``cell * 4**k``) holding its centroid;
    so a chunk's box is at most about twice its cell and a few huge triangles (a ground plane)
    do not inflate the boxes of the many small ones.  ``positions`` (V, 3), ``indices`` (T, 3).
    Raises ``ValueError`` for a non-finite or non-positive ``cell``.
    """
    if not (math.isfinite(cell) and cell > 0):
        raise ValueError(f"chunk cell size must be a finite number of meters > 0, got {cell!r}")
    pos = np.asarray(positions, dtype=np.float64)
    tri = pos[np.asarray(indices, dtype=np.int64)]  # (T, 3, 3)
    t = tri.shape[0]
    if t == 0:
        z = np.zeros(0, np.int64)
        return TriangleChunks(z, z, z, np.zeros((0, 3)), np.zeros((0, 3)))
    tlo, thi = tri.min(axis=1), tri.max(axis=1)
    ext = np.maximum(thi[:, 0] - tlo[:, 0], thi[:, 2] - tlo[:, 2])
    level = np.zeros(t, np.int64)
    big = ext > cell
    level[big] = np.ceil(np.log(ext[big] / cell) / math.log(4.0) - 1e-12).astype(np.int64)
    level = np.maximum(level, 0)
    while True:  # guard the float log against landing one level short
        short = ext > cell * 4.0 ** level
        if not short.any():
            break
        level[short] += 1
    size = cell * 4.0 ** level
    cen = 0.5 * (tlo + thi)
    ix = np.floor(cen[:, 0] / size).astype(np.int64)
    iz = np.floor(cen[:, 2] / size).astype(np.int64)
    order = np.lexsort((np.arange(t), iz, ix, level))  # stable: input order within a chunk
    keys = np.stack([level[order], ix[order], iz[order]], axis=1)
    new = np.ones(t, bool)
    new[1:] = np.any(keys[1:] != keys[:-1], axis=1)
    first = np.flatnonzero(new).astype(np.int64)
    count = np.diff(np.append(first, t)).astype(np.int64)
    lo = np.minimum.reduceat(tlo[order], first, axis=0)
    hi = np.maximum.reduceat(thi[order], first, axis=0)
    return TriangleChunks(order.astype(np.int64), first, count, lo, hi)


def _face_planes() -> NDArray[np.float64]:
    """(6, 4, 3) inward normals of each face frustum's side planes: ``n . r >= 0`` inside."""
    r = FACE_ROWS
    return np.stack([r[:, 2] - r[:, 0], r[:, 2] + r[:, 0], r[:, 2] - r[:, 1], r[:, 2] + r[:, 1]], axis=1)


_SIDE_PLANES = _face_planes()


def chunk_face_visibility(lo: NDArray[np.floating], hi: NDArray[np.floating], probe: NDArray[np.floating],
                          near: float = 0.05, far: float = math.inf,
                          rotation: NDArray[np.float64] | None = None) -> NDArray[np.bool_]:
    """Which boxes ``[lo, hi]`` (C, 3) meters may reach each cube face's frustum: (6, C) bool.
    ``rotation``: (3, 3) world -> cube frame of a cube turned with its street
    (:func:`envcap.core.street_frame.plan_rotation`); default: the world axes.

    Face ``f`` sees ``r = x - probe`` where ``ma >= |sc|``, ``ma >= |tc|`` and
    ``near <= ma <= far`` (``(sc, tc, ma) = R_f r``, as :func:`~envcap.capture.projection.face_clip_matrix`).  A box is
    rejected only when it lies wholly outside one of these planes, tested at its corner farthest
    along the plane's inward normal, with a margin of ``1e-5`` of the box's distance scale (plus
    1 micrometer) so that float32 rounding on the GPU can never make a rejected box produce a
    fragment.  Conservative: a box kept may still draw nothing.
    """
    p = np.asarray(probe, dtype=np.float64)
    blo = np.asarray(lo, dtype=np.float64) - p
    bhi = np.asarray(hi, dtype=np.float64) - p
    scale = np.maximum(np.abs(blo), np.abs(bhi)).sum(axis=1)  # (C,) >= |r| over the box
    eps = 1e-5 * scale + 1e-6
    n = _SIDE_PLANES if rotation is None else _SIDE_PLANES @ rotation  # (6, 4, 3): n . (R r) = (n R) . r
    # max over the box of n . r = sum_i max(n_i lo_i, n_i hi_i)
    reach = np.maximum(n[None] * blo[:, None, None, :], n[None] * bhi[:, None, None, :]).sum(axis=-1)  # (C, 6, 4)
    vis = np.all(reach >= -eps[:, None, None], axis=2)  # (C, 6)
    ma = FACE_ROWS[:, 2] if rotation is None else FACE_ROWS[:, 2] @ rotation  # (6, 3)
    ma_max = np.maximum(ma[None] * blo[:, None, :], ma[None] * bhi[:, None, :]).sum(axis=-1)  # (C, 6)
    vis &= ma_max >= near - eps[:, None]
    if math.isfinite(far):
        ma_min = np.minimum(ma[None] * blo[:, None, :], ma[None] * bhi[:, None, :]).sum(axis=-1)
        vis &= ma_min <= far + eps[:, None]
    return vis.T


def box_far_distance(lo: NDArray[np.float64], hi: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distance (m) from ``p`` to the farthest corner of each box, (C,): the draw-order key.

    Ordering by it draws small nearby chunks first and big boxes (the ground, long facades with
    details 1.5 cm in front of them) late, which lets the early depth test reject more hidden
    fragments than ordering by the nearest point (measured: 1.32 vs 1.55 shaded fragments per
    visible texel on canyon; 1.41 in buffer order).
    """
    d = np.maximum(np.abs(lo - p), np.abs(hi - p))
    return np.sqrt(np.einsum("ci,ci->c", d, d))


def _runs(ids: NDArray[np.int64], first: NDArray[np.int64],
          count: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Merge chunks drawn in the order ``ids`` into draw ranges (first triangles, triangle counts):
    a chunk that directly follows the previous one in the buffer extends its range."""
    if ids.size == 0:
        z = np.zeros(0, np.int64)
        return z, z
    brk = np.ones(ids.size, bool)
    brk[1:] = ids[1:] != ids[:-1] + 1
    starts = np.flatnonzero(brk)
    ends = np.append(starts[1:], ids.size) - 1
    f0 = first[ids[starts]]
    return f0, first[ids[ends]] + count[ids[ends]] - f0


@dataclass(frozen=True)
class FaceDraws:
    """Indirect draw commands of one probe, grouped by cube face.

    ``commands`` (K, 5) uint32: ``glMultiDrawElementsIndirect`` records ``(index count, 1,
    first index, 0, 0)`` for triangle ranges of the chunk-ordered index buffer.  ``faces[f] =
    (first command, command count)`` of face ``f``.  ``triangles``: summed over the six faces.
    """

    commands: NDArray[np.uint32]
    faces: list[tuple[int, int]]
    triangles: int


def face_draw_commands(chunks: TriangleChunks, probe: NDArray[np.floating], near: float = 0.05,
                       far: float = math.inf, rotation: NDArray[np.float64] | None = None) -> FaceDraws:
    """The chunks of ``chunks`` each cube face at ``probe`` (3,) meters may see
    (:func:`chunk_face_visibility`, cube turned by ``rotation``), sorted near first
    (:func:`box_far_distance`) and merged into contiguous index ranges, as indirect draw commands."""
    p = np.asarray(probe, dtype=np.float64)
    vis = chunk_face_visibility(chunks.lo, chunks.hi, p, near, far, rotation)  # (6, C)
    dist = box_far_distance(chunks.lo, chunks.hi, p)
    cmds, faces, k, triangles = [], [], 0, 0
    for f in range(6):
        ids = np.flatnonzero(vis[f])
        ids = ids[np.argsort(dist[ids], kind="stable")]  # near first: early depth rejects the rest
        f0, cnt = _runs(ids, chunks.first, chunks.count)
        c = np.zeros((f0.size, 5), np.uint32)
        c[:, 0], c[:, 1], c[:, 2] = 3 * cnt, 1, 3 * f0
        cmds.append(c)
        faces.append((k, int(f0.size)))
        k += int(f0.size)
        triangles += int(cnt.sum())
    return FaceDraws(np.concatenate(cmds), faces, triangles)
