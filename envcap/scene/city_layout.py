"""A procedural "OSM-like" city for tests and the demo: the layout and its ground truth.

Two districts, in the envcap world frame (meters, +Y up; plan coordinates ``(x, z)``):

* **a rotated grid** centred on ``grid_center``: ``grid_blocks = (nu, nv)`` blocks of
  ``block_size = (bu, bv)`` m, the whole grid turned by ``grid_angle_deg`` in plan; the inner
  streets between block rows have their own widths (facade to facade); each block is filled with
  buildings flush with its edges, so every facade lies exactly on a street's facade line;
* **an irregular district** of ``radial_streets`` streets leaving a plaza at ``radial_center`` at
  irregular angles, each lined on both sides by buildings turned to the street, on terrain that
  slopes (``slope`` rise per meter of +X east of ``slope_start_x``): its streets are sloped.

Angles in plan are ``atan2(dz, dx)`` in degrees (0 = +X, 90 = +Z).  Every building is a box
(footprint: four plan corners in order around it) from a base 1 m below the terrain to its roof.  :class:`CityLayout` holds the buildings and the streets' truth (centre line, direction,
facade offsets, slope) that street detection is graded against.  Writing the files (PLY per
building, Mitsuba XML, glTF, OBJ + MTL, terrain) is :mod:`envcap.scene.city_files`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

MATERIALS: dict[str, tuple[float, float, float]] = {
    "brick": (0.45, 0.22, 0.15),
    "plaster": (0.72, 0.68, 0.60),
    "concrete": (0.50, 0.50, 0.48),
    "dark_glass": (0.12, 0.15, 0.18),
    "sandstone": (0.62, 0.52, 0.36),
}
"""Linear diffuse albedo of the generated facades' materials (roofs share the facade's)."""

TERRAIN_MATERIAL = "asphalt"
TERRAIN_ALBEDO = (0.12, 0.12, 0.12)


@dataclass(frozen=True)
class CitySpec:
    """Parameters of the generated city (meters, degrees).  ``seed`` fixes every random choice."""

    seed: int = 7
    grid_center: tuple[float, float] = (0.0, 0.0)
    grid_angle_deg: float = 7.0
    grid_blocks: tuple[int, int] = (4, 3)
    block_size: tuple[float, float] = (72.0, 44.0)
    street_widths_u: tuple[float, ...] = (14.0, 11.0)
    """Widths of the inner streets running along the grid's u axis (one per gap between rows)."""
    street_widths_v: tuple[float, ...] = (12.0, 18.0, 10.0)
    """Widths of the inner streets running along v (one per gap between block columns)."""
    radial_center: tuple[float, float] = (330.0, 20.0)
    radial_angles_deg: tuple[float, ...] = (12.0, 71.0, 133.0, 197.0, 262.0, 318.0)
    radial_widths: tuple[float, ...] = (12.0, 10.0, 16.0, 13.0, 11.0, 14.0)
    radial_range: tuple[float, float] = (34.0, 130.0)
    """Plan distance from the plaza centre where each radial street's buildings start and end."""
    building_depth: float = 14.0
    height_range: tuple[float, float] = (9.0, 32.0)
    slope: float = 0.06
    slope_start_x: float = 200.0
    facade_cells: int = 1
    """Each facade is split into ``facade_cells`` x ``facade_cells`` quads (more triangles)."""
    inward_every: int = 7
    """Every n-th building file is written wound inward (faces reversed); 0: none."""

    def __post_init__(self) -> None:
        nu, nv = self.grid_blocks
        if nu < 1 or nv < 1:
            raise ValueError(f"grid_blocks must be >= 1 each, got {self.grid_blocks}")
        if len(self.street_widths_u) != nv - 1 or len(self.street_widths_v) != nu - 1:
            raise ValueError("street_widths_u needs grid_blocks[1]-1 widths and street_widths_v grid_blocks[0]-1")
        if len(self.radial_widths) != len(self.radial_angles_deg):
            raise ValueError("radial_widths needs one width per radial angle")
        if self.facade_cells < 1:
            raise ValueError(f"facade_cells must be >= 1, got {self.facade_cells}")


@dataclass(frozen=True)
class Building:
    """One box building.  ``footprint``: (4, 2) plan corners (x, z) in meters, in order around the
    box; ``base``/``top``: y of its floor (below the terrain) and roof (m); ``inward``: its file
    is written with reversed faces."""

    name: str
    district: Literal["grid", "radial"]
    footprint: NDArray[np.float64]
    base: float
    top: float
    material: str
    inward: bool = False


