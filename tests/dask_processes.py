"""Helpers shared by the tests that run real Dask processes (not a test module): a free port on
127.0.0.1, a process's output drained on a thread (so a chatty worker never blocks on a full
pipe), the live processes of a session, and stopping a whole session."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import threading
import time
from pathlib import Path


def free_port() -> int:
    """A TCP port on 127.0.0.1 that was free a moment ago."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Drained:
    """The output lines of ``proc`` (started with ``stdout=PIPE``, text), read on a thread."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        self.proc = proc
        self.lines: list[str] = []
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line)

    def wait_for(self, text: str, timeout: float) -> None:
        """Wait until a line contains ``text``; ``AssertionError`` with the output otherwise."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if any(text in line for line in self.lines):
                return
            if self.proc.poll() is not None:
                break
            time.sleep(0.1)
        raise AssertionError(f"no {text!r} from {self.proc.args} (exit {self.proc.poll()}):\n" + "".join(self.lines[-40:]))


def session_processes(sid: int) -> list[int]:
    """Live (not zombie) processes of session ``sid`` other than its leader."""
    found = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit() or int(d.name) == sid:
            continue
        try:
            fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[3]) == sid and fields[0] != "Z":
            found.append(int(d.name))
    return found


def wait_gone(sid: int, timeout: float) -> list[int]:
    """Wait until session ``sid`` has no live process left; return those still alive."""
    deadline = time.monotonic() + timeout
    while (left := session_processes(sid)) and time.monotonic() < deadline:
        time.sleep(0.1)
    return left


def stop_session(proc: subprocess.Popen[str]) -> None:
    """SIGTERM the session ``proc`` leads (started with ``start_new_session=True``), then SIGKILL
    whatever is left after 10 s."""
    for sig, wait in ((signal.SIGTERM, 10.0), (signal.SIGKILL, 5.0)):
        if proc.poll() is None or session_processes(proc.pid):
            try:
                os.killpg(proc.pid, sig)
            except ProcessLookupError:
                pass
            try:
                proc.wait(timeout=wait)
            except subprocess.TimeoutExpired:
                pass
            wait_gone(proc.pid, wait)
