"""Import triangle meshes (glTF/GLB, OBJ, PLY, Mitsuba 3 XML, or a directory of PLY files) into the envcap frame.

The transform from file coordinates ``p`` to envcap world coordinates (meters, +Y up) is,
in this order (see ``docs/scenes.md``)::

    1. scale:     p1 = scale * p
    2. up axis:   "y": p2 = p1;   "z": p2 = (x1, z1, -y1)   (rotation of -90 deg about +X)
    3. rotation:  p3 = R_y(rotation_deg) p2, right-handed about +Y
                  (x3 = x2 cos a + z2 sin a,  z3 = -x2 sin a + z2 cos a; +90 deg turns +Z into +X)
    4. offset:    p4 = p3 + offset

Geometry is made flat-shaded: every triangle gets its own three vertices and its face normal
(from the file's winding, counter-clockwise = front).  Degenerate (zero-area) triangles are
dropped.  Materials (vertex or face colors as sRGB, glTF / MTL / Mitsuba diffuse colours,
textures, emission) are read by :mod:`envcap.scene.mesh_surfaces` and
:mod:`envcap.scene.mitsuba_xml`; where a file has none, the default ``albedo`` is used.

After the transform, :func:`import_meshes` (see :mod:`envcap.scene.mesh_parts`) splits the
geometry into parts (each file's, or Mitsuba shape's, connected pieces), keeps the parts that
meet a crop box whole (``crop_by = "part"``) or the triangles that meet it (``"triangle"``:
terrain) and flips the parts wound inward (``winding = "auto"``),
or all of them (``"flip"``), or none (``"keep"``); the :class:`ImportReport` says what it did.

Errors are one line naming the file: whatever the loader (trimesh) raises becomes a ``ValueError``
``cannot read mesh file PATH: ...``; transformed vertices must lie within
:data:`~envcap.scene.limits.COORDINATE_LIMIT_M` of the origin on every axis.
"""

from __future__ import annotations

import hashlib

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core.checks import format_numbers
from envcap.scene.limits import COORDINATE_LIMIT_M
from envcap.scene.mesh_parts import component_labels, inward_parts, parts_meeting_box
from envcap.scene.mesh_select import mesh_files
from envcap.scene.mesh_surfaces import Surfaces, read_mesh_surfaces
from envcap.scene.mitsuba_xml import iter_mitsuba_surfaces
from envcap.scene.model import SceneMesh, Street, local_origin

CROP_MODES = ("part", "triangle")
"""``crop_by`` of :func:`import_meshes`: keep whole parts that meet the crop box, or triangles."""

WINDING_MODES = ("auto", "keep", "flip")
"""``winding`` of :func:`import_meshes`: flip the parts found wound inward, none, or all."""

IMPORT_CHUNK = 65536
"""Triangles transformed at a time (in place: the import holds one float64 copy of a file)."""


def import_transform(
    up_axis: str = "y",
    rotation_deg: float = 0.0,
    scale: float = 1.0,
    offset: Sequence[float] = (0.0, 0.0, 0.0),
) -> NDArray[np.float64]:
    """The 4x4 matrix (float64, column vectors: ``world = M @ [p, 1]``) of the import transform."""
    if up_axis not in ("y", "z"):
        raise ValueError(f"up_axis must be 'y' or 'z', got {up_axis!r}")
    vals = [rotation_deg, scale, *offset]
    if len(offset) != 3 or not np.all(np.isfinite(vals)):
        raise ValueError("rotation_deg, scale and offset (3 values) must be finite")
    if not scale > 0:
        raise ValueError(f"scale must be positive, got {scale}")
    s = np.diag([scale, scale, scale, 1.0])
    up = np.eye(4)
    if up_axis == "z":
        up[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]
    a = np.deg2rad(rotation_deg)
    ca, sa = np.cos(a), np.sin(a)
    rot = np.eye(4)
    rot[:3, :3] = [[ca, 0, sa], [0, 1, 0], [-sa, 0, ca]]
    t = np.eye(4)
    t[:3, 3] = offset
    return t @ rot @ up @ s


@dataclass(frozen=True)
class ImportReport:
    """What :func:`import_meshes` did: ``parts`` found (files' connected pieces), ``cropped``
    parts dropped by the crop box, ``flipped`` parts whose winding was reversed (``flipped_files``:
    their file names, each once), and ``below_ground``: the share (0..1) of the kept geometry's
    height range that lies below y = 0 (a Z-up file read as Y-up stands half under the ground).
    ``parts`` counts the parts kept, ``cropped`` those the crop dropped."""

    parts: int
    cropped: int
    flipped: int
    flipped_files: tuple[str, ...]
    below_ground: float
    notes: tuple[str, ...] = ()
    """What the readers took approximately or skipped (Mitsuba emitters, unsupported bsdfs, ...)."""


