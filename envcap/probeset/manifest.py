"""The probe-set manifest (``manifest.json``): typed dataclasses, one reader, one writer.

Format ``"envcap-probeset"``, version 1 (JSON Schema ``docs/manifest.schema.json``, fields in
``docs/formats.md``).  Dataclass field order = JSON key order, so :func:`write_manifest` of what
:func:`read_manifest` returned gives the same bytes.  :meth:`Manifest.from_json` /
:func:`read_manifest` check strictly (types, unknown or missing keys, :func:`check_manifest`),
every error one ``ValueError`` line naming the field path (``manifest.json:
streets[0].probes[1].position: ...``); :meth:`Manifest.to_json` / :func:`write_manifest` write
plain JSON, checked by the same reader.  Units: meters, +Y up, right-handed; radiance cd/m^2
(linear Rec.709); seconds.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from envcap import __version__
from envcap.core.street_frame import OptionalFrame, world_to_frame
from envcap.probeset.crossing_table import Crossing, check_crossing_table
from envcap.probeset.float32_range import check_number_ranges, positive_in_float32
from envcap.probeset.json_codec import ManifestError, from_json, json_text, read_json_file, to_json
from envcap.probeset.ladder_table import LadderTable, check_ladder_table
from envcap.probeset.manifest_files import Files, check_files
from envcap.probeset.placement_table import PlacementTable, check_placement_table
from envcap.probeset.planes import FittedPlanes, PerPlane, Planes

FORMAT = "envcap-probeset"
VERSION = 1
CUBE_CONVENTION = (
    "OpenGL cube map: faces +X,-X,+Y,-Y,+Z,-Z; arrays [layer, face, row=t, column=s, RGBA]; "
    "texel centers at s=(i+0.5)/N; see envcap/core/cube.py"
)
SKY_FORMAT = "RGBA32F"
AXES = ("x", "z")

__all__ = [
    "FORMAT", "VERSION", "CUBE_CONVENTION", "ManifestError", "ColorInfo", "Level", "LobeTable",
    "Planes", "PerPlane", "FittedPlanes", "PlacementTable", "Crossing", "Probe", "Street", "SunInfo", "SkyInfo", "Files", "Timings", "SceneInfo",
    "Manifest", "level_table", "check_manifest", "read_manifest", "write_manifest", "manifest_text", "dataclass_types",
]

_OMIT = {"json": "omit_none"}


@dataclass(frozen=True)
class ColorInfo:
    """Fixed: what the texels hold (linear Rec.709 radiance in cd/m^2, premultiplied alpha)."""

    space: str = "linear Rec.709"
    scale: str = "cd/m^2"
    alpha: str = "premultiplied"


@dataclass(frozen=True)
class Level:
    """Mip level ``level`` of the probe array: faces of ``size = max(1, N >> level)`` texels,
    filtered with the cosine lobe ``cos^lobe_power`` (``None``: not filtered, level 0 of an
    unfiltered set)."""

    level: int
    size: int
    lobe_power: float | None


@dataclass(frozen=True)
class LobeTable:
    """The lobe ladder (:meth:`envcap.core.lobes.LobeLadder.to_manifest`): face sizes and
    strictly decreasing powers per level, and the name of the ``z(w)`` rule a shader follows."""

    sizes: tuple[int, ...]
    powers: tuple[float, ...]
    z_of_w: str

    @staticmethod
    def from_json(obj: Any) -> "LobeTable":
        """From :meth:`envcap.core.lobes.LobeLadder.to_manifest`'s dict (type-checked)."""
        return from_json(LobeTable, obj, "lobes")


@dataclass(frozen=True)
class Probe:
    """One probe: its layer in the probe array (global over streets), its index along its
    street, center ``position`` (x, y, z) in m, nominal ``planes``, ``fitted_planes`` (``None``
    when not fitted) and whether it stands inside geometry (kept, with a warning)."""

    layer: int
    index: int
    position: tuple[float, float, float]
    planes: Planes
    fitted_planes: FittedPlanes | None
    inside_geometry: bool


