"""Import triangle meshes (glTF/GLB, OBJ, PLY, or a directory of PLY files) into the envcap frame.

The transform from file coordinates ``p`` to envcap world coordinates (meters, +Y up) is,
in this order (see ``docs/scenes.md``)::

    1. scale:     p1 = scale * p
    2. up axis:   "y": p2 = p1;   "z": p2 = (x1, z1, -y1)   (rotation of -90 deg about +X)
    3. rotation:  p3 = R_y(rotation_deg) p2, right-handed about +Y
                  (x3 = x2 cos a + z2 sin a,  z3 = -x2 sin a + z2 cos a; +90 deg turns +Z into +X)
    4. offset:    p4 = p3 + offset

Geometry is made flat-shaded: every triangle gets its own three vertices and its face normal
(from the file's winding, counter-clockwise = front).  Degenerate (zero-area) triangles are
dropped.  Vertex or face colors, if present, are read as sRGB and become linear albedo;
otherwise the default ``albedo`` is used.  Imported meshes have no emission.

Errors are one line naming the file: whatever the loader (trimesh) raises becomes a ``ValueError``
``cannot read mesh file PATH: ...``; transformed vertices must lie within
:data:`~envcap.scene.limits.COORDINATE_LIMIT_M` of the origin on every axis.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.scene.geometry import srgb_to_linear
from envcap.scene.limits import COORDINATE_LIMIT_M
from envcap.scene.model import SceneMesh

MESH_SUFFIXES = (".glb", ".gltf", ".obj", ".ply", ".stl", ".off")


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


def _load_trimesh(path: Path) -> Any:
    """The file as a ``trimesh.Trimesh``; any failure of the loader (a bad file, a module trimesh
    needs and cannot import, memory) is a one-line ``ValueError`` naming the file."""
    try:
        import trimesh  # heavy (~0.8 s): imported only when a mesh is actually read

        m = trimesh.load(str(path), force="mesh", process=False)
    except Exception as exc:  # trimesh raises many kinds, and its optional imports may fail
        raise ValueError(f"cannot read mesh file {path}: {_one_line(exc)}") from None
    if not isinstance(m, trimesh.Trimesh) or len(m.faces) == 0:
        raise ValueError(f"mesh file {path} has no triangles")
    return m


def _one_line(exc: Exception, limit: int = 300) -> str:
    """``Type: message`` on one line, at most ``limit`` characters."""
    text = " ".join(f"{type(exc).__name__}: {exc}".split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _read(path: Path, default_albedo: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`_flat` of the file; a failure reading its arrays (odd visuals, bad indices) names the file."""
    m = _load_trimesh(path)
    try:
        finite = bool(np.all(np.isfinite(np.asarray(m.vertices, np.float64))))
        flat = _flat(m, default_albedo) if finite else None
    except Exception as exc:
        raise ValueError(f"cannot read mesh file {path}: {_one_line(exc)}") from None
    if flat is None:
        raise ValueError(f"mesh file {path} has NaN or Inf vertex positions")
    return flat


def _flat(m: Any, default_albedo: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per-corner positions (T, 3, 3) and albedo (T, 3, 3) of a trimesh."""
    v = np.asarray(m.vertices, np.float64)
    f = np.asarray(m.faces, np.int64)
    tri = v[f]
    alb = np.broadcast_to(default_albedo, tri.shape).copy()
    kind = getattr(m.visual, "kind", None)
    if kind == "vertex":
        vc = np.asarray(m.visual.vertex_colors)[:, :3] / 255.0
        alb = srgb_to_linear(vc)[f]
    elif kind == "face":
        fc = np.asarray(m.visual.face_colors)[:, :3] / 255.0
        alb = np.repeat(srgb_to_linear(fc)[:, None, :], 3, axis=1)
    return tri, alb


def mesh_files(path: Path) -> list[Path]:
    """The mesh files a ``[mesh] file`` names: the file itself, or a directory's ``*.ply`` sorted."""
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() == ".ply" and p.is_file())
        if not files:
            raise ValueError(f"mesh directory {path} contains no .ply files")
        return files
    if not path.is_file():
        raise FileNotFoundError(f"mesh file {path} not found")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise ValueError(f"mesh file {path}: unsupported type '{path.suffix}' (use one of {', '.join(MESH_SUFFIXES)})")
    return [path]


def import_mesh(
    path: str | Path,
    *,
    up_axis: str = "y",
    rotation_deg: float = 0.0,
    offset: Sequence[float] = (0.0, 0.0, 0.0),
    scale: float = 1.0,
    albedo: ArrayLike = (0.5, 0.5, 0.5),
) -> SceneMesh:
    """Load a mesh file (or a directory of PLY files, concatenated) as a flat-shaded SceneMesh.

    See the module docstring for the transform order.  ``albedo`` (linear RGB in [0, 1]) is used
    where the file has no vertex or face colors.  Raises ``FileNotFoundError`` / ``ValueError``
    (one line naming the file; also for vertices past :data:`~envcap.scene.limits.COORDINATE_LIMIT_M`).
    """
    m4 = import_transform(up_axis, rotation_deg, scale, offset)
    default_albedo = np.asarray(albedo, np.float64)
    if default_albedo.shape != (3,) or not np.all((default_albedo >= 0) & (default_albedo <= 1)):
        raise ValueError(f"albedo must be 3 values in [0, 1], got {albedo!r}")
    tris, albs = [], []
    for f in mesh_files(Path(path)):
        t, a = _read(f, default_albedo)
        tris.append(t)
        albs.append(a)
    tri = np.concatenate(tris)
    alb = np.concatenate(albs)
    with np.errstate(over="ignore", invalid="ignore"):
        tri = tri @ m4[:3, :3].T + m4[:3, 3]
        reach = float(np.max(np.abs(tri)))
    if not reach <= COORDINATE_LIMIT_M:  # also NaN / inf (overflow)
        raise ValueError(f"{path}: vertices reach {reach:.10g} m after the import transform (scale {scale:g}, "
                         f"offset {list(offset)}), beyond the coordinate limit of +-{COORDINATE_LIMIT_M:g} m; "
                         f"change scale or offset")
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1)
    scale_ref = max(float(np.abs(tri).max()), 1.0)
    keep = length > 1e-12 * scale_ref * scale_ref
    if not np.any(keep):
        raise ValueError(f"mesh {path} has only degenerate (zero-area) triangles")
    tri, alb, n = tri[keep], alb[keep], n[keep] / length[keep, None]
    t = tri.shape[0]
    return SceneMesh.from_world(tri.reshape(-1, 3), np.repeat(n, 3, axis=0), alb.reshape(-1, 3),
                                np.zeros((3 * t, 3)), np.arange(3 * t, dtype=np.uint32).reshape(t, 3))
