"""Fixtures of the viewer tests: the session's canyon probe set written with its WebGL2 face atlas,
served by the viewer.  The session's ONE headless Chromium (``chromium``, tests/conftest.py: the
journeys use it too) is pointed by each module at its own page with ``viewer_pages.open_page``
(a Chromium start and stop cost ~1.5 s each)."""

import pytest
from viewer_pages import open_page

from envcap.probeset.store import write_probe_set
from envcap.viewer import ViewerSite, serve


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


@pytest.fixture
def browser(chromium, viewer_server):
    """Chromium on the canyon's viewer page, its probe set loaded (``window.envcap.ready``); opened
    again when another module's test left it on another page."""
    if chromium.evaluate("location.href") != viewer_server.url:
        open_page(chromium, viewer_server.url)
    return chromium
