"""envcap.gpu.float_depth: the float32 depth attachment and the reversed-depth state switch."""

import numpy as np
import pytest

from envcap.gpu import float_depth as fd


def test_reversed_depth_sets_and_restores_state_even_on_error(gl_ctx):
    gl = fd.FloatDepthGL()
    before = (gl.get(fd.GL_CLIP_ORIGIN), gl.get(fd.GL_CLIP_DEPTH_MODE), gl.get(fd.GL_DEPTH_FUNC))
    assert before[1] == 0x935E and before[2] != fd.GL_GREATER   # GL defaults: NEGATIVE_ONE_TO_ONE
    with pytest.raises(KeyError):
        with gl.reversed_depth():
            assert gl.get(fd.GL_CLIP_DEPTH_MODE) == fd.GL_ZERO_TO_ONE
            assert gl.get(fd.GL_DEPTH_FUNC) == fd.GL_GREATER
            raise KeyError("inside")
    assert (gl.get(fd.GL_CLIP_ORIGIN), gl.get(fd.GL_CLIP_DEPTH_MODE), gl.get(fd.GL_DEPTH_FUNC)) == before


def test_float_depth_keeps_float32_values(gl_ctx):
    """A depth cleared to a value that 24 bits cannot hold reads back exactly (float32)."""
    gl = fd.FloatDepthGL()
    color = gl_ctx.texture((4, 4), 4, dtype="f4")
    fbo = gl_ctx.framebuffer([color], gl_ctx.depth_renderbuffer((4, 4)))
    rb = gl.attach_float_depth(fbo.glo, 4, 4)
    try:
        fbo.use()
        v = np.float32(1e-7)   # 24-bit fixed point resolves only 6e-8: would read back 1.19e-7
        fbo.clear(depth=float(v))
        got = np.frombuffer(fbo.read(components=1, attachment=-1, dtype="f4"), np.float32)
        np.testing.assert_array_equal(got, np.full(16, v))
    finally:
        gl.delete_renderbuffer(rb)
        fbo.release()
        color.release()
