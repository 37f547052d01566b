"""Quick look at a scene's geometry: a top-down and a street-level view rendered with moderngl.

For eyes only (not a capture): Lambert with a fixed light plus emission, tone mapped, 8-bit PNG.
Shaders: ``shaders/preview/scene_preview_vert.glsl`` / ``shaders/preview/scene_preview_frag.glsl``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image, PngImagePlugin

from envcap.core.resources import shader_source
from envcap.core.view_matrices import look_at, ortho, perspective
from envcap.outputs import atomic_output_file
from envcap.outputs.guard import check_file_replaceable
from envcap.outputs.marker import PNG_MARK, png_marked
from envcap.scene.model import Scene, Street


def street_view_matrix(street: Street, aspect: float) -> NDArray[np.float64]:
    """Camera at 1.7 m on the street's probe line, 10 % in from ``start``, looking along it (in
    the street's frame, turned to the world, for a street at an angle)."""
    eye, tgt = np.zeros(3), np.zeros(3)
    eye[street.along_index] = street.start + 0.1 * street.length
    tgt[street.along_index] = street.end
    eye[street.cross_index] = tgt[street.cross_index] = street.center_line
    eye[1], tgt[1] = 1.7, 8.0
    eye, tgt = street.to_world(eye), street.to_world(tgt)  # a framed street's frame to the world
    return perspective(70.0, aspect, 0.1, 3000.0) @ look_at(eye, tgt, np.array([0.0, 1.0, 0.0]))


def top_view_matrix(scene: Scene, margin: float = 20.0) -> tuple[NDArray[np.float64], float]:
    """Orthographic top-down view (+X right, +Z down the image) of the streets' area; and aspect."""
    pts = []
    for st in scene.streets:
        a, c = st.along_index, st.cross_index
        for al in (st.start, st.end):
            for cr in (st.facade_min - 40.0, st.facade_max + 40.0):
                p = np.zeros(3)
                p[a], p[c] = al, cr
                pts.append(st.to_world(p))
    if not pts:
        pts = list(scene.mesh.world_bounds())
    pts = np.array(pts)
    x0, z0 = pts.min(0)[[0, 2]] - margin
    x1, z1 = pts.max(0)[[0, 2]] + margin
    view = look_at(np.array([0.0, 1000.0, 0.0]), np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, -1.0]))
    # in view space: x_view = x_world, y_view = -z_world
    proj = ortho(x0, x1, -z1, -z0, 1.0, 2000.0)
    return proj @ view, (x1 - x0) / (z1 - z0)


def render(ctx: Any, scene: Scene, mvp: NDArray[np.float64], size: tuple[int, int]) -> NDArray[np.uint8]:
    """Render ``scene`` with the 4x4 ``mvp`` (column vectors) into an (H, W, 3) uint8 image."""
    w, h = size
    m = scene.mesh
    prog = ctx.program(vertex_shader=shader_source("preview/scene_preview_vert.glsl"), fragment_shader=shader_source("preview/scene_preview_frag.glsl"))
    data = np.concatenate([m.positions, m.normals, m.albedo, m.emission], axis=1).astype("f4")
    vbo = ctx.buffer(data.tobytes())
    ibo = ctx.buffer(m.indices.astype("u4").tobytes())
    vao = ctx.vertex_array(prog, [(vbo, "3f 3f 3f 3f", "in_pos", "in_normal", "in_albedo", "in_emission")], ibo)
    to_world = np.eye(4)
    to_world[:3, 3] = m.origin  # mesh positions are relative to m.origin (float64, folded in here)
    prog["mvp"].write((mvp @ to_world).T.astype("f4").tobytes())
    light = np.array([0.4, 0.8, 0.3])
    prog["light_dir"].value = tuple(light / np.linalg.norm(light))
    color = ctx.renderbuffer((w, h), 4, samples=0)
    depth = ctx.depth_renderbuffer((w, h))
    fbo = ctx.framebuffer([color], depth)
    fbo.use()
    ctx.enable(ctx.DEPTH_TEST)
    fbo.clear(0.55, 0.7, 0.9, 1.0, depth=1.0)
    vao.render()
    img = np.frombuffer(fbo.read(components=3), np.uint8).reshape(h, w, 3)[::-1]
    for o in (vao, vbo, ibo, fbo, color, depth, prog):
        o.release()
    return img.copy()


def save_previews(ctx: Any, scene: Scene, path: str | Path, width: int = 640, *, force: bool = False) -> Path:
    """Write one PNG: the first street's street-level view above a top-down view of the streets.

    The PNG carries envcap's mark (:data:`envcap.outputs.marker.PNG_MARK`); an existing ``path``
    without it is not overwritten: refused (:class:`~envcap.outputs.guard.OutputRefused`), or with
    ``force`` moved aside (renamed beside it, never deleted)."""
    check_file_replaceable(Path(path), force)
    foreign = Path(path).exists() and not png_marked(Path(path))
    top, aspect = top_view_matrix(scene)
    th = int(min(max(round(width / max(aspect, 1e-3)), 160), 640))
    parts = []
    if scene.streets:
        sh = int(width * 0.6)
        parts.append(render(ctx, scene, street_view_matrix(scene.streets[0], width / sh), (width, sh)))
    parts.append(render(ctx, scene, top, (width, th)))
    img = np.concatenate(parts, axis=0)
    with atomic_output_file(path, keep_existing=foreign, lock=True) as tmp:
        info = PngImagePlugin.PngInfo()
        info.add_text(*PNG_MARK)
        Image.fromarray(img).save(tmp, format="PNG", optimize=True, pnginfo=info)
    return Path(path)
