"""Parts of an imported mesh (files and their connected pieces), the crop box, and winding.

A *part* is a connected piece of one file: triangles that share a vertex position (exactly, in
world coordinates) belong together, so one PLY per building is one part and one file holding a
whole district is one part per building.  Arrays are world-space triangle corners ``(T, 3, 3)``
float64 (meters, +Y up) and per-triangle integer part labels ``(T,)``.

Winding (:func:`inward_parts`): a part is *inward* (its front faces look into it) when

* it encloses volume (``|V| > ENCLOSED_SHARE`` of its bounding box, closed or open at the bottom
  like a building shell without a floor) and its signed volume ``V`` is negative.  ``V`` is
  taken about the bottom center of its box, so a missing floor in that plane adds nothing; or
* it encloses none (a facade sheet) and, over its walls (|n_y| < 0.7), more than
  ``AWAY_SHARE`` of the area faces away from the nearest street center line (in plan); without
  streets such a part is left as it is.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from envcap.scene.model import Street

ENCLOSED_SHARE = 0.05
"""A part whose signed volume is past this share of its bounding box's encloses volume."""
AWAY_SHARE = 0.6
"""A sheet whose wall area faces away from the street past this share is wound inward."""


def vertex_ids(points: NDArray[np.float64]) -> NDArray[np.int64]:
    """``(P,)`` ids of ``points`` (P, 3): equal positions (compared as numbers) share an id.

    A lexicographic sort of the three columns and a scan for changes: about 10x faster than
    ``np.unique(points, axis=0)``, which sorts the rows as raw bytes."""
    order = np.lexsort((points[:, 2], points[:, 1], points[:, 0]))
    ranked = points[order]
    changed = np.any(ranked[1:] != ranked[:-1], axis=1)
    ids = np.empty(points.shape[0], np.int64)
    ids[order] = np.concatenate([[0], np.cumsum(changed)])
    return ids


def component_labels(tri: NDArray[np.float64]) -> NDArray[np.int64]:
    """Connected pieces of ``tri`` (T, 3, 3): ``(T,)`` labels 0..K-1 in order of first triangle;
    triangles sharing a vertex position are connected."""
    t = tri.shape[0]
    if t == 0:
        return np.zeros(0, np.int64)
    vid = vertex_ids(tri.reshape(-1, 3)).reshape(t, 3)
    labels = np.arange(int(vid.max()) + 1)
    a = np.concatenate([vid[:, 0], vid[:, 1]])
    b = np.concatenate([vid[:, 1], vid[:, 2]])
    while True:  # min-label propagation with pointer jumping
        m = np.minimum(labels[a], labels[b])
        new = labels.copy()
        np.minimum.at(new, a, m)
        np.minimum.at(new, b, m)
        new = new[new]
        if np.array_equal(new, labels):
            break
        labels = new
    _, first, inverse = np.unique(labels[vid[:, 0]], return_index=True, return_inverse=True)
    order = np.argsort(np.argsort(first))  # renumber by first triangle
    return order[inverse].astype(np.int64)


def parts_meeting_box(tri: NDArray[np.float64], part: NDArray[np.int64], lo: Sequence[float],
                      hi: Sequence[float]) -> NDArray[np.bool_]:
    """``(T,)`` bool: the triangles of every part of which some triangle's bounding box meets the
    world box ``[lo, hi]`` (m); parts are kept whole."""
    meets = np.all(tri.max(axis=1) >= np.asarray(lo), axis=1) & np.all(tri.min(axis=1) <= np.asarray(hi), axis=1)
    kept = np.bincount(part, weights=meets, minlength=int(part.max(initial=-1)) + 1) > 0
    return kept[part]


def _toward_street(centers: NDArray[np.float64], streets: Sequence[Street]) -> NDArray[np.float64]:
    """``(T, 2)`` plan vectors (x, z) from each point to the nearest point of the nearest street's
    center line segment."""
    best = np.full(centers.shape[0], np.inf)
    vec = np.zeros((centers.shape[0], 2))
    for st in streets:
        a, c = st.along_index, st.cross_index
        q = np.zeros((centers.shape[0], 3))
        q[:, a] = np.clip(st.to_frame(centers)[:, a], min(st.start, st.end), max(st.start, st.end))
        q[:, c] = st.center_line
        d = (st.to_world(q) - centers)[:, [0, 2]]  # in the street's frame, turned back to the world
        dist = np.einsum("ij,ij->i", d, d)
        closer = dist < best
        best[closer], vec[closer] = dist[closer], d[closer]
    return vec


def inward_parts(tri: NDArray[np.float64], part: NDArray[np.int64], streets: Sequence[Street] = ()) -> NDArray[np.bool_]:
    """``(K,)`` bool: which parts are wound inward (see the module docstring)."""
    k = int(part.max(initial=-1)) + 1
    lo = np.full((k, 3), np.inf)
    hi = np.full((k, 3), -np.inf)
    np.minimum.at(lo, part, tri.min(axis=1))
    np.maximum.at(hi, part, tri.max(axis=1))
    ref = np.stack([0.5 * (lo[:, 0] + hi[:, 0]), lo[:, 1], 0.5 * (lo[:, 2] + hi[:, 2])], axis=1)[part]
    a, b, c = (tri[:, i] - ref for i in range(3))
    volume = np.bincount(part, weights=np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0, minlength=k)
    box = np.prod(hi - lo, axis=1)
    enclosed = np.abs(volume) > ENCLOSED_SHARE * box
    inward = enclosed & (volume < 0)
    if streets and not np.all(enclosed):
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        area = np.linalg.norm(n, axis=1)
        wall = np.abs(n[:, 1]) < 0.7 * np.maximum(area, 1e-300)
        facing = np.einsum("ij,ij->i", n[:, [0, 2]], _toward_street(tri.mean(axis=1), streets))
        away = np.bincount(part, weights=area * (wall & (facing < 0)), minlength=k)
        seen = np.bincount(part, weights=area * (wall & (facing != 0)), minlength=k)
        sheet_inward = away > AWAY_SHARE * seen
        inward |= ~enclosed & (seen > 0) & sheet_inward
    return inward
