"""Bounds before work: refuse a request whose memory (or count) would run away with the machine.

Every stage estimates what an allocation will cost *before* it makes it and calls one of:

* :func:`check_bytes` ``(what, nbytes, option)``: ``nbytes`` must not exceed :func:`memory_limit`;
* :func:`check_count` ``(what, count, limit, option)``: ``count`` must not exceed a documented
  per-stage ``limit`` (e.g. the number of probes).

Past the bound either raises :class:`BudgetError` (a ``ValueError``, so the CLI prints it as one
line and exits 2) whose message says what was asked, what it would cost, the bound and which
option changes it, e.g.::

    lat-long image 16384x8192 RGB float32: needs 1.50 GiB, more than the 1.00 GiB memory limit
    (ENVCAP_MAX_MEMORY); use a smaller input image or raise ENVCAP_MAX_MEMORY

The memory limit (bytes) is, in order:

1. ``ENVCAP_MAX_MEMORY`` if set: a byte count with an optional binary suffix ``K``, ``M``,
   ``G`` or ``T`` (``512M``, ``64G``, ``1.5T``); it replaces the default (raise it to try anyway,
   e.g. with swap; lower it to keep a run small);
2. otherwise ``MemAvailable`` from ``/proc/meminfo``, read at each check (what the kernel can
   give without swapping);
3. otherwise (no ``/proc/meminfo``, e.g. macOS) no memory limit: counts are still checked.

Estimates are the caller's: a stage passes the peak of the arrays it is about to hold at once,
not every byte of the process.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

__all__ = ["BudgetError", "MEMORY_ENV", "parse_bytes", "format_bytes", "available_memory",
           "memory_limit", "check_bytes", "check_count"]

MEMORY_ENV = "ENVCAP_MAX_MEMORY"
"""Environment variable that overrides the memory limit (bytes, optional K/M/G/T binary suffix)."""

_MEMINFO = Path("/proc/meminfo")
_SUFFIX = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}


class BudgetError(ValueError):
    """A request past a memory or count bound; the message is one line naming the option to change."""


def parse_bytes(text: str) -> int:
    """``"1500000"``, ``"512M"``, ``"64G"``, ``"1.5T"`` (binary suffixes, optional ``B``/``iB``) -> bytes.

    Raises ``ValueError`` for anything else (negative, empty, unknown suffix, not finite).
    """
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*([kKmMgGtT]?)(?:i?[bB])?\s*", str(text))
    if not m:
        raise ValueError(f"{MEMORY_ENV}={text!r} is not a byte count (e.g. 8000000000, 512M, 64G)")
    value = float(m.group(1)) * _SUFFIX[m.group(2).upper()]
    if not math.isfinite(value):
        raise ValueError(f"{MEMORY_ENV}={text!r} is not a finite byte count")
    return int(value)


def format_bytes(nbytes: float) -> str:
    """Bytes in binary units with three significant digits: ``1.50 GiB``, ``512 MiB``, ``40 B``."""
    if not math.isfinite(nbytes):
        return f"{nbytes} B"
    for unit, scale in (("TiB", 1 << 40), ("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if abs(nbytes) >= scale:
            return f"{nbytes / scale:.3g} {unit}" if nbytes / scale < 1000 else f"{nbytes / scale:,.0f} {unit}"
    return f"{int(nbytes)} B"


def available_memory() -> int | None:
    """``MemAvailable`` of ``/proc/meminfo`` in bytes, or ``None`` where it cannot be read."""
    try:
        for line in _MEMINFO.read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024  # the kernel writes kB (KiB)
    except (OSError, ValueError, IndexError):
        return None
    return None


def memory_limit() -> tuple[int | None, str]:
    """The memory limit in bytes and where it comes from (``None``: no limit known).

    ``ENVCAP_MAX_MEMORY`` if set, else ``MemAvailable``; see the module docstring.
    """
    env = os.environ.get(MEMORY_ENV)
    if env is not None and env.strip():
        return parse_bytes(env), MEMORY_ENV
    avail = available_memory()
    if avail is not None:
        return avail, "available memory (MemAvailable)"
    return None, "no limit known"


def check_bytes(what: str, nbytes: float, option: str) -> int:
    """Raise :class:`BudgetError` if ``nbytes`` (the estimated peak of ``what``) exceeds :func:`memory_limit`.

    ``what`` says what was asked (``"probe array of 2000000 probes"``), ``option`` what changes
    it (``"--resolution"``).  Returns ``nbytes`` as an int.  A non-finite or negative estimate is
    a bug in the caller: ``ValueError``.
    """
    nbytes = float(nbytes)
    if not math.isfinite(nbytes) or nbytes < 0:
        if nbytes == math.inf:
            raise BudgetError(f"{what}: needs more memory than can be counted; change {option}")
        raise ValueError(f"memory estimate for {what} must be a finite byte count >= 0, got {nbytes}")
    limit, source = memory_limit()
    if limit is not None and nbytes > limit:
        raise BudgetError(
            f"{what}: needs {format_bytes(nbytes)}, more than the {format_bytes(limit)} memory limit ({source}); "
            f"change {option} or set {MEMORY_ENV} (bytes, e.g. 64G) to raise the limit")
    return int(nbytes)


def check_count(what: str, count: float, limit: int, option: str) -> int:
    """Raise :class:`BudgetError` if ``count`` (e.g. probes or buildings) exceeds the documented ``limit``.

    ``count`` may be a float estimate (``1e12`` probes, before any array exists); returns it as
    an int.  A NaN count is refused like an infinite one.
    """
    count = float(count)
    if not count <= limit:  # also catches NaN and inf
        shown = f"{count:.3g}" if count >= 1e15 or not math.isfinite(count) else f"{int(count):,}"
        raise BudgetError(f"{what}: {shown} asked, more than the limit of {int(limit):,}; change {option}")
    return int(count)
