"""Crowds of walkers at a given density around an evaluation site: seeded placement of the
walkers (feet on the ground, headings both ways along the street, animation phases) and of the
points where the lit crowd is evaluated.

**Density** ``rho`` (walkers per m^2 of street): around a site centre ``c`` (3,) m, the
``round(rho * A)`` *neighbours* stand in the disc of radius ``radius`` about ``c`` (horizontal),
``A`` its area on the street (the disc's area where ``inside`` holds, on a grid of
:data:`AREA_GRID` squared cells; all of it without ``inside``).  One more walker, the *host*,
stands at ``c``: the avatar whose surface carries the "self" points (:func:`self_points`).  The
host and the *free points* (points among the neighbours, :data:`FREE_HEIGHT_M` above the ground,
within ``radius / 2`` of ``c``) depend on the seed only, not on the density, so that densities
compare the same points.

**Placement** (dart throwing, uniform over the disc): a neighbour's feet stay
:data:`SPACING_M` from every other walker's, :data:`HOST_CLEARANCE_M` from the host's and
:data:`POINT_CLEARANCE_M` from each free point (horizontal distances: no point inside a body);
headings along the street (``heading_deg``, the yaw that faces +along, or the opposite, equally
likely) turned by up to :data:`HEADING_JITTER_DEG`; phases drawn uniformly from the given
keyframe times.
Too dense to place: ``ValueError``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

DENSITIES: tuple[float, ...] = (0.05, 0.2, 0.5, 1.0)
"""Default crowd densities (walkers per m^2): a quiet street to a packed sidewalk."""
RADIUS_M = 4.0
"""Radius (m) of the disc the neighbours stand in."""
SPACING_M = 0.5
"""Smallest distance (m) between two walkers' feet (shoulder to shoulder)."""
HOST_CLEARANCE_M = 0.7
"""Smallest distance (m) of a neighbour's feet from the host's (its swinging arms and legs)."""
POINT_CLEARANCE_M = 0.5
"""Smallest distance (m) of a walker's feet from a free point."""
FREE_HEIGHT_M = 1.0
"""Height (m) of the free points above the ground under them."""
HEADING_JITTER_DEG = 15.0
"""Headings deviate from the street's direction by up to this (degrees, uniform)."""
AREA_GRID = 256
"""Cells per side of the grid that measures the disc's area on the street."""
MAX_TRIES = 400
"""Dart throws per walker before the density is declared too high to place."""

Inside = Callable[[NDArray[np.float64]], NDArray[np.bool_]]
"""``inside(xz (n, 2)) -> (n,)``: True where a world point (x, z) m is on the street."""


@dataclass(frozen=True)
class Walker:
    """One walker: its feet at ``(x, z)`` ``root_xz`` m, turned ``yaw_deg`` about +Y (0: facing
    +Z), posed at ``time`` s of the animation."""

    root_xz: tuple[float, float]
    yaw_deg: float
    time: float


@dataclass(frozen=True)
class CrowdSite:
    """A site: ``center`` (3,) m, the ``host`` walker at it, ``neighbours``, ``free_xz`` ``(F, 2)``
    m (the free points' horizontal positions), ``density`` (walkers per m^2), ``radius`` m,
    ``area`` m^2 (the disc's area on the street) and ``seed``."""

    center: tuple[float, float, float]
    host: Walker
    neighbours: tuple[Walker, ...]
    free_xz: NDArray[np.float64]
    density: float
    radius: float
    area: float
    seed: int

    @property
    def walkers(self) -> tuple[Walker, ...]:
        """The host first, then the neighbours."""
        return (self.host, *self.neighbours)


def disc_area(center_xz: ArrayLike, radius: float, inside: Inside | None = None, grid: int = AREA_GRID) -> float:
    """Area (m^2) of the disc of ``radius`` m about ``center_xz`` (2,) where ``inside`` holds
    (``pi r^2`` without it): the disc's area times the fraction of the centres of a ``grid`` x
    ``grid`` lattice over its bounding square that fall in both."""
    if inside is None:
        return math.pi * radius * radius
    u = (np.arange(grid) + 0.5) / grid * 2 - 1
    gx, gz = np.meshgrid(u, u, indexing="ij")
    disc = gx * gx + gz * gz <= 1
    pts = np.asarray(center_xz, np.float64) + radius * np.stack([gx[disc], gz[disc]], axis=1)
    return math.pi * radius * radius * float(np.mean(inside(pts)))


