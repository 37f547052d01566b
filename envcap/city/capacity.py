"""How many local Dask worker processes this machine holds for a city bake (issue 20: ``--workers
1000`` on 2 cores started 1,000 processes and finished nothing).

A worker needs one CPU core (its bake keeps one busy; llvmpipe's threads more) and the memory of
its largest shard: the bake estimate (:func:`envcap.probeset.bake_bounds.estimate_bake`, the
process's baseline included), plus the scene it holds and the shard's files it returns.  The
machine holds ``min(cores, memory limit // per worker)`` workers: its usable cores
(``sched_getaffinity``) and the memory limit of :mod:`envcap.core.budget` (``MemAvailable``, or
``ENVCAP_MAX_MEMORY``).  Asking for more is refused before anything starts, in one line that
says what the machine has, what a worker needs and the most that fits.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence

from envcap.city.plan import BakeSettings, ShardTask, probe_bytes
from envcap.core.budget import format_bytes, memory_limit
from envcap.probeset.bake_bounds import estimate_bake


def usable_cores() -> int:
    """CPU cores this process may run on (its affinity mask; ``os.cpu_count()`` elsewhere)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def worker_bytes(tasks: Sequence[ShardTask], settings: BakeSettings, scene_bytes: float) -> float:
    """Estimated peak bytes of one worker baking the largest of ``tasks``: the bake (baseline
    included), the scene (``scene_bytes``) and the shard's files twice (written, then returned)."""
    largest = max(t.probes for t in tasks)
    est = estimate_bake(largest, settings.resolution, filter_levels=settings.filter_levels, quality=settings.quality,
                        writers=settings.writers)
    return est.peak_bytes + scene_bytes + 2.0 * largest * probe_bytes(settings.resolution)


def check_local_workers(workers: int, tasks: Sequence[ShardTask], settings: BakeSettings, scene_bytes: float) -> None:
    """Refuse ``workers`` local worker processes past what this machine holds (see the module
    docstring): ``ValueError``, one line."""
    cores = usable_cores()
    per = worker_bytes(tasks, settings, scene_bytes)
    limit, source = memory_limit()
    fit = math.inf if limit is None else math.floor(limit / per)
    most = int(min(cores, fit))
    if workers <= most:
        return
    largest = max(t.probes for t in tasks)
    memory = "no memory limit known" if limit is None else f"{format_bytes(limit)} of memory ({source})"
    advice = f"use --workers {most} or fewer" if most >= 1 else "bake in this process (--workers 0) or free memory"
    raise ValueError(f"--workers {workers}: this machine holds at most {most} worker(s): {cores} CPU core(s) and "
                     f"{memory}, ~{format_bytes(per)} per worker (the bake estimate of the largest shard, "
                     f"{largest} probes at {settings.resolution}^2, with the scene); {advice}")
