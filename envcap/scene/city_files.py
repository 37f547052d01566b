"""Write a generated city (:mod:`envcap.scene.city_layout`) as a real city export would look.

The files are what OpenStreetMap -> Blender / Mitsuba pipelines produce, hard parts included:

* ``buildings/NAME.ply``: one binary PLY per building, **Z-up** (file x = east = world x, file
  y = north = -world z, file z = up = world y), in **projected coordinates** (file = world +
  ``PROJECTED_OFFSET``: about 512 km east, 5403 km north, float64 vertices), every
  ``inward_every``-th building **wound inward**;
* ``terrain.ply``: the terrain as a height-field grid (``terrain_cell`` m), same frame;
* ``textured/facade_house.glb``: one building as glTF 2.0 (+Y up as its spec says, local
  coordinates around the house: its own transform, in ``truth.json``) with a
  ``baseColorTexture`` (a window grid), a ``baseColorFactor`` and an ``emissiveFactor``;
  ``textured/obj_house.obj`` + ``.mtl``: one as OBJ (Z-up, projected, like the PLYs) with ``Kd``
  and ``map_Kd`` (these two are left out of ``buildings/``);
* ``city.xml``: a Mitsuba 3 scene: a ``diffuse`` bsdf per material (one ``twosided``, the OBJ's
  with a ``bitmap`` texture), a ``ply``/``obj`` shape per file referencing its bsdf, a
  ``to_world`` transform on the terrain (identity translate), and two emitters (``constant``,
  ``directional``) that an importer should report and skip;
* ``truth.json``: the frame (how to bring the files into envcap's frame: ``up_axis = "z"``,
  ``offset``), the streets' truth, the inward files, triangle counts.

To import: ``up_axis = "z"``, ``offset = [-E0, 0, N0]`` (see ``truth.json`` ``frame``).
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from envcap.scene.city_layout import MATERIALS, TERRAIN_ALBEDO, TERRAIN_MATERIAL, Building, CityLayout

PROJECTED_OFFSET = (512_000.0, 5_403_000.0)
"""(east, north) meters added to world (x, -z) in the files: projected coordinates (UTM-like)."""

TEXTURED_GLTF = 3
TEXTURED_OBJ = 5
"""Indices of the two grid buildings written textured (glTF, OBJ + MTL) instead of as PLY."""


def world_to_file(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """World (x, y, z) -> file (east, north, up) in projected coordinates, shape (..., 3)."""
    p = np.asarray(points, dtype=np.float64)
    return np.stack([p[..., 0] + PROJECTED_OFFSET[0], -p[..., 2] + PROJECTED_OFFSET[1], p[..., 1]], axis=-1)


def building_mesh(b: Building, cells: int = 1) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
    """World-frame triangles of a box building: its four walls (each ``cells`` x ``cells`` quads)
    and its roof, wound outward (counter-clockwise seen from outside).  Returns vertices (V, 3),
    faces (F, 3) and per-vertex texture coordinates (V, 2) in meters (along the wall, up)."""
    fp = b.footprint
    centroid = fp.mean(axis=0)
    verts: list[NDArray[np.float64]] = []
    uvs: list[NDArray[np.float64]] = []
    faces: list[tuple[int, int, int]] = []
    along = 0.0
    for k in range(4):
        a, c = fp[k], fp[(k + 1) % 4]
        outward = np.array([c[1] - a[1], -(c[0] - a[0])])
        flip = float(outward @ ((a + c) / 2.0 - centroid)) > 0.0  # (c - a) x up points the other way
        span = float(np.hypot(*(c - a)))
        s = np.linspace(0.0, 1.0, cells + 1)
        y = np.linspace(b.base, b.top, cells + 1)
        base = sum(len(v) for v in verts)
        grid = np.array([[a[0] + t * (c[0] - a[0]), yy, a[1] + t * (c[1] - a[1])] for yy in y for t in s])
        verts.append(grid)
        uvs.append(np.array([[along + t * span, yy - b.base] for yy in y for t in s]))
        along += span
        n = cells + 1
        for r in range(cells):
            for q in range(cells):
                i0, i1, i2, i3 = base + r * n + q, base + r * n + q + 1, base + (r + 1) * n + q + 1, base + (r + 1) * n + q
                tris = [(i0, i1, i2), (i0, i2, i3)]
                faces.extend([(t[0], t[2], t[1]) for t in tris] if flip else tris)
    base = sum(len(v) for v in verts)
    roof = np.array([[p[0], b.top, p[1]] for p in fp])
    verts.append(roof)
    uvs.append(fp - fp.min(axis=0))
    tris = [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    v = roof
    up = np.cross(v[1] - v[0], v[2] - v[0])[1] > 0.0
    faces.extend(tris if up else [(t[0], t[2], t[1]) for t in tris])
    return np.concatenate(verts), np.asarray(faces, dtype=np.int64), np.concatenate(uvs)


def terrain_mesh(layout: CityLayout, cell: float) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """World-frame height-field grid over the layout's bounds (``cell`` m), wound up (+Y)."""
    x0, z0, x1, z1 = layout.bounds
    xs = np.arange(x0, x1 + cell, cell)
    zs = np.arange(z0, z1 + cell, cell)
    gx, gz = np.meshgrid(xs, zs)
    verts = np.stack([gx, layout.terrain_height(gx, gz), gz], axis=-1).reshape(-1, 3)
    nx = len(xs)
    i = (np.arange(len(zs) - 1)[:, None] * nx + np.arange(nx - 1)[None, :]).ravel()
    # corners (x, z) -> (x, z+1) -> (x+1, z): (dz x dx) points up (+Y)
    faces = np.concatenate([np.stack([i, i + nx, i + 1], 1), np.stack([i + 1, i + nx, i + nx + 1], 1)])
    return verts, faces.astype(np.int64)


