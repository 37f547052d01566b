"""Fixtures of the journey tests: a user's terminal in a fresh, empty working directory.

A journey types whole command lines, exactly as the user guide (``docs/guide.md``) prints them,
and feeds each command's output to the next unchanged.  ``envcap`` on a line runs this checkout's
``envcap`` (``python -m envcap`` with the checkout first on ``PYTHONPATH``, as an installed
``envcap`` console script would run it); every other program is looked up on ``PATH``.
"""

from __future__ import annotations

import os
import shlex
import socket
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@dataclass
class Terminal:
    """A shell-like runner: ``cwd`` is the user's working directory (empty at the start).

    ``transcript`` keeps every line typed and its exit status, for failure messages."""

    cwd: Path
    env: dict[str, str]
    transcript: list[str] = field(default_factory=list)

    def argv(self, line: str) -> list[str]:
        words = shlex.split(line)
        if words and words[0] == "envcap":
            return [sys.executable, "-m", "envcap", *words[1:]]
        return words

    def run(self, line: str, *, ok: bool = True, timeout: float = 600) -> subprocess.CompletedProcess[str]:
        """Run ``line`` in :attr:`cwd` and wait.  ``ok``: fail the test (with the transcript and the
        command's output) unless it exits 0; ``ok=False`` returns whatever it did."""
        proc = subprocess.run(self.argv(line), cwd=self.cwd, env=self.env, capture_output=True, text=True,
                              timeout=timeout, check=False)
        self.transcript.append(f"$ {line}  # exit {proc.returncode}")
        if ok and proc.returncode != 0:
            pytest.fail("\n".join([*self.transcript, "--- stdout ---", proc.stdout[-4000:],
                                   "--- stderr ---", proc.stderr[-4000:]]), pytrace=False)
        return proc

    def start(self, line: str, *, cwd: Path | None = None) -> subprocess.Popen[str]:
        """Start ``line`` in the background (a server, a cluster process); the caller stops it."""
        self.transcript.append(f"$ {line} &")
        return subprocess.Popen(self.argv(line), cwd=cwd or self.cwd, env=self.env, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True, start_new_session=True)

    @staticmethod
    def first_line(proc: subprocess.Popen[str], prefix: str, limit: int = 40) -> str:
        """The first line of a background process's output (:meth:`start`) that starts with
        ``prefix``; fails the test with what it said when it exits or says ``limit`` lines first."""
        seen = []
        for _ in range(limit):
            line = proc.stdout.readline() if proc.stdout is not None else ""
            if not line:
                break
            seen.append(line)
            if line.startswith(prefix):
                return line
        pytest.fail(f"no '{prefix}' line; the process said:\n{''.join(seen)}", pytrace=False)

    @staticmethod
    def free_port() -> int:
        """A TCP port on 127.0.0.1 that nothing listens on now (for ``--port``)."""
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            return s.getsockname()[1]


@pytest.fixture
def terminal(tmp_path: Path) -> Terminal:
    """A fresh, empty working directory (``tmp_path / "work"``) and the environment a user has:
    this checkout importable, headless EGL, unbuffered Python output."""
    work = tmp_path / "work"
    work.mkdir()
    env = dict(os.environ, PYOPENGL_PLATFORM="egl", PYTHONUNBUFFERED="1")
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])
    return Terminal(work, env)