@dataclass(frozen=True)
class Street(OptionalFrame):
    """One street: ``axis`` "x" or "z" (the world axis it runs along), its extent ``start`` <
    ``end`` along that axis and its center line ``center`` on the cross axis (m), its nominal
    planes and its probes (in layer order).

    A street at any angle has its own frame (:mod:`envcap.core.street_frame`): ``yaw_deg`` (plan
    angle of its direction from +X toward +Z) and ``origin_xz`` (world plan point of its origin),
    omitted when ``None`` (world frame).  It has axis "x"; ``start``/``end``/``center`` and ALL
    planes are frame coordinates, each probe's ``position`` world coordinates."""

    name: str
    axis: str
    start: float
    end: float
    center: float
    planes: Planes
    probes: tuple[Probe, ...]
    yaw_deg: float | None = field(default=None, metadata=_OMIT)
    origin_xz: tuple[float, float] | None = field(default=None, metadata=_OMIT)

    @property
    def along_index(self) -> int:
        """World axis index along the street: 0 (x) or 2 (z)."""
        return 0 if self.axis == "x" else 2

    @property
    def cross_index(self) -> int:
        """World axis index across the street: 2 (z) or 0 (x)."""
        return 2 - self.along_index

    def frame_positions(self, probes: tuple[Probe, ...] | list[Probe] | None = None) -> Any:
        """``(P, 3)`` float64 positions (m) of ``probes`` (default: all, in layer order) in the
        street's frame (:func:`envcap.core.street_frame.world_to_frame`; the world's when it has none)."""
        probes = self.probes if probes is None else probes
        return world_to_frame([p.position for p in probes] or [(0.0, 0.0, 0.0)], self.frame_yaw_deg,
                              self.frame_origin_xz)[:len(probes)]

    def probes_along(self) -> list[Probe]:
        """The probes sorted by their coordinate along the street (frame x for a framed street;
        the runtime's order)."""
        pos = self.frame_positions()
        return [self.probes[i] for i in sorted(range(len(self.probes)), key=lambda i: pos[i, self.along_index])]


@dataclass(frozen=True)
class SunInfo:
    """The sun as an analytic light (:meth:`envcap.sky.Sun.spec`): unit ``direction``
    towards the sun, disk ``radiance`` (cd/m^2, RGB), ``angular_radius`` (rad), ``illuminance``
    at normal incidence (lux, RGB), elevation and azimuth in degrees."""

    direction: tuple[float, float, float]
    radiance: tuple[float, float, float]
    angular_radius: float
    illuminance: tuple[float, float, float]
    elevation_deg: float
    azimuth_deg: float

    @staticmethod
    def from_json(obj: Any) -> "SunInfo":
        """From :meth:`envcap.sky.sun.Sun.spec`'s dict (type-checked)."""
        return from_json(SunInfo, obj, "sky.sun")


@dataclass(frozen=True)
class SkyInfo:
    """The sky: its model ``spec`` (free-form, see ``docs/sky.md``), the sky map's texel format,
    the sun (``None`` for a sky without one) and whether the sun's disk is in the sky map
    (``sun_in_map``; ``None`` in sets baked before the key existed, which held the sun)."""

    spec: dict[str, Any]
    format: str = SKY_FORMAT
    sun: SunInfo | None = None
    sun_in_map: bool | None = field(default=None, metadata=_OMIT)

    @property
    def sun_baked_in_map(self) -> bool:
        """Whether the sky map holds the sun (``sun_in_map``, true when not recorded)."""
        return True if self.sun_in_map is None else self.sun_in_map


@dataclass(frozen=True)
class Timings:
    """Bake times in seconds: sky, capture (all passes), per capture pass (``passes_s``, JSON
    keys ``pass_<name>_s``), prefilter and the whole command; ``None`` when not measured."""

    sky_s: float | None = field(default=None, metadata=_OMIT)
    capture_s: float | None = field(default=None, metadata=_OMIT)
    passes_s: dict[str, float] = field(
        default_factory=dict, metadata={"json": "rest", "pattern": "pass_(.+)_s", "key_format": "pass_{}_s"})
    prefilter_s: float | None = field(default=None, metadata=_OMIT)
    total_s: float | None = field(default=None, metadata=_OMIT)

    @staticmethod
    def from_json(obj: Any) -> "Timings":
        """From ``{"sky_s": ..., "pass_<name>_s": ..., ...}`` (type-checked)."""
        return from_json(Timings, obj, "timings")


@dataclass(frozen=True)
class SceneInfo:
    """The baked scene: name, description and triangle count."""

    name: str
    description: str
    triangles: int


