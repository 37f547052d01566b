""":class:`~envcap.scene.spec.SceneSpec` -> :class:`~envcap.scene.model.Scene`: buildings, windows,
walls, the ground and imported meshes as one flat-shaded mesh.

Placement rules and the exact geometry are documented in ``docs/scenes.md``.  World frame:
right-handed, meters, +Y up, ground at y = 0; streets run along X or Z.  Random rows draw from
``numpy.random.default_rng([side seed, street index, side index])``, so a scene is reproducible.

Before anything is built, :func:`~envcap.scene.estimate.check_geometry_budget` bounds the number of
buildings and quads (one-line ``ValueError`` naming the key to change).  A side that asks for
buildings but gets none prints ``envcap: warning: ...`` on stderr, naming the side.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from envcap.scene.bundled import scene_path
from envcap.scene.clearing import GroundRects, clear_pieces, roadways
from envcap.scene.estimate import check_geometry_budget
from envcap.scene.geometry import MeshBuilder
from envcap.scene.ground_overlap import ground_overlap, ground_overlap_warning
from envcap.scene.mesh_import import import_meshes
from envcap.scene.mesh_select import select_mesh_files
from envcap.scene.model import Scene, SceneMesh, Street
from envcap.scene.parse import parse_scene, read_toml
from envcap.scene.spec import (
    BuildingSpec,
    GroundSpec,
    MeshSpec,
    RandomBuildingsSpec,
    SceneSpec,
    SideSpec,
    StreetSpec,
    WallSpec,
    WindowsSpec,
    side_key,
)

BELOW_GROUND_SHARE = 0.25
"""An imported mesh with more than this share of its height range below y = 0 gets a warning."""


def build_scene(spec: SceneSpec) -> Scene:
    """Build the scene's geometry; ``meta`` counts buildings, windows and lit windows.

    Raises ``ValueError`` before building if the scene is past its bounds
    (:func:`~envcap.scene.estimate.check_geometry_budget`)."""
    check_geometry_budget(spec)
    builder = MeshBuilder()
    parts: list[SceneMesh] = []
    stats = {"buildings": 0, "windows": 0, "lit_windows": 0}
    placed = roadways([s.street for s in spec.streets])  # and every building piece, as it is placed
    for si, s in enumerate(spec.streets):
        for side_index, side in enumerate((s.side_min, s.side_max)):
            if side is None:
                continue
            before = stats["buildings"]
            _build_side(builder, s, side, side_index, si, placed, stats)
            if stats["buildings"] == before:
                _warn_if_empty(spec.source, side_key(si, side_index), s, side)

    for index, mesh_spec in enumerate(spec.meshes):
        where = "mesh" if len(spec.meshes) == 1 else f"mesh[{index}]"
        if mesh_spec.scene is not None:
            parts.append(_scene_geometry(mesh_spec, where))
        else:
            parts.append(_import(mesh_spec, [s.street for s in spec.streets], spec.source, where))
        if spec.ground is not None:
            warning = ground_overlap_warning(ground_overlap(parts[-1]), f"{spec.source}: {where}" if spec.source else where)
            if warning:
                print(f"envcap: warning: {warning}", file=sys.stderr)

    center = ground_center(spec, parts)
    if spec.ground is not None:
        _build_ground(builder, spec.ground, center)
    mesh = SceneMesh.concatenate([builder.build(), *parts]) if parts else builder.build()
    return Scene(
        name=spec.name,
        mesh=mesh,
        streets=[s.street for s in spec.streets],
        sky=spec.sky,
        effects=spec.effects,
        description=spec.description,
        meta=dict(stats, source=spec.source, ground_center=center),
        shadows=spec.shadows,
    )


def _scene_geometry(m: MeshSpec, table: str) -> SceneMesh:
    """A mesh table ``scene = ...``: the geometry that scene builds (buildings, walls, meshes), without
    its ground.  The scene named must not itself take another scene's geometry (one level)."""
    name = m.scene or ""
    p = Path(name)
    if p.suffix.lower() == ".toml" or len(p.parts) > 1 or p.is_absolute():
        path = (m.base_dir or Path.cwd()) / p
        if not path.is_file():
            raise FileNotFoundError(f"{table}.scene: scene file {path} not found")
    else:
        try:
            path = scene_path(name)
        except FileNotFoundError as exc:
            raise FileNotFoundError(f"{table}.scene: {exc}") from None
    try:
        spec = parse_scene(read_toml(path), base_dir=path.parent.resolve(), default_name=path.stem, source=str(path))
        if any(ms.scene is not None for ms in spec.meshes):
            raise ValueError("it takes its own geometry from another scene: only one level is allowed")
        mesh = build_scene(replace(spec, ground=None)).mesh
    except (FileNotFoundError, ValueError) as exc:
        raise type(exc)(f"{table}.scene {name!r}: {exc}") from None
    if mesh.triangle_count == 0:
        raise ValueError(f"{table}.scene {name!r}: that scene builds no geometry (no buildings, walls or meshes)")
    return mesh


