"""Imported surfaces that lie on the scene's ground plane: the two z-fight in captures.

A city mesh often brings its own ground (terrain, roads, plazas).  Where such a surface lies at
the height of the scene's default ground plane (``[ground]`` enabled, y = 0), the capture sees two
coincident surfaces and the depth test picks one or the other texel by texel, differently from
one position to the next: probe and truth then see different ground (in a flat city the parallax
ratio of a street fell from 5.1x to 2.1x).  :func:`ground_overlap` measures it: the area of the
mesh's up-facing triangles lying entirely within :data:`GROUND_OVERLAP_TOLERANCE_M` of the plane.
The scene build warns (one line per mesh table, ``envcap: warning: ...``) when it reaches
:data:`GROUND_OVERLAP_WARN_M2`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envcap.scene.model import SceneMesh

GROUND_OVERLAP_TOLERANCE_M = 0.05
"""A triangle lies on the ground plane when all its corners are within this height (m) of it."""
GROUND_OVERLAP_UP_COS = 0.98
"""... and it faces up: the y of its unit normal exceeds this (within ~11 deg of +Y).  Faces
turned down at that height (the floors of closed buildings) are hidden by the buildings' walls."""
GROUND_OVERLAP_WARN_M2 = 1.0
"""Area (m^2) from which the scene build warns."""
CHUNK = 1 << 20
"""Triangles measured at a time (bounded temporaries on a city mesh of millions)."""


@dataclass(frozen=True)
class GroundOverlap:
    """Up-facing surface of a mesh on a horizontal plane: ``area_m2`` (m^2) in ``triangles``
    triangles, within ``tolerance_m`` of the plane at ``height`` (m)."""

    area_m2: float
    triangles: int
    height: float
    tolerance_m: float


def ground_overlap(mesh: SceneMesh, height: float = 0.0,
                   tolerance_m: float = GROUND_OVERLAP_TOLERANCE_M) -> GroundOverlap:
    """The up-facing triangles of ``mesh`` (world m) whose three corners all lie within
    ``tolerance_m`` of the plane y = ``height``, and their area."""
    pos = mesh.positions
    idx = mesh.indices.astype(np.int64)
    area, count = 0.0, 0
    for i in range(0, idx.shape[0], CHUNK):
        tri = pos[idx[i:i + CHUNK]].astype(np.float64) + mesh.origin          # (C, 3, 3) world m
        near = np.all(np.abs(tri[:, :, 1] - height) <= tolerance_m, axis=1)
        if not near.any():
            continue
        tri = tri[near]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        length = np.linalg.norm(n, axis=1)
        up = (length > 0) & (n[:, 1] > GROUND_OVERLAP_UP_COS * length)
        area += 0.5 * float(length[up].sum())
        count += int(up.sum())
    return GroundOverlap(area, count, float(height), float(tolerance_m))


def ground_overlap_warning(overlap: GroundOverlap, where: str) -> str | None:
    """The one-line warning (without ``envcap: warning:``) for a mesh table ``where`` (e.g.
    ``"scene.toml: mesh[0]"``), or ``None`` below :data:`GROUND_OVERLAP_WARN_M2`."""
    if overlap.area_m2 < GROUND_OVERLAP_WARN_M2:
        return None
    return (f"{where}: {overlap.area_m2:,.0f} m² of its up-facing surfaces ({overlap.triangles:,} triangles) lie within "
            f"{overlap.tolerance_m:g} m of the default ground plane (y = {overlap.height:g}): the two z-fight in "
            f"captures; set [ground] enabled = false if the mesh brings its own ground")
