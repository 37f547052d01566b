"""The viewer's HTTP server: :mod:`http.server` on the loopback interface, hardened for a probe set
that is untrusted input and for a browser whose other tabs are not.

Routes (GET / HEAD): the site's :meth:`~envcap.viewer.site.ViewerSite.routes` (a city's:
:meth:`~envcap.viewer.city_site.CitySite.routes`), the list ``envcap export web`` writes too:
``/`` -> ``web/index.html``; ``/three.html``; ``/three_webgpu.html``; ``/web/NAME`` and ``/three/NAME`` -> the page's static
files (:data:`envcap.viewer.site.WEB_DIR`); ``/set/NAME`` -> the files the probe set's manifest
names (``manifest.json``, ``probes_atlas.ktx2``, ``sky.ktx2``, ...); ``/report/NAME`` -> the
report's ``report.json`` and PNG plots; ``/api/config.json`` and ``/api/runtime.glsl``
(:mod:`envcap.viewer.site`); the crowd's fixed ``/api/crowd*`` routes (:mod:`envcap.viewer.crowd_site`).  Anything else is 404.

What the server guarantees (``docs/reliability.md``, "Threat model"):

* **files of the set only**: a route's file is the resolved path the site checked to lie inside
  the set (:func:`envcap.core.contained_path.resolve_inside`), fixed when the server starts; no
  request path is ever joined to a directory.  When a file is read, it must still be that path
  with no link on the way (``realpath``, ``O_NOFOLLOW``) and a regular file, else 404: a file
  swapped for a link while the server runs is not followed;
* **no echo**: every error is a fixed status line with the code's standard reason phrase and a
  fixed ``text/plain`` body (:meth:`_Handler.send_error`), so nothing of the request reaches a
  header or a page;
* **well-formed requests only**: a request target that is not ``/``-rooted ASCII, holds a control
  byte, or whose percent-escapes are not UTF-8 (``/%c0%ae``) is a 400; a request line without an
  HTTP version is a 400 (no HTTP/0.9);
* **Host check** (DNS rebinding): exactly one ``Host`` header naming ``127.0.0.1``, ``localhost``
  or ``[::1]`` with the served port, else 421 Misdirected Request;
* **bounded**: each connection's socket times out after ``timeout_s`` without progress; at most
  ``max_connections`` are served at once (one thread each), the others get a 503 at once and no
  thread; the listen queue is :attr:`ViewerServer.request_queue_size`;
* **quiet**: a client that goes away mid-answer (``BrokenPipeError``, ``ConnectionResetError``) or
  times out prints nothing; anything else unexpected prints one line, never a traceback;
* **security headers** on every answer: ``X-Content-Type-Options: nosniff``, a
  ``Content-Security-Policy`` (:func:`content_security_policy`: same-origin scripts, styles,
  images and fetches; inline ``<script>``/``<style>`` blocks of the page by their SHA-256 hashes,
  no ``'unsafe-inline'``, no ``eval``; no framing), ``Referrer-Policy: no-referrer``,
  ``Cross-Origin-Resource-Policy`` and ``Cross-Origin-Opener-Policy: same-origin``,
  ``Cache-Control: no-store``, and a ``Server`` header without versions.

The standard library fits here: the site is a fixed list of files read once per request on one
machine, and the hardening above is a few overrides of :class:`http.server.BaseHTTPRequestHandler`
(a framework would add a dependency to a package that otherwise needs none for ``envcap view``).
"""

from __future__ import annotations

import base64
import hashlib
import math
import os
import re
import socket
import stat
import sys
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Mapping
from urllib.parse import unquote

from envcap.viewer.city_site import CitySite
from envcap.viewer.site import Body, ViewerSite

CONTENT_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
                 ".css": "text/css; charset=utf-8", ".json": "application/json", ".png": "image/png",
                 ".ktx2": "image/ktx2", ".glsl": "text/plain; charset=utf-8",
                 ".wgsl": "text/wgsl; charset=utf-8", ".exr": "image/x-exr",
                 ".md": "text/markdown; charset=utf-8", ".glb": "model/gltf-binary"}

TIMEOUT_S = 10.0
"""Default socket timeout of a connection (s): an idle or stalled client is dropped after it."""
MAX_CONNECTIONS = 32
"""Default number of connections served at once (one thread each); a browser opens about 6."""
LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]")
"""The host names a request's ``Host`` header may carry (with the served port)."""

_INLINE = re.compile(rb"<(script|style)\b([^>]*)>(.*?)</\1\s*>", re.IGNORECASE | re.DOTALL)
_BUSY = (b"HTTP/1.0 503 Service Unavailable\r\nContent-Type: text/plain; charset=utf-8\r\nContent-Length: 24\r\n"
         b"Retry-After: 1\r\nConnection: close\r\nX-Content-Type-Options: nosniff\r\n\r\n503 Service Unavailable\n")