def _import(m: MeshSpec, streets: list[Street], source: str, table: str = "mesh") -> SceneMesh:
    """One ``[mesh]`` / ``[[mesh]]`` table's geometry; a ``ValueError`` (bad file, pattern
    matching nothing, coordinates past the limit) names the table.  Prints one note when parts
    were flipped, one per thing the readers skipped, and a warning when most of the mesh lies
    below the ground (a Z-up file read without ``up_axis = "z"``)."""
    try:
        files = select_mesh_files(m.base_dir or Path.cwd(), file=m.path, files=m.files, globs=m.globs,
                                  include=m.include, exclude=m.exclude)
        mesh, report = import_meshes(files, up_axis=m.up_axis, rotation_deg=m.rotation_deg, offset=m.offset,
                                     scale=m.scale, albedo=m.albedo, winding=m.winding, crop=m.crop, crop_by=m.crop_by,
                                     emission_scale=m.emission_scale,
                                     streets=streets, where=str(m.path if m.path is not None and not m.files
                                                                and not m.globs else "the selected files"))
    except FileNotFoundError as exc:
        raise FileNotFoundError(f"{table}: {exc}") from None
    except ValueError as exc:
        raise ValueError(f"{table}: {exc}") from None
    where = f"{source}: " if source else ""
    if report.flipped:
        names = ", ".join(report.flipped_files[:5]) + (f" and {len(report.flipped_files) - 5} more"
                                                       if len(report.flipped_files) > 5 else "")
        how = "as asked (winding = \"flip\")" if m.winding == "flip" else "wound inward"
        print(f"envcap: note: {where}{table}: flipped {report.flipped} of {report.parts} meshes {how} (files {names})",
              file=sys.stderr)
    for note in report.notes:
        print(f"envcap: note: {where}{table}: skipped or approximated: {note}", file=sys.stderr)
    if report.below_ground > BELOW_GROUND_SHARE:
        print(f"envcap: warning: {where}{table}: {100 * report.below_ground:.0f} % of the imported geometry's height "
              f"lies below the ground (y = 0) after the import transform: a Z-up file needs up_axis = \"z\"",
              file=sys.stderr)
    return mesh


def _warn_if_empty(source: str, where: str, s: StreetSpec, side: SideSpec) -> None:
    """A warning on stderr when a side that asks for buildings places none (a ``count`` of 0 asks for none)."""
    layout = side.layout
    if layout is None or isinstance(layout, WallSpec):
        return
    if isinstance(layout, RandomBuildingsSpec):
        if layout.count == 0:
            return
        room = s.street.length - side.start_offset
        why = (f"the {room:g} m from start + start_offset to the street's end are shorter than the minimum "
               f"width {layout.width[0]:g} m" if room < layout.width[0]
               else "every building fell inside a roadway or a building placed before it")
    else:
        why = ("the list is empty" if not layout
               else "every building fell inside a roadway or a building placed before it")
    print(f"envcap: warning: {source + ': ' if source else ''}{where}: no building placed ({why})", file=sys.stderr)


