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
geometry into parts (each file's connected pieces), keeps the parts that meet a crop box (whole:
terrain is not clipped per triangle yet) and flips the parts wound inward (``winding = "auto"``),
or all of them (``"flip"``), or none (``"keep"``); the :class:`ImportReport` says what it did.

Errors are one line naming the file: whatever the loader (trimesh) raises becomes a ``ValueError``
``cannot read mesh file PATH: ...``; transformed vertices must lie within
:data:`~envcap.scene.limits.COORDINATE_LIMIT_M` of the origin on every axis.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.scene.limits import COORDINATE_LIMIT_M
from envcap.scene.mesh_parts import component_labels, inward_parts, parts_meeting_box
from envcap.scene.mesh_select import mesh_files
from envcap.scene.mesh_surfaces import Surfaces, read_mesh_surfaces
from envcap.scene.mitsuba_xml import read_mitsuba_surfaces
from envcap.scene.model import SceneMesh, Street

CROP_MODES = ("part", "triangle")
"""``crop_by`` of :func:`import_meshes`: keep whole parts that meet the crop box, or triangles."""

WINDING_MODES = ("auto", "keep", "flip")
"""``winding`` of :func:`import_meshes`: flip the parts found wound inward, none, or all."""


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


def read_surfaces(path: Path, default_albedo: NDArray[np.float64], emission_scale: float = 100.0) -> Surfaces:
    """Per-corner triangles and materials of a mesh file or a Mitsuba scene XML
    (:mod:`envcap.scene.mesh_surfaces`, :mod:`envcap.scene.mitsuba_xml`); failures name the file."""
    if path.suffix.lower() == ".xml":
        return read_mitsuba_surfaces(path, default_albedo, emission_scale)
    return read_mesh_surfaces(path, default_albedo, emission_scale)


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
    should face (:func:`envcap.scene.mesh_parts.inward_parts`).  Raises ``FileNotFoundError`` /
    ``ValueError`` (one line naming the file or ``where``; also for vertices past
    :data:`~envcap.scene.limits.COORDINATE_LIMIT_M`, or a crop that keeps nothing).
    """
    m4 = import_transform(up_axis, rotation_deg, scale, offset)
    if winding not in WINDING_MODES:
        raise ValueError(f"winding must be one of {list(WINDING_MODES)}, got {winding!r}")
    default_albedo = np.asarray(albedo, np.float64)
    if default_albedo.shape != (3,) or not np.all((default_albedo >= 0) & (default_albedo <= 1)):
        raise ValueError(f"albedo must be 3 values in [0, 1], got {albedo!r}")
    surfaces = [read_surfaces(Path(f), default_albedo, emission_scale) for f in files]
    joined = Surfaces.join(surfaces)
    source_names = [name for name, _ in joined.sources]     # a file, or a Mitsuba shape's file
    sizes = [count for _, count in joined.sources]
    file_of = np.repeat(np.arange(len(sizes)), sizes)
    tri, alb, emission, uvl = joined.tri, joined.albedo, joined.emission, joined.uvl
    notes = tuple(f"{Path(f).name}: {n}" for f, sf in zip(files, surfaces) for n in sf.notes)
    with np.errstate(over="ignore", invalid="ignore"):
        tri = tri @ m4[:3, :3].T + m4[:3, 3]
        reach = float(np.max(np.abs(tri)))
    if not reach <= COORDINATE_LIMIT_M:  # also NaN / inf (overflow)
        raise ValueError(f"{where}: vertices reach {reach:.10g} m after the import transform (scale {scale:g}, "
                         f"offset {list(offset)}), beyond the coordinate limit of +-{COORDINATE_LIMIT_M:g} m; "
                         f"change scale or offset")
    part = np.zeros(tri.shape[0], np.int64)
    start, parts = 0, 0
    for size in sizes:
        labels = component_labels(tri[start:start + size])
        part[start:start + size] = labels + parts
        parts += int(labels.max(initial=-1)) + 1
        start += size
    cropped = 0
    if crop_by not in CROP_MODES:
        raise ValueError(f"crop_by must be one of {list(CROP_MODES)}, got {crop_by!r}")
    if crop is not None:
        if crop_by == "part":
            keep = parts_meeting_box(tri, part, crop[0], crop[1])
        else:
            lo, hi = np.asarray(crop[0], np.float64), np.asarray(crop[1], np.float64)
            keep = np.all((tri.max(axis=1) >= lo) & (tri.min(axis=1) <= hi), axis=1)
        if not np.any(keep):
            raise ValueError(f"{where}: the crop box {list(crop[0])} .. {list(crop[1])} meets none of the {parts} parts "
                             f"(the mesh spans {list(np.round(tri.min(axis=(0, 1)), 2))} .. "
                             f"{list(np.round(tri.max(axis=(0, 1)), 2))} after the transform)")
        tri, alb, emission, file_of = tri[keep], alb[keep], emission[keep], file_of[keep]
        uvl = uvl[keep] if uvl is not None else None
        part = np.unique(part[keep], return_inverse=True)[1].reshape(-1)
        cropped, parts = parts - int(part.max()) - 1, int(part.max()) + 1
    flip_part = np.zeros(parts, bool)
    if winding == "flip":
        flip_part[:] = True
    elif winding == "auto":
        flip_part = inward_parts(tri, part, streets)
    flip = flip_part[part]
    if np.any(flip):
        tri[flip] = tri[flip][:, [0, 2, 1]]
        alb[flip] = alb[flip][:, [0, 2, 1]]
        emission[flip] = emission[flip][:, [0, 2, 1]]
        if uvl is not None:
            uvl[flip] = uvl[flip][:, [0, 2, 1]]
    flipped_files = tuple(dict.fromkeys(source_names[i] for i in file_of[flip]))
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1)
    scale_ref = max(float(np.abs(tri).max()), 1.0)
    keep = length > 1e-12 * scale_ref * scale_ref
    if not np.any(keep):
        raise ValueError(f"mesh {where} has only degenerate (zero-area) triangles")
    tri, alb, emission, n = tri[keep], alb[keep], emission[keep], n[keep] / length[keep, None]
    t = tri.shape[0]
    y_lo, y_hi = float(tri[..., 1].min()), float(tri[..., 1].max())
    below = 0.0 if y_lo >= 0 else (min(0.0, y_hi) - y_lo) / max(y_hi - y_lo, 1e-300)
    report = ImportReport(parts, cropped, int(np.unique(part[flip]).size), flipped_files, below, notes)
    mesh = SceneMesh.from_world(tri.reshape(-1, 3), np.repeat(n, 3, axis=0), alb.reshape(-1, 3),
                                emission.reshape(-1, 3), np.arange(3 * t, dtype=np.uint32).reshape(t, 3))
    if uvl is not None and joined.textures:
        mesh = dataclasses.replace(mesh, uv_layer=uvl[keep].reshape(-1, 3), textures=np.stack(joined.textures))
    return mesh, report