def window_texture(size: int = 64) -> Image.Image:
    """A facade texture (sRGB): pale wall with a 2 x 2 grid of dark windows (one 4 m x 3.5 m bay)."""
    img = np.full((size, size, 3), (205, 190, 165), dtype=np.uint8)
    for r0 in (0.15, 0.6):
        for c0 in (0.12, 0.6):
            img[int(r0 * size):int((r0 + 0.28) * size), int(c0 * size):int((c0 + 0.28) * size)] = (40, 55, 70)
    return Image.fromarray(img)


def _export_ply(path: Path, verts: NDArray[np.float64], faces: NDArray[np.int64], inward: bool) -> int:
    """Binary PLY with **double** vertices (trimesh writes float32, which rounds projected
    coordinates of ~5e6 m to 0.5 m); faces reversed when ``inward``."""
    faces = faces[:, ::-1] if inward else faces
    header = (f"ply\nformat binary_little_endian 1.0\ncomment envcap generated city\nelement vertex {len(verts)}\n"
              "property double x\nproperty double y\nproperty double z\n"
              f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    face_rec = np.zeros(len(faces), dtype=[("n", "u1"), ("v", "<i4", (3,))])
    face_rec["n"] = 3
    face_rec["v"] = faces
    path.write_bytes(header.encode("ascii") + world_to_file(verts).astype("<f8").tobytes() + face_rec.tobytes())
    return len(faces)


def _textured(verts: NDArray[np.float64], faces: NDArray[np.int64], uv_m: NDArray[np.float64], color: tuple[float, float, float],
              emissive: tuple[float, float, float]) -> Any:
    """A textured ``trimesh.Trimesh``; ``verts`` already in the file's frame."""
    import trimesh  # heavy (~0.3 s): only when a city is written, not when envcap's CLI starts

    material = trimesh.visual.material.PBRMaterial(
        baseColorTexture=window_texture(), baseColorFactor=[*(int(255 * c) for c in color), 255],
        emissiveFactor=list(emissive), metallicFactor=0.0, roughnessFactor=1.0)
    uv = np.stack([uv_m[:, 0] / 4.0, uv_m[:, 1] / 3.5], axis=1)
    visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    return trimesh.Trimesh(verts, faces, visual=visual, process=False)


def _mitsuba_xml(layout: CityLayout, shapes: list[tuple[str, str, str]]) -> ET.ElementTree:
    root = ET.Element("scene", version="3.0.0")
    for name, rgb in [*MATERIALS.items(), (TERRAIN_MATERIAL, TERRAIN_ALBEDO)]:
        bsdf = ET.Element("bsdf", type="diffuse", id=name)
        ET.SubElement(bsdf, "rgb", name="reflectance", value=", ".join(f"{c:.3f}" for c in rgb))
        if name == "concrete":
            wrap = ET.SubElement(root, "bsdf", type="twosided", id=name)
            bsdf.attrib.pop("id")
            wrap.append(bsdf)
        else:
            root.append(bsdf)
    textured = ET.SubElement(root, "bsdf", type="diffuse", id="window_texture")
    tex = ET.SubElement(textured, "texture", type="bitmap", name="reflectance")
    ET.SubElement(tex, "string", name="filename", value="textured/obj_house_windows.png")
    ET.SubElement(root, "emitter", type="constant")
    sun = ET.SubElement(root, "emitter", type="directional")
    ET.SubElement(sun, "vector", name="direction", value="0.3, 0.5, -0.8")
    for kind, filename, bsdf_id in shapes:
        shape = ET.SubElement(root, "shape", type=kind)
        ET.SubElement(shape, "string", name="filename", value=filename)
        if filename == "terrain.ply":
            tr = ET.SubElement(shape, "transform", name="to_world")
            ET.SubElement(tr, "translate", x="0", y="0", z="0")
        ET.SubElement(shape, "ref", id=bsdf_id)
    ET.indent(root)
    return ET.ElementTree(root)


def write_city(layout: CityLayout, out_dir: Path, terrain_cell: float = 10.0) -> dict[str, object]:
    """Write ``layout``'s files into ``out_dir`` (created; must not exist or be empty) and return
    the ``truth.json`` content.  See the module docstring for the files and their frame."""
    out_dir = Path(out_dir)
    if out_dir.exists() and any(out_dir.iterdir()):
        raise FileExistsError(f"{out_dir} exists and is not empty: write_city writes only into a new directory")
    (out_dir / "buildings").mkdir(parents=True)
    (out_dir / "textured").mkdir()
    shapes: list[tuple[str, str, str]] = []
    gltf_offset = [0.0, 0.0, 0.0]
    triangles = 0
    inward_files: list[str] = []
    cells = layout.spec.facade_cells
    for index, b in enumerate(layout.buildings):
        verts, faces, uv = building_mesh(b, cells)
        if index == TEXTURED_GLTF:   # glTF is +Y up (its spec): local coordinates around the house
            local = np.round(b.footprint.mean(axis=0))
            gltf_offset = [float(local[0]), 0.0, float(local[1])]
            mesh = _textured(verts - np.array(gltf_offset), faces, uv, MATERIALS[b.material], (0.0, 0.0, 0.0))
            mesh.export(out_dir / "textured" / "facade_house.glb")
            triangles += len(faces)
            continue
        if index == TEXTURED_OBJ:
            mesh = _textured(world_to_file(verts), faces, uv, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0))
            import trimesh  # heavy: see _textured

            obj_text, extra = trimesh.exchange.obj.export_obj(mesh, include_texture=True, mtl_name="obj_house.mtl", return_texture=True)
            (out_dir / "textured" / "obj_house.obj").write_text(obj_text)
            for fname, data in extra.items():
                target = "obj_house_windows.png" if fname.endswith(".png") else fname
                (out_dir / "textured" / target).write_bytes(data)
            mtl = out_dir / "textured" / "obj_house.mtl"
            if mtl.exists():
                text = mtl.read_text()
                text = "\n".join("map_Kd obj_house_windows.png" if line.startswith("map_Kd") else line for line in text.splitlines())
                mtl.write_text(text + "\n")
            shapes.append(("obj", "textured/obj_house.obj", "window_texture"))
            triangles += len(faces)
            continue
        rel = f"buildings/{b.name}.ply"
        triangles += _export_ply(out_dir / rel, verts, faces, b.inward)
        shapes.append(("ply", rel, b.material))
        if b.inward:
            inward_files.append(rel)
    tv, tf = terrain_mesh(layout, terrain_cell)
    terrain_triangles = _export_ply(out_dir / "terrain.ply", tv, tf, False)
    shapes.append(("ply", "terrain.ply", TERRAIN_MATERIAL))
    _mitsuba_xml(layout, shapes).write(out_dir / "city.xml", encoding="unicode", xml_declaration=False)
    truth: dict[str, object] = {
        "frame": {"up_axis": "z", "offset": [-PROJECTED_OFFSET[0], 0.0, PROJECTED_OFFSET[1]],
                  "note": "file (east, north, up) = (x + E0, -z + N0, y); import with up_axis z and this offset"},
        "spec": asdict(layout.spec),
        "bounds_xz": list(layout.bounds),
        "streets": [{**asdict(s), "length": s.length} for s in layout.streets],
        "buildings": len(layout.buildings),
        "building_triangles": triangles,
        "terrain_triangles": terrain_triangles,
        "inward_files": inward_files,
        "textured_files": [
            {"file": "textured/facade_house.glb", "up_axis": "y", "offset": gltf_offset},
            {"file": "textured/obj_house.obj", "up_axis": "z", "offset": [-PROJECTED_OFFSET[0], 0.0, PROJECTED_OFFSET[1]]},
        ],
    }
    (out_dir / "truth.json").write_text(json.dumps(truth, indent=1, allow_nan=True) + "\n")
    return truth
