"""Cube-map textures with mip levels, uploaded with raw GL where moderngl 5.13 cannot.

moderngl has no cube-map-array texture type, so :class:`CubeArrayTexture` creates one with raw GL
calls on the current context and binds it to a texture unit that a program's
``samplerCubeArray`` uniform points at (``layout(binding = UNIT)``).  moderngl cannot write mip
levels of a cube texture, so :func:`cube_texture` writes them with raw GL.  Faces are uploaded
as-is per the convention of :mod:`envcap.core.cube` (faces in GL order, rows = t, columns = s).
"""

from __future__ import annotations

import ctypes
from typing import Sequence

import moderngl
import numpy as np
from numpy.typing import NDArray

from envcap.gpu.context import RawGL

# GL enums used below (from the OpenGL 4.5 core headers).
GL_TEXTURE_CUBE_MAP = 0x8513
GL_TEXTURE_CUBE_MAP_ARRAY = 0x9009
GL_TEXTURE_CUBE_MAP_POSITIVE_X = 0x8515
GL_TEXTURE0 = 0x84C0
GL_TEXTURE_MIN_FILTER = 0x2801
GL_TEXTURE_MAG_FILTER = 0x2800
GL_TEXTURE_WRAP_S = 0x2802
GL_TEXTURE_WRAP_T = 0x2803
GL_TEXTURE_WRAP_R = 0x8072
GL_TEXTURE_BASE_LEVEL = 0x813C
GL_TEXTURE_MAX_LEVEL = 0x813D
GL_CLAMP_TO_EDGE = 0x812F
GL_NEAREST = 0x2600
GL_LINEAR = 0x2601
GL_LINEAR_MIPMAP_LINEAR = 0x2703
GL_NEAREST_MIPMAP_NEAREST = 0x2700
GL_RGBA = 0x1908
GL_RGBA32F = 0x8814
GL_RGBA16F = 0x881A
GL_FLOAT = 0x1406
GL_HALF_FLOAT = 0x140B
GL_UNPACK_ALIGNMENT = 0x0CF5
GL_PACK_ALIGNMENT = 0x0D05


class CubeArrayTexture:
    """A ``GL_TEXTURE_CUBE_MAP_ARRAY`` texture made with raw GL on the current context.

    ``levels`` is a list of float arrays, one per mip level, each of shape ``(L, 6, N_k, N_k, 4)``
    (layers, faces in GL order, rows = t, columns = s, RGBA), with ``N_k = N_0 >> k``.  The face
    arrays are uploaded as-is, per the convention of :mod:`envcap.core.cube`.  ``internal`` is
    ``"rgba16f"`` or ``"rgba32f"``.  Filtering is trilinear (``GL_LINEAR_MIPMAP_LINEAR``), and
    seamless cube filtering is on for the context (:func:`envcap.gpu.context.create_context`).
    """

    def __init__(self, levels: Sequence[NDArray[np.floating]], internal: str = "rgba32f",
                 filter: str = "linear") -> None:
        if not levels:
            raise ValueError("CubeArrayTexture needs at least one level")
        first = np.asarray(levels[0])
        if first.ndim != 5 or first.shape[1] != 6 or first.shape[2] != first.shape[3] or first.shape[4] != 4:
            raise ValueError(f"level 0 must have shape (L, 6, N, N, 4), got {first.shape}")
        self.layers, _, self.size = first.shape[0], first.shape[1], first.shape[2]
        for k, lv in enumerate(levels):
            want = (self.layers, 6, max(self.size >> k, 1), max(self.size >> k, 1), 4)
            if np.asarray(lv).shape != want:
                raise ValueError(f"level {k} must have shape {want}, got {np.asarray(lv).shape}")
        fmt = {"rgba16f": GL_RGBA16F, "rgba32f": GL_RGBA32F}.get(internal)
        if fmt is None:
            raise ValueError(f"internal format must be 'rgba16f' or 'rgba32f', got {internal!r}")
        self.gl = RawGL()
        gl = self.gl
        gl.clear_errors()
        tex = ctypes.c_uint(0)
        gl.glGenTextures(1, ctypes.byref(tex))
        self.glo = tex.value
        gl.glBindTexture(GL_TEXTURE_CUBE_MAP_ARRAY, self.glo)
        self.levels = len(levels)
        gl.glTexStorage3D(GL_TEXTURE_CUBE_MAP_ARRAY, self.levels, fmt, self.size, self.size, 6 * self.layers)
        gl.glPixelStorei(GL_UNPACK_ALIGNMENT, 1)
        for k, lv in enumerate(levels):
            data = np.ascontiguousarray(np.asarray(lv, dtype=np.float32))
            nk = data.shape[2]
            # layer-faces are addressed as depth = 6 * layer + face
            gl.glTexSubImage3D(GL_TEXTURE_CUBE_MAP_ARRAY, k, 0, 0, 0, nk, nk, 6 * self.layers, GL_RGBA, GL_FLOAT,
                               data.ctypes.data)
        mag = GL_LINEAR if filter == "linear" else GL_NEAREST
        minf = GL_LINEAR_MIPMAP_LINEAR if filter == "linear" else GL_NEAREST_MIPMAP_NEAREST
        gl.glTexParameteri(GL_TEXTURE_CUBE_MAP_ARRAY, GL_TEXTURE_MIN_FILTER, minf)
        gl.glTexParameteri(GL_TEXTURE_CUBE_MAP_ARRAY, GL_TEXTURE_MAG_FILTER, mag)
        gl.glTexParameteri(GL_TEXTURE_CUBE_MAP_ARRAY, GL_TEXTURE_BASE_LEVEL, 0)
        gl.glTexParameteri(GL_TEXTURE_CUBE_MAP_ARRAY, GL_TEXTURE_MAX_LEVEL, self.levels - 1)
        for p in (GL_TEXTURE_WRAP_S, GL_TEXTURE_WRAP_T, GL_TEXTURE_WRAP_R):
            gl.glTexParameteri(GL_TEXTURE_CUBE_MAP_ARRAY, p, GL_CLAMP_TO_EDGE)
        gl.glBindTexture(GL_TEXTURE_CUBE_MAP_ARRAY, 0)
        gl.check("CubeArrayTexture upload")

    def use(self, unit: int) -> None:
        """Bind to texture unit ``unit``.

        Declare the sampler in GLSL with an explicit binding,
        ``layout(binding = UNIT) uniform samplerCubeArray probes;``: moderngl 5.13 does not set
        ``samplerCubeArray`` uniforms (writes to them are silently ignored).  Pick a unit that no
        moderngl texture uses in the same draw or dispatch.
        """
        self.gl.glActiveTexture(GL_TEXTURE0 + unit)
        self.gl.glBindTexture(GL_TEXTURE_CUBE_MAP_ARRAY, self.glo)

    def read(self, level: int = 0) -> NDArray[np.float32]:
        """Read mip ``level`` back as float32 ``(L, 6, N_k, N_k, 4)``."""
        nk = max(self.size >> level, 1)
        out = np.empty((self.layers, 6, nk, nk, 4), dtype=np.float32)
        self.gl.clear_errors()
        self.gl.glBindTexture(GL_TEXTURE_CUBE_MAP_ARRAY, self.glo)
        self.gl.glPixelStorei(GL_PACK_ALIGNMENT, 1)
        self.gl.glGetTexImage(GL_TEXTURE_CUBE_MAP_ARRAY, level, GL_RGBA, GL_FLOAT, out.ctypes.data)
        self.gl.glBindTexture(GL_TEXTURE_CUBE_MAP_ARRAY, 0)
        self.gl.check("CubeArrayTexture read")
        return out

    def release(self) -> None:
        """Delete the GL texture."""
        if self.glo:
            tex = ctypes.c_uint(self.glo)
            self.gl.glDeleteTextures(1, ctypes.byref(tex))
            self.glo = 0


