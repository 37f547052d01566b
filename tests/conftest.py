"""Shared fixtures: one headless OpenGL context (Mesa llvmpipe through EGL) per test session,
one small probe set baked per session for the tests that need a real bake but not particular
settings (``canyon_probe_set``), and one headless Chromium per session (``chromium``: the viewer
tests and the journeys point it at their pages)."""

import os

import pytest

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


_SESSION_CONTEXT = []  # the session context once made, for the module-scope fixture below


@pytest.fixture(scope="session")
def gl_ctx():
    from envcap.gpu.context import create_context

    ctx = create_context()
    _SESSION_CONTEXT.append(ctx)
    yield ctx
    _SESSION_CONTEXT.clear()
    ctx.release()


@pytest.fixture(scope="session")
def canyon_probe_set(gl_ctx):
    """The bundled canyon baked once per session: 6 probes of 6 x 8^2 texels every 100 m, 4 filtered
    levels, the sun in the manifest (not in the sky); ~1 s.  Shared: read it, do not modify it."""
    # Imported here, not at the top: collecting any test must not depend on the whole pipeline importing.
    from envcap.probeset.bake import bake_probe_set
    from envcap.scene import load_scene

    return bake_probe_set(load_scene("canyon"), resolution=8, spacing=100.0, ctx=gl_ctx, progress=False)


WINDOW = (1000, 560)
"""The session browser's viewport (CSS px)."""


@pytest.fixture(scope="session")
def chromium():
    """The session's headless Chromium (``WINDOW``), on whatever page the last test module opened
    (skipped only where no Chromium is installed: ``.ci/run`` installs Debian's ``chromium``)."""
    from envcap.viewer.browser import find_chromium

    if find_chromium() is None:
        pytest.skip("no chromium executable on PATH (Debian: apt-get install chromium; .ci/run installs it)")
    pytest.importorskip("websocket", reason="websocket-client is not installed (pip install websocket-client)")
    from envcap.viewer.browser import Chromium

    with Chromium(*WINDOW) as b:
        yield b


@pytest.fixture(scope="module", autouse=True)
def _gl_ctx_current_for_module_fixtures():
    """Make the session context current before a module's own module-scope fixtures run.

    A module-scope fixture that makes textures with raw GL (``CubeArrayTexture``) runs before the
    function-scope fixture below; after a test whose bake made and released a private context, no
    context was current and the textures were silently empty (the GLSL read zeros)."""
    if _SESSION_CONTEXT:
        _SESSION_CONTEXT[0].__enter__()


@pytest.fixture(autouse=True)
def _gl_ctx_current(request):
    """Make the session context current for every test that uses it.

    A test (or library call) that creates and releases a context of its own leaves no context
    current, and moderngl and raw GL calls act on the current context.
    """
    if "gl_ctx" in request.fixturenames:
        request.getfixturevalue("gl_ctx").__enter__()
