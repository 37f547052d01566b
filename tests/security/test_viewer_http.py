"""The viewer's HTTP server (``envcap view``) against hostile requests, over raw sockets: a path
with CR LF never becomes a header or a page (fixed reason phrases and bodies, the path never
echoed), a path that is not UTF-8 is a 400 (no traceback, no dropped connection), a Host header
other than the loopback at the served port is refused (DNS rebinding), idle connections are
closed after the timeout, connections past the limit add no thread, an aborted download prints
nothing, every response carries the security headers, and the pages still run under their
Content-Security-Policy in Chromium.  A Hypothesis fuzz sends random request lines and headers:
always a well-formed status line or a close, never a traceback, never a file outside the set."""

from __future__ import annotations

import re
import shutil
import socket
import threading
import time

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from raw_http import exchange, get, parse

from envcap.viewer import ViewerSite, serve

SECRET = b"envcap-test-secret-3f9c2e1d"


@pytest.fixture(scope="module")
def site_root(web_probe_dir, tmp_path_factory):
    """``root/set`` (a copy of the probe set), ``root/secret.txt`` beside it (never to be served)
    and ``root/big.bin`` (16 MiB, served at ``/big.bin`` by the tests' extra route)."""
    root = tmp_path_factory.mktemp("viewer_http")
    shutil.copytree(web_probe_dir, root / "set")
    (root / "secret.txt").write_bytes(SECRET + b"\n")
    (root / "big.bin").write_bytes(bytes(range(256)) * (16 << 12))
    return root


@pytest.fixture(scope="module")
def server(site_root):
    srv, thread = serve(ViewerSite.open(site_root / "set"), extra_routes={"/big.bin": site_root / "big.bin"})
    yield srv
    srv.shutdown()
    srv.server_close()
    thread.join(5)


def port_of(srv) -> int:
    return srv.server_address[1]


def test_the_page_is_served_to_a_loopback_host(server):
    p = port_of(server)
    for host in (f"127.0.0.1:{p}", f"localhost:{p}", f"LocalHost:{p}", f"[::1]:{p}"):
        r = get(p, "/", host=host)
        assert r.status == 200 and b'src="web/viewer.js"' in r.body, host


@pytest.mark.parametrize("target", [
    "/x%0d%0aSet-Cookie:%20injected=1",
    "/x%0aSet-Cookie:%20injected=1",
    "/x%0d%0a%0d%0a<script>alert('injected')</script>",
    "/<script>alert('injected')</script>",
    "/set/manifest.json%0d%0aX-Injected:%201",
])
def test_a_path_with_cr_lf_injects_no_header_and_is_never_echoed(server, target):
    r = get(port_of(server), target)
    assert r.status in (400, 404)   # parse() checked the reason phrase is the code's standard one
    assert not [k for k, _ in r.headers if k in ("set-cookie", "x-injected")]
    assert b"injected" not in r.raw.lower() and b"<script" not in r.raw.lower() and b"%0d" not in r.raw.lower()
    assert r.header("content-type").startswith("text/plain")


@pytest.mark.parametrize("request_line, code", [
    (b"GET / HTTP/9.<b>x</b>", 400),            # http.server's own errors put this in the reason phrase
    (b"GET / HTTP/1.1 <b>x</b>", 400),
    (b"FOO<b>x</b> / HTTP/1.0", 501),
    (b"POST / HTTP/1.0", 501),
])
def test_errors_have_fixed_reason_phrases_and_bodies(server, request_line, code):
    p = port_of(server)
    r = parse(exchange(p, request_line + f"\r\nHost: 127.0.0.1:{p}\r\n\r\n".encode()))
    assert r.status == code
    assert b"<b>" not in r.raw and b"FOO" not in r.raw


@pytest.mark.parametrize("target", ["/%c0%ae%c0%ae/etc/passwd", "/%ff", "/set/%e9t%e9.ktx2", b"/caf\xc3\xa9",
                                    b"/\xff\xfe", "/set/a%00b"])
def test_a_path_that_is_not_utf8_or_has_control_bytes_is_400(server, target, capfd):
    r = get(port_of(server), target)
    assert r.status == 400 and r.reason == "Bad Request"
    assert b"etc" not in r.body and b"%" not in r.body
    assert capfd.readouterr().err == ""


def test_a_utf8_path_that_is_not_latin1_is_an_ordinary_404(server, capfd):
    r = get(port_of(server), "/%e2%82%ac/%d0%96")   # U+20AC, U+0416: UTF-8, outside Latin-1
    assert r.status == 404 and r.reason == "Not Found"
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("host", ["evil.example", "evil.example:{p}", "127.0.0.1:{q}", "localhost", "127.0.0.2:{p}",
                                  "localhost.evil.example:{p}", "127.0.0.1:{p}@evil.example", "0.0.0.0:{p}",
                                  "[::1]", "[::ffff:127.0.0.1]:{p}", "", None])