def cube_texture(ctx: moderngl.Context, levels: Sequence[NDArray[np.floating]],
                 dtype: str = "f4") -> moderngl.TextureCube:
    """A moderngl ``TextureCube`` from mip levels, each ``(6, N_k, N_k, 4)`` with ``N_k = N_0 >> k``.

    Faces are uploaded as-is per :mod:`envcap.core.cube`.  Trilinear filtering, seamless (context-wide).
    moderngl cannot write mip levels of a cube texture, so levels are written with raw GL.
    """
    first = np.asarray(levels[0])
    if first.ndim != 4 or first.shape[0] != 6 or first.shape[1] != first.shape[2] or first.shape[3] != 4:
        raise ValueError(f"level 0 must have shape (6, N, N, 4), got {first.shape}")
    n = first.shape[1]
    np_dtype, gl_type = {"f4": (np.float32, GL_FLOAT), "f2": (np.float16, GL_HALF_FLOAT)}[dtype]
    tex = ctx.texture_cube((n, n), 4, dtype=dtype)
    if len(levels) > 1:
        tex.build_mipmaps(0, len(levels) - 1)
    gl = RawGL()
    gl.clear_errors()
    gl.glBindTexture(GL_TEXTURE_CUBE_MAP, tex.glo)
    gl.glPixelStorei(GL_UNPACK_ALIGNMENT, 1)
    for k, lv in enumerate(levels):
        a = np.ascontiguousarray(np.asarray(lv, dtype=np_dtype))
        nk = max(n >> k, 1)
        if a.shape != (6, nk, nk, 4):
            raise ValueError(f"level {k} must have shape {(6, nk, nk, 4)}, got {a.shape}")
        for f in range(6):
            gl.glTexSubImage2D(GL_TEXTURE_CUBE_MAP_POSITIVE_X + f, k, 0, 0, nk, nk, GL_RGBA, gl_type, a[f].ctypes.data)
    gl.glBindTexture(GL_TEXTURE_CUBE_MAP, 0)
    gl.check("cube_texture upload")
    tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR if len(levels) > 1 else moderngl.LINEAR, moderngl.LINEAR)
    return tex
