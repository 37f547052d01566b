"""The in-memory scene model shared by the scene loaders, the capture and the evaluator.

World frame: right-handed, meters, +Y up, ground at y = 0.  Streets run along X or Z, or at any
angle in their own frame (:class:`Street`, ``yaw_deg``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from envcap.capture.effects import check_effects, effect_names
from envcap.core.street_frame import frame_to_world, world_to_frame
from envcap.sky.registry import SkySpec

EFFECTS: tuple[str, ...] = effect_names()
"""Effects a scene may call for: the capture effects registered at import
(:mod:`envcap.capture.effects`, one module each: ``sun_light``, ``sky_light``, ``sun_shadows``,
``emissive_windows``); each runs only when listed.  Scenes are checked against the registry
itself (:func:`envcap.capture.effects.check_effects`), so effects registered later count too.
"""


ORIGIN_GRID_M = 1000.0
"""A mesh's origin is its bounding-box center rounded to a multiple of this (meters, per axis):
:func:`local_origin`."""


def local_origin(lo: NDArray[np.floating], hi: NDArray[np.floating]) -> NDArray[np.float64]:
    """The origin for geometry spanning the world box ``[lo, hi]`` (3,) meters: the box center
    rounded to whole multiples of :data:`ORIGIN_GRID_M` per axis, (3,) float64.

    Coordinates relative to it are at most half the box plus ``ORIGIN_GRID_M / 2``, so their
    float32 steps are those of the geometry's own size, wherever it lies (10^6 m away: ~6 cm in
    absolute float32, ~0.06 mm relative to this origin for a 1 km scene).  A scene centered
    within 500 m of the world origin gets (0, 0, 0): its float32 positions are the absolute ones.
    """
    c = 0.5 * (np.asarray(lo, np.float64) + np.asarray(hi, np.float64))
    return np.round(c / ORIGIN_GRID_M) * ORIGIN_GRID_M + 0.0  # + 0.0: no -0.0


@dataclass(frozen=True)
class SceneMesh:
    """Triangle geometry with per-vertex material attributes (all float32 unless noted).

    Shapes: ``positions``, ``normals``, ``albedo``, ``emission`` are ``(V, 3)``; ``indices`` is
    ``(T, 3)`` uint32.  ``positions`` are meters relative to ``origin`` ((3,) float64, world
    meters; default (0, 0, 0)): a vertex's world position is ``origin + positions`` in float64,
    so geometry far from the world origin (projected coordinates such as UTM) keeps float32
    steps of its own size (:func:`local_origin`, ``docs/capture.md``, "Precision").
    ``albedo`` is the diffuse reflectance in [0, 1] (linear RGB); ``emission`` is emitted
    radiance in the sky's units (linear RGB, cd/m^2-scaled, see :mod:`envcap.sky.base`).
    Normals are unit length and face the side that is lit (flat shading: vertices are not shared
    between faces of different normal).

    Textured surfaces (optional, both or neither): ``uv_layer`` (V, 3) float32 is a vertex's
    texture coordinates (u, v; OpenGL convention, v = 0 at the image's bottom row) and the layer
    of ``textures`` it reads, -1 for none; ``textures`` (K, S, S, 4) uint8 are sRGB RGBA images,
    row 0 = the bottom row (t = 0, ready for upload).  A textured vertex's diffuse reflectance is
    ``albedo`` times the texel (decoded to linear), repeating outside [0, 1].
    """

    positions: NDArray[np.float32]
    normals: NDArray[np.float32]
    albedo: NDArray[np.float32]
    emission: NDArray[np.float32]
    indices: NDArray[np.uint32]
    origin: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    uv_layer: NDArray[np.float32] | None = None
    textures: NDArray[np.uint8] | None = None

    def __post_init__(self) -> None:
        v = self.positions.shape[0]
        for name in ("positions", "normals", "albedo", "emission"):
            a = getattr(self, name)
            if a.ndim != 2 or a.shape != (v, 3):
                raise ValueError(f"SceneMesh.{name} must have shape ({v}, 3), got {a.shape}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"SceneMesh.{name} contains NaN or Inf")
        if self.indices.ndim != 2 or self.indices.shape[1] != 3:
            raise ValueError(f"SceneMesh.indices must have shape (T, 3), got {self.indices.shape}")
        if self.indices.size and int(self.indices.max()) >= v:
            raise ValueError("SceneMesh.indices refer to vertices that do not exist")
        origin = np.asarray(self.origin, dtype=np.float64)
        if origin.shape != (3,) or not np.all(np.isfinite(origin)):
            raise ValueError(f"SceneMesh.origin must be 3 finite numbers, got {self.origin!r}")
        object.__setattr__(self, "origin", origin)
        if (self.uv_layer is None) != (self.textures is None):
            raise ValueError("SceneMesh.uv_layer and SceneMesh.textures go together (both or neither)")
        if self.textures is not None and self.uv_layer is not None:
            t, uvl = self.textures, self.uv_layer
            if t.dtype != np.uint8 or t.ndim != 4 or t.shape[1] != t.shape[2] or t.shape[3] != 4 or not t.shape[0]:
                raise ValueError(f"SceneMesh.textures must be (K, S, S, 4) uint8 with K >= 1, got {t.dtype} {t.shape}")
            if uvl.shape != (v, 3) or not np.all(np.isfinite(uvl)):
                raise ValueError(f"SceneMesh.uv_layer must be finite with shape ({v}, 3), got {uvl.shape}")
            if uvl.size and (uvl[:, 2].min() < -1 or uvl[:, 2].max() >= t.shape[0] or np.any(uvl[:, 2] != np.round(uvl[:, 2]))):
                raise ValueError(f"SceneMesh.uv_layer layers must be whole numbers in [-1, {t.shape[0] - 1}]")

    @property
    def textured(self) -> bool:
        """True when the mesh carries textures (``uv_layer`` and ``textures``)."""
        return self.textures is not None

    @classmethod
    def from_world(cls, positions: NDArray[np.floating], normals: NDArray[np.floating],
                   albedo: NDArray[np.floating], emission: NDArray[np.floating],
                   indices: NDArray[np.integer]) -> "SceneMesh":
        """A mesh from float64 world ``positions`` (V, 3): relative to their
        :func:`local_origin`, subtracted in float64 and rounded to float32 once."""
        pos = np.asarray(positions, dtype=np.float64)
        origin = local_origin(pos.min(axis=0), pos.max(axis=0)) if pos.shape[0] else np.zeros(3)
        return cls((pos - origin).astype(np.float32), np.asarray(normals, np.float32),
                   np.asarray(albedo, np.float32), np.asarray(emission, np.float32),
                   np.asarray(indices, np.uint32), origin)

    @property
    def triangle_count(self) -> int:
        return int(self.indices.shape[0])

    def world_bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(lo, hi)`` (3,) float64 world meters of the vertices; the origin twice if none."""
        if not self.positions.shape[0]:
            return self.origin.copy(), self.origin.copy()
        return (self.origin + self.positions.min(axis=0).astype(np.float64),
                self.origin + self.positions.max(axis=0).astype(np.float64))

    def rebased(self, origin: NDArray[np.floating]) -> "SceneMesh":
        """The same mesh with positions relative to ``origin`` (3,) world meters: shifted in
        float64, rounded to float32 once (exact when ``origin`` is the mesh's own)."""
        o = np.asarray(origin, dtype=np.float64)
        if np.array_equal(o, self.origin):
            return self
        pos = (self.positions.astype(np.float64) + (self.origin - o)).astype(np.float32)
        return SceneMesh(pos, self.normals, self.albedo, self.emission, self.indices, o, self.uv_layer, self.textures)

    @staticmethod
    def concatenate(parts: list["SceneMesh"]) -> "SceneMesh":
        """Join meshes into one (indices are offset).  Parts that share an origin keep it (and
        their float32 positions); otherwise every part is rebased to the :func:`local_origin` of
        their joint world bounds."""
        if not parts:
            z = np.zeros((0, 3), np.float32)
            return SceneMesh(z, z, z, z, np.zeros((0, 3), np.uint32))
        origin = parts[0].origin
        if any(not np.array_equal(p.origin, origin) for p in parts[1:]):
            bounds = [p.world_bounds() for p in parts if p.positions.shape[0]]
            origin = local_origin(np.min([b[0] for b in bounds], axis=0), np.max([b[1] for b in bounds], axis=0)) \
                if bounds else np.zeros(3)
            parts = [p.rebased(origin) for p in parts]
        offs = np.cumsum([0] + [p.positions.shape[0] for p in parts[:-1]])
        uv_layer, textures = _joined_textures(parts)
        return SceneMesh(
            np.concatenate([p.positions for p in parts]).astype(np.float32),
            np.concatenate([p.normals for p in parts]).astype(np.float32),
            np.concatenate([p.albedo for p in parts]).astype(np.float32),
            np.concatenate([p.emission for p in parts]).astype(np.float32),
            np.concatenate([p.indices + np.uint32(o) for p, o in zip(parts, offs)]).astype(np.uint32),
            origin,
            uv_layer,
            textures,
        )


def _joined_textures(parts: list[SceneMesh]) -> tuple[NDArray[np.float32] | None, NDArray[np.uint8] | None]:
    """``uv_layer`` and ``textures`` of concatenated ``parts``: layers renumbered, untextured
    parts at layer -1; every part's textures must share one size."""
    stacks = [p.textures for p in parts if p.textures is not None]
    if not stacks:
        return None, None
    sizes = {t.shape[1] for t in stacks}
    if len(sizes) != 1:
        raise ValueError(f"SceneMesh.concatenate: textures of different sizes {sorted(sizes)}")
    uvls, base = [], 0
    for p in parts:
        if p.uv_layer is None or p.textures is None:
            uvl = np.zeros((p.positions.shape[0], 3), np.float32)
            uvl[:, 2] = -1.0
        else:
            uvl = p.uv_layer.copy()
            uvl[:, 2] = np.where(uvl[:, 2] >= 0, uvl[:, 2] + base, -1.0)
            base += p.textures.shape[0]
        uvls.append(uvl)
    return np.concatenate(uvls).astype(np.float32), np.concatenate(stacks)


@dataclass(frozen=True)
class Street:
    """A street: the three planes of the parallax model and the probe line.

    ``axis`` is the axis the street runs along ("x" or "z"); the other horizontal axis is
    the *cross axis*.  ``start`` < ``end`` are along-axis coordinates (m) of the street's ends.
    ``facade_min`` < ``facade_max`` are cross-axis coordinates (m) of the two facade planes
    (nominal building front lines).  ``ground`` is the height of the ground plane (m, normally 0).
    The probe line runs along the center ``(facade_min + facade_max) / 2`` unless ``center`` is
    given.

    Streets at any angle (issue 10): a *framed* street (``yaw_deg != 0`` or ``origin_xz != (0, 0)``)
    has its own frame (:mod:`envcap.core.street_frame`): world -> frame is ``R(yaw) (p - (ox, 0,
    oz))``.  It must have ``axis`` "x"; ``start``/``end``/``center`` and the facades are then
    FRAME coordinates (along = frame x, cross = frame z); ``ground`` is a height (the same in both).
    Defaults (yaw 0, origin (0, 0)) are the world frame: every street written before keeps its meaning.
    """

    name: str
    axis: Literal["x", "z"]
    start: float
    end: float
    facade_min: float
    facade_max: float
    ground: float = 0.0
    center: float | None = None
    follow_terrain: bool = False
    """Probes stand ``height`` above the ground under each of them (:mod:`envcap.scene.ground_height`)
    rather than above ``ground``; each probe's nominal ground plane is at that height."""
    yaw_deg: float = 0.0
    """Plan angle of the street's direction, degrees from world +X toward +Z (``atan2(dz, dx)``)."""
    origin_xz: tuple[float, float] = (0.0, 0.0)
    """World plan point (x, z), m, that is the frame's origin (``p0`` of a TOML ``p0``/``p1`` street)."""

    def __post_init__(self) -> None:
        if self.axis not in ("x", "z"):
            raise ValueError(f"street '{self.name}': axis must be 'x' or 'z', got {self.axis!r}")
        try:
            yaw, ox, oz = float(self.yaw_deg), *(float(v) for v in self.origin_xz)
        except (TypeError, ValueError):
            raise ValueError(f"street '{self.name}': yaw_deg must be a number and origin_xz two numbers, "
                             f"got {self.yaw_deg!r}, {self.origin_xz!r}") from None
        if not all(math.isfinite(v) for v in (yaw, ox, oz)):
            raise ValueError(f"street '{self.name}': yaw_deg and origin_xz must be finite, got {yaw}, ({ox}, {oz})")
        object.__setattr__(self, "yaw_deg", yaw)
        object.__setattr__(self, "origin_xz", (ox, oz))
        if self.framed and self.axis != "x":
            raise ValueError(f"street '{self.name}': a street with its own frame (yaw {yaw} deg, origin ({ox}, {oz})) "
                             f"must have axis 'x' (it runs along its frame's x), got {self.axis!r}")
        vals = (self.start, self.end, self.facade_min, self.facade_max, self.ground)
        if not all(np.isfinite(vals)):
            raise ValueError(f"street '{self.name}': coordinates must be finite")
        if not self.end > self.start:
            raise ValueError(f"street '{self.name}': length must be positive (start {self.start}, end {self.end})")
        if not self.facade_max > self.facade_min:
            raise ValueError(f"street '{self.name}': width must be positive (facades {self.facade_min}, {self.facade_max})")

    @property
    def width(self) -> float:
        return self.facade_max - self.facade_min

    @property
    def length(self) -> float:
        return self.end - self.start

    @property
    def center_line(self) -> float:
        return 0.5 * (self.facade_min + self.facade_max) if self.center is None else self.center

    @property
    def along_index(self) -> int:
        """World axis index (0 = x, 2 = z) the street runs along."""
        return 0 if self.axis == "x" else 2

    @property
    def cross_index(self) -> int:
        """World axis index of the cross axis (the facade planes are normal to it)."""
        return 2 if self.axis == "x" else 0

    @property
    def framed(self) -> bool:
        """True when the street has its own frame (``yaw_deg != 0`` or ``origin_xz != (0, 0)``);
        its coordinates are then frame coordinates, its axis "x"."""
        return self.yaw_deg != 0.0 or self.origin_xz != (0.0, 0.0)

    def to_frame(self, points: NDArray[np.floating] | Any) -> NDArray[np.float64]:
        """World points (..., 3) (m) in this street's frame (float64; a copy of them when not framed)."""
        return world_to_frame(points, self.yaw_deg, self.origin_xz)

    def to_world(self, points: NDArray[np.floating] | Any) -> NDArray[np.float64]:
        """Points (..., 3) (m) of this street's frame in the world (float64)."""
        return frame_to_world(points, self.yaw_deg, self.origin_xz)

    def plan_corners(self, pad: float = 0.0) -> NDArray[np.float64]:
        """(4, 2) world plan points (x, z), m, of the street's rectangle (``start``..``end`` by
        ``facade_min``..``facade_max``) grown by ``pad`` m on every side, in order around it."""
        a, c = (self.start - pad, self.end + pad), (self.facade_min - pad, self.facade_max + pad)
        loc = np.zeros((4, 3))
        loc[:, self.along_index] = (a[0], a[1], a[1], a[0])
        loc[:, self.cross_index] = (c[0], c[0], c[1], c[1])
        return self.to_world(loc)[:, [0, 2]]

    def plan_box(self, pad: float = 0.0) -> tuple[float, float, float, float]:
        """World axis-aligned box ``(x0, x1, z0, z1)`` (m) of the street's rectangle grown by
        ``pad`` m on every side (of the rectangle, before it is turned by ``yaw_deg``)."""
        xz = self.plan_corners(pad)
        return (float(xz[:, 0].min()), float(xz[:, 0].max()), float(xz[:, 1].min()), float(xz[:, 1].max()))


SHADOW_FITS = ("mesh", "streets")
"""``[shadows] fit``: the sun's shadow map covers the whole mesh, or the streets' neighbourhood."""

SHADOW_STREET_PAD_M = 60.0
"""Meters around each street's box (along and across) that a ``fit = "streets"`` map also covers."""


@dataclass(frozen=True)
class ShadowSettings:
    """A scene's ``[shadows]`` table (for the ``sun_shadows`` effect): ``fit`` one of
    :data:`SHADOW_FITS`; ``texel_m`` the texel size (m) to reach, or ``None`` for the effect's
    default resolution.  The defaults reproduce a scene without the table."""

    texel_m: float | None = None
    fit: str = "mesh"

    def __post_init__(self) -> None:
        if self.fit not in SHADOW_FITS:
            raise ValueError(f"shadows.fit must be one of {list(SHADOW_FITS)}, got {self.fit!r}")
        if self.texel_m is not None and not (math.isfinite(self.texel_m) and self.texel_m > 0):
            raise ValueError(f"shadows.texel_m must be a positive number of meters, got {self.texel_m!r}")

    @property
    def default(self) -> bool:
        """True when the settings change nothing (the effect's own fit and resolution)."""
        return self.texel_m is None and self.fit == "mesh"


@dataclass
class Scene:
    """A city scene: geometry, streets, sky description and the effects it calls for.

    ``sky`` is the scene's ``[sky]`` table, parsed once at load (:class:`envcap.sky.SkySpec`);
    ``sky.build()`` makes the :class:`envcap.sky.Sky` (relative file names in it were resolved
    against the scene file's directory at load).  ``meta`` holds the build counts (buildings,
    windows, lit windows) and the ``source`` file; ``shadows`` the ``[shadows]`` table.
    """

    name: str
    mesh: SceneMesh
    streets: list[Street]
    sky: SkySpec
    effects: frozenset[str]
    description: str = ""
    meta: dict[str, Any] = field(default_factory=dict)
    shadows: ShadowSettings = field(default_factory=ShadowSettings)

    def __post_init__(self) -> None:
        try:
            check_effects(self.effects)
        except ValueError as exc:
            raise ValueError(f"scene '{self.name}': {exc}") from None
