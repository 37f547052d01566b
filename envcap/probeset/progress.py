"""Progress of a bake on stderr: the stage and probes per second.

A :class:`BakeProgress` is handed to :func:`envcap.probeset.bake.bake_probe_set` (and the
writing that follows it); each stage (``sky``, ``capture``, ``prefilter``, ``write ktx2``, ...)
counts probes.  On a terminal it is one tqdm bar per stage (``capture: 40%|... 48/120
[00:03, 14.2 probe/s]``); elsewhere (a log file, a pipe, CI) one plain line per finished
stage (``progress: capture: 120 probes in 8.41 s, 14.3 probes/s``); ``mode="off"`` prints
nothing.  Seconds per stage are kept either way: :attr:`BakeProgress.seconds` (wall clock,
``time.perf_counter``) and :attr:`BakeProgress.cpu_seconds`.
"""

from __future__ import annotations

import sys
import time
from typing import Any, Literal, TextIO

from tqdm import tqdm

Mode = Literal["auto", "bar", "lines", "off"]

PREFIX = "progress: "
"""What a progress line starts with (not ``envcap:``, which marks errors, warnings and notes)."""


class BakeProgress:
    """Stages of a bake with a probe count each, reported on ``stream`` (stderr by default).

    ``mode``: ``"auto"`` (a bar when ``stream`` is a terminal, else lines), ``"bar"``,
    ``"lines"`` or ``"off"``.  Use :meth:`stage` as a context manager and :meth:`advance` inside.
    """

    def __init__(self, mode: Mode = "auto", stream: TextIO | None = None) -> None:
        if mode not in ("auto", "bar", "lines", "off"):
            raise ValueError(f"progress mode must be auto, bar, lines or off, got {mode!r}")
        self.stream = sys.stderr if stream is None else stream
        if mode == "auto":
            isatty = getattr(self.stream, "isatty", None)
            mode = "bar" if callable(isatty) and isatty() else "lines"
        self.mode: Mode = mode
        self.seconds: dict[str, float] = {}
        """Wall seconds of each finished stage, by name (a repeated name adds up)."""
        self.cpu_seconds: dict[str, float] = {}
        """CPU seconds of the process in each stage (``time.process_time``: every thread, llvmpipe's too)."""
        self._bar: Any = None
        self._name = ""
        self._count = 0
        self._t0 = self._c0 = 0.0

    def start(self, name: str, total: int) -> None:
        """Begin stage ``name`` of ``total`` probes (ends the stage before, if any)."""
        self.finish()
        self._name, self._count, self._t0, self._c0 = name, 0, time.perf_counter(), time.process_time()
        if self.mode == "bar":
            self._bar = tqdm(total=total, desc=name, unit="probe", file=self.stream, leave=True)

    def advance(self, probes: int = 1) -> None:
        """``probes`` more probes done in the current stage."""
        self._count += probes
        if self._bar is not None:
            self._bar.update(probes)

    def finish(self) -> None:
        """End the current stage (nothing when none is running)."""
        if not self._name:
            return
        dt = time.perf_counter() - self._t0
        self.seconds[self._name] = self.seconds.get(self._name, 0.0) + dt
        self.cpu_seconds[self._name] = self.cpu_seconds.get(self._name, 0.0) + time.process_time() - self._c0
        if self._bar is not None:
            self._bar.close()
            self._bar = None
        elif self.mode == "lines":
            if self._count:
                rate = f", {self._count / dt:.1f} probes/s" if dt > 0 else ""
                line = f"{self._count} probes in {dt:.2f} s{rate}"
            else:
                line = f"{dt:.2f} s"
            print(f"{PREFIX}{self._name}: {line}", file=self.stream, flush=True)
        self._name = ""

    def stage(self, name: str, total: int) -> "_Stage":
        """``with progress.stage("capture", 120): ...``: :meth:`start`, then :meth:`finish` at the end."""
        return _Stage(self, name, total)


class _Stage:
    def __init__(self, progress: BakeProgress, name: str, total: int) -> None:
        self.progress, self.name, self.total = progress, name, total

    def __enter__(self) -> BakeProgress:
        self.progress.start(self.name, self.total)
        return self.progress

    def __exit__(self, *exc: object) -> None:
        self.progress.finish()
