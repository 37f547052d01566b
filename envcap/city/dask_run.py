"""Run shard jobs on a Dask cluster (:class:`envcap.city.cluster.ClusterSession`): the worker
side (a plugin holding each worker's baker, the task) and the client side (submit, collect,
watch the scheduler).

* Workers are processes with one thread each (``threads_per_worker=1`` for a ``LocalCluster``;
  ``dask worker ADDRESS --nthreads 1`` for an existing one): OpenGL contexts are per thread and
  the bake is numpy/GL bound.  Each worker gets a :class:`BakerPlugin`, which keeps one
  :class:`envcap.city.shard.ShardBaker` (its EGL context, made on the first shard, and the
  scenes it unpacked) for the worker's life: a scene is unpacked once per worker.
* The scene travels as a :class:`~envcap.city.scene_parcel.SceneParcel` (the built scene and the
  bytes of its sky files, no client path), scattered once; a shard comes back as its files'
  bytes, which the client installs in the city directory (:func:`envcap.city.shard.install_shard_files`).
  Workers need neither the scene's files nor the city directory: no shared disk is needed.
* Retries: a task that raises is retried ``retries`` times; a task whose worker dies (killed,
  out of memory) is rescheduled by the scheduler on another worker, up to Dask's
  ``distributed.scheduler.allowed-failures`` (default 3) deaths.
* Bounded: every call to the scheduler waits at most the session's timeout; while shards bake,
  a watchdog asks the scheduler for its workers every timeout: a scheduler that stops answering,
  goes away, or is left without workers ends the run with one line (the shards already
  installed stay: rerunning the command resumes).
* GPU: where this machine has a GPU driver (:func:`has_gpu`), the local workers declare the
  resource ``GPU: 1``; shard tasks ask for ``GPU: 1`` whenever some worker of the cluster
  declares it (``dask worker ADDRESS --resources GPU=1``), so a mixed cluster runs shards only on
  its GPU workers.

``dask[distributed]`` is the optional extra ``envcap[city]`` (and part of ``envcap[test]``);
it takes ~0.6 s to import, so :mod:`envcap.city.bake` imports this module only when a city is
baked on Dask.
"""

from __future__ import annotations

import asyncio
import queue
import resource
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import distributed
from distributed import WorkerPlugin

from envcap.city.cluster import ClusterError, ClusterSession, one_line
from envcap.city.scene_parcel import SceneParcel
from envcap.city.shard import ShardBaker, ShardFiles, ShardJob, shard_files
from envcap.core.budget import format_bytes
from envcap.gpu.context import create_context

PLUGIN_NAME = "envcap-shard-baker"
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swiftshader", "swrast")
SCENE_RATE_BPS = 10e6
"""The slowest transfer the scene's scatter is given time for (bytes/s), beyond the timeout."""


def has_gpu() -> bool:
    """Whether this machine's EGL renderer is a GPU (not Mesa's llvmpipe / a software renderer)."""
    ctx = create_context()
    try:
        renderer = str(ctx.info.get("GL_RENDERER", "")).lower()
    finally:
        ctx.release()
    return not any(s in renderer for s in SOFTWARE_RENDERERS)


class BakerPlugin(WorkerPlugin):
    """A Dask worker plugin holding the worker's :class:`ShardBaker` and the folder its shipped
    scene files are written to (removed when the worker closes)."""

    name = PLUGIN_NAME

    def __init__(self) -> None:
        self.baker: ShardBaker | None = None
        self._folder: str | None = None

    def setup(self, worker: Any) -> None:
        self.baker = ShardBaker()

    def folder(self) -> str:
        """This worker's folder of shipped files (made on first use)."""
        if self._folder is None:
            self._folder = tempfile.mkdtemp(prefix="envcap-worker-files-")
        return self._folder

    def teardown(self, worker: Any) -> None:
        if self.baker is not None:
            self.baker.release()
            self.baker = None
        if self._folder is not None:
            shutil.rmtree(self._folder, ignore_errors=True)
            self._folder = None


def _stats(baker: ShardBaker | None) -> dict[str, float]:
    use = resource.getrusage(resource.RUSAGE_SELF)
    return {"peak_rss_bytes": use.ru_maxrss * 1024, "cpu_s": round(use.ru_utime + use.ru_stime, 3),
            "scene_loads": 0 if baker is None else baker.loads}


def bake_on_worker(job: ShardJob, parcel: SceneParcel) -> ShardFiles:
    """The Dask task: unpack the scene (once per worker), bake ``job``'s shard, return its files."""
    plugin = distributed.get_worker().plugins[PLUGIN_NAME]
    baker = plugin.baker
    baker.unpack(parcel, plugin.folder())
    return shard_files(baker.bake(job), job.settings)


def worker_stats(dask_worker: Any) -> dict[str, float]:
    """Peak resident memory (bytes) and CPU time (s, user + system) of this worker process and
    the scenes its baker unpacked (``client.run`` passes the worker as ``dask_worker``)."""
    plugin = dask_worker.plugins.get(PLUGIN_NAME)
    return _stats(None if plugin is None else plugin.baker)