@dataclass
class _Building:
    """A building of a row before clipping: along-street extent [a0, a1] (m) and its sizes."""

    a0: float
    a1: float
    height: float
    depth: float
    setback: float
    albedo: tuple[float, ...]
    windows: bool


def _listed_buildings(s: StreetSpec, side: SideSpec, listed: tuple[BuildingSpec, ...]) -> list[_Building]:
    """An explicit list: each building ``gap`` after the previous one, from the side's start."""
    pos = s.street.start + side.start_offset
    out: list[_Building] = []
    for b in listed:
        pos += b.gap
        out.append(_Building(pos, pos + b.width, b.height, b.depth, b.setback, b.albedo, b.windows))
        pos += b.width
    return out


def _random_buildings(s: StreetSpec, side: SideSpec, r: RandomBuildingsSpec, rng: np.random.Generator) -> list[_Building]:
    """A random row from the side's start until ``count`` buildings or the street's end."""
    st = s.street
    pos = st.start + side.start_offset
    out: list[_Building] = []
    while r.count is None or len(out) < r.count:
        if r.gap_probability > 0 and rng.random() < r.gap_probability:
            pos += rng.uniform(*r.gap_width)
        w = rng.uniform(*r.width)
        if pos + w > st.end:
            w = st.end - pos
            if w < r.width[0]:
                break
        jit = side.facade.albedo_jitter
        alb = tuple(np.clip(np.asarray(side.facade.albedo) * rng.uniform(1 - jit, 1 + jit), 0.0, 1.0)) if jit else side.facade.albedo
        out.append(_Building(pos, pos + w, rng.uniform(*r.height), rng.uniform(*r.depth), rng.uniform(*r.setback), alb, True))
        pos += w
    return out


def _build_side(builder: MeshBuilder, s: StreetSpec, side: SideSpec, side_index: int, street_index: int,
                placed: GroundRects, stats: dict[str, int]) -> None:
    st = s.street
    a, c = st.along_index, st.cross_index
    sign = 1 if side_index == 0 else -1  # front-face normal along the cross axis (toward the street)
    plane = st.facade_min if side_index == 0 else st.facade_max
    rng = np.random.default_rng([side.seed, street_index, side_index])
    if side.layout is None:
        return
    if isinstance(side.layout, WallSpec):
        _build_wall(builder, s, side, side.layout, side_index)
        return
    if isinstance(side.layout, tuple):
        buildings = _listed_buildings(s, side, side.layout)
    else:
        buildings = _random_buildings(s, side, side.layout, rng)
    for b in buildings:
        front = plane - sign * b.setback
        back = front - sign * b.depth
        c0, c1 = min(front, back), max(front, back)
        for a0, a1 in clear_pieces(placed, a, b.a0, b.a1, c0, c1):
            placed.add_along(a, a0, a1, c0, c1)
            lo, hi = np.zeros(3), np.zeros(3)
            lo[a], hi[a], lo[c], hi[c], hi[1] = a0, a1, c0, c1, b.height
            builder.add_boxes(lo, hi, b.albedo)
            stats["buildings"] += 1
            if b.windows and side.facade.windows is not None:
                _add_windows(builder, side.facade.windows, a, c, sign, front, a0, a1, b.height, rng, stats)


