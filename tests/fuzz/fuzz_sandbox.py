"""Sandboxes and guards for the fuzz cases: a fresh directory per case (``work/`` is the current
directory, ``tmp/`` the temporary one), snapshots of it, and cut-offs for runaways (``SIGALRM``
for time, a soft ``RLIMIT_AS`` for memory) so that a runaway case never endangers a shared machine.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import resource
import shutil
import signal
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

# --------------------------------------------------------------------------------------------
# Sandboxes and snapshots


class Sandbox:
    """A fresh directory for one case: ``work/`` (the current directory) and ``tmp/`` (temporary files)."""

    def __init__(self, base: Path) -> None:
        self.root = Path(tempfile.mkdtemp(prefix="case-", dir=base))
        self.work = self.root / "work"
        self.tmp = self.root / "tmp"
        self.work.mkdir()
        self.tmp.mkdir()

    def path(self, rel: str | os.PathLike[str]) -> Path:
        return self.work / rel

    def write(self, rel: str, data: bytes | str) -> Path:
        p = self.work / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(data, str):
            p.write_text(data)
        else:
            p.write_bytes(data)
        return p

    def copy(self, src: Path, rel: str) -> Path:
        dst = self.work / rel
        dst.parent.mkdir(parents=True, exist_ok=True)
        if src.is_dir():
            shutil.copytree(src, dst)
        else:
            shutil.copyfile(src, dst)
        return dst

    def remove(self) -> None:
        shutil.rmtree(self.root, ignore_errors=True)


@contextlib.contextmanager
def sandbox(base: Path) -> Iterator[Sandbox]:
    """A :class:`Sandbox` under ``base``, removed with everything in it when the block ends."""
    sb = Sandbox(base)
    try:
        yield sb
    finally:
        sb.remove()


def snapshot(root: Path) -> dict[str, str]:
    """Relative path -> ``"dir"`` / ``"link:target"`` / content digest, for everything under ``root``."""
    out: dict[str, str] = {}
    for dirpath, dirnames, filenames in os.walk(root):
        d = Path(dirpath)
        for name in dirnames:
            p = d / name
            out[str(p.relative_to(root))] = f"link:{os.readlink(p)}" if p.is_symlink() else "dir"
        for name in filenames:
            p = d / name
            rel = str(p.relative_to(root))
            if p.is_symlink():
                out[rel] = f"link:{os.readlink(p)}"
                continue
            try:
                out[rel] = hashlib.sha1(p.read_bytes()).hexdigest()
            except OSError as e:
                out[rel] = f"unreadable:{e.errno}"
    return out


# --------------------------------------------------------------------------------------------
# Guards against runaways


class Runaway(BaseException):
    """Raised by the watchdog in the case's own thread (a BaseException: ``except Exception`` misses it)."""


def _vm_bytes() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    return 0


@contextlib.contextmanager
def guard(timeout: float, mem: int) -> Iterator[None]:
    """Cut the block after ``timeout`` s (``Runaway``) and let it map at most ``mem`` new bytes."""
    def on_alarm(signum: int, frame: Any) -> None:
        raise Runaway(f"still running after {timeout:g} s")

    old_handler = signal.signal(signal.SIGALRM, on_alarm)
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = _vm_bytes() + mem
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    signal.setitimer(signal.ITIMER_REAL, timeout)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old_handler)
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


@contextlib.contextmanager
def inside(sb: Sandbox) -> Iterator[None]:
    """Run with ``sb.work`` as the current directory and ``sb.tmp`` as the temporary directory."""
    old_cwd = os.getcwd()
    old_tempdir = tempfile.tempdir
    old_env = os.environ.get("TMPDIR")
    os.chdir(sb.work)
    tempfile.tempdir = str(sb.tmp)
    os.environ["TMPDIR"] = str(sb.tmp)
    try:
        yield
    finally:
        os.chdir(old_cwd)
        tempfile.tempdir = old_tempdir
        if old_env is None:
            os.environ.pop("TMPDIR", None)
        else:
            os.environ["TMPDIR"] = old_env