def neighbour_count(density: float, area: float) -> int:
    """Neighbours at ``density`` walkers per m^2 on ``area`` m^2: ``round(density * area)``."""
    return int(round(density * area))


def check_density(density: float) -> float:
    """``density`` as a float, or ``ValueError`` unless finite and >= 0."""
    d = float(density)
    if not (math.isfinite(d) and d >= 0):
        raise ValueError(f"crowd density must be a finite number >= 0 walkers per m^2, got {density!r}")
    return d


def _disc_sample(rng: np.random.Generator, center: NDArray, radius: float) -> NDArray[np.float64]:
    r = radius * math.sqrt(rng.random())
    a = 2 * math.pi * rng.random()
    return center + r * np.array([math.cos(a), math.sin(a)])


def _walker(rng: np.random.Generator, xz: NDArray, heading_deg: float, phases: tuple[float, ...]) -> Walker:
    yaw = heading_deg + (180.0 if rng.random() < 0.5 else 0.0) + HEADING_JITTER_DEG * (2 * rng.random() - 1)
    return Walker((float(xz[0]), float(xz[1])), float(yaw % 360.0), float(phases[int(rng.integers(len(phases)))]))


def place_crowd(center: ArrayLike, density: float, *, heading_deg: float, phases: Sequence[float], seed: int,
                radius: float = RADIUS_M, free_points: int = 2, inside: Inside | None = None) -> CrowdSite:
    """The site about ``center`` (3,) m at ``density`` walkers per m^2 (module docstring).
    ``heading_deg``: the yaw of the street's +along direction; ``phases``: the animation times (s)
    a walker is posed at, one drawn per walker (the keyframes: every pose is then one of a few);
    ``seed``: the placement's seed (the host and free points use
    ``(seed, 0)``, the neighbours ``(seed, 1, density in 1/1000 walkers per m^2)``)."""
    d = check_density(density)
    if not (math.isfinite(radius) and radius > 1.0):
        raise ValueError(f"crowd radius must be a finite number > 1 m, got {radius!r}")
    if free_points < 0:
        raise ValueError(f"free points must be >= 0, got {free_points}")
    keys = tuple(float(t) for t in phases)
    if not keys or not all(math.isfinite(t) for t in keys):
        raise ValueError(f"walker phases must be finite times in s, at least one, got {phases!r}")
    c3 = np.asarray(center, np.float64).reshape(3)
    c = c3[[0, 2]]
    site_rng = np.random.default_rng((int(seed), 0))
    host = _walker(site_rng, c, heading_deg, keys)
    free: list[NDArray] = []
    for _ in range(MAX_TRIES * max(free_points, 1)):
        if len(free) == free_points:
            break
        p = _disc_sample(site_rng, c, radius / 2)
        if np.hypot(*(p - c)) >= HOST_CLEARANCE_M and all(np.hypot(*(p - q)) >= 2 * POINT_CLEARANCE_M for q in free) \
                and (inside is None or bool(inside(p[None])[0])):
            free.append(p)
    if len(free) < free_points:
        raise ValueError(f"could not place {free_points} free points within {radius / 2:g} m of {c.tolist()}")
    area = disc_area(c, radius, inside)
    n = neighbour_count(d, area)
    rng = np.random.default_rng((int(seed), 1, int(round(d * 1000))))
    feet = [c]
    out: list[Walker] = []
    tries = 0
    while len(out) < n:
        tries += 1
        if tries > MAX_TRIES * n:
            raise ValueError(f"crowd density {d:g} walkers per m^2 is too high to place {n} walkers "
                             f"{SPACING_M:g} m apart in {area:.1f} m^2 (placed {len(out)})")
        p = _disc_sample(rng, c, radius)
        if inside is not None and not bool(inside(p[None])[0]):
            continue
        if np.hypot(*(p - c)) < HOST_CLEARANCE_M or any(np.hypot(*(p - q)) < POINT_CLEARANCE_M for q in free):
            continue
        if np.min(np.hypot(*(np.asarray(feet) - p).T)) < SPACING_M:
            continue
        feet.append(p)
        out.append(_walker(rng, p, heading_deg, keys))
    return CrowdSite((float(c3[0]), float(c3[1]), float(c3[2])), host, tuple(out),
                     np.array(free, np.float64).reshape(-1, 2), d, float(radius), area, int(seed))