def _add_windows(builder: MeshBuilder, w: WindowsSpec, a: int, c: int, sign: int, front: float,
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


def _build_wall(builder: MeshBuilder, s: StreetSpec, side: SideSpec, wall: WallSpec, side_index: int) -> None:
    """A continuous checkered facade exactly on the nominal plane, closed by a thin box behind."""
    st = s.street
    a, c = st.along_index, st.cross_index
    sign = 1 if side_index == 0 else -1
    plane = st.facade_min if side_index == 0 else st.facade_max
    a_edges = _tile_edges(st.start + side.start_offset, st.end, wall.tile)
    y_edges = _tile_edges(0.0, wall.height, wall.tile)
    ia, iy = np.meshgrid(np.arange(a_edges.size - 1), np.arange(y_edges.size - 1))
    ia, iy = ia.ravel(), iy.ravel()
    lo, hi = np.zeros((ia.size, 3)), np.zeros((ia.size, 3))
    lo[:, a], hi[:, a] = a_edges[ia], a_edges[ia + 1]
    lo[:, 1], hi[:, 1] = y_edges[iy], y_edges[iy + 1]
    alb = np.where(((ia + iy) % 2 == 0)[:, None], np.asarray(wall.albedo)[None], np.asarray(wall.albedo2)[None])
    builder.add_rects(c, sign, plane, lo, hi, alb)
    blo, bhi = np.zeros(3), np.zeros(3)
    blo[a], bhi[a] = a_edges[0], a_edges[-1]
    blo[c], bhi[c] = sorted((plane, plane - sign * wall.thickness))
    bhi[1] = wall.height
    faces = ["+y", "+x", "-x", "+z", "-z"]
    faces.remove(("+" if sign > 0 else "-") + "xyz"[c])  # the front is the checker
    builder.add_boxes(blo, bhi, wall.albedo, faces=tuple(faces))


def _tile_edges(lo: float, hi: float, tile: float) -> np.ndarray:
    """Edges of ``tile``-m tiles from ``lo`` to ``hi`` (the last one shortened); their count was
    bounded by :func:`~envcap.scene.estimate.check_geometry_budget`."""
    n = max(1, int(np.ceil((hi - lo) / tile - 1e-9)))
    e = lo + tile * np.arange(n + 1, dtype=np.float64)
    e[-1] = hi
    return e


def ground_center(spec: SceneSpec, parts: list[SceneMesh]) -> tuple[float, float]:
    """Plan centre (x, z), m, of the scene's ground quad: ``[ground] center``, else the middle of the
    box of the streets' corners and the imported meshes ``parts`` (procedural buildings left out)."""
    if spec.ground is not None and spec.ground.center is not None:
        return (float(spec.ground.center[0]), float(spec.ground.center[1]))
    pts = []
    for s in spec.streets:
        pts += [np.array([x, 0.0, z]) for x, z in s.street.plan_corners()]  # world, framed streets too
    for m in parts:
        if m.positions.size:
            pts += list(m.world_bounds())
    bb = np.array(pts) if pts else np.zeros((1, 3))
    cx, cz = 0.5 * (bb.min(0) + bb.max(0))[[0, 2]]
    return (float(cx), float(cz))


def _build_ground(builder: MeshBuilder, g: GroundSpec, center: tuple[float, float]) -> None:
    cx, cz = center
    h = 0.5 * g.extent
    if g.checker <= 0:
        builder.add_rects(1, 1, 0.0, (cx - h, 0, cz - h), (cx + h, 0, cz + h), g.albedo)
        return
    hc = 0.5 * min(g.checker_extent, g.extent)
    ex = _tile_edges(cx - hc, cx + hc, g.checker)
    ez = _tile_edges(cz - hc, cz + hc, g.checker)
    ix, iz = (v.ravel() for v in np.meshgrid(np.arange(ex.size - 1), np.arange(ez.size - 1)))
    lo, hi = np.zeros((ix.size, 3)), np.zeros((ix.size, 3))
    lo[:, 0], hi[:, 0], lo[:, 2], hi[:, 2] = ex[ix], ex[ix + 1], ez[iz], ez[iz + 1]
    alb = np.where(((ix + iz) % 2 == 0)[:, None], np.asarray(g.albedo)[None], np.asarray(g.albedo2)[None])
    builder.add_rects(1, 1, 0.0, lo, hi, alb)
    if hc < h:  # a ring of four plain quads out to the full extent
        ring_lo = [(cx - h, 0, cz - h), (cx - h, 0, cz + hc), (cx - h, 0, cz - hc), (cx + hc, 0, cz - hc)]
        ring_hi = [(cx + h, 0, cz - hc), (cx + h, 0, cz + h), (cx - hc, 0, cz + hc), (cx + h, 0, cz + hc)]
        builder.add_rects(1, 1, 0.0, ring_lo, ring_hi, g.albedo)