@dataclass
class DaskRun:
    """What a Dask run reports: per job its outcome, and per worker its stats."""

    outcomes: list[str] = field(default_factory=list)
    workers: dict[str, dict[str, float]] = field(default_factory=dict)
    gpu: bool = False
    start_s: float = 0.0       # wall time until the client was connected and the plugin registered


def _gpu_workers(info: dict[str, Any]) -> bool:
    return any(w.get("resources", {}).get("GPU", 0) >= 1 for w in info.get("workers", {}).values())


async def _collect(client: Any, futures: dict[Any, ShardJob], results: "queue.Queue[Any]", retries: int,
                   where: str) -> None:
    """Put ``(job, files)`` in ``results`` as shards finish; a failed or lost shard raises."""
    async for fut in distributed.as_completed(list(futures), loop=client.loop):
        job = futures[fut]
        if fut.status == "finished":
            results.put((job, await fut.result()))
            fut.release()
        elif fut.status == "error":
            exc = await fut.exception()
            raise ClusterError(f"shard {job.task.path} failed on a worker of {where} ({retries} retries): {one_line(exc)}")
        else:
            raise ClusterError(f"{where} went away mid-bake (shard {job.task.path}: {fut.status})")


async def _watch(client: Any, timeout_s: float, where: str) -> None:
    """Ask the scheduler for its workers every ``timeout_s``: raise when it does not answer in
    time, or has had no worker for two looks in a row."""
    empty = 0
    while True:
        await asyncio.sleep(timeout_s)
        try:
            info = await asyncio.wait_for(client.scheduler.identity(), timeout_s)
        except asyncio.TimeoutError:
            raise ClusterError(f"{where} stopped answering (nothing in {timeout_s:g} s, --cluster-timeout)") from None
        except Exception as exc:
            raise ClusterError(f"{where} went away mid-bake ({one_line(exc)})") from None
        empty = empty + 1 if not info.get("workers") else 0
        if empty >= 2:
            raise ClusterError(f"{where} has no workers left")


async def _bake_all(client: Any, futures: dict[Any, ShardJob], results: "queue.Queue[Any]", retries: int,
                    timeout_s: float, where: str) -> None:
    work = asyncio.ensure_future(_collect(client, futures, results, retries, where))
    dog = asyncio.ensure_future(_watch(client, timeout_s, where))
    try:
        done, _ = await asyncio.wait({work, dog}, return_when=asyncio.FIRST_COMPLETED)
        for t in done:
            t.result()
    finally:
        for t in (work, dog):
            t.cancel()


def run_on_dask(session: ClusterSession, jobs: Sequence[ShardJob], parcel: SceneParcel, *, retries: int = 2,
                on_done: Callable[[ShardJob, ShardFiles], None], gpu: bool | None = None,
                say: Callable[[str], None] = lambda line: None) -> DaskRun:
    """Bake ``jobs`` on the connected ``session`` (scene: ``parcel``); ``on_done(job, files)`` is
    called in this thread as each shard comes back (it installs the files).  ``gpu``: whether
    the workers declared a GPU (None: ask the scheduler).  Any cluster failure, or a shard
    failing ``retries + 1`` times, raises :class:`ClusterError` saying how many shards were done."""
    run = DaskRun()
    client = session.client
    where = session.where
    run.gpu = _gpu_workers(session.identity()) if gpu is None else gpu
    session.call(lambda: client.register_plugin(BakerPlugin(), name=PLUGIN_NAME),
                 f"installing envcap's baker on the workers of {where}")
    scattered = session.call(lambda: client.scatter(parcel, hash=False),
                             f"sending the scene ({format_bytes(parcel.nbytes)}) to a worker of {where}",
                             session.timeout_s + parcel.nbytes / SCENE_RATE_BPS)
    res = {"GPU": 1} if run.gpu else None
    results: queue.Queue[Any] = queue.Queue()
    done = 0

    async def submit() -> dict[Any, ShardJob]:
        return {client.submit(bake_on_worker, job, scattered, key=f"envcap-shard-{job.task.key}", retries=retries,
                              resources=res, pure=False): job for job in jobs}

    futures = session.call(submit, f"submitting shards to {where}")
    bg = session.start(lambda: _bake_all(client, futures, results, retries, session.timeout_s, where))
    try:
        while done < len(jobs):
            try:
                job, files = results.get(timeout=0.2)
            except queue.Empty:
                if bg.done():
                    session.result(bg, f"baking on {where}")
                    if results.empty():
                        raise ClusterError(f"{where} ended the bake with shards missing")
                continue
            on_done(job, files)
            done += 1
        run.workers = session.call(lambda: client.run(worker_stats), f"asking the workers of {where} for their stats")
    except ClusterError as exc:
        raise ClusterError(f"{exc}; {done} of {len(jobs)} shard(s) done and kept: rerun the same command to resume"
                           ) from None
    finally:
        bg.cancel()
    run.outcomes = ["baked"] * len(jobs)
    say(f"envcap: dask: {len(jobs)} shard(s) on {len(run.workers)} worker(s){' (GPU)' if run.gpu else ''}")
    return run
