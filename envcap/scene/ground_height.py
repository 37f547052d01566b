"""The height of the ground under plan points, from a scene mesh (terrain-following probes).

The ground under ``(x, z)`` is the highest surface there that faces up (normal within 60 deg of
+Y), found by a vertical ray through the triangles whose plan box holds the point; a street's
centre line has open sky above it, so the highest such surface is the road, not a roof.  Points
with no such surface get NaN.  Triangles are binned on a square grid of ``cell`` meters so that
a query touches only the triangles near it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.scene.model import SceneMesh

UP_COS = 0.5
"""A triangle faces up when its unit normal's y exceeds this (within 60 deg of +Y)."""


class GroundHeights:
    """The ground-height query of one mesh: its up-facing triangles binned once (``cell`` m),
    then ``self(xz)`` for any number of point sets (every street of a bake)."""

    def __init__(self, mesh: SceneMesh, cell: float = 16.0) -> None:
        tri = (mesh.positions.astype(np.float64) + mesh.origin)[mesh.indices.astype(np.int64)]   # (T, 3, 3)
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        length = np.linalg.norm(n, axis=1)
        self.tri = tri[(length > 0) & (n[:, 1] > UP_COS * length)]
        self.cell = float(cell)
        lo, hi = self.tri[:, :, [0, 2]].min(axis=1), self.tri[:, :, [0, 2]].max(axis=1)
        self.origin = lo.min(axis=0) if len(self.tri) else np.zeros(2)
        c_lo = np.floor((lo - self.origin) / cell).astype(np.int64)
        c_hi = np.floor((hi - self.origin) / cell).astype(np.int64)
        self.bins: dict[tuple[int, int], list[int]] = {}
        for t in range(len(self.tri)):
            for i in range(c_lo[t, 0], c_hi[t, 0] + 1):
                for j in range(c_lo[t, 1], c_hi[t, 1] + 1):
                    self.bins.setdefault((i, j), []).append(t)

    def __call__(self, xz: ArrayLike) -> NDArray[np.float64]:
        """World y (m) of the highest up-facing surface under each plan point ``xz`` (P, 2) world m;
        NaN where there is none.  ``ValueError`` for non-finite points."""
        pts = np.asarray(xz, np.float64).reshape(-1, 2)
        if not np.all(np.isfinite(pts)):
            raise ValueError("ground height query points must be finite (x, z) meters")
        out = np.full(len(pts), np.nan)
        cells = np.floor((pts - self.origin) / self.cell).astype(np.int64)
        for p, (x, z) in enumerate(pts):
            ids = np.asarray(self.bins.get((int(cells[p, 0]), int(cells[p, 1])), []), np.int64)
            if not ids.size:
                continue
            a, b, c = self.tri[ids, 0], self.tri[ids, 1], self.tri[ids, 2]
            # barycentric coordinates of (x, z) in each triangle's plan projection
            v0, v1 = b[:, [0, 2]] - a[:, [0, 2]], c[:, [0, 2]] - a[:, [0, 2]]
            v2 = np.array([x, z]) - a[:, [0, 2]]
            den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
            ok = np.abs(den) > 1e-12
            with np.errstate(divide="ignore", invalid="ignore"):
                s = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
                t = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
            eps = 1e-9
            inside = ok & (s >= -eps) & (t >= -eps) & (s + t <= 1 + eps)
            if inside.any():
                y = a[:, 1] + s * (b[:, 1] - a[:, 1]) + t * (c[:, 1] - a[:, 1])
                out[p] = float(y[inside].max())
        return out


def ground_heights(mesh: SceneMesh, xz: ArrayLike, cell: float = 16.0) -> NDArray[np.float64]:
    """:class:`GroundHeights` of ``mesh`` at ``xz`` (one query; build the class once for several)."""
    return GroundHeights(mesh, cell)(xz)
