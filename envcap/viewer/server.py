"""The viewer's HTTP server: :mod:`http.server` on 127.0.0.1 (loopback only), one thread per request.

Routes (GET / HEAD): the site's :meth:`~envcap.viewer.site.ViewerSite.routes` (a city's:
:meth:`~envcap.viewer.city_site.CitySite.routes`), the list ``envcap export web`` writes too:
``/`` -> ``web/index.html``; ``/three.html``; ``/web/NAME`` and ``/three/NAME`` -> the page's static
files (:data:`envcap.viewer.site.WEB_DIR`); ``/set/NAME`` -> the files the probe set's manifest
names (``manifest.json``, ``probes_atlas.ktx2``, ``sky.ktx2``, ...); ``/report/NAME`` -> the
report's ``report.json`` and PNG plots; ``/api/config.json`` and ``/api/runtime.glsl``
(:mod:`envcap.viewer.site`).  Anything else is 404: only files listed for serving are read, so no
path can escape the directories.
"""

from __future__ import annotations

import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Mapping
from urllib.parse import unquote, urlsplit

from envcap.viewer.city_site import CitySite
from envcap.viewer.site import Body, ViewerSite

CONTENT_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
                 ".css": "text/css; charset=utf-8", ".json": "application/json", ".png": "image/png",
                 ".ktx2": "image/ktx2", ".glsl": "text/plain; charset=utf-8", ".exr": "image/x-exr",
                 ".md": "text/markdown; charset=utf-8", ".glb": "model/gltf-binary"}


class ViewerServer(ThreadingHTTPServer):
    """Serves one :class:`ViewerSite` on ``host:port`` (port 0: the OS picks a free one), and
    ``extra_routes`` (URL path -> file) besides.
    ``url``: the page's address.  ``serve_forever`` / ``shutdown`` as any ``socketserver``."""

    daemon_threads = True

    def __init__(self, site: ViewerSite | CitySite, port: int = 0, host: str = "127.0.0.1",
                 extra_routes: Mapping[str, Path] | None = None) -> None:
        if host not in ("127.0.0.1", "localhost", "::1"):
            raise ValueError(f"the viewer serves on the loopback interface only, got host {host!r}")
        if not 0 <= int(port) <= 65535:
            raise ValueError(f"port must be in 0..65535, got {port}")
        self.site = site
        self.routes: dict[str, Body] = dict(site.routes())
        self._made: dict[str, bytes] = {}
        self._made_lock = threading.Lock()
        config = self.routes["/api/config.json"]
        self.routes["/api/config.json"] = config() if callable(config) else config   # bad content fails here, not in a request
        for route, path in (extra_routes or {}).items():  # e.g. a test page and the three.js build
            if not route.startswith("/") or not Path(path).is_file():
                raise ValueError(f"extra route {route!r}: must start with '/' and name a file, got {path}")
            self.routes[route] = Path(path)
        super().__init__((host, int(port)), _Handler)

    def body(self, path: str) -> bytes | None:
        """The bytes served at ``path``, or ``None`` (404); a route made on request is made once."""
        item = self.routes.get(path)
        if item is None or isinstance(item, bytes):
            return item
        if isinstance(item, Path):
            return item.read_bytes()
        with self._made_lock:
            if path not in self._made:
                self._made[path] = item()
            return self._made[path]

    @property
    def url(self) -> str:
        """``http://127.0.0.1:PORT/``."""
        host, port = self.server_address[:2]
        return f"http://{host}:{port}/"


class _Handler(BaseHTTPRequestHandler):
    server: ViewerServer

    def _send(self, head_only: bool) -> None:
        path = unquote(urlsplit(self.path).path)
        body = self.server.body(path)
        if body is None:
            self.send_error(HTTPStatus.NOT_FOUND, f"{path} is not served")
            return
        suffix = Path(path).suffix if path != "/" else ".html"
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", CONTENT_TYPES.get(suffix, "application/octet-stream"))
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        if not head_only:
            self.wfile.write(body)

    def do_GET(self) -> None:  # noqa: N802 (http.server's name)
        self._send(False)

    def do_HEAD(self) -> None:  # noqa: N802
        self._send(True)

    def log_message(self, format: str, *args: object) -> None:  # quiet: the page makes many requests
        pass


def serve(site: ViewerSite | CitySite, port: int = 0, host: str = "127.0.0.1",
          extra_routes: Mapping[str, Path] | None = None) -> tuple[ViewerServer, threading.Thread]:
    """Start a :class:`ViewerServer` for ``site`` in a daemon thread; returns it and the thread
    (stop with ``server.shutdown(); server.server_close()``)."""
    server = ViewerServer(site, port, host, extra_routes)
    # a short poll: shutdown() returns within 50 ms (the default 0.5 s adds up over the tests' servers)
    thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, name="envcap-viewer", daemon=True)
    thread.start()
    return server, thread