@dataclass(frozen=True, kw_only=True)
class Manifest:
    """A probe-set manifest, version 1.  Fixed fields first (checked equal to their defaults,
    except ``cube_convention`` and ``envcap_version``, any string); ``resolution`` N is the
    face size of level 0 (texels); ``levels`` the mip levels in order; ``lobes`` the lobe
    ladder (``None`` -> JSON ``{}``: unfiltered); ``prefilter_quality`` the filter that made
    levels 1.. (``envcap.prefilter.QUALITIES``; ``None``: not recorded, omitted from the JSON);
    ``shadow_texel_m`` the sun shadow map's texel size in m (``None``: no sun shadows, omitted);
    ``shadow_cascade_texels_m`` the texel (m) of each shadow cascade, finest first, the last the
    whole fitted map (``None``: one map, omitted);
    ``probe_height``, ``probe_spacing`` in m (the mean spacing when ``placement`` is present);
    ``placement`` how the probes were placed (:mod:`envcap.probeset.placement_table`; ``None``:
    uniformly at ``probe_spacing``, omitted);
    ``crossings`` where streets meet and the probe at each centre (:mod:`envcap.probeset.crossing_table`;
    ``None``: no crossings recorded, omitted);
    ``effects`` the scene's capture effects and ``passes_run`` the capture passes run;
    ``scene`` (``None`` -> JSON ``{}``: unknown)."""

    format: str = FORMAT
    version: int = VERSION
    units: str = "meters"
    up_axis: str = "+Y"
    handedness: str = "right"
    cube_convention: str = CUBE_CONVENTION
    color: ColorInfo = ColorInfo()
    envcap_version: str = __version__
    resolution: int
    levels: tuple[Level, ...]
    lobes: LobeTable | None = field(default=None, metadata={"json": "empty_object_none"})
    ladder: LadderTable | None = field(default=None, metadata=_OMIT)  # rung ladder (ladder_table.py)
    prefilter_quality: str | None = field(default=None, metadata=_OMIT)
    shadow_texel_m: float | None = field(default=None, metadata=_OMIT)
    shadow_cascade_texels_m: tuple[float, ...] | None = field(default=None, metadata=_OMIT)
    probe_height: float
    probe_spacing: float
    placement: PlacementTable | None = field(default=None, metadata=_OMIT)
    streets: tuple[Street, ...]
    crossings: tuple[Crossing, ...] | None = field(default=None, metadata=_OMIT)  # crossing_table.py
    effects: tuple[str, ...] = ()
    passes_run: tuple[str, ...] = ()
    sky: SkyInfo
    files: Files = Files()
    timings: Timings = Timings()
    scene: SceneInfo | None = field(default=None, metadata={"json": "empty_object_none"})

    @property
    def layer_count(self) -> int:
        """Number of probes (layers of the probe array) over all streets."""
        return sum(len(st.probes) for st in self.streets)

    @property
    def lobe_powers(self) -> tuple[float, ...] | None:
        """The lobe power of each level (``lobes.powers``, else the levels' ``lobe_power``);
        ``None`` when a level is unfiltered."""
        if self.lobes is not None and self.lobes.powers:
            return self.lobes.powers
        pw = [lv.lobe_power for lv in self.levels]
        return None if any(p is None for p in pw) else tuple(float(p) for p in pw)  # type: ignore[arg-type]

    def with_timings(self, **seconds: float) -> "Manifest":
        """A copy with the given :class:`Timings` fields set (e.g. ``total_s=3.9``)."""
        return replace(self, timings=replace(self.timings, **seconds))

    @staticmethod
    def from_json(obj: Any, where: str = "manifest") -> "Manifest":
        """The manifest of parsed JSON ``obj``, checked (``ValueError`` naming the field)."""
        if isinstance(obj, dict):
            if obj.get("format") != FORMAT:
                raise ManifestError(f"{where}: format is {obj.get('format')!r}, expected {FORMAT!r}")
            if obj.get("version") != VERSION:
                raise ManifestError(f"{where}: version {obj.get('version')!r} not supported "
                                    f"(this envcap reads version {VERSION})")
        try:
            m = from_json(Manifest, obj)
        except ManifestError as e:
            raise ManifestError(f"{where}: {e}") from None
        check_manifest(m, where)
        return m

    def to_json(self) -> dict[str, Any]:
        """Plain-JSON dict (key order as written), checked by :meth:`from_json` before it is returned."""
        obj = to_json(self)
        try:
            json.dumps(obj, allow_nan=False)
        except ValueError as e:
            raise ManifestError(f"manifest is not strict JSON (no NaN/Inf): {e}") from e
        Manifest.from_json(obj)
        return obj


def level_table(resolution: int, count: int, powers: list[float | None] | None = None) -> tuple[Level, ...]:
    """``count`` levels of a chain of face size ``resolution``, with ``powers[k]`` (or ``None``)."""
    pw = powers if powers is not None else [None] * count
    if len(pw) != count:
        raise ValueError(f"level_table: {count} levels but {len(pw)} powers")
    return tuple(Level(k, max(1, int(resolution) >> k), None if w is None else float(w)) for k, w in enumerate(pw))


_FIXED = ("format", "version", "units", "up_axis", "handedness", "color")
"""Manifest fields whose value is fixed (their defaults)."""


def _check_planes(p: Planes, where: str) -> None:
    if not p.facade_max > p.facade_min:
        raise ManifestError(f"{where}: facade_max {p.facade_max} must exceed facade_min {p.facade_min}")


