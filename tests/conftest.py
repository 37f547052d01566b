"""Shared fixtures: one headless OpenGL context (Mesa llvmpipe through EGL) per test session."""

import os

import pytest

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


@pytest.fixture(scope="session")
def gl_ctx():
    from envcap.gl import create_context

    ctx = create_context()
    yield ctx
    ctx.release()
