"""Extra spheres in a scene (dynamic occluders made solid, for fresh captures): icosphere meshes
added to a copy of a :class:`~envcap.scene.model.Scene`, lit by the scene's capture effects like
any other geometry (sun, sky, sun shadows: they cast and receive them).

Used by the street evaluation of the dynamic terms (:mod:`envcap.evaluate.dynamic_occluders`):
the truth is a capture of the scene with the spheres in it.  The original scene is not changed,
and a scene given no spheres is returned as is, so its captures stay bit-identical.

Geometry: an icosahedron subdivided ``subdivisions`` times (``20 * 4^k`` triangles), smooth
(radial) normals, uniform albedo per sphere, no emission.  A subdivided icosphere is a polyhedron
inscribed in a sphere; its vertices are placed at radius ``r / mean(cos)`` where ``mean(cos)`` is
the mean ratio of face-center to vertex radius, so that the polyhedron's faces lie on average at
the requested radius (at ``k = 3`` vertices are 0.2 % outside, face centers about 0.2 % inside;
the silhouette's solid angle is then within ~0.5 % of the sphere's).  Vertices are stored
relative to the scene mesh's origin, so the scene's own float32 positions are kept unchanged.
Units: meters, world frame (+Y up).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.scene.model import Scene, SceneMesh

DEFAULT_SUBDIVISIONS = 3
"""Icosphere subdivisions (1280 triangles per sphere)."""
MAX_SUBDIVISIONS = 6
"""Most subdivisions accepted (81920 triangles per sphere)."""


@dataclass(frozen=True)
class OccluderSphere:
    """A sphere: ``center`` (3,) world meters, ``radius`` m (> 0), ``albedo`` (3,) linear RGB in [0, 1]."""

    center: tuple[float, float, float]
    radius: float
    albedo: tuple[float, float, float] = (0.5, 0.5, 0.5)

    def __post_init__(self) -> None:
        c = np.asarray(self.center, np.float64)
        a = np.asarray(self.albedo, np.float64)
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise ValueError(f"occluder sphere center must be 3 finite numbers, got {self.center!r}")
        if not (isinstance(self.radius, (int, float, np.integer, np.floating)) and math.isfinite(self.radius)
                and self.radius > 0):
            raise ValueError(f"occluder sphere radius must be a finite number > 0 m, got {self.radius!r}")
        if a.shape != (3,) or not np.all(np.isfinite(a)) or np.any(a < 0) or np.any(a > 1):
            raise ValueError(f"occluder sphere albedo must be 3 numbers in [0, 1], got {self.albedo!r}")
        object.__setattr__(self, "center", tuple(float(v) for v in c))
        object.__setattr__(self, "radius", float(self.radius))
        object.__setattr__(self, "albedo", tuple(float(v) for v in a))


def unit_icosphere(subdivisions: int) -> tuple[NDArray[np.float64], NDArray[np.uint32]]:
    """Vertices ``(V, 3)`` on the unit sphere and counter-clockwise (seen from outside) triangles
    ``(T, 3)`` of an icosahedron subdivided ``subdivisions`` times (shared vertices)."""
    if isinstance(subdivisions, bool) or not isinstance(subdivisions, (int, np.integer)) \
            or not 0 <= subdivisions <= MAX_SUBDIVISIONS:
        raise ValueError(f"icosphere subdivisions must be an integer in [0, {MAX_SUBDIVISIONS}], got {subdivisions!r}")
    g = (1 + math.sqrt(5)) / 2
    verts = [(-1, g, 0), (1, g, 0), (-1, -g, 0), (1, -g, 0), (0, -1, g), (0, 1, g), (0, -1, -g), (0, 1, -g),
             (g, 0, -1), (g, 0, 1), (-g, 0, -1), (-g, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
             (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
             (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    v = [np.array(p, np.float64) / np.linalg.norm(p) for p in verts]
    for _ in range(int(subdivisions)):
        mid: dict[tuple[int, int], int] = {}

        def midpoint(a: int, b: int, mid: dict[tuple[int, int], int] = mid) -> int:
            key = (min(a, b), max(a, b))
            if key not in mid:
                m = v[a] + v[b]
                v.append(m / np.linalg.norm(m))
                mid[key] = len(v) - 1
            return mid[key]
        new = []
        for a, b, c in faces:
            ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return np.array(v), np.array(faces, np.uint32)


def sphere_mesh(spheres: Sequence[OccluderSphere], origin: ArrayLike = (0.0, 0.0, 0.0),
                subdivisions: int = DEFAULT_SUBDIVISIONS) -> SceneMesh:
    """One :class:`SceneMesh` holding every sphere (positions relative to ``origin`` (3,) m,
    float64 arithmetic rounded to float32 once; normals radial; albedo per sphere; emission 0)."""
    unit, tris = unit_icosphere(subdivisions)
    centers = unit[tris].mean(axis=1)
    scale = 1.0 / float(np.mean(np.linalg.norm(centers, axis=1)))   # faces on average at the radius
    o = np.asarray(origin, np.float64)
    parts = []
    for k, s in enumerate(spheres):
        if not isinstance(s, OccluderSphere):
            raise TypeError(f"spheres[{k}] must be an OccluderSphere, got {type(s).__name__}")
        pos = (np.asarray(s.center) - o) + unit * (s.radius * scale)
        nv = unit.shape[0]
        parts.append(SceneMesh(pos.astype(np.float32), unit.astype(np.float32),
                               np.tile(np.asarray(s.albedo, np.float32), (nv, 1)), np.zeros((nv, 3), np.float32),
                               tris.copy(), o))
    return SceneMesh.concatenate(parts) if parts else SceneMesh.concatenate([])


def with_spheres(scene: Scene, spheres: Sequence[OccluderSphere], subdivisions: int = DEFAULT_SUBDIVISIONS) -> Scene:
    """A new :class:`Scene` whose mesh is ``scene.mesh`` followed by the spheres' triangles (the
    scene's vertices first, unchanged, same origin); ``scene`` itself is returned when
    ``spheres`` is empty.  ``meta["occluder_spheres"]`` counts them."""
    spheres = list(spheres)
    if not spheres:
        return scene
    extra = sphere_mesh(spheres, scene.mesh.origin, subdivisions)
    mesh = SceneMesh.concatenate([scene.mesh, extra]) if scene.mesh.positions.shape[0] else extra
    return dataclasses.replace(scene, mesh=mesh, meta={**scene.meta, "occluder_spheres": len(spheres)})


def ring_of_spheres(point: ArrayLike, count: int, distance: float, radius: float, elevation_deg: float = 0.0,
                    azimuth_deg: float = 0.0, albedo: tuple[float, float, float] = (0.5, 0.5, 0.5)) -> list[OccluderSphere]:
    """``count`` spheres of ``radius`` m whose centers are ``distance`` m from ``point`` (3,) m, at
    ``elevation_deg`` above its horizontal plane, evenly spaced in azimuth (about +Y) starting at
    ``azimuth_deg`` from +X toward +Z."""
    p = np.asarray(point, np.float64)
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
        raise ValueError(f"ring sphere count must be an integer >= 1, got {count!r}")
    if not (math.isfinite(distance) and distance > 0):
        raise ValueError(f"ring distance must be a finite number > 0 m, got {distance!r}")
    el = math.radians(elevation_deg)
    out = []
    for i in range(int(count)):
        az = math.radians(azimuth_deg) + 2 * math.pi * i / count
        d = np.array([math.cos(el) * math.cos(az), math.sin(el), math.cos(el) * math.sin(az)])
        out.append(OccluderSphere(tuple(p + distance * d), radius, albedo))
    return out
