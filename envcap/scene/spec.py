"""Typed scene specs: a scene TOML document, checked, before any geometry is built.

:func:`envcap.scene.parse.parse_scene` produces a :class:`SceneSpec`; :func:`envcap.scene.build.build_scene`
turns it into a :class:`~envcap.scene.model.Scene`.  The keys, defaults and placement rules are
documented in ``docs/scenes.md``.  Lengths in meters, angles in degrees, colors linear RGB
(albedo in [0, 1], emission in the sky's cd/m^2-scaled units); along / cross are the street's axes.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from envcap.scene.model import ShadowSettings, Street
from envcap.sky.registry import SkySpec

RGB = tuple[float, float, float]


@dataclass(frozen=True)
class WindowsSpec:
    """A facade's window grid (``[streets.facade.windows]``): one window per ``spacing`` along the
    building and per ``floor_height`` from ``first_floor`` up, glass ``offset`` in front of the wall,
    an optional ``frame`` strip around it, ``emissive_fraction`` of the windows emitting ``emission``."""

    width: float
    height: float
    spacing: float
    floor_height: float
    sill: float
    first_floor: int
    top_margin: float
    albedo: RGB
    frame: float
    frame_albedo: RGB
    offset: float
    emissive_fraction: float
    emission: RGB


@dataclass(frozen=True)
class FacadeSpec:
    """Building color (``albedo``, jittered by a factor in ``1 +- albedo_jitter`` per building) and windows."""

    albedo: RGB
    albedo_jitter: float
    windows: WindowsSpec | None


@dataclass(frozen=True)
class BuildingSpec:
    """One building of an explicit ``[[...buildings]]`` list, placed ``gap`` after the previous one."""

    gap: float
    width: float
    height: float
    depth: float
    setback: float
    albedo: RGB
    windows: bool


@dataclass(frozen=True)
class RandomBuildingsSpec:
    """A ``random`` row of buildings: sizes drawn uniformly from the ``[min, max]`` ranges, a gap of
    ``gap_width`` before a building with probability ``gap_probability``; ``count`` buildings, or
    (``None``) until the street's end."""

    count: int | None
    width: tuple[float, float]
    height: tuple[float, float]
    depth: tuple[float, float]
    setback: tuple[float, float]
    gap_probability: float
    gap_width: tuple[float, float]


@dataclass(frozen=True)
class WallSpec:
    """A continuous checkered wall on the facade plane: ``tile``-sized squares of ``albedo`` and
    ``albedo2``, ``height`` tall, closed by a box ``thickness`` deep behind it."""

    height: float
    tile: float
    albedo: RGB
    albedo2: RGB
    thickness: float


Layout = RandomBuildingsSpec | tuple[BuildingSpec, ...] | WallSpec | None
"""What stands on one side of a street: a random row, an explicit list, a wall, or nothing."""


@dataclass(frozen=True)
class SideSpec:
    """One side of a street (``side_min`` / ``side_max``): RNG ``seed``, ``start_offset`` from the
    street's start, the side's facade (the street's, merged with the side's own) and its layout."""

    seed: int
    start_offset: float
    facade: FacadeSpec
    layout: Layout


SIDE_KEYS: tuple[str, str] = ("side_min", "side_max")
"""The keys of a street's two sides, in build order (index 0 faces +cross, index 1 faces -cross)."""


def side_key(street_index: int, side_index: int) -> str:
    """The dotted location of a side in the scene file, as errors name it: ``streets[0].side_min``."""
    return f"streets[{street_index}].{SIDE_KEYS[side_index]}"


@dataclass(frozen=True)
class StreetSpec:
    """A street (its planes and probe line) and what stands on its two sides."""

    street: Street
    side_min: SideSpec | None
    side_max: SideSpec | None


@dataclass(frozen=True)
class GroundSpec:
    """The ground quad at y = 0: ``extent`` square around ``center`` (x, z; ``None`` = the middle of
    the streets and the mesh), optionally a checker of ``checker``-sized tiles over ``checker_extent``."""

    albedo: RGB
    extent: float
    center: tuple[float, float] | None
    checker: float
    albedo2: RGB
    checker_extent: float


@dataclass(frozen=True)
class MeshSpec:
    """An imported mesh (``[mesh]``): which files (``path`` = the ``file`` key and ``files``,
    resolved against the scene's directory ``base_dir``; ``globs``, ``include``, ``exclude``
    patterns, see :mod:`envcap.scene.mesh_select`), the import transform, ``winding``
    (``"auto"``, ``"keep"``, ``"flip"``) and ``crop`` (``(min, max)`` world corners, m) of
    :func:`envcap.scene.mesh_import.import_meshes`.  Files are looked up when the scene is built."""

    path: Path | None
    up_axis: str
    rotation_deg: float
    offset: tuple[float, float, float]
    scale: float
    albedo: RGB
    files: tuple[Path, ...] = ()
    globs: tuple[str, ...] = ()
    include: tuple[str, ...] = ()
    exclude: tuple[str, ...] = ()
    base_dir: Path | None = None
    winding: str = "auto"
    crop: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    crop_by: str = "part"
    """``"part"``: a crop keeps the parts (buildings) that meet it whole; ``"triangle"``: it keeps
    the triangles that meet it (terrain)."""
    emission_scale: float = 100.0
    """Radiance (sky units) per unit of a file's emissive factor (glTF ``emissiveFactor``, MTL ``Ke``)."""
    scene: str | None = None
    """``scene = "NAME"`` (a bundled scene) or a ``.toml`` path (relative to ``base_dir``): instead of
    files, the whole geometry that scene builds (its buildings, walls and meshes; not its ground, sky
    or probes).  The other fields are then unused."""


@dataclass(frozen=True)
class SceneSpec:
    """A whole scene document, checked: everything :func:`~envcap.scene.build.build_scene` needs.

    ``meshes``: the ``[mesh]`` table or the ``[[mesh]]`` tables, in order; ``ground`` is ``None``
    when the document disables it; ``source`` names the file (or is empty)."""

    name: str
    description: str
    effects: frozenset[str]
    sky: SkySpec
    streets: tuple[StreetSpec, ...]
    meshes: tuple[MeshSpec, ...]
    ground: GroundSpec | None
    source: str
    shadows: ShadowSettings = ShadowSettings()
