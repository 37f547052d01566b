"""Read one mesh file into per-corner triangles and their materials (``Surfaces``).

Loaders: trimesh for glTF/GLB, OBJ (+ MTL), PLY, STL, OFF (each geometry of a multi-part file
with its own material, node transforms applied); :mod:`envcap.scene.mitsuba_xml` reads Mitsuba 3
scene XML into the same ``Surfaces``.  Materials, per file kind (colors are linear RGB unless said otherwise):

* vertex or face colors (PLY, OBJ ``v x y z r g b``): read as sRGB, decoded to linear;
* glTF ``baseColorFactor`` (linear) x ``baseColorTexture`` (sRGB), ``emissiveFactor`` (linear);
* OBJ/MTL ``Kd`` (linear) x ``map_Kd`` (sRGB), ``Ke``;
* Mitsuba ``diffuse`` ``reflectance`` (rgb, float, or a ``bitmap`` texture), inside
  ``twosided``/``mask``/``bumpmap``/``normalmap``; ``plastic``' ``diffuse_reflectance``,
  ``principled``' ``base_color``; an ``area`` emitter's ``radiance``;
* otherwise the mesh table's ``albedo``.

Emission (glTF, MTL) is scaled by ``emission_scale`` (radiance in the sky's units per unit of
emissive factor; default 100, a lit window).  Textures are resampled to ``TEXTURE_SIZE`` squared
(sRGB RGBA, row 0 = bottom, see :class:`envcap.scene.model.SceneMesh`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import ImageFile

from envcap.core.color import srgb_to_linear

TEXTURE_SIZE = 256
"""Side (texels) every surface texture is resampled to (a 4 m facade bay: 1.6 cm per texel)."""


@dataclass
class Surfaces:
    """Triangles of one file, per corner, in the file's coordinates (after any transform the file
    itself gives: glTF nodes, Mitsuba ``to_world``): ``tri`` (T, 3, 3) float64 m, ``albedo`` and
    ``emission`` (T, 3, 3) float32 linear RGB, ``uvl`` (T, 3, 3) float32 (u, v, layer of
    ``textures``; layer -1: no texture; u, v NaN: no texture coordinates) or None, ``textures`` (S, S, 4) uint8 images, ``notes``: what
    was read approximately or skipped (one short line each), ``sources``: (name, triangle count)
    of each piece in order (a file, or a Mitsuba shape's file): winding is judged per piece."""

    tri: NDArray[np.float64]
    albedo: NDArray[np.float32]
    emission: NDArray[np.float32]
    uvl: NDArray[np.float32] | None = None
    textures: list[NDArray[np.uint8]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    sources: list[tuple[str, int]] = field(default_factory=list)

    @staticmethod
    def join(parts: list["Surfaces"]) -> "Surfaces":
        """Concatenate ``parts`` in order (texture layers renumbered)."""
        if len(parts) == 1:
            return parts[0]
        uvls, textures, base = [], [], 0
        any_tex = any(p.uvl is not None for p in parts)
        for p in parts:
            if any_tex:
                uvl = p.uvl.copy() if p.uvl is not None else _untextured(p.tri.shape[0])
                uvl[..., 2] = np.where(uvl[..., 2] >= 0, uvl[..., 2] + base, -1.0)
                uvls.append(uvl)
            base += len(p.textures)
            textures += p.textures
        return Surfaces(np.concatenate([p.tri for p in parts]), np.concatenate([p.albedo for p in parts]),
                        np.concatenate([p.emission for p in parts]), np.concatenate(uvls) if any_tex else None,
                        textures, [n for p in parts for n in p.notes], [src for p in parts for src in p.sources])


def _untextured(t: int) -> NDArray[np.float32]:
    """``uvl`` of corners without texture coordinates: (nan, nan, -1)."""
    uvl = np.full((t, 3, 3), np.nan, np.float32)
    uvl[..., 2] = -1.0
    return uvl


def texture_image(image: Any) -> NDArray[np.uint8]:
    """A PIL image as (TEXTURE_SIZE, TEXTURE_SIZE, 4) uint8 sRGB RGBA, row 0 = the image's bottom."""
    from PIL import Image

    rgba = image.convert("RGBA").resize((TEXTURE_SIZE, TEXTURE_SIZE), Image.Resampling.LANCZOS)
    return np.ascontiguousarray(np.asarray(rgba, dtype=np.uint8)[::-1])


def _material_colors(visual: Any, default_albedo: NDArray[np.float64], emission_scale: float
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64], Any]:
    """(albedo factor (3,), emission (3,), PIL image or None) of a TextureVisuals' material."""
    mat = getattr(visual, "material", None)
    albedo, emission, image = default_albedo, np.zeros(3), None
    if mat is None:
        return albedo, emission, image
    if hasattr(mat, "baseColorFactor"):                       # glTF PBRMaterial
        factor = mat.baseColorFactor
        if factor is not None:
            albedo = np.asarray(factor, np.float64)[:3] / (255.0 if np.asarray(factor).dtype == np.uint8 else 1.0)
        else:
            albedo = np.ones(3)
        image = mat.baseColorTexture
        if getattr(mat, "emissiveFactor", None) is not None:
            emission = np.asarray(mat.emissiveFactor, np.float64)[:3] * emission_scale
    else:                                                     # OBJ SimpleMaterial (also PLY with UVs)
        kw = getattr(mat, "kwargs", {}) or {}
        image = getattr(mat, "image", None)
        # trimesh invents a 2 x 2 grey image and a 0.4 diffuse for texture coordinates without a
        # texture (PLY u,v; OBJ vt): only an image decoded from a file is the file's, only an MTL
        # Kd is a colour; otherwise the table's albedo (x 1 under a texture of the file's own).
        if not isinstance(image, ImageFile.ImageFile):
            image = None
        if "kd" in kw:
            albedo = np.asarray([float(x) for x in np.ravel(kw["kd"])[:3]])
        elif image is not None:
            albedo = np.ones(3)
        if "ke" in kw:
            emission = np.asarray([float(x) for x in np.ravel(kw["ke"])[:3]]) * emission_scale
    if not np.all(np.isfinite(albedo)) or not np.all(np.isfinite(emission)):
        raise ValueError(f"material colours must be finite, got albedo {albedo.tolist()}, emission {emission.tolist()}")
    return np.clip(albedo, 0.0, 1.0), emission, image


def geometry_surfaces(m: Any, default_albedo: NDArray[np.float64], emission_scale: float = 100.0) -> Surfaces:
    """:class:`Surfaces` of one ``trimesh.Trimesh`` (its visual: colors or a textured material)."""
    v = np.asarray(m.vertices, np.float64)
    f = np.asarray(m.faces, np.int64)
    tri = v[f]
    t = tri.shape[0]
    albedo = np.broadcast_to(np.asarray(default_albedo, np.float32), tri.shape).copy()
    emission = np.zeros(tri.shape, np.float32)
    kind = getattr(m.visual, "kind", None)
    if kind == "vertex":
        vc = np.asarray(m.visual.vertex_colors)[:, :3] / 255.0   # uint8 codes: in [0, 1]
        albedo = srgb_to_linear(vc)[f].astype(np.float32)
    elif kind == "face":
        fc = np.asarray(m.visual.face_colors)[:, :3] / 255.0
        albedo = np.repeat(srgb_to_linear(fc)[:, None, :], 3, axis=1).astype(np.float32)
    elif kind == "texture":
        factor, emit, image = _material_colors(m.visual, np.asarray(default_albedo, np.float64), emission_scale)
        albedo[:] = factor.astype(np.float32)
        emission[:] = emit.astype(np.float32)
        uv = getattr(m.visual, "uv", None)
        if uv is not None and len(uv) == len(v):   # coordinates kept even without an image: a bsdf may add one
            uvl = np.empty((t, 3, 3), np.float32)
            uvl[..., :2] = np.asarray(uv, np.float64)[f]
            uvl[..., 2] = 0.0 if image is not None else -1.0
            if not np.all(np.isfinite(uvl)):
                raise ValueError("texture coordinates contain NaN or Inf")
            return Surfaces(tri, albedo, emission, uvl, [texture_image(image)] if image is not None else [])
    return Surfaces(tri, albedo, emission)


def _load(path: Path) -> list[Any]:
    """The file's triangle geometries (node transforms applied); one-line ``ValueError`` naming
    the file on any loader failure."""
    try:
        import trimesh  # heavy (~0.8 s): imported only when a mesh is actually read

        loaded = trimesh.load(str(path), process=False)
        geoms = loaded.dump(concatenate=False) if isinstance(loaded, trimesh.Scene) else [loaded]
    except Exception as exc:  # trimesh raises many kinds, and its optional imports may fail
        raise ValueError(f"cannot read mesh file {path}: {one_line(exc)}") from None
    geoms = [g for g in geoms if isinstance(g, trimesh.Trimesh) and len(g.faces)]
    if not geoms:
        raise ValueError(f"mesh file {path} has no triangles")
    return geoms


def one_line(exc: Exception, limit: int = 300) -> str:
    """``Type: message`` on one line, at most ``limit`` characters."""
    text = " ".join(f"{type(exc).__name__}: {exc}".split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def read_mesh_surfaces(path: Path, default_albedo: NDArray[np.float64], emission_scale: float = 100.0) -> Surfaces:
    """:class:`Surfaces` of a mesh file (not XML: :mod:`envcap.scene.mitsuba_xml`); a failure names the file."""
    geoms = _load(path)
    try:
        parts = [geometry_surfaces(g, default_albedo, emission_scale) for g in geoms]
    except Exception as exc:
        raise ValueError(f"cannot read mesh file {path}: {one_line(exc)}") from None
    surfaces = Surfaces.join(parts)
    surfaces.sources = [(path.name, surfaces.tri.shape[0])]
    if not np.all(np.isfinite(surfaces.tri)):
        raise ValueError(f"mesh file {path} has NaN or Inf vertex positions")
    return surfaces