@dataclass(frozen=True)
class StreetTruth:
    """One straight street of the generated city, as street detection should find it.

    ``p0``/``p1``: plan end points (x, z) of the centre line between its outermost facades;
    ``angle_deg``: direction p0 -> p1, ``atan2(dz, dx)``; ``width``: facade to facade (m);
    ``facade_offsets``: signed distances of the two facade lines from the centre line along the
    plan normal ``(-sin a, cos a)``; ``slope``: rise per meter along p0 -> p1 (``nan`` where the
    street crosses a kink of the terrain); ``intersections``: distances along the centre line
    (from p0) of the centre lines of the streets that cross it (grid streets only)."""

    name: str
    district: Literal["grid", "radial"]
    p0: tuple[float, float]
    p1: tuple[float, float]
    angle_deg: float
    width: float
    facade_offsets: tuple[float, float]
    slope: float
    intersections: tuple[float, ...] = ()

    @property
    def length(self) -> float:
        """Length of the centre line in plan (m)."""
        return float(np.hypot(self.p1[0] - self.p0[0], self.p1[1] - self.p0[1]))


@dataclass(frozen=True)
class CityLayout:
    """The generated city: its spec, buildings and streets' truth (world frame, meters)."""

    spec: CitySpec
    buildings: tuple[Building, ...]
    streets: tuple[StreetTruth, ...]
    bounds: tuple[float, float, float, float] = field(default=(0.0, 0.0, 0.0, 0.0))
    """Plan box (x_min, z_min, x_max, z_max) of every building, padded by 20 m."""

    def terrain_height(self, x: NDArray[np.float64] | float, z: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """Terrain height y (m) at plan points: 0 west of ``slope_start_x``, rising ``slope``
        per meter east of it (a ramp; the grid district stays flat)."""
        return terrain_height(self.spec, x, z)


def terrain_height(spec: CitySpec, x: NDArray[np.float64] | float, z: NDArray[np.float64] | float) -> NDArray[np.float64]:
    """Terrain height (m) of ``spec``'s city at plan points ``(x, z)`` (any broadcastable shapes)."""
    xs = np.asarray(x, dtype=np.float64) + 0.0 * np.asarray(z, dtype=np.float64)
    return spec.slope * np.maximum(xs - spec.slope_start_x, 0.0)


def _rotation(angle_deg: float) -> NDArray[np.float64]:
    a = np.radians(angle_deg)
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def _rect(center: NDArray[np.float64], axis_u: NDArray[np.float64], half_u: float, half_v: float) -> NDArray[np.float64]:
    """Plan corners (4, 2) of a rectangle centred on ``center`` with ``axis_u`` (unit) along its
    ``2*half_u`` side, in order around it."""
    axis_v = np.array([-axis_u[1], axis_u[0]])
    corners = [(-half_u, -half_v), (-half_u, half_v), (half_u, half_v), (half_u, -half_v)]
    return np.array([center + cu * axis_u + cv * axis_v for cu, cv in corners])


def _split_lengths(rng: np.random.Generator, total: float, lo: float, hi: float) -> list[float]:
    """Split ``total`` into pieces in [lo, hi] (the last one absorbs the rest, >= lo)."""
    pieces: list[float] = []
    left = total
    while left > hi:
        w = float(rng.uniform(lo, hi))
        if left - w < lo:
            w = left - lo
        pieces.append(w)
        left -= w
    pieces.append(left)
    return pieces


def _rects_overlap(a: NDArray[np.float64], b: NDArray[np.float64], margin: float = -0.05) -> bool:
    """Separating-axis test for two convex plan quads, grown by ``margin`` meters (the default
    shrinks them a little: quads that only touch do not overlap)."""
    for poly in (a, b):
        for i in range(4):
            edge = poly[(i + 1) % 4] - poly[i]
            n = np.array([-edge[1], edge[0]]) / np.hypot(*edge)
            pa, pb = a @ n, b @ n
            if pa.max() + margin <= pb.min() or pb.max() + margin <= pa.min():
                return False
    return True


def _building(spec: CitySpec, rng: np.random.Generator, name: str, district: Literal["grid", "radial"],
              footprint: NDArray[np.float64], index: int) -> Building:
    ground = terrain_height(spec, footprint[:, 0], footprint[:, 1])
    height = float(rng.uniform(*spec.height_range))
    material = sorted(MATERIALS)[int(rng.integers(len(MATERIALS)))]
    inward = spec.inward_every > 0 and index % spec.inward_every == spec.inward_every - 1
    return Building(name, district, footprint, float(ground.min()) - 1.0, float(ground.max()) + height, material, inward)


def _grid(spec: CitySpec, rng: np.random.Generator, buildings: list[Building]) -> list[StreetTruth]:
    nu, nv = spec.grid_blocks
    bu, bv = spec.block_size
    rot = _rotation(spec.grid_angle_deg)
    axis_u, axis_v = rot[:, 0], rot[:, 1]
    # block edges along u and v (local coordinates, grid centred on grid_center)
    u_edges = [0.0]
    for i in range(nu):
        u_edges.append(u_edges[-1] + bu)
        if i < nu - 1:
            u_edges.append(u_edges[-1] + spec.street_widths_v[i])
    v_edges = [0.0]
    for j in range(nv):
        v_edges.append(v_edges[-1] + bv)
        if j < nv - 1:
            v_edges.append(v_edges[-1] + spec.street_widths_u[j])
    u0, v0 = u_edges[-1] / 2.0, v_edges[-1] / 2.0
    center = np.asarray(spec.grid_center, dtype=np.float64)

    def world(u: float, v: float) -> NDArray[np.float64]:
        return center + (u - u0) * axis_u + (v - v0) * axis_v

    for i in range(nu):
        ua, ub = u_edges[2 * i], u_edges[2 * i + 1]
        for j in range(nv):
            va, vb = v_edges[2 * j], v_edges[2 * j + 1]
            vm = (va + vb) / 2.0
            for row, (ra, rb) in enumerate(((va, vm), (vm, vb))):
                u = ua
                for w in _split_lengths(rng, ub - ua, 12.0, 26.0):
                    c = world(u + w / 2.0, (ra + rb) / 2.0)
                    fp = _rect(c, axis_u, w / 2.0, (rb - ra) / 2.0)
                    name = f"grid_{i}{j}_{row}_{len(buildings):03d}"
                    buildings.append(_building(spec, rng, name, "grid", fp, len(buildings)))
                    u += w
    streets: list[StreetTruth] = []
    cross_u = [(u_edges[2 * i + 1] + u_edges[2 * i + 2]) / 2.0 for i in range(nu - 1)]
    cross_v = [(v_edges[2 * j + 1] + v_edges[2 * j + 2]) / 2.0 for j in range(nv - 1)]
    for j, width in enumerate(spec.street_widths_u):
        v = cross_v[j]
        p0, p1 = world(0.0, v), world(u_edges[-1], v)
        streets.append(StreetTruth(f"grid_u{j}", "grid", (float(p0[0]), float(p0[1])), (float(p1[0]), float(p1[1])),
                                   spec.grid_angle_deg, width, (-width / 2.0, width / 2.0), 0.0, tuple(cross_u)))
    for i, width in enumerate(spec.street_widths_v):
        u = cross_u[i]
        p0, p1 = world(u, 0.0), world(u, v_edges[-1])
        streets.append(StreetTruth(f"grid_v{i}", "grid", (float(p0[0]), float(p0[1])), (float(p1[0]), float(p1[1])),
                                   spec.grid_angle_deg + 90.0, width, (-width / 2.0, width / 2.0), 0.0, tuple(cross_v)))
    return streets


def _radial(spec: CitySpec, rng: np.random.Generator, buildings: list[Building]) -> list[StreetTruth]:
    center = np.asarray(spec.radial_center, dtype=np.float64)
    r0, r1 = spec.radial_range
    streets: list[StreetTruth] = []
    placed: list[NDArray[np.float64]] = [b.footprint for b in buildings]
    for k, (angle, width) in enumerate(zip(spec.radial_angles_deg, spec.radial_widths)):
        axis_u = _rotation(angle)[:, 0]
        axis_v = np.array([-axis_u[1], axis_u[0]])
        first = r1
        for side in (-1.0, 1.0):
            offset = side * (width / 2.0 + spec.building_depth / 2.0)
            r = r0
            for w in _split_lengths(rng, r1 - r0, 10.0, 22.0):
                c = center + (r + w / 2.0) * axis_u + offset * axis_v
                fp = _rect(c, axis_u, w / 2.0, spec.building_depth / 2.0)
                if not any(_rects_overlap(fp, other) for other in placed):
                    placed.append(fp)
                    buildings.append(_building(spec, rng, f"radial_{k}_{len(buildings):03d}", "radial", fp, len(buildings)))
                    first = min(first, r)
                r += w
        p0, p1 = center + first * axis_u, center + r1 * axis_u
        slope = spec.slope * float(axis_u[0]) if min(p0[0], p1[0]) >= spec.slope_start_x else float("nan")
        streets.append(StreetTruth(f"radial_{k}", "radial", (float(p0[0]), float(p0[1])), (float(p1[0]), float(p1[1])),
                                   float(angle), width, (-width / 2.0, width / 2.0), slope))
    return streets


def generate_city_layout(spec: CitySpec | None = None) -> CityLayout:
    """The buildings and streets' truth of the city ``spec`` describes (deterministic in ``seed``).

    Radial streets whose buildings would overlap the grid's or another street's are shortened
    (buildings that would overlap are left out); a radial street crossing the slope's start line
    has ``slope = nan`` (a kink, not one slope)."""
    spec = spec or CitySpec()
    rng = np.random.default_rng(spec.seed)
    buildings: list[Building] = []
    streets = _grid(spec, rng, buildings) + _radial(spec, rng, buildings)
    corners = np.concatenate([b.footprint for b in buildings])
    lo, hi = corners.min(axis=0) - 20.0, corners.max(axis=0) + 20.0
    return CityLayout(spec, tuple(buildings), tuple(streets), (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])))
