"""Small synthetic scene meshes (quads, boxes, a street canyon) for capture tests and benchmarks.

All in the envcap world frame (meters, +Y up).  Flat shaded: each quad has its own 4 vertices.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from envcap.scene.model import SceneMesh


def quad(corner: Sequence[float], edge_u: Sequence[float], edge_v: Sequence[float],
         albedo: Sequence[float] = (0.5, 0.5, 0.5), emission: Sequence[float] = (0.0, 0.0, 0.0)) -> SceneMesh:
    """A parallelogram ``corner + a edge_u + b edge_v`` (a, b in [0, 1]), 2 triangles.

    Its normal is ``normalize(edge_u x edge_v)`` (the lit side); triangles wind counter-clockwise
    seen from that side.
    """
    c, u, v = (np.asarray(x, dtype=np.float64) for x in (corner, edge_u, edge_v))
    nrm = np.cross(u, v)
    ln = np.linalg.norm(nrm)
    if not ln > 0:
        raise ValueError("quad edges are parallel or zero")
    pos = np.array([c, c + u, c + u + v, c + v], dtype=np.float32)
    f = np.float32
    return SceneMesh(pos, np.tile((nrm / ln).astype(f), (4, 1)), np.tile(np.asarray(albedo, f), (4, 1)),
                     np.tile(np.asarray(emission, f), (4, 1)), np.array([[0, 1, 2], [0, 2, 3]], np.uint32))


def box(lo: Sequence[float], hi: Sequence[float], albedo: Sequence[float] = (0.5, 0.5, 0.5),
        emission: Sequence[float] = (0.0, 0.0, 0.0), inward: bool = False) -> SceneMesh:
    """Axis-aligned box ``[lo, hi]`` as 6 quads, normals outward (or inward: a room)."""
    lo_, hi_ = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    if not np.all(hi_ > lo_):
        raise ValueError(f"box needs hi > lo, got {lo}, {hi}")
    x0, y0, z0 = lo_
    dx, dy, dz = hi_ - lo_
    ex, ey, ez = np.array([dx, 0, 0]), np.array([0, dy, 0]), np.array([0, 0, dz])
    faces = [
        (lo_ + ex, ey, ez),   # +X: ey x ez = +x
        (lo_, ez, ey),        # -X
        (lo_ + ey, ez, ex),   # +Y: ez x ex = +y
        (lo_, ex, ez),        # -Y
        (lo_ + ez, ex, ey),   # +Z: ex x ey = +z
        (lo_, ey, ex),        # -Z
    ]
    parts = []
    for c, u, v in faces:
        if inward:
            u, v = v, u
        parts.append(quad(c, u, v, albedo, emission))
    return SceneMesh.concatenate(parts)


def grid_quad(corner: Sequence[float], edge_u: Sequence[float], edge_v: Sequence[float], nu: int, nv: int,
              albedo: Sequence[float] = (0.5, 0.5, 0.5), emission: Sequence[float] = (0.0, 0.0, 0.0),
              window_emission: Sequence[float] | None = None) -> SceneMesh:
    """A parallelogram split into ``nu x nv`` quads; with ``window_emission`` every other cell emits."""
    c, u, v = (np.asarray(x, dtype=np.float64) for x in (corner, edge_u, edge_v))
    parts = []
    for j in range(nv):
        for i in range(nu):
            em = window_emission if (window_emission is not None and (i + j) % 2 == 0 and j > 0) else emission
            parts.append(quad(c + u * i / nu + v * j / nv, u / nu, v / nv, albedo, em))
    return SceneMesh.concatenate(parts)


def street_canyon(length: float = 120.0, width: float = 16.0, target_triangles: int = 50000,
                  seed: int = 0) -> SceneMesh:
    """A street along X from 0 to ``length``, facades at z = +-width/2, with ~``target_triangles``.

    Ground plane, two rows of box buildings of random height (8 to 30 m) whose street facades are
    subdivided into window cells (every other cell emissive) to reach the triangle budget.
    """
    rng = np.random.default_rng(seed)
    parts = [quad((-20.0, 0.0, 60.0), (length + 40.0, 0.0, 0.0), (0.0, 0.0, -120.0), (0.25, 0.25, 0.25))]
    n_bld = max(int(length // 12), 1)
    cells = max(int(np.sqrt(max(target_triangles - 12 * 2 * n_bld, 2) / (2 * 2 * n_bld))), 1)
    for side in (-1, 1):
        for b in range(n_bld):
            x0 = b * length / n_bld
            x1 = x0 + length / n_bld * 0.95
            h = float(rng.uniform(8.0, 30.0))
            zf = side * width / 2
            zb = side * (width / 2 + 15.0)
            lo, hi = (x0, 0.0, min(zf, zb)), (x1, h, max(zf, zb))
            alb = tuple(rng.uniform(0.2, 0.7, 3))
            parts.append(box(lo, hi, alb))
            # Subdivided street facade, 1 cm in front of the box face, facing the street.
            if side < 0:
                parts.append(grid_quad((x0, 0.0, zf + 0.01), (x1 - x0, 0, 0), (0, h, 0), cells, cells, alb,
                                       window_emission=(3.0, 2.6, 1.8)))
            else:
                parts.append(grid_quad((x0, 0.0, zf - 0.01), (0, h, 0), (x1 - x0, 0, 0), cells, cells, alb,
                                       window_emission=(3.0, 2.6, 1.8)))
    return SceneMesh.concatenate(parts)