def _positive(x: float, where: str, unit: str) -> None:
    if not positive_in_float32(x):
        raise ManifestError(f"{where}: must be positive ({unit}) and stay so as float32, got {x!r}")


def check_manifest(m: Manifest, where: str = "manifest") -> int:
    """Check the rules beyond types (the list: ``docs/formats.md``, "Manifest, version 1";
    numbers in float32/int32 range by :func:`envcap.probeset.float32_range.check_number_ranges`);
    return the number of probe layers."""
    for f in fields(Manifest):
        if f.name in _FIXED and getattr(m, f.name) != f.default:
            raise ManifestError(f"{where}: {f.name} is {getattr(m, f.name)!r}, expected {f.default!r}")
    check_number_ranges(m, where)
    n = m.resolution
    _positive(n, f"{where}: resolution", "texels")
    most = int(math.log2(n)) + 1
    if not 1 <= len(m.levels) <= most:
        raise ManifestError(f"{where}: levels must be a list of 1..{most} entries, got {len(m.levels)}")
    for k, lev in enumerate(m.levels):
        if lev.level != k or lev.size != max(1, n >> k):
            raise ManifestError(f"{where}: levels[{k}] must be {{'level': {k}, 'size': {max(1, n >> k)}, ...}}, got {lev}")
        if lev.lobe_power is not None:
            _positive(lev.lobe_power, f"{where}: levels[{k}].lobe_power", "a power, or null")
    if m.lobes is not None and not len(m.lobes.sizes) == len(m.lobes.powers) == len(m.levels):
        raise ManifestError(f"{where}: lobes must list a size and a power per level ({len(m.levels)})")
    if m.ladder is not None:
        check_ladder_table(m.ladder, tuple(lv.size for lv in m.levels), where)
    check_files(m.files, f"{where}: files")
    _positive(m.probe_height, f"{where}: probe_height", "meters")
    _positive(m.probe_spacing, f"{where}: probe_spacing", "meters")
    if m.sky.format != SKY_FORMAT:
        raise ManifestError(f"{where}: sky.format is {m.sky.format!r}, expected {SKY_FORMAT!r}")
    layers: list[int] = []
    names: set[str] = set()
    for i, st in enumerate(m.streets):
        sw = f"{where}: streets[{i}]"
        if st.name in names:
            raise ManifestError(f"{sw}.name: {st.name!r} is not unique")
        names.add(st.name)
        if st.axis not in AXES:
            raise ManifestError(f"{sw}.axis: must be 'x' or 'z', got {st.axis!r}")
        if not st.end > st.start:
            raise ManifestError(f"{sw}: start {st.start} must be below end {st.end}")
        if st.framed and st.axis != "x":
            raise ManifestError(f"{sw}.axis: a street with yaw_deg/origin_xz runs along its frame's x, got {st.axis!r}")
        _check_planes(st.planes, f"{sw}.planes")
        for j, pr in enumerate(st.probes):
            pw = f"{sw}.probes[{j}]"
            if pr.layer < 0 or pr.index < 0:
                raise ManifestError(f"{pw}: layer and index must be >= 0, got {pr.layer}, {pr.index}")
            _check_planes(pr.planes, f"{pw}.planes")
            layers.append(pr.layer)
    if m.placement is not None:
        check_placement_table(m.placement, [st.name for st in m.streets], where)
    if m.crossings is not None:
        check_crossing_table(m.crossings, {st.name: [pr.layer for pr in st.probes] for st in m.streets}, where)
    if sorted(layers) != list(range(len(layers))):
        raise ManifestError(f"{where}: probe layers must be 0..{len(layers) - 1}, each once; got {sorted(layers)}")
    return len(layers)


def read_manifest(path: str | os.PathLike[str]) -> Manifest:
    """Read and check a ``manifest.json`` (``FileNotFoundError``; ``ValueError`` naming the
    file and the field)."""
    return Manifest.from_json(read_json_file(path, "manifest"), str(Path(path)))


def manifest_text(m: Manifest) -> str:
    """The file content of ``m``: 2-space indented JSON and a final newline."""
    return json_text(m.to_json())


def write_manifest(path: str | os.PathLike[str], m: Manifest) -> Path:
    """Write ``m`` as ``path`` (not atomically: the probe-set writer writes it inside its
    atomic directory); return the path."""
    (p := Path(path)).write_text(manifest_text(m))
    return p


def dataclass_types() -> dict[str, type]:
    """The manifest's dataclasses by name (the ``$defs`` names of ``docs/manifest.schema.json``)."""
    return {c.__name__: c for c in (Manifest, ColorInfo, Level, LobeTable, LadderTable, PlacementTable, Crossing, Street, Probe,
                                    Planes, PerPlane, FittedPlanes, SkyInfo, SunInfo, Files, Timings, SceneInfo)}