def inside_body(origin: ArrayLike, direction: ArrayLike, positions: ArrayLike, normals: ArrayLike,
                triangles: ArrayLike) -> bool:
    """Whether the point ``origin`` (3,) m is inside the closed parts of a mesh: the first triangle
    that the ray along ``direction`` (3,) hits (float64 Moller-Trumbore, both faces) faces away from
    the ray's origin (its outward side, the mean of its vertex ``normals``, along the ray: the ray
    leaves a body).  No hit: outside."""
    o, d = np.asarray(origin, np.float64), np.asarray(direction, np.float64)
    p, nv = np.asarray(positions, np.float64), np.asarray(normals, np.float64)
    tri = np.asarray(triangles, np.int64)
    a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    e1, e2 = b - a, c - a
    q = np.cross(d, e2)
    det = np.einsum("tk,tk->t", e1, q)
    ok = np.abs(det) > 1e-15
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = o - a
    u = np.einsum("tk,tk->t", s, q) * inv
    r = np.cross(s, e1)
    v = (r @ d) * inv
    t = np.einsum("tk,tk->t", e2, r) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9)
    if not hit.any():
        return False
    first = int(np.argmin(np.where(hit, t, np.inf)))
    outward = nv[tri[first]].sum(axis=0)
    return bool(outward @ d > 0)


def self_vertices(positions: ArrayLike, normals: ArrayLike, triangles: ArrayLike, ground: float, count: int,
                  seed: int, offset: float = 0.02, low: float = 0.3, high: float = 1.7) -> NDArray[np.int64]:
    """``count`` distinct vertex indices of a posed avatar (``positions``, ``normals`` ``(V, 3)``
    world m, ``triangles`` ``(T, 3)``) drawn uniformly (seeded) among the vertices ``low`` ..
    ``high`` m above ``ground`` (m) with a non-degenerate normal whose point ``offset`` m along the
    normal is not inside another part of the body (:func:`inside_body` along the normal: a
    capsule's end buried in the next one is never seen): where a self point stands (the feet and
    the top of the head left out)."""
    p = np.asarray(positions, np.float64)
    n = np.asarray(normals, np.float64)
    length = np.linalg.norm(n, axis=1)
    ok = np.flatnonzero((p[:, 1] - ground >= low) & (p[:, 1] - ground <= high) & (length > 1e-6))
    rng = np.random.default_rng((int(seed), 2))
    out: list[int] = []
    for v in rng.permutation(ok):
        if len(out) == count:
            break
        unit = n[v] / length[v]
        if not inside_body(p[v] + offset * unit, unit, p, n, triangles):
            out.append(int(v))
    if len(out) < count:
        raise ValueError(f"asked for {count} self points, the avatar has {len(out)} visible vertices "
                         f"{low:g}-{high:g} m up")
    return np.sort(np.array(out, np.int64))


def street_inside(extent: object, margin: float = 0.5) -> Inside:
    """``inside`` for a :class:`envcap.evaluate.sweep.StreetExtent`: between its facades less
    ``margin`` m and between its ends."""
    def inside(xz: NDArray[np.float64]) -> NDArray[np.bool_]:
        xz = np.asarray(xz, np.float64).reshape(-1, 2)
        pts = np.stack([xz[:, 0], np.zeros(len(xz)), xz[:, 1]], axis=1)
        f = np.asarray(extent.to_frame(pts), np.float64).reshape(-1, 3)  # type: ignore[attr-defined]
        a, c = f[:, extent.along], f[:, extent.cross]  # type: ignore[attr-defined]
        return ((c >= extent.fmin + margin) & (c <= extent.fmax - margin)  # type: ignore[attr-defined]
                & (a >= extent.start) & (a <= extent.end))  # type: ignore[attr-defined]
    return inside
