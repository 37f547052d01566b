"""Reversed float32 depth: the raw GL that moderngl 5.13 lacks for it.

A float32 depth buffer (``GL_DEPTH_COMPONENT32F``) cleared to 0, with clip-space depth mapped to
[0, 1] by ``glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE)`` (core since OpenGL 4.5) and the depth
test ``GREATER``, keeps about 2^-24 relative precision in distance at every range when the
projection puts the near plane at depth 1 and infinity at 0 (see
:func:`envcap.capture.projection.face_clip_matrix_reversed`).  moderngl makes only 24-bit depth
renderbuffers and has no clip control, so :class:`FloatDepthGL` attaches the buffer to a moderngl
framebuffer and switches the state with raw GL calls on the current context.
"""

from __future__ import annotations

import ctypes
from contextlib import contextmanager
from typing import Any, Iterator

from envcap.gpu.context import load_gl_functions

# GL enums (OpenGL 4.5 core headers).
GL_FRAMEBUFFER = 0x8D40
GL_RENDERBUFFER = 0x8D41
GL_DEPTH_ATTACHMENT = 0x8D00
GL_DEPTH_COMPONENT32F = 0x8CAC
GL_FRAMEBUFFER_COMPLETE = 0x8CD5
GL_FRAMEBUFFER_BINDING = 0x8CA6
GL_CLIP_ORIGIN = 0x935C
GL_CLIP_DEPTH_MODE = 0x935D
GL_ZERO_TO_ONE = 0x935F
GL_LOWER_LEFT = 0x8CA1
GL_DEPTH_FUNC = 0x0B74
GL_GREATER = 0x0204


class FloatDepthGL:
    """Raw GL for reversed float32 depth on the current context: attach a float32 depth
    renderbuffer to a moderngl framebuffer (:meth:`attach_float_depth`), and switch clip control
    and depth test for a block of draws (:meth:`reversed_depth`)."""

    _signatures: dict[str, tuple[Any, tuple[Any, ...]]] = {
        "glClipControl": (None, (ctypes.c_uint, ctypes.c_uint)),
        "glDepthFunc": (None, (ctypes.c_uint,)),
        "glGetIntegerv": (None, (ctypes.c_uint, ctypes.POINTER(ctypes.c_int))),
        "glGenRenderbuffers": (None, (ctypes.c_int, ctypes.POINTER(ctypes.c_uint))),
        "glDeleteRenderbuffers": (None, (ctypes.c_int, ctypes.POINTER(ctypes.c_uint))),
        "glBindRenderbuffer": (None, (ctypes.c_uint, ctypes.c_uint)),
        "glRenderbufferStorage": (None, (ctypes.c_uint, ctypes.c_uint, ctypes.c_int, ctypes.c_int)),
        "glBindFramebuffer": (None, (ctypes.c_uint, ctypes.c_uint)),
        "glFramebufferRenderbuffer": (None, (ctypes.c_uint, ctypes.c_uint, ctypes.c_uint, ctypes.c_uint)),
        "glCheckFramebufferStatus": (ctypes.c_uint, (ctypes.c_uint,)),
    }

    def __init__(self) -> None:
        for name, fn in load_gl_functions(self._signatures).items():
            setattr(self, name, fn)

    def get(self, pname: int) -> int:
        """``glGetIntegerv(pname)`` for a single-valued state, e.g. ``GL_DEPTH_FUNC``."""
        v = ctypes.c_int(0)
        self.glGetIntegerv(pname, ctypes.byref(v))
        return int(v.value)

    def attach_float_depth(self, fbo_glo: int, width: int, height: int) -> int:
        """Replace the depth attachment of framebuffer ``fbo_glo`` (a moderngl ``Framebuffer.glo``)
        by a new ``width`` x ``height`` DEPTH_COMPONENT32F renderbuffer; returns its name (free it
        with :meth:`delete_renderbuffer`).  Raises ``RuntimeError`` if the result is incomplete."""
        rb = ctypes.c_uint(0)
        self.glGenRenderbuffers(1, ctypes.byref(rb))
        self.glBindRenderbuffer(GL_RENDERBUFFER, rb.value)
        self.glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, width, height)
        prev = self.get(GL_FRAMEBUFFER_BINDING)
        self.glBindFramebuffer(GL_FRAMEBUFFER, fbo_glo)
        self.glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, rb.value)
        status = self.glCheckFramebufferStatus(GL_FRAMEBUFFER)
        self.glBindFramebuffer(GL_FRAMEBUFFER, prev)
        self.glBindRenderbuffer(GL_RENDERBUFFER, 0)
        if status != GL_FRAMEBUFFER_COMPLETE:
            self.delete_renderbuffer(rb.value)
            raise RuntimeError(f"float32 depth framebuffer incomplete (status 0x{status:04X})")
        return int(rb.value)

    def delete_renderbuffer(self, name: int) -> None:
        """Delete renderbuffer ``name`` (from :meth:`attach_float_depth`)."""
        rb = ctypes.c_uint(name)
        self.glDeleteRenderbuffers(1, ctypes.byref(rb))

    @contextmanager
    def reversed_depth(self) -> Iterator[None]:
        """Within the block: clip-space depth maps to [0, 1] (``GL_ZERO_TO_ONE``, origin lower
        left) and the depth test passes fragments ``GREATER`` than the stored depth (clear the
        depth buffer to 0).  The clip control and depth function found are restored on exit,
        also when the block raises."""
        saved = (self.get(GL_CLIP_ORIGIN), self.get(GL_CLIP_DEPTH_MODE), self.get(GL_DEPTH_FUNC))
        self.glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE)
        self.glDepthFunc(GL_GREATER)
        try:
            yield
        finally:
            self.glClipControl(saved[0], saved[1])  # leave the context as found
            self.glDepthFunc(saved[2])
