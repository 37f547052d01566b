"""The headless OpenGL context (EGL through moderngl) and raw GL entry points where moderngl stops.

Raw entry points are loaded with ``ctypes`` through ``eglGetProcAddress`` (no PyOpenGL) and act
on whichever context is current: moderngl makes its standalone context current on creation and
keeps it so.  Everything here runs on Mesa llvmpipe (no GPU) as well as on a GPU driver.
"""

from __future__ import annotations

import ctypes
import os
from typing import Any

import moderngl

GL_TEXTURE_CUBE_MAP_SEAMLESS = 0x884F


def create_context(require: int = 430) -> moderngl.Context:
    """Create a headless moderngl context (EGL) with at least OpenGL ``require`` (e.g. 430).

    Seamless cube-map filtering is switched on for the whole context.  Raises ``RuntimeError``
    naming the system packages to install when EGL or Mesa is missing.
    """
    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=require)
    except Exception as exc:  # moderngl raises plain Exception subclasses here
        raise RuntimeError(
            f"could not create a headless OpenGL {require // 100}.{require % 100 // 10} context through EGL ({exc}). "
            "Install Mesa's EGL and llvmpipe (Debian/Ubuntu: apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri), "
            "or set EGL_PLATFORM=surfaceless if a display server interferes."
        ) from exc
    raw = RawGL()
    raw.glEnable(GL_TEXTURE_CUBE_MAP_SEAMLESS)
    return ctx


def load_gl_functions(signatures: dict[str, tuple[Any, tuple[Any, ...]]]) -> dict[str, Any]:
    """OpenGL entry points ``{name: (restype, argtypes)}`` as ctypes callables, via
    ``eglGetProcAddress`` (they act on whichever context is current).  The EGL library is
    ``$ENVCAP_LIBEGL`` or ``libEGL.so.1``.  Raises ``RuntimeError`` naming a missing entry point."""
    egl = ctypes.CDLL(os.environ.get("ENVCAP_LIBEGL", "libEGL.so.1"))
    egl.eglGetProcAddress.restype = ctypes.c_void_p
    egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
    out = {}
    for name, (res, args) in signatures.items():
        ptr = egl.eglGetProcAddress(name.encode())
        if not ptr:
            raise RuntimeError(f"OpenGL entry point {name} not available through EGL")
        out[name] = ctypes.CFUNCTYPE(res, *args)(ptr)
    return out


class RawGL:
    """The OpenGL entry points that moderngl does not expose and envcap's textures need, loaded
    through EGL as attributes (``glTexStorage3D``, ``glGetTexImage``, ...), with error checks."""

    _signatures: dict[str, tuple[Any, tuple[Any, ...]]] = {
        "glEnable": (None, (ctypes.c_uint,)),
        "glGenTextures": (None, (ctypes.c_int, ctypes.POINTER(ctypes.c_uint))),
        "glDeleteTextures": (None, (ctypes.c_int, ctypes.POINTER(ctypes.c_uint))),
        "glBindTexture": (None, (ctypes.c_uint, ctypes.c_uint)),
        "glActiveTexture": (None, (ctypes.c_uint,)),
        "glTexParameteri": (None, (ctypes.c_uint, ctypes.c_uint, ctypes.c_int)),
        "glPixelStorei": (None, (ctypes.c_uint, ctypes.c_int)),
        "glTexStorage3D": (None, (ctypes.c_uint, ctypes.c_int, ctypes.c_uint, ctypes.c_int, ctypes.c_int, ctypes.c_int)),
        "glTexSubImage3D": (
            None,
            (ctypes.c_uint, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_int,
             ctypes.c_int, ctypes.c_uint, ctypes.c_uint, ctypes.c_void_p),
        ),
        "glTexSubImage2D": (
            None,
            (ctypes.c_uint, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_uint,
             ctypes.c_uint, ctypes.c_void_p),
        ),
        "glGetTexImage": (None, (ctypes.c_uint, ctypes.c_int, ctypes.c_uint, ctypes.c_uint, ctypes.c_void_p)),
        "glGetError": (ctypes.c_uint, ()),
        "glFinish": (None, ()),
    }

    def __init__(self) -> None:
        for name, fn in load_gl_functions(self._signatures).items():
            setattr(self, name, fn)

    def clear_errors(self) -> None:
        """Drop errors that earlier calls left queued (moderngl leaves some, e.g. when it makes a
        framebuffer), so that :meth:`check` reports only what the calls after it caused."""
        for _ in range(64):
            if not self.glGetError():
                return

    def check(self, what: str) -> None:
        """Raise ``RuntimeError`` naming ``what`` if a GL error is queued."""
        err = self.glGetError()
        if err:
            raise RuntimeError(f"OpenGL error 0x{err:04X} in {what}")
