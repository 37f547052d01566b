"""The scene near the streets as a binary glTF 2.0 file (``scene.glb``), for viewers.

:func:`crop_to_streets` keeps the triangles whose horizontal (x, z) bounding box overlaps a
street's box (along ``[start, end]``, across ``[facade_min, facade_max]``) grown by ``pad_m``
meters, so a city's file holds only what a street-level view sees.  :func:`write_scene_glb`
writes a mesh with trimesh's glTF exporter:

* one node ``scene`` whose ``matrix`` translates by the mesh origin (world meters, float64 in
  the JSON), one mesh of one triangle primitive; ``POSITION`` are float32 meters relative to
  that origin (the :class:`~envcap.scene.model.SceneMesh` positions, unchanged), so a world
  position is ``origin + POSITION`` (float64); the origin is also in
  ``scenes[0].extras.envcap.origin``;
* ``NORMAL``: the flat-shading normals (float32, facing the lit side);
* ``COLOR_0``: the linear diffuse albedo, RGBA8 normalized (glTF colours are linear), alpha 1;
  a textured mesh's textures are not exported (its albedo factor is);
* ``_EMISSION`` (only when some vertex emits): emitted radiance, linear RGB float32 in the sky's
  units (``envcap.sky.base``), a glTF application-specific attribute.

Axes are glTF's (+Y up, right-handed, meters), the same as envcap's world frame.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.core.street_frame import frame_to_world
from envcap.scene.model import SceneMesh

SCENE_GLB = "scene.glb"
"""The file name inside a probe-set directory."""

DEFAULT_PAD_M = 60.0
"""How far beyond each street's box (m, horizontally) :func:`crop_to_streets` keeps geometry."""


def street_boxes(streets: Sequence[Any], pad_m: float = DEFAULT_PAD_M) -> NDArray[np.float64]:
    """World x-z boxes ``(S, 4)`` float64 ``[x0, x1, z0, z1]`` meters of ``streets`` (objects with
    ``axis`` "x"|"z", ``start``, ``end`` and ``facade_min``, ``facade_max`` themselves (a scene
    street) or in ``planes`` (a manifest street)), each grown by ``pad_m`` >= 0 meters on every side;
    a framed street (``yaw_deg``/``origin_xz``) gives the world box of its turned rectangle."""
    if not (np.isfinite(pad_m) and pad_m >= 0):
        raise ValueError(f"scene crop padding must be a finite number of meters >= 0, got {pad_m!r}")
    out = []
    for st in streets:
        along = (float(st.start) - pad_m, float(st.end) + pad_m)
        fac = getattr(st, "planes", st)
        across = (float(fac.facade_min) - pad_m, float(fac.facade_max) + pad_m)
        yaw = float(getattr(st, "frame_yaw_deg", getattr(st, "yaw_deg", 0.0)))
        origin = tuple(getattr(st, "frame_origin_xz", getattr(st, "origin_xz", (0.0, 0.0))))
        if st.axis == "x" and (yaw != 0.0 or tuple(origin) != (0.0, 0.0)):  # a framed street: its world plan box
            xz = frame_to_world([[a, 0.0, c] for a in along for c in across], yaw, origin)[:, [0, 2]]
            out.append([xz[:, 0].min(), xz[:, 0].max(), xz[:, 1].min(), xz[:, 1].max()])
        elif st.axis == "x":
            out.append([*along, *across])
        elif st.axis == "z":
            out.append([*across, *along])
        else:
            raise ValueError(f"street {getattr(st, 'name', '?')!r}: axis must be 'x' or 'z', got {st.axis!r}")
    return np.array(out, np.float64).reshape(-1, 4)


def crop_to_streets(mesh: SceneMesh, streets: Sequence[Any], pad_m: float = DEFAULT_PAD_M) -> SceneMesh:
    """The triangles of ``mesh`` whose world x-z bounding box overlaps a padded street box
    (:func:`street_boxes`), with only the vertices they use (reindexed in order); the origin,
    float32 positions and attributes are ``mesh``'s own (no rounding)."""
    boxes = street_boxes(streets, pad_m)
    if not boxes.shape[0]:
        raise ValueError("cannot crop the scene to the streets: there are no streets")
    tri = mesh.positions[mesh.indices].astype(np.float64) + mesh.origin  # (T, 3, 3) world m
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    keep = np.zeros(tri.shape[0], bool)
    for x0, x1, z0, z1 in boxes:
        keep |= (lo[:, 0] <= x1) & (hi[:, 0] >= x0) & (lo[:, 2] <= z1) & (hi[:, 2] >= z0)
    idx = mesh.indices[keep]
    used, inverse = np.unique(idx.ravel(), return_inverse=True)
    pick = (lambda a: None if a is None else a[used])
    return SceneMesh(mesh.positions[used], mesh.normals[used], mesh.albedo[used], mesh.emission[used],
                     inverse.reshape(-1, 3).astype(np.uint32), mesh.origin, pick(mesh.uv_layer),
                     None if mesh.textures is None else mesh.textures)


def write_scene_glb(path: str | os.PathLike[str], mesh: SceneMesh) -> Path:
    """Write ``mesh`` as binary glTF at ``path`` (the layout in the module docstring); return
    the path.  ``ValueError`` for a mesh without triangles or albedo outside [0, 1]."""
    import trimesh  # a heavy import, only when a glTF file is written

    if not mesh.triangle_count:
        raise ValueError(f"{path}: the scene has no triangles near the streets to export")
    if mesh.albedo.size and (mesh.albedo.min() < 0 or mesh.albedo.max() > 1):
        raise ValueError(f"{path}: scene albedo must lie in [0, 1], got [{mesh.albedo.min()}, {mesh.albedo.max()}]")
    rgba = np.empty((mesh.positions.shape[0], 4), np.uint8)
    rgba[:, :3] = np.round(mesh.albedo * 255.0).astype(np.uint8)
    rgba[:, 3] = 255
    tm = trimesh.Trimesh(vertices=mesh.positions, faces=mesh.indices.astype(np.int64), process=False,
                         vertex_normals=mesh.normals, vertex_colors=rgba)
    if np.any(mesh.emission != 0):
        tm.vertex_attributes["_EMISSION"] = mesh.emission.astype(np.float32)
    origin = [float(v) for v in mesh.origin]
    scene = trimesh.Scene()
    scene.add_geometry(tm, node_name="scene", geom_name="scene",
                       transform=trimesh.transformations.translation_matrix(origin))
    scene.metadata["envcap"] = {"origin": origin, "units": "meters", "albedo": "COLOR_0 linear",
                                "emission": "_EMISSION linear RGB, sky units"}
    p = Path(path)
    p.write_bytes(scene.export(file_type="glb", include_normals=True))
    return p
