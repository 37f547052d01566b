"""Fixtures of the viewer tests: the session's canyon probe set written with its WebGL2 face atlas,
served by the viewer, and one headless Chromium on the page (skipped only where no Chromium is
installed: ``.ci/run`` installs Debian's ``chromium``)."""

import pytest

from envcap.probeset.store import write_probe_set
from envcap.viewer import ViewerSite, serve
from envcap.viewer.browser import find_chromium


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
def browser(viewer_server):
    """Chromium on the viewer page, its probe set loaded (``window.envcap.ready``)."""
    if find_chromium() is None:
        pytest.skip("no chromium executable on PATH (Debian: apt-get install chromium; .ci/run installs it)")
    pytest.importorskip("websocket", reason="websocket-client is not installed (pip install websocket-client)")
    from envcap.viewer.browser import Chromium

    with Chromium(1000, 560) as b:
        b.goto(viewer_server.url)
        assert b.evaluate("window.envcap.ready.then(() => 'ok', e => 'error: ' + e.message)") == "ok", b.errors
        yield b
