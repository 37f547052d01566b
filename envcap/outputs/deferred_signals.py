"""Hold SIGINT and SIGTERM back while a few file-system steps must run to the end together.

Inside ``deferred_signals()`` (main thread) the two signals only get recorded; when the block
ends, the previous handlers are put back and each recorded signal is raised again, so that its
handler runs (e.g. ``KeyboardInterrupt``) right after the block.  Python handlers, not the
thread's signal mask, are what counts: a process with other threads (OpenGL drivers, BLAS) gets
its signals on any thread, but the Python handler always runs in the main thread.  SIGKILL cannot
be held back: what it interrupts, the next run on that output recovers
(:mod:`envcap.outputs.swap`).
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from types import FrameType

DEFERRED = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def deferred_signals() -> Iterator[None]:
    """Record SIGINT and SIGTERM during the block and deliver them after it (a no-op outside the
    main thread, where Python cannot set handlers)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []

    def record(signum: int, frame: FrameType | None) -> None:
        pending.append(signum)

    previous = {s: signal.signal(s, record) for s in DEFERRED}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, signal.SIG_DFL if handler is None else handler)
        for s in dict.fromkeys(pending):
            signal.raise_signal(s)