def import_mesh(
    path: str | Path,
    *,
    up_axis: str = "y",
    rotation_deg: float = 0.0,
    offset: Sequence[float] = (0.0, 0.0, 0.0),
    scale: float = 1.0,
    albedo: ArrayLike = (0.5, 0.5, 0.5),
    winding: str = "auto",
) -> SceneMesh:
    """Load a mesh file (or a directory of PLY files, concatenated) as a flat-shaded SceneMesh:
    :func:`import_meshes` of :func:`envcap.scene.mesh_select.mesh_files` ``(path)``, without a crop."""
    mesh, _ = import_meshes(mesh_files(Path(path)), up_axis=up_axis, rotation_deg=rotation_deg, offset=offset,
                            scale=scale, albedo=albedo, winding=winding, where=str(path))
    return mesh


def import_meshes(
    files: Sequence[Path],
    *,
    up_axis: str = "y",
    rotation_deg: float = 0.0,
    offset: Sequence[float] = (0.0, 0.0, 0.0),
    scale: float = 1.0,
    albedo: ArrayLike = (0.5, 0.5, 0.5),
    winding: str = "auto",
    crop: tuple[Sequence[float], Sequence[float]] | None = None,
    streets: Sequence[Street] = (),
    where: str = "mesh",
    emission_scale: float = 100.0,
    crop_by: str = "part",
    progress: Callable[[str, int], None] | None = None,
) -> tuple[SceneMesh, ImportReport]:
    """Load mesh ``files`` (concatenated, in order) as one flat-shaded SceneMesh, and what was done.

    See the module docstring for the transform order.  ``albedo`` (linear RGB in [0, 1]) is used
    where a file has no material of its own (see :mod:`envcap.scene.mesh_surfaces`: vertex colors,
    glTF / MTL / Mitsuba materials and textures; ``emission_scale`` converts emissive factors to
    radiance).  ``crop``: ``(min, max)`` world corners (m, after
    the transform); with ``crop_by = "part"`` the parts that meet it are kept whole (buildings),
    with ``"triangle"`` the triangles that meet it (terrain: a triangle is kept when its bounding
    box meets the crop box).  ``winding``: one of
    :data:`WINDING_MODES`; ``streets`` tell which way a facade sheet (a part enclosing no volume)
    should face (:func:`envcap.scene.mesh_parts.inward_parts`).  ``progress(name, triangles)`` is
    called after each file (each shape of a Mitsuba XML) is read.  Raises ``FileNotFoundError`` /
    ``ValueError`` (one line naming the file or ``where``; also for vertices past
    :data:`~envcap.scene.limits.COORDINATE_LIMIT_M`, or a crop that keeps nothing).
    """
    m4 = import_transform(up_axis, rotation_deg, scale, offset)
    if winding not in WINDING_MODES:
        raise ValueError(f"winding must be one of {list(WINDING_MODES)}, got {winding!r}")
    default_albedo = np.asarray(albedo, np.float64)
    if default_albedo.shape != (3,) or not np.all((default_albedo >= 0) & (default_albedo <= 1)):
        raise ValueError(f"albedo must be 3 values in [0, 1], got {albedo!r}")
    if crop_by not in CROP_MODES:
        raise ValueError(f"crop_by must be one of {list(CROP_MODES)}, got {crop_by!r}")
    pieces: list[_Piece] = []
    notes: list[str] = []
    span_lo, span_hi = np.full(3, np.inf), np.full(3, -np.inf)
    for f in files:   # one file (or Mitsuba shape) at a time: only the prepared triangles stay in memory
        f = Path(f)
        file_notes: list[str] = []
        if f.suffix.lower() == ".xml":
            shapes: Iterable[Surfaces] = iter_mitsuba_surfaces(f, default_albedo, emission_scale, file_notes)
        else:
            shapes = [read_mesh_surfaces(f, default_albedo, emission_scale)]
        for surf in shapes:
            file_notes += surf.notes
            piece = _prepare(surf, m4, where, scale, offset, crop, crop_by, winding, streets)
            span_lo, span_hi = np.minimum(span_lo, piece.span[0]), np.maximum(span_hi, piece.span[1])
            pieces.append(piece)
            if progress is not None:
                progress(surf.sources[0][0] if surf.sources else f.name, int(piece.tri.shape[0]))
            del surf
        notes += [f"{f.name}: {n}" for n in file_notes]
    parts = sum(p.parts for p in pieces)
    if crop is not None and parts == 0:
        raise ValueError(f"{where}: the crop box {format_numbers(crop[0])} .. {format_numbers(crop[1])} meets none of "
                         f"the {sum(p.cropped for p in pieces)} parts (the mesh spans {format_numbers(np.round(span_lo, 2))} "
                         f".. {format_numbers(np.round(span_hi, 2))} after the transform)")
    if not sum(p.tri.shape[0] for p in pieces):
        raise ValueError(f"mesh {where} has only degenerate (zero-area) triangles")
    y_lo = min(float(p.tri[..., 1].min()) for p in pieces if p.tri.shape[0])
    y_hi = max(float(p.tri[..., 1].max()) for p in pieces if p.tri.shape[0])
    below = 0.0 if y_lo >= 0 else (min(0.0, y_hi) - y_lo) / max(y_hi - y_lo, 1e-300)
    flipped_files = tuple(dict.fromkeys(name for p in pieces for name in p.flipped_files))
    report = ImportReport(parts, sum(p.cropped for p in pieces), sum(p.flipped for p in pieces), flipped_files,
                          below, tuple(notes))
    return _assemble(pieces), report


