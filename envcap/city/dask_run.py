"""Run shard jobs on Dask: a ``LocalCluster`` of worker processes, or an existing cluster.

* Workers are processes with one thread each (``threads_per_worker=1``): OpenGL contexts are
  per thread and the bake is numpy/GL bound.  Each worker gets a :class:`BakerPlugin`, which
  keeps one :class:`envcap.city.shard.ShardBaker` (its EGL context, made on the first shard, and
  the scenes it loaded) for the worker's life: a scene is loaded once per worker.
* Retries: a task that raises is retried ``retries`` times; a task whose worker dies (killed,
  out of memory) is rescheduled by the scheduler on another worker, up to Dask's
  ``distributed.scheduler.allowed-failures`` (default 3) deaths.  A retried shard rewrites its
  directory atomically, so a half-written shard never shows.
* GPU: where this machine has a GPU driver (:func:`has_gpu`), the local workers declare the
  resource ``GPU: 1``; shard tasks ask for ``GPU: 1`` whenever some worker of the cluster
  declares it (an existing cluster: ``dask worker ADDRESS --resources GPU=1``), so a mixed
  cluster runs shards only on its GPU workers.
* Files: workers write shards into the city directory by its absolute path; with an existing
  cluster every worker must see that path (a shared file system).

``dask[distributed]`` is the optional extra ``envcap[city]`` (and part of ``envcap[test]``);
it takes ~0.6 s to import, so :mod:`envcap.city.bake` imports this module only when a city is
baked on Dask.
"""

from __future__ import annotations

import resource
import sys
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import distributed
from distributed import WorkerPlugin

from envcap.city.shard import ShardBaker, ShardJob
from envcap.gpu.context import create_context

PLUGIN_NAME = "envcap-shard-baker"
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swiftshader", "swrast")


def has_gpu() -> bool:
    """Whether this machine's EGL renderer is a GPU (not Mesa's llvmpipe / a software renderer)."""
    ctx = create_context()
    try:
        renderer = str(ctx.info.get("GL_RENDERER", "")).lower()
    finally:
        ctx.release()
    return not any(s in renderer for s in SOFTWARE_RENDERERS)


class BakerPlugin(WorkerPlugin):
    """A Dask worker plugin holding the worker's :class:`ShardBaker` (``name``: one per worker)."""

    name = PLUGIN_NAME

    def __init__(self) -> None:
        self.baker: ShardBaker | None = None

    def setup(self, worker: Any) -> None:
        self.baker = ShardBaker()

    def teardown(self, worker: Any) -> None:
        if self.baker is not None:
            self.baker.release()
            self.baker = None


def bake_on_worker(job: ShardJob) -> str:
    """The Dask task: bake ``job`` with this worker's baker; ``"baked"`` or ``"skipped"``."""
    plugin = distributed.get_worker().plugins[PLUGIN_NAME]
    return plugin.baker.bake(job)


def worker_stats(dask_worker: Any) -> dict[str, float]:
    """Peak resident memory (bytes) and CPU time (s, user + system) of this worker process and
    the scenes its baker loaded (``client.run`` passes the worker as ``dask_worker``)."""
    plugin = dask_worker.plugins.get(PLUGIN_NAME)
    loads = 0 if plugin is None or plugin.baker is None else plugin.baker.loads
    use = resource.getrusage(resource.RUSAGE_SELF)
    return {"peak_rss_bytes": use.ru_maxrss * 1024, "cpu_s": round(use.ru_utime + use.ru_stime, 3), "scene_loads": loads}


@dataclass
class DaskRun:
    """What a Dask run reports: per job its outcome, and per worker its stats."""

    outcomes: list[str] = field(default_factory=list)
    workers: dict[str, dict[str, float]] = field(default_factory=dict)
    gpu: bool = False
    start_s: float = 0.0       # wall time until the client was connected and the plugin registered


def run_on_dask(jobs: Sequence[ShardJob], *, workers: int = 2, scheduler: str | None = None, retries: int = 2,
                on_done: Callable[[ShardJob, str], None] | None = None) -> DaskRun:
    """Run ``jobs`` on a new ``LocalCluster`` of ``workers`` processes, or on the cluster at
    ``scheduler`` (an address such as ``tcp://host:8786``); ``on_done(job, outcome)`` is called in
    this process as each job finishes.  A job that fails ``retries + 1`` times raises here."""
    dd = distributed
    run = DaskRun()
    t0 = time.perf_counter()
    cluster = None
    if scheduler is None:
        if workers < 1:
            raise ValueError(f"--workers must be >= 1 for a Dask run, got {workers}")
        run.gpu = has_gpu()
        cluster = dd.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                                  resources={"GPU": 1} if run.gpu else None, silence_logs=40)
    try:
        with dd.Client(cluster if cluster is not None else scheduler) as client:
            client.register_plugin(BakerPlugin(), name=PLUGIN_NAME)
            info = client.scheduler_info().get("workers", {})
            run.gpu = any(w.get("resources", {}).get("GPU", 0) >= 1 for w in info.values())
            run.start_s = time.perf_counter() - t0
            res = {"GPU": 1} if run.gpu else None
            futures = {client.submit(bake_on_worker, job, key=f"envcap-shard-{job.task.key}", retries=retries,
                                     resources=res, pure=False): job for job in jobs}
            outcome = {}
            for fut in dd.as_completed(list(futures)):
                job = futures[fut]
                outcome[job.task.key] = fut.result()
                if on_done is not None:
                    on_done(job, outcome[job.task.key])
            run.outcomes = [outcome[j.task.key] for j in jobs]
            run.workers = client.run(worker_stats)
    finally:
        if cluster is not None:
            cluster.close()
    print(f"envcap: dask: {len(jobs)} shard(s) on {len(run.workers)} worker(s){' (GPU)' if run.gpu else ''}",
          file=sys.stderr)
    return run