def test_a_host_that_is_not_the_loopback_at_the_served_port_is_refused(server, host):
    """DNS rebinding: a page of evil.example whose name now points to 127.0.0.1 sends
    ``Host: evil.example:P``; the viewer must not answer it with the page or the probe set."""
    p = port_of(server)
    h = None if host is None else host.format(p=p, q=p + 1 if p < 65535 else p - 1)
    for target in ("/", "/set/manifest.json", "/api/config.json"):
        r = get(p, target, host=h)
        assert r.status in (421, 400), (h, r.status)
        assert b"envcap" not in r.body and b"streets" not in r.body


def test_two_host_headers_are_refused(server):
    p = port_of(server)
    r = get(p, "/", extra=b"Host: evil.example\r\n")
    assert r.status in (400, 421) and b"viewer.js" not in r.body


def test_every_response_carries_the_security_headers(server):
    p = port_of(server)
    for target, status in (("/", 200), ("/three.html", 200), ("/web/viewer.js", 200), ("/set/manifest.json", 200),
                           ("/nothing", 404)):
        r = get(p, target)
        assert r.status == status
        assert r.header("x-content-type-options") == "nosniff"
        csp = r.header("content-security-policy")
        assert csp and "default-src 'none'" in csp and "frame-ancestors 'none'" in csp, csp
        assert "'unsafe-inline'" not in csp and "'unsafe-eval'" not in csp
        assert r.header("referrer-policy") == "no-referrer"
        assert "python" not in (r.header("server") or "").lower()   # no version banner


def test_an_idle_connection_is_closed_after_the_timeout(site_root):
    srv, thread = serve(ViewerSite.open(site_root / "set"), timeout_s=0.3)
    try:
        for sent in (b"", b"GET / HTTP/1.1\r\nHost: 127.0.0.1"):   # nothing, and half a request
            with socket.create_connection(("127.0.0.1", port_of(srv)), timeout=5) as s:
                s.sendall(sent)
                t0 = time.monotonic()
                assert s.recv(65536) == b""        # closed by the server, not by our 5 s timeout
                assert time.monotonic() - t0 < 3.0
    finally:
        srv.shutdown()
        srv.server_close()
        thread.join(5)


def test_connections_past_the_limit_add_no_thread_and_are_answered_503(server):
    """200 idle sockets made 202 threads; now at most ``max_connections`` (default) handler
    threads, and the connections past it get a 503 at once; the server serves again after."""
    p = port_of(server)
    limit = server.max_connections
    assert 4 <= limit <= 64
    before = threading.active_count()
    socks = []
    try:
        for _ in range(limit + 40):
            socks.append(socket.create_connection(("127.0.0.1", p), timeout=5))
        time.sleep(0.3)
        assert threading.active_count() - before <= limit
        # the last ones were over the limit: answered 503 and closed, without a thread
        over = socks[-1]
        data = b""
        while chunk := over.recv(65536):
            data += chunk
        r = parse(data)
        assert r.status == 503 and r.header("retry-after")
    finally:
        for s in socks:
            s.close()
    end = time.monotonic() + 5
    while threading.active_count() - before > 0 and time.monotonic() < end:
        time.sleep(0.05)
    assert get(p, "/").status == 200


def test_an_aborted_download_prints_nothing(server, capfd):
    p = port_of(server)
    for _ in range(4):
        s = socket.create_connection(("127.0.0.1", p), timeout=5)
        s.sendall(f"GET /big.bin HTTP/1.1\r\nHost: 127.0.0.1:{p}\r\n\r\n".encode())
        assert s.recv(4096)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")   # close = RST
        s.close()
    time.sleep(0.5)
    assert get(p, "/").status == 200
    assert capfd.readouterr().err == ""


def _inline_hashes_needed(html: bytes) -> int:
    return len(re.findall(rb"<script(?![^>]*\bsrc=)[^>]*>|<style[^>]*>", html))