@dataclass
class _Piece:
    """One file after the transform, crop, winding fix and degenerate filter: ``tri`` (T, 3, 3)
    float64 world m, ``albedo``/``emission`` (T, 3, 3) float32, ``normals`` (T, 3) float32 unit,
    ``uvl`` (T, 3, 3) or None, its ``textures``; counts for the report; ``span`` its world box
    before the crop."""

    tri: NDArray[np.float64] | None
    albedo: NDArray[np.float32] | None
    emission: NDArray[np.float32] | None
    normals: NDArray[np.float32] | None
    uvl: NDArray[np.float32] | None
    textures: list[NDArray[np.uint8]]
    parts: int
    cropped: int
    flipped: int
    flipped_files: list[str]
    span: tuple[NDArray[np.float64], NDArray[np.float64]]


def _prepare(surf: Surfaces, m4: NDArray[np.float64], where: str, scale: float, offset: Sequence[float],
             crop: tuple[Sequence[float], Sequence[float]] | None, crop_by: str, winding: str,
             streets: Sequence[Street]) -> _Piece:
    """A file's :class:`Surfaces` (modified in place) as a :class:`_Piece`."""
    tri, alb, emission, uvl = surf.tri, surf.albedo, surf.emission, surf.uvl
    rot, shift = m4[:3, :3].T, m4[:3, 3]
    with np.errstate(over="ignore", invalid="ignore"):
        for i in range(0, tri.shape[0], IMPORT_CHUNK):      # in place, a chunk at a time: no second copy
            tri[i:i + IMPORT_CHUNK] = tri[i:i + IMPORT_CHUNK] @ rot + shift
        reach = float(np.max(np.abs(tri)))
    if not reach <= COORDINATE_LIMIT_M:  # also NaN / inf (overflow)
        raise ValueError(f"{where}: vertices reach {reach:.10g} m after the import transform (scale {scale:g}, "
                         f"offset {format_numbers(offset)}), beyond the coordinate limit of +-{COORDINATE_LIMIT_M:g} m; "
                         f"change scale or offset")
    span = (tri.min(axis=(0, 1)), tri.max(axis=(0, 1)))
    names = [name for name, _ in surf.sources]              # a file, or a Mitsuba shape's file
    sizes = [count for _, count in surf.sources]
    source_of = np.repeat(np.arange(len(sizes), dtype=np.int32), sizes)
    part = np.zeros(tri.shape[0], np.int32)
    start, parts = 0, 0
    for size in sizes:                                      # parts never span two sources
        labels = component_labels(tri[start:start + size])
        part[start:start + size] = labels + parts
        parts += int(labels.max(initial=-1)) + 1
        start += size
    cropped = 0
    if crop is not None:
        if crop_by == "part":
            keep = parts_meeting_box(tri, part, crop[0], crop[1])
        else:
            lo, hi = np.asarray(crop[0], np.float64), np.asarray(crop[1], np.float64)
            keep = np.all((tri.max(axis=1) >= lo) & (tri.min(axis=1) <= hi), axis=1)
        tri, alb, emission, source_of = tri[keep], alb[keep], emission[keep], source_of[keep]
        uvl = uvl[keep] if uvl is not None else None
        part = np.unique(part[keep], return_inverse=True)[1].reshape(-1)
        kept = int(part.max(initial=-1)) + 1
        cropped, parts = parts - kept, kept
    flip_part = np.zeros(parts, bool)
    if winding == "flip":
        flip_part[:] = True
    elif winding == "auto" and parts:
        flip_part = inward_parts(tri, part, streets)
    flip = flip_part[part]
    if np.any(flip):
        tri[flip] = tri[flip][:, [0, 2, 1]]
        alb[flip] = alb[flip][:, [0, 2, 1]]
        emission[flip] = emission[flip][:, [0, 2, 1]]
        if uvl is not None:
            uvl[flip] = uvl[flip][:, [0, 2, 1]]
    flipped_files = list(dict.fromkeys(names[i] for i in source_of[flip]))
    flipped = int(np.unique(part[flip]).size)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1)
    scale_ref = max(float(np.abs(tri).max(initial=0.0)), 1.0)
    keep = length > 1e-12 * scale_ref * scale_ref
    if not np.all(keep):
        tri, alb, emission = tri[keep], alb[keep], emission[keep]
        uvl = uvl[keep] if uvl is not None else None
    normals = (n[keep] / length[keep, None]).astype(np.float32)
    return _Piece(tri, _compact(alb), _compact(emission), normals, uvl, surf.textures if uvl is not None else [], parts, cropped,
                  flipped, flipped_files, span)


