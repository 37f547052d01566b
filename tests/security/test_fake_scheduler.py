"""Hostile schedulers (issue 20): ``envcap capture CITY --scheduler ADDRESS`` against a peer that
is not a Dask scheduler.  A peer that accepts the connection and never speaks hung the bake
forever; one that answers garbage gave a traceback (a frame header of 3 EiB became a 3 EiB
allocation).  Each must be one line ``envcap: error: ...`` naming the address, exit 2, within the
``--cluster-timeout``, before any output is claimed.

The fakes are plain sockets on 127.0.0.1 served by a thread of the test; the bake is the real
command in a child process (its whole stderr is judged).
"""

from __future__ import annotations

import os
import random
import socket
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

REPLIES = {
    "silent": None,                                                   # accepts, reads, never writes
    "huge_frame": struct.pack("<Q", 3 << 60) + b"x" * 64,          # a message header of 3 EiB
    "random_bytes": random.Random(20).randbytes(4096),
    "http": b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\nConnection: close\r\n\r\n",
}


class FakeScheduler:
    """A listening socket on 127.0.0.1 that answers every connection with ``reply`` (``None``:
    nothing, ever) and keeps it open until :meth:`close`."""

    def __init__(self, reply: bytes | None) -> None:
        self.reply = reply
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        self.conns: list[socket.socket] = []
        self.accepted = 0
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.server.accept()
            except OSError:
                return
            self.accepted += 1
            self.conns.append(conn)
            threading.Thread(target=self._talk, args=(conn,), daemon=True).start()

    def _talk(self, conn: socket.socket) -> None:
        try:
            if self.reply is not None:
                conn.sendall(self.reply)
            while conn.recv(65536):
                pass
        except OSError:
            pass

    def close(self) -> None:
        self.server.close()
        for c in self.conns:
            c.close()


@pytest.fixture(params=sorted(REPLIES))
def fake(request):
    f = FakeScheduler(REPLIES[request.param])
    yield f
    f.close()


@pytest.mark.slow                                                      # ~3-5 s each: a child interpreter
def test_a_peer_that_is_not_a_scheduler_is_one_line_within_the_timeout(fake, tmp_path):
    env = dict(os.environ, PYOPENGL_PLATFORM="egl", PYTHONPATH=os.pathsep.join(filter(None, [str(REPO),
                                                                                            os.environ.get("PYTHONPATH")])))
    address = f"tcp://127.0.0.1:{fake.port}"
    t0 = time.monotonic()
    r = subprocess.run([sys.executable, "-m", "envcap", "capture", "crossing", "--out", "city", "--resolution", "8",
                        "--spacing", "100", "--scheduler", address, "--cluster-timeout", "2"],
                       cwd=tmp_path, env=env, capture_output=True, text=True, timeout=90)
    took = time.monotonic() - t0
    lines = r.stderr.splitlines()
    assert r.returncode == 2 and len(lines) == 1 and lines[0].startswith("envcap: error:"), r.stderr
    assert address in lines[0]
    assert took < 30, f"took {took:.1f} s"
    assert fake.accepted >= 1                                         # it did talk to the fake
    assert list(tmp_path.iterdir()) == []                              # no city folder, nothing else
