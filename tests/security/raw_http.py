"""Raw HTTP for the viewer's security tests: bytes on a socket, exactly as given (no client that
normalises the path, adds a Host header or refuses control characters), and a strict reading of
what comes back."""

from __future__ import annotations

import re
import socket
from dataclasses import dataclass
from http import HTTPStatus

STATUS_LINE = re.compile(rb"HTTP/1\.[01] (\d{3}) ([^\r\n]*)")


@dataclass
class Response:
    """What the server sent: ``raw`` bytes; ``status`` and ``reason`` of a well-formed status line
    (``None`` when nothing came back); header ``(name, value)`` pairs (lower-case names); ``body``."""

    raw: bytes
    status: int | None
    reason: str | None
    headers: list[tuple[str, str]]
    body: bytes

    def header(self, name: str) -> str | None:
        return next((v for k, v in self.headers if k == name.lower()), None)


def exchange(port: int, data: bytes, timeout: float = 5.0) -> bytes:
    """Send ``data`` to 127.0.0.1:``port``, half-close, and read until the server closes (or
    ``timeout`` s pass without a byte: ``TimeoutError``)."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        try:
            s.sendall(data)
            s.shutdown(socket.SHUT_WR)
        except (BrokenPipeError, ConnectionResetError):   # the server may answer and close before all was sent
            pass
        out = bytearray()
        while True:
            try:
                chunk = s.recv(65536)
            except ConnectionResetError:
                break
            if not chunk:
                break
            out += chunk
    return bytes(out)


def parse(raw: bytes) -> Response:
    """Read ``raw`` as an HTTP/1.x response: ``AssertionError`` unless it is empty (the server
    closed) or a status line with the standard reason phrase of its code, headers of
    ``name: value`` lines, a blank line and the body."""
    if not raw:
        return Response(raw, None, None, [], b"")
    head, sep, body = raw.partition(b"\r\n\r\n")
    assert sep, f"no end of the header block in {raw[:300]!r}"
    lines = head.split(b"\r\n")
    m = STATUS_LINE.fullmatch(lines[0])
    assert m, f"not a status line: {lines[0][:200]!r}"
    code, reason = int(m.group(1)), m.group(2).decode("latin-1")
    assert reason == HTTPStatus(code).phrase, f"reason phrase {reason!r} for {code}"
    headers = []
    for ln in lines[1:]:
        name, colon, value = ln.partition(b":")
        assert colon and re.fullmatch(rb"[!#$%&'*+.^_`|~0-9A-Za-z-]+", name), f"not a header line: {ln[:200]!r}"
        headers.append((name.decode().lower(), value.strip().decode("latin-1")))
    return Response(raw, code, reason, headers, body)


def get(port: int, target: bytes | str, host: str | None = "default", extra: bytes = b"",
        method: bytes = b"GET", timeout: float = 5.0) -> Response:
    """``METHOD target HTTP/1.1`` with ``Host: 127.0.0.1:port`` (``host``: another value, or
    ``None`` for no Host header), ``extra`` header lines (each ending in CRLF), then parsed."""
    t = target.encode("latin-1") if isinstance(target, str) else target
    h = f"127.0.0.1:{port}" if host == "default" else host
    req = method + b" " + t + b" HTTP/1.1\r\n" + (b"" if h is None else b"Host: " + h.encode("latin-1") + b"\r\n")
    return parse(exchange(port, req + extra + b"Connection: close\r\n\r\n", timeout))
