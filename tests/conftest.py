"""Shared fixtures: one headless OpenGL context (Mesa llvmpipe through EGL) per test session."""

import os

import pytest

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


@pytest.fixture(scope="session")
def gl_ctx():
    from envcap.gpu.gl import create_context

    ctx = create_context()
    yield ctx
    ctx.release()


@pytest.fixture(autouse=True)
def _gl_ctx_current(request):
    """Make the session context current for every test that uses it.

    A test (or library call) that creates and releases a context of its own leaves no context
    current, and moderngl and raw GL calls act on the current context.
    """
    if "gl_ctx" in request.fixturenames:
        request.getfixturevalue("gl_ctx").__enter__()