def content_security_policy(html: bytes | None = None) -> str:
    """The ``Content-Security-Policy`` of a response: everything from the viewer's own origin,
    nothing inline except the ``<script>`` (without ``src``) and ``<style>`` blocks of ``html``
    (the page served), allowed by their SHA-256 hashes; ``data:`` images (the page's blank
    icon); no ``eval``, plugins, forms, ``<base>`` or framing."""
    scripts: list[str] = []
    styles: list[str] = []
    for tag, attrs, text in _INLINE.findall(html or b""):
        if tag.lower() == b"script" and re.search(rb"\bsrc\s*=", attrs):
            continue
        digest = "'sha256-" + base64.b64encode(hashlib.sha256(text).digest()).decode() + "'"
        (scripts if tag.lower() == b"script" else styles).append(digest)
    return ("default-src 'none'; " + " ".join(["script-src 'self'", *scripts]) + "; "
            + " ".join(["style-src 'self'", *styles]) + "; img-src 'self' data:; connect-src 'self'; "
            "base-uri 'none'; form-action 'none'; frame-ancestors 'none'")


def request_path(target: str) -> str | None:
    """The decoded path of a request target (``/set/a%20b.ktx2?x=1`` -> ``/set/a b.ktx2``), or
    ``None`` when the target is malformed: not starting with ``/``, not printable ASCII,
    percent-escapes that are not UTF-8, or a control character once decoded."""
    if not target.startswith("/") or not target.isascii() or any(c <= " " or c == "\x7f" for c in target):
        return None
    path = target.split("?", 1)[0].split("#", 1)[0]
    try:
        decoded = unquote(path, errors="strict")
    except UnicodeDecodeError:
        return None
    if any(ord(c) < 0x20 or 0x7f <= ord(c) < 0xa0 for c in decoded):
        return None
    return decoded


