"""SIGTERM handled like Ctrl-C: it raises :class:`Terminated` in the main thread, so that every
``with`` block unwinds (temporary outputs are removed, locks released) before the process exits
with status 143 (SIGINT: ``KeyboardInterrupt``, status 130)."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from types import FrameType

EXIT_INTERRUPTED = 130  # 128 + SIGINT
EXIT_TERMINATED = 143  # 128 + SIGTERM


class Terminated(BaseException):
    """The process received SIGTERM.  A ``BaseException``, like ``KeyboardInterrupt``, so that
    ``except Exception`` blocks do not swallow it."""


def _raise_terminated(signum: int, frame: FrameType | None) -> None:
    raise Terminated(signal.Signals(signum).name)


@contextlib.contextmanager
def sigterm_raises() -> Iterator[None]:
    """Within the block, SIGTERM raises :class:`Terminated` (main thread only; elsewhere a no-op)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