def _compact(corners: NDArray[np.float32]) -> NDArray[np.float32]:
    """``corners`` (T, 3, 3), or a read-only broadcast of its one value when every corner has the
    same (a file with one material): no memory until the mesh is assembled."""
    flat = corners.reshape(-1, 3)
    if flat.shape[0] and np.all(flat == flat[0]):
        return np.broadcast_to(flat[0].copy(), corners.shape)
    return corners


def _assemble(pieces: list[_Piece]) -> SceneMesh:
    """The flat-shaded SceneMesh of ``pieces``, as :meth:`SceneMesh.from_world` would make it
    (positions relative to the :func:`local_origin` of their bounds, in float64, rounded to
    float32 once), filling one output array at a time and freeing each piece's input to it."""
    t = sum(p.tri.shape[0] for p in pieces)
    lo = np.min([p.tri.reshape(-1, 3).min(axis=0) for p in pieces if p.tri.shape[0]], axis=0)
    hi = np.max([p.tri.reshape(-1, 3).max(axis=0) for p in pieces if p.tri.shape[0]], axis=0)
    origin = local_origin(lo, hi)
    bounds = np.cumsum([0] + [3 * p.tri.shape[0] for p in pieces])

    def fill(name: str, per_corner: Callable[[NDArray[np.floating]], NDArray[np.floating]]) -> NDArray[np.float32]:
        out = np.empty((3 * t, 3), np.float32)
        for p, a, b in zip(pieces, bounds[:-1], bounds[1:]):
            out[a:b] = per_corner(getattr(p, name))
            setattr(p, name, None)            # freed as soon as copied: one output array at a time
        return out

    def points(tri: NDArray[np.float64]) -> NDArray[np.float64]:
        pts = tri.reshape(-1, 3)
        pts -= origin
        return pts

    positions = fill("tri", points)
    normals = fill("normals", lambda n: np.repeat(n, 3, axis=0))
    albedo = fill("albedo", lambda a: a.reshape(-1, 3))
    emission = fill("emission", lambda e: e.reshape(-1, 3))
    uv_layer, textures = None, None
    if any(p.uvl is not None and p.textures for p in pieces):
        distinct: dict[bytes, int] = {}           # one layer per distinct image, however many files use it
        stack: list[NDArray[np.uint8]] = []
        uv_layer = np.zeros((3 * t, 3), np.float32)
        uv_layer[:, 2] = -1.0                     # untextured: (0, 0) at layer -1
        for p, a, b in zip(pieces, bounds[:-1], bounds[1:]):
            if p.uvl is None or not p.textures:
                continue
            index = []
            for tex in p.textures:
                key = hashlib.sha256(tex.tobytes()).digest()
                if key not in distinct:
                    distinct[key] = len(stack)
                    stack.append(tex)
                index.append(distinct[key])
            remap = np.asarray(index + [-1], np.float32)                # layer -1 stays -1
            uvl = p.uvl.reshape(-1, 3)
            uv_layer[a:b, :2] = np.nan_to_num(uvl[:, :2], nan=0.0)      # no coordinates: (0, 0)
            uv_layer[a:b, 2] = remap[uvl[:, 2].astype(np.int64)]
            p.uvl = None
        textures = np.stack(stack)
    return SceneMesh(positions, normals, albedo, emission, np.arange(3 * t, dtype=np.uint32).reshape(t, 3), origin,
                     uv_layer, textures)
