"""Scene TOML -> :class:`~envcap.scene.spec.SceneSpec`: every key read, checked and typed once.

Errors raise ``ValueError`` naming the key (``streets[1].side_min.random: unknown key(s) ...``);
unknown keys are errors.  Every number is checked against its own range (the constants of
:mod:`envcap.scene.limits`; the table in ``docs/scenes.md``, "Ranges and limits").  The format is
documented in ``docs/scenes.md``.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

from envcap.capture.effects import check_effects
from envcap.core.checks import format_numbers
from envcap.scene.model import Street
from envcap.scene.spec import (
    BuildingSpec,
    FacadeSpec,
    GroundSpec,
    Layout,
    MeshSpec,
    RandomBuildingsSpec,
    SceneSpec,
    SideSpec,
    StreetSpec,
    WallSpec,
    WindowsSpec,
)
from envcap.scene.limits import (
    ANGLE_LIMIT_DEG,
    BUILDING_LIMIT,
    COORDINATE_LIMIT_M,
    EMISSION_LIMIT,
    FIRST_FLOOR_LIMIT,
    GROUND_EXTENT_LIMIT_M,
    MESH_SCALE_RANGE,
    MIN_PIECE_M,
    MIN_SIZE_M,
    MIN_STREET_LENGTH_M,
    MIN_STREET_WIDTH_M,
    SEED_LIMIT,
    SIZE_LIMIT_M,
    SPAN_LIMIT_M,
)
from envcap.scene.mesh_import import CROP_MODES, WINDING_MODES
from envcap.scene.model import SHADOW_FITS, ShadowSettings
from envcap.scene.table import Table
from envcap.sky.registry import SkySpec, parse_sky_spec

DEFAULT_GROUND_EXTENT = 1000.0
"""Default side length (m) of the square ground quad."""


def read_toml(path: Path) -> dict[str, Any]:
    """The TOML document at ``path`` as a dict; ``ValueError`` naming the file (and line) if invalid."""
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a UTF-8 text file ({exc})") from None
    except ValueError as exc:  # TOMLDecodeError: "(at line L, column C)"; or an integer of > 4300 digits
        raise ValueError(f"{path}: invalid TOML: {exc}") from None


def parse_scene(data: dict[str, Any], base_dir: Path | None = None, default_name: str = "scene",
                source: str = "") -> SceneSpec:
    """Check a scene document (the TOML as a dict) and type it.

    ``base_dir`` resolves relative file names (``[mesh] file``, ``[sky] file``); the sky is built
    once here so that a missing or bad sky file is reported at load.
    """
    top = Table(data, "")
    name = top.string("name", default_name)
    description = top.string("description", "")
    effects = _parse_effects(top.raw("effects"))
    sky = _parse_sky(top.raw("sky"), base_dir)
    mesh_value = top.raw("mesh", None)
    street_tables = top.tables("streets")
    ground_table = top.sub("ground")
    shadows_table = top.sub("shadows")
    top.close()

    streets = tuple(_parse_street(t, i) for i, t in enumerate(street_tables))
    names = [s.street.name for s in streets]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"street names must be unique, repeated: {dup}")
    if mesh_value is None:
        mesh_tables = []
    elif isinstance(mesh_value, list):
        mesh_tables = top.tables("mesh")
    else:
        mesh_tables = [Table(mesh_value, "mesh")]
    meshes = tuple(_parse_mesh(t, base_dir) for t in mesh_tables)
    if not streets and not meshes:
        raise ValueError("a scene needs at least one [[streets]] or a [mesh]")
    return SceneSpec(name=name, description=" ".join(description.split()), effects=effects, sky=sky,
                     streets=streets, meshes=meshes, ground=_parse_ground(ground_table), source=source,
                     shadows=_parse_shadows(shadows_table))


def _parse_shadows(t: Table | None) -> ShadowSettings:
    """The ``[shadows]`` table (keys: texel_m, fit); none: the defaults."""
    if t is None:
        return ShadowSettings()
    texel = t.raw("texel_m", None)
    settings = ShadowSettings(
        texel_m=None if texel is None else t.number("texel_m", positive=True, max=100.0),
        fit=t.string("fit", "mesh", choices=SHADOW_FITS),
    )
    t.close()
    return settings


def _parse_effects(v: Any) -> frozenset[str]:
    if not isinstance(v, list) or not all(isinstance(e, str) for e in v):
        raise ValueError(f"effects: expected a list of names, got {v!r}")
    try:
        return check_effects(v)
    except ValueError as exc:
        raise ValueError(f"effects: {exc}") from None


def _parse_sky(v: Any, base_dir: Path | None) -> SkySpec:
    """The ``[sky]`` table through the sky registry, built once to check its files."""
    Table(v, "sky")  # a table, not a string or a number
    spec = parse_sky_spec(dict(v), base_dir)
    spec.build()
    return spec


def _parse_mesh(t: Table, base_dir: Path | None) -> MeshSpec:
    """A scene's ``[mesh]`` table, or one of its ``[[mesh]]`` tables (keys: file, files, glob,
    include, exclude, up_axis, rotation_deg, offset, scale, albedo, winding, crop, crop_by,
    emission_scale); at least one of file, files, glob; or only ``scene`` (another scene's geometry)."""
    base = base_dir if base_dir is not None else Path.cwd()
    if t.has("scene"):
        return _parse_scene_mesh(t, base)
    file = t.raw("file", None)
    if file is not None:
        file = base / Path(t.string("file"))
    files = tuple(base / Path(f) for f in _strings(t, "files"))
    globs = _strings(t, "glob")
    if file is None and not files and not globs:
        raise ValueError(f"{t.where}: give the mesh files with 'file', 'files' or 'glob'")
    crop_table = t.sub("crop")
    crop = None
    if crop_table is not None:
        lo = crop_table.vector("min", 3, min=-COORDINATE_LIMIT_M, max=COORDINATE_LIMIT_M)
        hi = crop_table.vector("max", 3, min=-COORDINATE_LIMIT_M, max=COORDINATE_LIMIT_M)
        crop_table.close()
        if not all(a < b for a, b in zip(lo, hi)):
            raise ValueError(f"{t.where}.crop: min {format_numbers(lo)} must be below max {format_numbers(hi)} on every axis")
        crop = (lo, hi)
    spec = MeshSpec(
        path=file,
        up_axis=t.string("up_axis", "y", choices=("y", "z")),
        rotation_deg=t.number("rotation_deg", 0.0, min=-ANGLE_LIMIT_DEG, max=ANGLE_LIMIT_DEG),
        offset=t.vector("offset", 3, (0.0, 0.0, 0.0), min=-COORDINATE_LIMIT_M, max=COORDINATE_LIMIT_M),
        scale=t.number("scale", 1.0, min=MESH_SCALE_RANGE[0], max=MESH_SCALE_RANGE[1]),
        albedo=t.vector("albedo", 3, (0.5, 0.5, 0.5), min=0.0, max=1.0, gray=True),
        files=files,
        globs=globs,
        include=_strings(t, "include"),
        exclude=_strings(t, "exclude"),
        base_dir=base,
        winding=t.string("winding", "auto", choices=WINDING_MODES),
        crop=crop,
        crop_by=t.string("crop_by", "part", choices=CROP_MODES),
        emission_scale=t.number("emission_scale", 100.0, min=0.0, max=1e6),
    )
    t.close()
    return spec


def _parse_scene_mesh(t: Table, base: Path) -> MeshSpec:
    """A mesh table ``scene = "NAME"`` (or a ``.toml`` path relative to ``base``): that scene's whole
    geometry, taken as it builds it; no other key (a transform or crop would change what it is)."""
    scene = t.string("scene")
    if not scene.strip():
        raise ValueError(f"{t.where}.scene: expected a bundled scene name or a .toml path, got an empty string")
    others = sorted(k for k in t.data if k != "scene")
    if others:
        raise ValueError(f"{t.where}: 'scene' takes another scene's geometry as it is built; it takes no other key "
                         f"(also has {', '.join(others)})")
    t.close()
    return MeshSpec(path=None, up_axis="y", rotation_deg=0.0, offset=(0.0, 0.0, 0.0), scale=1.0,
                    albedo=(0.5, 0.5, 0.5), base_dir=base, scene=scene)


def _strings(t: Table, key: str) -> tuple[str, ...]:
    """A string or a list of non-empty strings (default: none)."""
    v = t.raw(key, [])
    v = [v] if isinstance(v, str) else v
    if not isinstance(v, list) or not all(isinstance(x, str) and x for x in v):
        raise ValueError(f"{t.where}.{key}: expected a string or a list of strings, got {v!r}")
    return tuple(v)


def _parse_windows(t: Table) -> WindowsSpec:
    w = WindowsSpec(
        width=t.number("width", 1.2, positive=True, min=MIN_SIZE_M, max=SIZE_LIMIT_M),
        height=t.number("height", 1.6, positive=True, min=MIN_SIZE_M, max=SIZE_LIMIT_M),
        spacing=t.number("spacing", 3.0, positive=True, min=MIN_SIZE_M, max=SIZE_LIMIT_M),
        floor_height=t.number("floor_height", 3.2, positive=True, min=MIN_SIZE_M, max=SIZE_LIMIT_M),
        sill=t.number("sill", 0.9, min=0.0, max=SIZE_LIMIT_M),
        first_floor=t.integer("first_floor", 0, min=0, max=FIRST_FLOOR_LIMIT),
        top_margin=t.number("top_margin", 0.5, min=0.0, max=SIZE_LIMIT_M),
        albedo=t.vector("albedo", 3, (0.04, 0.05, 0.06), min=0.0, max=1.0, gray=True),
        frame=t.number("frame", 0.0, min=0.0, max=SIZE_LIMIT_M),
        frame_albedo=t.vector("frame_albedo", 3, (0.6, 0.6, 0.6), min=0.0, max=1.0, gray=True),
        offset=t.number("offset", 0.015, positive=True, max=0.5),
        emissive_fraction=t.number("emissive_fraction", 0.0, min=0.0, max=1.0),
        emission=t.vector("emission", 3, (0.0, 0.0, 0.0), min=0.0, max=EMISSION_LIMIT),
    )
    t.close()
    if w.width + 2 * w.frame >= w.spacing:
        raise ValueError(f"{t.where}: width + 2*frame ({w.width + 2 * w.frame}) must be smaller than spacing ({w.spacing})")
    if w.sill < w.frame or w.sill + w.height + w.frame >= w.floor_height:
        raise ValueError(f"{t.where}: a window (sill {w.sill} + height {w.height} + frame {w.frame}) must fit in one floor ({w.floor_height})")
    return w


def _merge(a: dict[str, Any] | None, b: dict[str, Any] | None) -> dict[str, Any]:
    """A side's facade table over the street's: keys of ``b`` win, ``windows`` tables merge key by key."""
    out = dict(a or {})
    for k, v in (b or {}).items():
        if k == "windows" and isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = {**out[k], **v}
        else:
            out[k] = v
    return out


def _parse_facade(data: dict[str, Any], where: str) -> FacadeSpec:
    t = Table(data, where)
    albedo = t.vector("albedo", 3, (0.35, 0.33, 0.3), min=0.0, max=1.0, gray=True)
    jitter = t.number("albedo_jitter", 0.0, min=0.0, max=1.0)
    wt = t.sub("windows")
    t.close()
    return FacadeSpec(albedo, jitter, _parse_windows(wt) if wt is not None else None)


def _parse_street(t: Table, index: int) -> StreetSpec:
    name = t.string("name", f"street{index}")
    yaw, origin = 0.0, (0.0, 0.0)
    if t.has("p0") or t.has("p1"):
        axis, start, end, yaw, origin = _street_ends(t)
    else:
        axis, start, end = _street_along(t)
    width = t.number("width", positive=True, min=MIN_STREET_WIDTH_M, max=SIZE_LIMIT_M)
    cross = t.number("cross", 0.0, min=-COORDINATE_LIMIT_M, max=COORDINATE_LIMIT_M)
    _check_coordinates(t.where, "cross +- width/2", (cross - 0.5 * width, cross + 0.5 * width))
    probe_line = t.raw("probe_line", None)
    if probe_line is not None:
        probe_line = t.number("probe_line", min=cross - 0.5 * width, max=cross + 0.5 * width)
    follow_terrain = t.boolean("follow_terrain", False)
    facade_raw = t.raw("facade", {})
    street_facade = _parse_facade(facade_raw, f"{t.where}.facade")  # validates the street's own table
    sides = []
    for key in ("side_min", "side_max"):
        st = t.sub(key)
        sides.append(None if st is None else _parse_side(st, facade_raw, street_facade, end - start))
    t.close()
    street = Street(name=name, axis=axis, start=start, end=end, facade_min=cross - 0.5 * width,
                    facade_max=cross + 0.5 * width, ground=0.0, center=probe_line, follow_terrain=follow_terrain,
                    yaw_deg=yaw, origin_xz=origin)
    if street.framed:
        _check_coordinates(t.where, "the street's corners", tuple(street.plan_corners().ravel()))
    return StreetSpec(street, sides[0], sides[1])


def _street_ends(t: Table) -> tuple[str, float, float, float, tuple[float, float]]:
    """A street given by the world plan points ``p0``, ``p1`` (x, z) of its centre line's ends:
    ``(axis "x", start 0, end |p1 - p0|, yaw_deg = atan2(dz, dx) in degrees, origin p0)``."""
    mixed = [k for k in ("axis", "start", "end", "length", "along_center") if t.has(k)]
    if mixed:
        raise ValueError(f"{t.where}: give either p0/p1 or axis with start/end (or along_center/length), "
                         f"not both (also has {', '.join(mixed)})")
    sides = [k for k in ("side_min", "side_max") if t.has(k)]
    if sides:
        raise ValueError(f"{t.where}: {'/'.join(sides)} build along an axis street; a p0/p1 street takes its "
                         f"buildings from a [mesh]")
    if not (t.has("p0") and t.has("p1")):
        raise ValueError(f"{t.where}: a street by its ends needs both p0 and p1 ([x, z], m)")
    p0 = t.vector("p0", 2, min=-COORDINATE_LIMIT_M, max=COORDINATE_LIMIT_M)
    p1 = t.vector("p1", 2, min=-COORDINATE_LIMIT_M, max=COORDINATE_LIMIT_M)
    dx, dz = p1[0] - p0[0], p1[1] - p0[1]
    length = math.hypot(dx, dz)
    if not length > 0.0:
        raise ValueError(f"{t.where}: p0 and p1 are the same point {format_numbers(p0)}: a street needs a length")
    if length < MIN_STREET_LENGTH_M:
        raise ValueError(f"{t.where}: p0 to p1 is {length:.3g} m; a street must be at least {MIN_STREET_LENGTH_M:g} m long")
    if length > SPAN_LIMIT_M:
        raise ValueError(f"{t.where}: p0 to p1 is {length:.10g} m, beyond the span limit of {SPAN_LIMIT_M:g} m")
    return "x", 0.0, length, math.degrees(math.atan2(dz, dx)), (p0[0], p0[1])


def _street_along(t: Table) -> tuple[str, float, float]:
    """A street along a world axis: ``(axis, start, end)`` from start/end or along_center/length."""
    axis = t.string("axis", choices=("x", "z"))
    if t.has("start") or t.has("end"):
        if t.has("length") or t.has("along_center"):
            raise ValueError(f"{t.where}: give either start/end or along_center/length, not both")
        start = t.number("start", min=-COORDINATE_LIMIT_M, max=COORDINATE_LIMIT_M)
        end = t.number("end", min=-COORDINATE_LIMIT_M, max=COORDINATE_LIMIT_M)
    else:
        length = t.number("length", positive=True, min=MIN_STREET_LENGTH_M, max=SPAN_LIMIT_M)
        mid = t.number("along_center", 0.0, min=-COORDINATE_LIMIT_M, max=COORDINATE_LIMIT_M)
        start, end = mid - 0.5 * length, mid + 0.5 * length
        _check_coordinates(t.where, "along_center +- length/2", (start, end))
    if not end > start:
        raise ValueError(f"{t.where}: end ({end:g}) must be larger than start ({start:g})")
    if end - start < MIN_STREET_LENGTH_M:
        raise ValueError(f"{t.where}: the street is {end - start:.3g} m long (start {start:g}, end {end:g}); "
                         f"a street must be at least {MIN_STREET_LENGTH_M:g} m long")
    return axis, start, end


def _check_coordinates(where: str, what: str, values: tuple[float, ...]) -> None:
    """Derived world coordinates (m) within the coordinate limit."""
    if not all(abs(v) <= COORDINATE_LIMIT_M for v in values):
        raise ValueError(f"{where}: {what} reaches {max(abs(v) for v in values):.10g} m, beyond the coordinate "
                         f"limit of +-{COORDINATE_LIMIT_M:g} m")


def _parse_side(t: Table, street_facade_raw: dict[str, Any], street_facade: FacadeSpec, length: float) -> SideSpec:
    seed = t.integer("seed", 0, min=0, max=SEED_LIMIT)
    start_offset = t.number("start_offset", 0.0, min=0.0, max=SPAN_LIMIT_M)
    if not start_offset < length:
        raise ValueError(f"{t.where}.start_offset: must be smaller than the street's length ({length:g} m), "
                         f"got {start_offset:g}")
    side_facade_raw = t.raw("facade", None)
    facade = street_facade
    if side_facade_raw is not None:
        Table(side_facade_raw, f"{t.where}.facade")  # type check
        facade = _parse_facade(_merge(street_facade_raw, side_facade_raw), f"{t.where}.facade")
    present = [k for k in ("random", "buildings", "wall") if t.has(k)]
    if len(present) > 1:
        raise ValueError(f"{t.where}: give only one of 'random', 'buildings', 'wall' (got {present})")
    layout_table: Table | list[Table] | None = None
    if present == ["random"]:
        layout_table = t.sub("random")
    elif present == ["buildings"]:
        layout_table = t.tables("buildings")
    elif present == ["wall"]:
        layout_table = t.sub("wall")
    t.close()
    layout: Layout = None
    if present == ["random"]:
        layout = _parse_random(layout_table)
    elif present == ["buildings"]:
        layout = tuple(_parse_building(b, facade) for b in layout_table)
    elif present == ["wall"]:
        layout = _parse_wall(layout_table, facade)
    return SideSpec(seed, start_offset, facade, layout)


def _parse_building(b: Table, facade: FacadeSpec) -> BuildingSpec:
    spec = BuildingSpec(
        gap=b.number("gap", 0.0, min=0.0, max=SPAN_LIMIT_M),
        width=b.number("width", min=MIN_PIECE_M, max=SIZE_LIMIT_M),
        albedo=b.vector("albedo", 3, facade.albedo, min=0.0, max=1.0, gray=True),
        height=b.number("height", positive=True, min=MIN_SIZE_M, max=SIZE_LIMIT_M),
        depth=b.number("depth", 12.0, positive=True, min=MIN_SIZE_M, max=SIZE_LIMIT_M),
        setback=b.number("setback", 0.0, min=0.0, max=SIZE_LIMIT_M),
        windows=b.boolean("windows", True),
    )
    b.close()
    return spec


def _parse_random(r: Table) -> RandomBuildingsSpec:
    spec = RandomBuildingsSpec(
        count=r.integer("count", -1, min=0, max=BUILDING_LIMIT) if r.has("count") else None,
        width=r.range("width", min=MIN_PIECE_M, max=SIZE_LIMIT_M),
        height=r.range("height", positive=True, min=MIN_SIZE_M, max=SIZE_LIMIT_M),
        depth=r.range("depth", (10.0, 15.0), positive=True, min=MIN_SIZE_M, max=SIZE_LIMIT_M),
        setback=r.range("setback", (0.0, 0.0), min=0.0, max=SIZE_LIMIT_M),
        gap_probability=r.number("gap_probability", 0.0, min=0.0, max=1.0),
        gap_width=r.range("gap_width", (2.0, 6.0), positive=True, min=MIN_SIZE_M, max=SPAN_LIMIT_M),
    )
    r.close()
    return spec


def _parse_wall(t: Table, facade: FacadeSpec) -> WallSpec:
    spec = WallSpec(
        height=t.number("height", positive=True, min=MIN_SIZE_M, max=SIZE_LIMIT_M),
        tile=t.number("tile", 2.0, positive=True, min=MIN_SIZE_M, max=SIZE_LIMIT_M),
        albedo=t.vector("albedo", 3, facade.albedo, min=0.0, max=1.0, gray=True),
        albedo2=t.vector("albedo2", 3, (0.1, 0.1, 0.1), min=0.0, max=1.0, gray=True),
        thickness=t.number("thickness", 0.5, positive=True, min=MIN_SIZE_M, max=SIZE_LIMIT_M),
    )
    t.close()
    return spec


def _parse_ground(t: Table | None) -> GroundSpec | None:
    """The ``[ground]`` table (absent: all defaults); ``None`` when ``enabled = false``."""
    spec = t if t is not None else Table({}, "ground")
    if not spec.boolean("enabled", True):
        spec.close()
        return None
    albedo = spec.vector("albedo", 3, (0.18, 0.18, 0.18), min=0.0, max=1.0, gray=True)
    extent = spec.number("extent", DEFAULT_GROUND_EXTENT, positive=True, min=MIN_SIZE_M, max=GROUND_EXTENT_LIMIT_M)
    center = spec.vector("center", 2, None, min=-COORDINATE_LIMIT_M, max=COORDINATE_LIMIT_M) if spec.has("center") else None
    checker = spec.number("checker", 0.0, min=0.0, max=GROUND_EXTENT_LIMIT_M)
    albedo2 = spec.vector("albedo2", 3, (0.08, 0.08, 0.08), min=0.0, max=1.0, gray=True)
    checker_extent = spec.number("checker_extent", min(extent, 200.0), positive=True, min=MIN_SIZE_M, max=GROUND_EXTENT_LIMIT_M)
    spec.close()
    return GroundSpec(albedo, extent, center, checker, albedo2, checker_extent)
