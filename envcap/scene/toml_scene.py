"""Declarative street scenes in TOML -> :class:`envcap.scene.model.Scene`.

The format, the placement rules and the exact geometry are documented in ``docs/scenes.md``.
World frame: right-handed, meters, +Y up, ground at y = 0; streets run along X or Z.

Public API: :func:`load_scene`, :func:`scene_from_dict`, :func:`list_scenes`.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from envcap.core.resources import city_scenes_dir
from envcap.scene._spec import Table
from envcap.scene.geometry import MeshBuilder, subtract_interval
from envcap.scene.model import EFFECTS, Scene, SceneMesh, Street

MIN_PIECE = 0.5
"""Building pieces narrower than this (m, along the street) after clipping are dropped."""

DEFAULT_GROUND_EXTENT = 1000.0
"""Default side length (m) of the square ground quad."""


# --------------------------------------------------------------------------------------------
# Public API


def list_scenes() -> list[tuple[str, str]]:
    """``(name, description)`` of every bundled scene (``city_scenes/*.toml``), sorted by name.

    Only the TOML text is parsed (no geometry is built), so this is fast.
    """
    out = []
    for path in sorted(city_scenes_dir().glob("*.toml")):
        data = _read_toml(path)
        desc = data.get("description", "")
        out.append((path.stem, " ".join(str(desc).split())))
    return out


def scene_path(name_or_path: str | Path) -> Path:
    """Resolve a bundled scene name (``"canyon"``) or a path to a ``.toml`` file.

    Raises ``FileNotFoundError`` naming the bundled scenes when neither exists.
    """
    p = Path(name_or_path)
    looks_like_path = isinstance(name_or_path, Path) or p.suffix == ".toml" or len(p.parts) > 1
    if looks_like_path:
        if p.is_dir():
            raise ValueError(f"scene path {p} is a directory, expected a .toml file")
        if not p.is_file():
            raise FileNotFoundError(f"scene file {p} not found")
        return p
    bundled = city_scenes_dir() / f"{name_or_path}.toml"
    if bundled.is_file():
        return bundled
    names = [n for n, _ in list_scenes()]
    raise FileNotFoundError(f"no bundled scene named '{name_or_path}' (bundled: {', '.join(names)}) and no such .toml file")


def load_scene(name_or_path: str | Path) -> Scene:
    """Load a bundled scene by name (``"canyon"``) or a scene ``.toml`` file by path.

    Errors in the file raise ``ValueError`` (or ``FileNotFoundError`` for missing files) with a
    message that starts with the file name and names the offending key.
    """
    path = scene_path(name_or_path)
    data = _read_toml(path)
    try:
        return scene_from_dict(data, base_dir=path.parent.resolve(), default_name=path.stem, source=str(path))
    except FileNotFoundError as exc:
        raise FileNotFoundError(f"{path}: {exc}") from None
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def scene_from_dict(
    data: dict[str, Any],
    base_dir: Path | None = None,
    default_name: str = "scene",
    source: str = "",
) -> Scene:
    """Build a :class:`Scene` from a parsed scene table (the TOML document as a dict).

    ``base_dir`` resolves relative file names (``[mesh] file``, ``[sky] file``).
    """
    top = Table(data, "")
    name = top.string("name", default_name)
    description = top.string("description", "")
    effects = _parse_effects(top.raw("effects"))
    sky = _parse_sky(top.raw("sky"), base_dir)
    mesh_spec = top.sub("mesh")
    street_tables = top.tables("streets")
    ground_tab = top.sub("ground")
    top.close()

    builder = MeshBuilder()
    parts: list[SceneMesh] = []
    streets = [_parse_street(t, i) for i, t in enumerate(street_tables)]
    names = [s.street.name for s in streets]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"street names must be unique, repeated: {dup}")

    stats = {"buildings": 0, "windows": 0, "lit_windows": 0}
    placed: list[_Footprint] = []
    for si, s in enumerate(streets):
        for side_index, side in enumerate((s.side_min, s.side_max)):
            if side is None:
                continue
            _build_side(builder, s, side, side_index, si, streets, placed, stats)

    if mesh_spec is not None:
        from envcap.scene.mesh_import import import_mesh_spec

        parts.append(import_mesh_spec(mesh_spec, base_dir))

    if not streets and mesh_spec is None:
        raise ValueError("a scene needs at least one [[streets]] or a [mesh]")

    _build_ground(builder, ground_tab, streets, parts)
    mesh = SceneMesh.concatenate([builder.build(), *parts]) if parts else builder.build()
    meta = dict(stats, source=source)
    return Scene(
        name=name,
        mesh=mesh,
        streets=[s.street for s in streets],
        sky=sky,
        effects=effects,
        description=" ".join(description.split()),
        base_dir=base_dir,
        meta=meta,
    )


# --------------------------------------------------------------------------------------------
# Reading


def _read_toml(path: Path) -> dict[str, Any]:
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:  # message carries "(at line L, column C)"
        raise ValueError(f"{path}: invalid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a UTF-8 text file ({exc})") from None


def _parse_effects(v: Any) -> frozenset[str]:
    if not isinstance(v, list) or not all(isinstance(e, str) for e in v):
        raise ValueError(f"effects: expected a list of names, got {v!r}")
    unknown = sorted(set(v) - set(EFFECTS))
    if unknown:
        raise ValueError(f"effects: unknown effect(s) {unknown}; known: {list(EFFECTS)}")
    if "sun_shadows" in v and "sun_light" not in v:
        raise ValueError("effects: 'sun_shadows' needs 'sun_light'")
    return frozenset(v)


def _parse_sky(v: Any, base_dir: Path | None) -> dict[str, Any]:
    """Check the ``[sky]`` table with :func:`envcap.sky.sky.sky_from_spec` (the one interpreter of
    it: unknown keys, types, missing files) and pass it through unchanged as a dict."""
    from envcap.sky.sky import sky_from_spec

    Table(v, "sky")  # a table, not a string or a number
    sky_from_spec(dict(v), base_dir)
    return dict(v)


@dataclass
class _Windows:
    width: float
    height: float
    spacing: float
    floor_height: float
    sill: float
    first_floor: int
    top_margin: float
    albedo: tuple[float, ...]
    frame: float
    frame_albedo: tuple[float, ...]
    offset: float
    emissive_fraction: float
    emission: tuple[float, ...]


@dataclass
class _Facade:
    albedo: tuple[float, ...]
    albedo_jitter: float
    windows: _Windows | None


@dataclass
class _Side:
    seed: int
    start_offset: float
    facade: _Facade
    mode: str  # "none" | "random" | "list" | "wall"
    spec: Any  # Table (random / wall) or list[Table] (list)


@dataclass
class _StreetSpec:
    street: Street
    side_min: _Side | None
    side_max: _Side | None


@dataclass
class _Footprint:
    along_axis: int
    a0: float
    a1: float
    c0: float
    c1: float


def _parse_windows(t: Table) -> _Windows:
    w = _Windows(
        width=t.number("width", 1.2, positive=True),
        height=t.number("height", 1.6, positive=True),
        spacing=t.number("spacing", 3.0, positive=True),
        floor_height=t.number("floor_height", 3.2, positive=True),
        sill=t.number("sill", 0.9, min=0.0),
        first_floor=t.integer("first_floor", 0, min=0),
        top_margin=t.number("top_margin", 0.5, min=0.0),
        albedo=t.vector("albedo", 3, (0.04, 0.05, 0.06), min=0.0, max=1.0, gray=True),
        frame=t.number("frame", 0.0, min=0.0),
        frame_albedo=t.vector("frame_albedo", 3, (0.6, 0.6, 0.6), min=0.0, max=1.0, gray=True),
        offset=t.number("offset", 0.015, positive=True, max=0.5),
        emissive_fraction=t.number("emissive_fraction", 0.0, min=0.0, max=1.0),
        emission=t.vector("emission", 3, (0.0, 0.0, 0.0), min=0.0),
    )
    t.close()
    if w.width + 2 * w.frame >= w.spacing:
        raise ValueError(f"{t.where}: width + 2*frame ({w.width + 2 * w.frame}) must be smaller than spacing ({w.spacing})")
    if w.sill < w.frame or w.sill + w.height + w.frame >= w.floor_height:
        raise ValueError(f"{t.where}: a window (sill {w.sill} + height {w.height} + frame {w.frame}) must fit in one floor ({w.floor_height})")
    return w


def _merge(a: dict[str, Any] | None, b: dict[str, Any] | None) -> dict[str, Any]:
    out = dict(a or {})
    for k, v in (b or {}).items():
        if k == "windows" and isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = {**out[k], **v}
        else:
            out[k] = v
    return out


def _parse_facade(data: dict[str, Any], where: str) -> _Facade:
    t = Table(data, where)
    albedo = t.vector("albedo", 3, (0.35, 0.33, 0.3), min=0.0, max=1.0, gray=True)
    jitter = t.number("albedo_jitter", 0.0, min=0.0, max=1.0)
    wt = t.sub("windows")
    t.close()
    return _Facade(albedo, jitter, _parse_windows(wt) if wt is not None else None)


def _parse_street(t: Table, index: int) -> _StreetSpec:
    name = t.string("name", f"street{index}")
    axis = t.string("axis", choices=("x", "z"))
    if t.has("start") or t.has("end"):
        if t.has("length") or t.has("along_center"):
            raise ValueError(f"{t.where}: give either start/end or along_center/length, not both")
        start, end = t.number("start"), t.number("end")
    else:
        length = t.number("length", positive=True)
        mid = t.number("along_center", 0.0)
        start, end = mid - 0.5 * length, mid + 0.5 * length
    if not end > start:
        raise ValueError(f"{t.where}: end ({end}) must be larger than start ({start})")
    width = t.number("width", positive=True)
    cross = t.number("cross", 0.0)
    probe_line = t.raw("probe_line", None)
    if probe_line is not None:
        probe_line = t.number("probe_line", min=cross - 0.5 * width, max=cross + 0.5 * width)
    facade_raw = t.raw("facade", {})
    street_facade = _parse_facade(facade_raw, f"{t.where}.facade")  # validates the street's own table
    sides = []
    for key in ("side_min", "side_max"):
        st = t.sub(key)
        sides.append(None if st is None else _parse_side(st, facade_raw, street_facade))
    t.close()
    street = Street(name=name, axis=axis, start=start, end=end, facade_min=cross - 0.5 * width,
                    facade_max=cross + 0.5 * width, ground=0.0, center=probe_line)
    return _StreetSpec(street, sides[0], sides[1])


def _parse_side(t: Table, street_facade_raw: dict[str, Any], street_facade: _Facade) -> _Side:
    seed = t.integer("seed", 0)
    start_offset = t.number("start_offset", 0.0, min=0.0)
    side_facade_raw = t.raw("facade", None)
    facade = street_facade
    if side_facade_raw is not None:
        Table(side_facade_raw, f"{t.where}.facade")  # type check
        facade = _parse_facade(_merge(street_facade_raw, side_facade_raw), f"{t.where}.facade")
    present = [k for k in ("random", "buildings", "wall") if t.has(k)]
    if len(present) > 1:
        raise ValueError(f"{t.where}: give only one of 'random', 'buildings', 'wall' (got {present})")
    mode, spec = "none", None
    if present == ["random"]:
        mode, spec = "random", t.sub("random")
    elif present == ["buildings"]:
        mode, spec = "list", t.tables("buildings")
    elif present == ["wall"]:
        mode, spec = "wall", t.sub("wall")
    t.close()
    return _Side(seed, start_offset, facade, mode, spec)


# --------------------------------------------------------------------------------------------
# Building


@dataclass
class _Building:
    a0: float
    a1: float
    height: float
    depth: float
    setback: float
    albedo: tuple[float, ...]
    windows: bool


def _side_buildings(s: _StreetSpec, side: _Side, rng: np.random.Generator) -> list[_Building]:
    st = s.street
    pos = st.start + side.start_offset
    out: list[_Building] = []
    if side.mode == "list":
        for b in side.spec:
            pos += b.number("gap", 0.0, min=0.0)
            w = b.number("width", positive=True)
            alb = b.vector("albedo", 3, side.facade.albedo, min=0.0, max=1.0, gray=True)
            out.append(_Building(pos, pos + w, b.number("height", positive=True), b.number("depth", 12.0, positive=True),
                                 b.number("setback", 0.0, min=0.0), alb, b.boolean("windows", True)))
            b.close()
            pos += w
        return out
    r: Table = side.spec
    count = r.integer("count", -1, min=0) if r.has("count") else -1
    wr = r.range("width", positive=True)
    hr = r.range("height", positive=True)
    dr = r.range("depth", (10.0, 15.0), positive=True)
    sr = r.range("setback", (0.0, 0.0), min=0.0)
    gp = r.number("gap_probability", 0.0, min=0.0, max=1.0)
    gr = r.range("gap_width", (2.0, 6.0), positive=True)
    r.close()
    while count < 0 or len(out) < count:
        if gp > 0 and rng.random() < gp:
            pos += rng.uniform(*gr)
        w = rng.uniform(*wr)
        if pos + w > st.end:
            w = st.end - pos
            if w < wr[0]:
                break
        jit = side.facade.albedo_jitter
        alb = tuple(np.clip(np.asarray(side.facade.albedo) * rng.uniform(1 - jit, 1 + jit), 0.0, 1.0)) if jit else side.facade.albedo
        out.append(_Building(pos, pos + w, rng.uniform(*hr), rng.uniform(*dr), rng.uniform(*sr), alb, True))
        pos += w
    return out


def _clip(fp: _Footprint, streets: list[_StreetSpec], placed: list[_Footprint]) -> list[tuple[float, float]]:
    """Along-street pieces of a footprint that stay out of every roadway and every placed building."""
    a, c = fp.along_axis, 2 - fp.along_axis
    rects = []
    for s in streets:
        st = s.street
        lo, hi = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
        lo[st.along_index], hi[st.along_index] = st.start, st.end
        lo[st.cross_index], hi[st.cross_index] = st.facade_min, st.facade_max
        rects.append((lo[a], hi[a], lo[c], hi[c]))
    for p in placed:
        lo, hi = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
        pc = 2 - p.along_axis
        lo[p.along_axis], hi[p.along_axis] = p.a0, p.a1
        lo[pc], hi[pc] = p.c0, p.c1
        rects.append((lo[a], hi[a], lo[c], hi[c]))
    pieces = [(fp.a0, fp.a1)]
    eps = 1e-6
    for ra0, ra1, rc0, rc1 in rects:
        if rc1 <= fp.c0 + eps or rc0 >= fp.c1 - eps:
            continue
        pieces = subtract_interval(pieces, ra0, ra1)
    return [(x0, x1) for x0, x1 in pieces if x1 - x0 >= MIN_PIECE]


def _build_side(builder: MeshBuilder, s: _StreetSpec, side: _Side, side_index: int, street_index: int,
                streets: list[_StreetSpec], placed: list[_Footprint], stats: dict[str, int]) -> None:
    st = s.street
    a, c = st.along_index, st.cross_index
    sign = 1 if side_index == 0 else -1  # front-face normal along the cross axis (toward the street)
    plane = st.facade_min if side_index == 0 else st.facade_max
    rng = np.random.default_rng([side.seed, street_index, side_index])
    if side.mode == "none":
        return
    if side.mode == "wall":
        _build_wall(builder, s, side, side_index)
        return
    for b in _side_buildings(s, side, rng):
        front = plane - sign * b.setback
        back = front - sign * b.depth
        fp = _Footprint(a, b.a0, b.a1, min(front, back), max(front, back))
        for a0, a1 in _clip(fp, streets, placed):
            piece = _Footprint(a, a0, a1, fp.c0, fp.c1)
            placed.append(piece)
            lo, hi = np.zeros(3), np.zeros(3)
            lo[a], hi[a], lo[c], hi[c], hi[1] = a0, a1, fp.c0, fp.c1, b.height
            builder.add_boxes(lo, hi, b.albedo)
            stats["buildings"] += 1
            if b.windows and side.facade.windows is not None:
                _add_windows(builder, side.facade.windows, a, c, sign, front, a0, a1, b.height, rng, stats)


def _add_windows(builder: MeshBuilder, w: _Windows, a: int, c: int, sign: int, front: float,
                 a0: float, a1: float, height: float, rng: np.random.Generator, stats: dict[str, int]) -> None:
    ncol = int(np.floor((a1 - a0) / w.spacing + 1e-9))
    floors = []
    f = w.first_floor
    while f * w.floor_height + w.sill + w.height + w.frame + w.top_margin <= height + 1e-9:
        floors.append(f)
        f += 1
    if ncol == 0 or not floors:
        return
    margin = 0.5 * ((a1 - a0) - ncol * w.spacing)
    cx = a0 + margin + w.spacing * (np.arange(ncol) + 0.5)
    y0 = np.asarray(floors, np.float64) * w.floor_height + w.sill
    cx, y0 = (x.ravel() for x in np.meshgrid(cx, y0))
    n = cx.size
    lo, hi = np.zeros((n, 3)), np.zeros((n, 3))
    lo[:, a], hi[:, a] = cx - 0.5 * w.width, cx + 0.5 * w.width
    lo[:, 1], hi[:, 1] = y0, y0 + w.height
    lit = rng.random(n) < w.emissive_fraction
    emission = np.where(lit[:, None], np.asarray(w.emission)[None, :], 0.0)
    glass = front + sign * w.offset
    builder.add_rects(c, sign, glass, lo, hi, w.albedo, emission)
    stats["windows"] += n
    stats["lit_windows"] += int(lit.sum())
    if w.frame > 0:  # four strips around the glass, in the glass plane, not overlapping it
        f = w.frame
        x0, x1, g0, g1 = lo[:, a], hi[:, a], lo[:, 1], hi[:, 1]
        strips = (
            (x0 - f, x1 + f, g0 - f, g0),  # bottom (sill)
            (x0 - f, x1 + f, g1, g1 + f),  # top
            (x0 - f, x0, g0, g1),  # left
            (x1, x1 + f, g0, g1),  # right
        )
        for sx0, sx1, sy0, sy1 in strips:
            flo, fhi = np.zeros((n, 3)), np.zeros((n, 3))
            flo[:, a], fhi[:, a], flo[:, 1], fhi[:, 1] = sx0, sx1, sy0, sy1
            builder.add_rects(c, sign, glass, flo, fhi, w.frame_albedo)


def _build_wall(builder: MeshBuilder, s: _StreetSpec, side: _Side, side_index: int) -> None:
    """A continuous checkered facade exactly on the nominal plane, closed by a thin box behind."""
    t: Table = side.spec
    height = t.number("height", positive=True)
    tile = t.number("tile", 2.0, positive=True)
    alb1 = t.vector("albedo", 3, side.facade.albedo, min=0.0, max=1.0, gray=True)
    alb2 = t.vector("albedo2", 3, (0.1, 0.1, 0.1), min=0.0, max=1.0, gray=True)
    thick = t.number("thickness", 0.5, positive=True)
    t.close()
    st = s.street
    a, c = st.along_index, st.cross_index
    sign = 1 if side_index == 0 else -1
    plane = st.facade_min if side_index == 0 else st.facade_max
    a_edges = _tile_edges(st.start + side.start_offset, st.end, tile)
    y_edges = _tile_edges(0.0, height, tile)
    ia, iy = np.meshgrid(np.arange(a_edges.size - 1), np.arange(y_edges.size - 1))
    ia, iy = ia.ravel(), iy.ravel()
    lo, hi = np.zeros((ia.size, 3)), np.zeros((ia.size, 3))
    lo[:, a], hi[:, a] = a_edges[ia], a_edges[ia + 1]
    lo[:, 1], hi[:, 1] = y_edges[iy], y_edges[iy + 1]
    alb = np.where(((ia + iy) % 2 == 0)[:, None], np.asarray(alb1)[None], np.asarray(alb2)[None])
    builder.add_rects(c, sign, plane, lo, hi, alb)
    blo, bhi = np.zeros(3), np.zeros(3)
    blo[a], bhi[a] = a_edges[0], a_edges[-1]
    blo[c], bhi[c] = sorted((plane, plane - sign * thick))
    bhi[1] = height
    faces = ["+y", "+x", "-x", "+z", "-z"]
    faces.remove(("+" if sign > 0 else "-") + "xyz"[c])  # the front is the checker
    builder.add_boxes(blo, bhi, alb1, faces=tuple(faces))


def _tile_edges(lo: float, hi: float, tile: float) -> np.ndarray:
    n = max(1, int(np.ceil((hi - lo) / tile - 1e-9)))
    if n > 100_000:
        raise ValueError(f"tile size {tile} m gives {n} tiles; use a larger tile")
    e = lo + tile * np.arange(n + 1, dtype=np.float64)
    e[-1] = hi
    return e


def _build_ground(builder: MeshBuilder, t: Table | None, streets: list[_StreetSpec], parts: list[SceneMesh]) -> None:
    spec = t if t is not None else Table({}, "ground")
    if not spec.boolean("enabled", True):
        spec.close()
        return
    albedo = spec.vector("albedo", 3, (0.18, 0.18, 0.18), min=0.0, max=1.0, gray=True)
    extent = spec.number("extent", DEFAULT_GROUND_EXTENT, positive=True)
    center = spec.vector("center", 2, None) if spec.has("center") else None
    checker = spec.number("checker", 0.0, min=0.0)
    albedo2 = spec.vector("albedo2", 3, (0.08, 0.08, 0.08), min=0.0, max=1.0, gray=True)
    checker_extent = spec.number("checker_extent", min(extent, 200.0), positive=True)
    spec.close()
    if center is None:
        pts = []
        for s in streets:
            st = s.street
            p0, p1 = np.zeros(3), np.zeros(3)
            p0[st.along_index], p1[st.along_index] = st.start, st.end
            p0[st.cross_index], p1[st.cross_index] = st.facade_min, st.facade_max
            pts += [p0, p1]
        for m in parts:
            if m.positions.size:
                pts += [m.positions.min(0), m.positions.max(0)]
        bb = np.array(pts) if pts else np.zeros((1, 3))
        cx, cz = 0.5 * (bb.min(0) + bb.max(0))[[0, 2]]
    else:
        cx, cz = center
    h = 0.5 * extent
    if checker <= 0:
        builder.add_rects(1, 1, 0.0, (cx - h, 0, cz - h), (cx + h, 0, cz + h), albedo)
        return
    hc = 0.5 * min(checker_extent, extent)
    ex = _tile_edges(cx - hc, cx + hc, checker)
    ez = _tile_edges(cz - hc, cz + hc, checker)
    ix, iz = (g.ravel() for g in np.meshgrid(np.arange(ex.size - 1), np.arange(ez.size - 1)))
    lo, hi = np.zeros((ix.size, 3)), np.zeros((ix.size, 3))
    lo[:, 0], hi[:, 0], lo[:, 2], hi[:, 2] = ex[ix], ex[ix + 1], ez[iz], ez[iz + 1]
    alb = np.where(((ix + iz) % 2 == 0)[:, None], np.asarray(albedo)[None], np.asarray(albedo2)[None])
    builder.add_rects(1, 1, 0.0, lo, hi, alb)
    if hc < h:  # a ring of four plain quads out to the full extent
        ring_lo = [(cx - h, 0, cz - h), (cx - h, 0, cz + hc), (cx - h, 0, cz - hc), (cx + hc, 0, cz - hc)]
        ring_hi = [(cx + h, 0, cz - hc), (cx + h, 0, cz + h), (cx - hc, 0, cz + hc), (cx + h, 0, cz + hc)]
        builder.add_rects(1, 1, 0.0, ring_lo, ring_hi, albedo)