def read_route_file(path: Path) -> bytes | None:
    """The bytes of the regular file ``path`` (an absolute path with every link resolved), or
    ``None`` when it is no longer that: a link now sits on the way (``realpath`` differs, or the
    file itself is a link: ``O_NOFOLLOW``), it is gone, or it is not a regular file (a FIFO is
    opened without blocking and refused)."""
    if os.path.realpath(path) != str(path):
        return None
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError:
        return None
    with os.fdopen(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
            return None
        return f.read()


class ViewerServer(ThreadingHTTPServer):
    """Serves one :class:`ViewerSite` (or :class:`CitySite`) on ``host:port`` (port 0: the OS
    picks a free one; ``host`` a loopback name only), and ``extra_routes`` (URL path -> file)
    besides.  ``timeout_s``: each connection's socket timeout (s); ``max_connections``: how many
    are served at once (module docstring).  ``url``: the page's address.  ``serve_forever`` /
    ``shutdown`` as any ``socketserver``."""

    daemon_threads = True
    request_queue_size = 128

    def __init__(self, site: ViewerSite | CitySite, port: int = 0, host: str = "127.0.0.1",
                 extra_routes: Mapping[str, Path] | None = None, *, timeout_s: float = TIMEOUT_S,
                 max_connections: int = MAX_CONNECTIONS) -> None:
        if host not in ("127.0.0.1", "localhost", "::1"):
            raise ValueError(f"the viewer serves on the loopback interface only, got host {host!r}")
        if not 0 <= int(port) <= 65535:
            raise ValueError(f"port must be in 0..65535, got {port}")
        if not (math.isfinite(timeout_s) and timeout_s > 0):
            raise ValueError(f"timeout_s must be a positive number of seconds, got {timeout_s}")
        if not 1 <= int(max_connections) <= 10_000:
            raise ValueError(f"max_connections must be in 1..10000, got {max_connections}")
        self.site = site
        self.timeout_s = float(timeout_s)
        self.max_connections = int(max_connections)
        self._slots = threading.BoundedSemaphore(self.max_connections)
        self.routes: dict[str, Body] = {}
        for route, item in site.routes().items():   # files: the resolved paths the site checked
            self.routes[route] = Path(item).resolve() if isinstance(item, Path) else item
        self._made: dict[str, bytes] = {}
        self._made_lock = threading.Lock()
        config = self.routes["/api/config.json"]
        self.routes["/api/config.json"] = config() if callable(config) else config   # bad content fails here, not in a request
        for route, path in (extra_routes or {}).items():  # e.g. a test page and the three.js build
            if not route.startswith("/") or not Path(path).is_file():
                raise ValueError(f"extra route {route!r}: must start with '/' and name a file, got {path}")
            self.routes[route] = Path(path).resolve()
        self.address_family = socket.AF_INET6 if host == "::1" else socket.AF_INET
        super().__init__((host, int(port)), _Handler)
        served = self.server_address[1]
        self.allowed_hosts = frozenset({f"{h}:{served}" for h in LOOPBACK_NAMES}
                                       | (set(LOOPBACK_NAMES) if served == 80 else set()))

    def body(self, path: str) -> bytes | None:
        """The bytes served at ``path``, or ``None`` (404); a route made on request is made once."""
        item = self.routes.get(path)
        if item is None or isinstance(item, bytes):
            return item
        if isinstance(item, Path):
            return read_route_file(item)
        with self._made_lock:
            if path not in self._made:
                self._made[path] = item()
            return self._made[path]

    @property
    def url(self) -> str:
        """``http://127.0.0.1:PORT/`` (``http://[::1]:PORT/`` on IPv6)."""
        host, port = self.server_address[:2]
        return f"http://{'[' + host + ']' if ':' in host else host}:{port}/"

    def process_request(self, request, client_address) -> None:  # type: ignore[no-untyped-def]
        """A thread for the connection while fewer than ``max_connections`` are served, else a
        503 at once from this thread, and the connection closed."""
        if not self._slots.acquire(blocking=False):
            try:
                request.setblocking(False)
                try:
                    request.recv(65536)   # what the client sent already: closing on unread data would reset
                except OSError:
                    pass
                request.send(_BUSY)
            except OSError:
                pass
            self.shutdown_request(request)
            return
        try:
            super().process_request(request, client_address)
        except BaseException:
            self._slots.release()
            raise

    def process_request_thread(self, request, client_address) -> None:  # type: ignore[no-untyped-def]
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._slots.release()

    def handle_error(self, request, client_address) -> None:  # type: ignore[no-untyped-def]
        """Nothing for a client that went away or timed out; one line for anything else."""
        exc = sys.exc_info()[1]
        if isinstance(exc, (ConnectionError, TimeoutError)):
            return
        print(f"envcap viewer: error answering a request: {type(exc).__name__}: {exc}", file=sys.stderr, flush=True)


class _Handler(BaseHTTPRequestHandler):
    server: ViewerServer
    server_version = "envcap-viewer"
    default_request_version = "HTTP/1.0"   # errors before the version is read still get a status line

    def setup(self) -> None:
        self.timeout = self.server.timeout_s   # the socket's timeout (StreamRequestHandler.setup)
        super().setup()

    def version_string(self) -> str:
        return self.server_version

    def parse_request(self) -> bool:
        if not super().parse_request():
            return False
        if len(self.requestline.split()) != 3:   # no HTTP version: HTTP/0.9 is not served
            self.send_error(HTTPStatus.BAD_REQUEST)
            return False
        return True

    def _headers(self, content_type: str, length: int, html: bytes | None = None) -> None:
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(length))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Content-Security-Policy", content_security_policy(html))
        self.send_header("Referrer-Policy", "no-referrer")
        self.send_header("Cross-Origin-Resource-Policy", "same-origin")
        self.send_header("Cross-Origin-Opener-Policy", "same-origin")

    def send_error(self, code: int, message: str | None = None, explain: str | None = None) -> None:
        """A fixed answer: the code's standard reason phrase and body, whatever ``message`` and
        ``explain`` say (http.server puts parts of the request in them), and the connection closed."""
        try:
            status = HTTPStatus(int(code))
        except ValueError:
            status = HTTPStatus.INTERNAL_SERVER_ERROR
        body = f"{status.value} {status.phrase}\n".encode()
        self.close_connection = True
        self.send_response(status.value)
        self._headers("text/plain; charset=utf-8", len(body))
        self.send_header("Connection", "close")
        self.end_headers()
        if self.command != "HEAD" and status.value >= 200 and status.value not in (204, 304):
            self.wfile.write(body)

    def _host_ok(self) -> bool:
        hosts = self.headers.get_all("Host") or []
        return len(hosts) == 1 and hosts[0].strip().lower() in self.server.allowed_hosts

    def _send(self, head_only: bool) -> None:
        if not self._host_ok():
            self.send_error(HTTPStatus.MISDIRECTED_REQUEST)
            return
        path = request_path(self.path)
        if path is None:
            self.send_error(HTTPStatus.BAD_REQUEST)
            return
        try:
            body = self.server.body(path)
        except Exception as exc:   # a route made on request failed: one line, a fixed 500
            print(f"envcap viewer: error making {path!r}: {type(exc).__name__}: {exc}", file=sys.stderr, flush=True)
            self.send_error(HTTPStatus.INTERNAL_SERVER_ERROR)
            return
        if body is None:
            self.send_error(HTTPStatus.NOT_FOUND)
            return
        suffix = Path(path).suffix if path != "/" else ".html"
        ctype = CONTENT_TYPES.get(suffix, "application/octet-stream")
        self.send_response(HTTPStatus.OK)
        self._headers(ctype, len(body), body if suffix == ".html" else None)
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
          extra_routes: Mapping[str, Path] | None = None, *, timeout_s: float = TIMEOUT_S,
          max_connections: int = MAX_CONNECTIONS) -> tuple[ViewerServer, threading.Thread]:
    """Start a :class:`ViewerServer` for ``site`` in a daemon thread; returns it and the thread
    (stop with ``server.shutdown(); server.server_close()``)."""
    server = ViewerServer(site, port, host, extra_routes, timeout_s=timeout_s, max_connections=max_connections)
    # a short poll: shutdown() returns within 50 ms (the default 0.5 s adds up over the tests' servers)
    thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, name="envcap-viewer", daemon=True)
    thread.start()
    return server, thread
