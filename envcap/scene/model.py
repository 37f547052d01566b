"""The in-memory scene model shared by the scene loaders, the capture and the evaluator.

World frame: right-handed, meters, +Y up, ground at y = 0.  Streets run along X or Z.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

EFFECTS: tuple[str, ...] = ("sun_light", "sun_shadows", "sky_light", "emissive_windows")
"""Effects a scene may call for; each is one capture pass that runs only when listed.

* ``sun_light``: direct light from the sun on surfaces (Lambert), no occlusion.
* ``sun_shadows``: occlusion of the sun with a shadow map (needs ``sun_light``).
* ``sky_light``: light from the sky dome on surfaces (diffuse irradiance of the sky).
* ``emissive_windows``: emission of lit windows (materials with non-zero emission).
"""


@dataclass(frozen=True)
class SceneMesh:
    """Triangle geometry with per-vertex material attributes (all float32 unless noted).

    Shapes: ``positions``, ``normals``, ``albedo``, ``emission`` are ``(V, 3)``; ``indices`` is
    ``(T, 3)`` uint32.  Positions in meters in the envcap world frame.  ``albedo`` is the diffuse
    reflectance in [0, 1] (linear RGB); ``emission`` is emitted radiance in the sky's units
    (linear RGB, cd/m^2-scaled, see :mod:`envcap.sky.sky`).  Normals are unit length and face the
    side that is lit (flat shading: vertices are not shared between faces of different normal).
    """

    positions: NDArray[np.float32]
    normals: NDArray[np.float32]
    albedo: NDArray[np.float32]
    emission: NDArray[np.float32]
    indices: NDArray[np.uint32]

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

    @property
    def triangle_count(self) -> int:
        return int(self.indices.shape[0])

    @staticmethod
    def concatenate(parts: list["SceneMesh"]) -> "SceneMesh":
        """Join meshes into one (indices are offset)."""
        if not parts:
            z = np.zeros((0, 3), np.float32)
            return SceneMesh(z, z, z, z, np.zeros((0, 3), np.uint32))
        offs = np.cumsum([0] + [p.positions.shape[0] for p in parts[:-1]])
        return SceneMesh(
            np.concatenate([p.positions for p in parts]).astype(np.float32),
            np.concatenate([p.normals for p in parts]).astype(np.float32),
            np.concatenate([p.albedo for p in parts]).astype(np.float32),
            np.concatenate([p.emission for p in parts]).astype(np.float32),
            np.concatenate([p.indices + np.uint32(o) for p, o in zip(parts, offs)]).astype(np.uint32),
        )


@dataclass(frozen=True)
class Street:
    """An axis-aligned street: the three planes of the parallax model and the probe line.

    ``axis`` is the world axis the street runs along ("x" or "z"); the other horizontal axis is
    the *cross axis*.  ``start`` < ``end`` are along-axis coordinates (m) of the street's ends.
    ``facade_min`` < ``facade_max`` are cross-axis coordinates (m) of the two facade planes
    (nominal building front lines).  ``ground`` is the height of the ground plane (m, normally 0).
    The probe line runs along the center ``(facade_min + facade_max) / 2`` unless ``center`` is
    given.
    """

    name: str
    axis: Literal["x", "z"]
    start: float
    end: float
    facade_min: float
    facade_max: float
    ground: float = 0.0
    center: float | None = None

    def __post_init__(self) -> None:
        if self.axis not in ("x", "z"):
            raise ValueError(f"street '{self.name}': axis must be 'x' or 'z', got {self.axis!r}")
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


@dataclass
class Scene:
    """A city scene: geometry, streets, sky description and the effects it calls for.

    ``sky`` is the scene's ``[sky]`` table as a plain dict, interpreted by
    :func:`envcap.sky.sky.sky_from_spec`; ``base_dir`` resolves relative file names in it.
    """

    name: str
    mesh: SceneMesh
    streets: list[Street]
    sky: dict[str, Any]
    effects: frozenset[str]
    description: str = ""
    base_dir: Path | None = None
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        unknown = sorted(set(self.effects) - set(EFFECTS))
        if unknown:
            raise ValueError(f"scene '{self.name}': unknown effect(s) {unknown}; known: {list(EFFECTS)}")
        if "sun_shadows" in self.effects and "sun_light" not in self.effects:
            raise ValueError(f"scene '{self.name}': effect 'sun_shadows' needs 'sun_light'")
