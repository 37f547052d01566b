"""Fixtures of the viewer tests: the session's canyon probe set written with its WebGL2 face atlas,
served by the viewer, and ONE headless Chromium for the whole session (``chromium``; skipped only
where no Chromium is installed: ``.ci/run`` installs Debian's ``chromium``), which each module
points at its own page with ``viewer_pages.open_page`` (a Chromium start and stop cost ~1.5 s each)."""

import pytest
from viewer_pages import open_page

from envcap.probeset.store import write_probe_set
from envcap.viewer import ViewerSite, serve
from envcap.viewer.browser import find_chromium

WINDOW = (1000, 560)
"""The session browser's viewport (CSS px)."""


@pytest.fixture(scope="session")
def viewer_probe_dir(canyon_probe_set, tmp_path_factory):
    """``canyon_probe_set`` (6 probes, 8^2 faces, 4 levels) written with ``probes_atlas.ktx2``."""
    return write_probe_set(tmp_path_factory.mktemp("viewer") / "canyon", canyon_probe_set, exr=False,
                           previews=False, writers=["ktx2", "webgl2"])


@pytest.fixture(scope="session")
def viewer_server(viewer_probe_dir):
    server, thread = serve(ViewerSite.open(viewer_probe_dir))
    yield server
    server.shutdown()
    server.server_close()
    thread.join(5)


@pytest.fixture(scope="session")
def chromium():
    """The session's headless Chromium (``WINDOW``), on whatever page the last module opened."""
    if find_chromium() is None:
        pytest.skip("no chromium executable on PATH (Debian: apt-get install chromium; .ci/run installs it)")
    pytest.importorskip("websocket", reason="websocket-client is not installed (pip install websocket-client)")
    from envcap.viewer.browser import Chromium

    with Chromium(*WINDOW) as b:
        yield b


@pytest.fixture
def browser(chromium, viewer_server):
    """Chromium on the canyon's viewer page, its probe set loaded (``window.envcap.ready``); opened
    again when another module's test left it on another page."""
    if chromium.evaluate("location.href") != viewer_server.url:
        open_page(chromium, viewer_server.url)
    return chromium