def test_the_pages_run_under_their_content_security_policy(server, chromium):
    """The viewer page and three.html in Chromium: ready, no CSP violation, styles applied (the
    stylesheet of index.html, the inline <style> and import map of three.html)."""
    from envcap.viewer.site import WEB_DIR

    assert _inline_hashes_needed((WEB_DIR / "three.html").read_bytes()) == 2
    for page, ready, check in (
            ("", "window.envcap.ready", "getComputedStyle(document.querySelector('aside')).position !== 'static'"
                                        " || document.styleSheets[0].cssRules.length > 0"),
            ("three.html", "window.example.ready", "getComputedStyle(document.body).marginTop === '0px'"
                                                    " && getComputedStyle(document.body).overflow === 'hidden'")):
        chromium.errors.clear()
        chromium.goto(server.url + page)
        assert chromium.evaluate(f"{ready}.then(() => 'ok', e => 'error: ' + e.message)") == "ok", chromium.errors
        assert chromium.evaluate(check) is True, page
        assert not [e for e in chromium.errors if "Content Security Policy" in e or "Refused" in e], chromium.errors


# --------------------------------------------------------------------------------------------
# Fuzz: random request lines, paths and headers

SEGMENTS = ["set", "..", "%2e%2e", "%2E%2e", ".", "", "secret.txt", "manifest.json", "%2f", "%00", "%0d%0a",
            "%c0%ae", "%ff", "web", "api", "config.json", "probes_atlas.ktx2", "report", "etc", "passwd", "%5c..",
            "..%2f..%2fsecret.txt", "big.bin", "three", "//", "?q=1", "#f", "%", "%2", "\\..\\"]


@st.composite
def requests(draw, port: int, root) -> bytes:
    seg = st.sampled_from(SEGMENTS) | st.text(max_size=6)
    parts = draw(st.lists(seg, max_size=7))
    path = ("/" if draw(st.booleans()) else "") + "/".join(parts)
    target = draw(st.sampled_from([path.encode("utf-8", "surrogatepass"), path.encode("utf-8", "surrogatepass"),
                                   ("/set/" + str(root / "secret.txt")).encode(),
                                   ("/set/../" * draw(st.integers(1, 8)) + "secret.txt").encode(),
                                   f"http://127.0.0.1:{port}/set/manifest.json".encode(), b"*"])
                         | st.binary(max_size=24))
    method = draw(st.sampled_from([b"GET", b"GET", b"HEAD", b"POST", b"OPTIONS", b"get", b"", b"GET GET", b"CONNECT"])
                  | st.binary(max_size=6))
    version = draw(st.sampled_from([b"HTTP/1.1", b"HTTP/1.1", b"HTTP/1.0", b"HTTP/0.9", b"HTTP/2.0", b"", b"HTTP/1.1x",
                                    b"HTTP/1.1 extra", b"HTTP/01.01"]) | st.binary(max_size=10))
    host = draw(st.sampled_from([f"127.0.0.1:{port}", f"localhost:{port}", "evil.example", None, f"[::1]:{port}"]))
    names = st.sampled_from([b"Host", b"Content-Length", b"Transfer-Encoding", b"Range", b"Expect", b"Connection",
                             b"X-Forwarded-Host", b"Cookie"]) | st.binary(min_size=1, max_size=12)
    values = st.sampled_from([b"100-continue", b"chunked", b"bytes=0-10", b"-1", b"99999999999999999999", b"keep-alive",
                              b"\xff\xfe", b"evil.example"]) | st.binary(max_size=30)
    headers = draw(st.lists(st.tuples(names, values), max_size=4))
    line_end = draw(st.sampled_from([b"\r\n", b"\r\n", b"\n"]))
    req = method + b" " + target + (b" " + version if version else b"") + line_end
    if host is not None:
        req += b"Host: " + host.encode() + line_end
    for k, v in headers:
        req += k + b": " + v + line_end
    return req + line_end


def test_fuzzed_requests_get_a_status_line_or_a_close_never_a_traceback_or_a_file_outside(server, site_root, capfd):
    p = port_of(server)
    seen: dict[int | None, int] = {}

    @settings(max_examples=250, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    @given(req=requests(p, site_root))
    @example(req=b"GET /%c0%ae%c0%ae/etc/passwd HTTP/1.1\r\nHost: 127.0.0.1:" + str(p).encode() + b"\r\n\r\n")
    @example(req=b"GET /set//" + str(site_root / "secret.txt").encode().lstrip(b"/") + b" HTTP/1.1\r\n\r\n")
    def check(req: bytes) -> None:
        raw = exchange(p, req, timeout=10)
        r = parse(raw)                                 # empty, or a status line with its standard phrase
        seen[r.status] = seen.get(r.status, 0) + 1
        assert SECRET not in raw

    check()
    err = capfd.readouterr().err
    assert err == "", err[-2000:]
    assert len(seen) >= 3, seen      # the fuzz reached several outcomes (200, 400, 404, 421, 501, ...)
