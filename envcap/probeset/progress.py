"""Progress of a long job on stderr: the stage, items done and items per second.

A :class:`BakeProgress` is handed to :func:`envcap.probeset.bake.bake_probe_set` (and the
writing that follows it); each stage (``sky``, ``capture``, ``prefilter``, ``write ktx2``, ...)
counts probes.  ``envcap evaluate`` counts positions, ``envcap avatar`` vertices (``unit``).
On a terminal it is one tqdm bar per stage (``capture: 40%|... 48/120 [00:03, 14.2 probe/s]``);
elsewhere (a log file, a pipe, CI) one plain line per finished stage (``progress: capture: 120
probes in 8.41 s, 14.3 probes/s``) and, while a stage runs, one line every ``interval`` seconds
(default :data:`INTERVAL_S`) with what is done so far (``progress: truth: 3/8 positions, 24.1 s,
0.12 positions/s``), so that no stage is silent for long; ``mode="off"`` prints nothing.
Seconds per stage are kept either way: :attr:`BakeProgress.seconds` (wall clock,
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
INTERVAL_S = 10.0
"""In ``lines`` mode, a stage still running prints what it has done at most this often (seconds)."""


class BakeProgress:
    """Stages of a bake with a probe count each, reported on ``stream`` (stderr by default).

    ``mode``: ``"auto"`` (a bar when ``stream`` is a terminal, else lines), ``"bar"``,
    ``"lines"`` or ``"off"``.  ``unit`` / ``units``: what a stage counts (default ``"probe"`` /
    ``unit`` + ``"s"``).  ``interval``: seconds between the lines of a running stage in
    ``lines`` mode.  Use :meth:`stage` as a context manager and :meth:`advance` inside.
    """

    def __init__(self, mode: Mode = "auto", stream: TextIO | None = None, *, unit: str = "probe",
                 units: str | None = None, interval: float = INTERVAL_S) -> None:
        if mode not in ("auto", "bar", "lines", "off"):
            raise ValueError(f"progress mode must be auto, bar, lines or off, got {mode!r}")
        self.stream = sys.stderr if stream is None else stream
        if mode == "auto":
            isatty = getattr(self.stream, "isatty", None)
            mode = "bar" if callable(isatty) and isatty() else "lines"
        self.mode: Mode = mode
        self.unit, self.units, self.interval = unit, units or f"{unit}s", float(interval)
        self.seconds: dict[str, float] = {}
        """Wall seconds of each finished stage, by name (a repeated name adds up)."""
        self.cpu_seconds: dict[str, float] = {}
        """CPU seconds of the process in each stage (``time.process_time``: every thread, llvmpipe's too)."""
        self._bar: Any = None
        self._name = ""
        self._count = self._total = 0
        self._t0 = self._c0 = self._last = 0.0

    def start(self, name: str, total: int) -> None:
        """Begin stage ``name`` of ``total`` items (0: not known; ends the stage before, if any)."""
        self.finish()
        self._name, self._count, self._t0, self._c0 = name, 0, time.perf_counter(), time.process_time()
        self._total, self._last = total, self._t0
        if self.mode == "bar":
            self._bar = tqdm(total=total, desc=name, unit=self.unit, file=self.stream, leave=True)

    def advance(self, probes: int = 1) -> None:
        """``probes`` more items (probes, positions, ...) done in the current stage."""
        self._count += probes
        if self._bar is not None:
            self._bar.update(probes)
        elif self.mode == "lines" and self._name:
            now = time.perf_counter()
            if now - self._last >= self.interval:
                self._last = now
                dt = now - self._t0
                of = f"/{self._total}" if self._total else ""
                print(f"{PREFIX}{self._name}: {self._count}{of} {self.units}, {dt:.1f} s, "
                      f"{self._count / dt:.3g} {self.units}/s", file=self.stream, flush=True)

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
                rate = f", {self._count / dt:.1f} {self.units}/s" if dt > 0 else ""
                line = f"{self._count} {self.units} in {dt:.2f} s{rate}"
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
