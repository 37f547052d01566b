"""Extra triangle meshes in a scene (dynamic objects made solid, e.g. posed avatars, for fresh
captures): world-space meshes added to a copy of a :class:`~envcap.scene.model.Scene`, lit by the
scene's capture effects like any other geometry (sun, sky, sun shadows: cast and received).

The sibling of :func:`envcap.scene.occluder_spheres.with_spheres` for arbitrary geometry; used by
the street evaluation with avatars (:mod:`envcap.evaluate.dynamic_avatars`).  The original scene
is not changed, and a scene given no meshes is returned as is (its captures stay bit-identical).

An :class:`ExtraMesh` is given in world meters (float64, +Y up) with per-vertex normals (smooth
shading; they are normalized here) and one uniform albedo, no emission.  Its vertices are stored
relative to the scene mesh's origin (float64 arithmetic rounded to float32 once), so the scene's
own float32 positions are kept unchanged.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.scene.model import Scene, SceneMesh


@dataclass(frozen=True)
class ExtraMesh:
    """A mesh to add: ``positions`` ``(V, 3)`` world m, ``normals`` ``(V, 3)`` (any non-zero
    length; normalized), ``triangles`` ``(T, 3)`` vertex indices, ``albedo`` ``(3,)`` linear RGB in
    [0, 1].  Arrays are validated and stored as float64 / int64 copies."""

    positions: NDArray[np.float64]
    normals: NDArray[np.float64]
    triangles: NDArray[np.int64]
    albedo: tuple[float, float, float] = (0.5, 0.5, 0.5)

    def __post_init__(self) -> None:
        p = np.array(self.positions, np.float64)
        n = np.array(self.normals, np.float64)
        t = np.array(self.triangles)
        a = np.asarray(self.albedo, np.float64)
        if p.ndim != 2 or p.shape[1] != 3 or not np.all(np.isfinite(p)):
            raise ValueError(f"extra mesh positions must be finite with shape (V, 3), got shape {p.shape}")
        if n.shape != p.shape or not np.all(np.isfinite(n)):
            raise ValueError(f"extra mesh normals must be finite with shape {p.shape}, got {n.shape}")
        length = np.linalg.norm(n, axis=1, keepdims=True)
        if np.any(length <= 0):
            raise ValueError(f"extra mesh has {int(np.sum(length <= 0))} zero-length normal(s)")
        if t.ndim != 2 or t.shape[1] != 3 or (t.size and not np.issubdtype(t.dtype, np.integer)):
            raise ValueError(f"extra mesh triangles must be integers with shape (T, 3), got {t.dtype} {t.shape}")
        if t.size and (int(t.min()) < 0 or int(t.max()) >= len(p)):
            raise ValueError(f"extra mesh triangles index vertices outside 0..{len(p) - 1}")
        if a.shape != (3,) or not np.all(np.isfinite(a)) or np.any(a < 0) or np.any(a > 1):
            raise ValueError(f"extra mesh albedo must be 3 numbers in [0, 1], got {self.albedo!r}")
        object.__setattr__(self, "positions", p)
        object.__setattr__(self, "normals", n / length)
        object.__setattr__(self, "triangles", t.astype(np.int64).reshape(-1, 3))
        object.__setattr__(self, "albedo", tuple(float(v) for v in a))

    def bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World ``(min (3,), max (3,))`` of the vertices (m)."""
        return self.positions.min(axis=0), self.positions.max(axis=0)


def extra_scene_mesh(meshes: Sequence[ExtraMesh], origin: ArrayLike = (0.0, 0.0, 0.0)) -> SceneMesh:
    """One :class:`SceneMesh` holding every mesh (positions relative to ``origin`` (3,) m; uniform
    albedo per mesh; emission 0)."""
    o = np.asarray(origin, np.float64)
    parts = []
    for k, m in enumerate(meshes):
        if not isinstance(m, ExtraMesh):
            raise TypeError(f"meshes[{k}] must be an ExtraMesh, got {type(m).__name__}")
        nv = m.positions.shape[0]
        parts.append(SceneMesh((m.positions - o).astype(np.float32), m.normals.astype(np.float32),
                               np.tile(np.asarray(m.albedo, np.float32), (nv, 1)), np.zeros((nv, 3), np.float32),
                               m.triangles.astype(np.uint32), o))
    return SceneMesh.concatenate(parts)


def with_meshes(scene: Scene, meshes: Sequence[ExtraMesh]) -> Scene:
    """A new :class:`Scene` whose mesh is ``scene.mesh`` followed by the meshes' triangles (the
    scene's vertices first, unchanged, same origin); ``scene`` itself is returned when ``meshes``
    is empty.  ``meta["extra_meshes"]`` counts them."""
    meshes = list(meshes)
    if not meshes:
        return scene
    extra = extra_scene_mesh(meshes, scene.mesh.origin)
    mesh = SceneMesh.concatenate([scene.mesh, extra]) if scene.mesh.positions.shape[0] else extra
    return dataclasses.replace(scene, mesh=mesh, meta={**scene.meta, "extra_meshes": len(meshes)})
