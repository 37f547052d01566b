"""Run shard jobs on a Dask cluster (:class:`envcap.city.cluster.ClusterSession`): the worker
side (a plugin holding each worker's baker, the task) and the client side (submit, collect,
watch the scheduler).

* Workers are processes with one thread each (``threads_per_worker=1`` for a ``LocalCluster``;
  ``dask worker ADDRESS --nthreads 1`` for an existing one): OpenGL contexts are per thread and
  the bake is numpy/GL bound.  Each worker gets a :class:`BakerPlugin`, which keeps one
  :class:`envcap.city.shard.ShardBaker` (its EGL context, made on the first shard, and the
  scenes it unpacked) for the worker's life: a scene is unpacked once per worker.
* The scene travels as a :class:`~envcap.city.scene_parcel.SceneParcel` (the built scene and the
  bytes of its sky files, no client path), scattered once to every worker (a copy on each, so a
  dead worker loses no scene; should every copy be lost, the remaining shards are sent again with
  it, :data:`SCENE_RESENDS` times); a shard comes back as its files' bytes, which the client
  installs in the city directory (:func:`envcap.city.shard.install_shard_files`).
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
SCENE_RESENDS = 2
"""How many times shards whose scene was lost with its workers are sent again."""


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


def _stats_of(session: ClusterSession) -> dict[str, dict[str, float]]:
    """Each worker's :func:`worker_stats`, as far as they answer (a worker that just died, still
    listed by the scheduler, is left out: the shards are already home)."""
    try:
        got = session.call(lambda: session.client.run(worker_stats, on_error="return"), "asking the workers for stats")
    except ClusterError:
        return {}
    return {w: v for w, v in got.items() if isinstance(v, dict)}


def _gpu_workers(info: dict[str, Any]) -> bool:
    return any(w.get("resources", {}).get("GPU", 0) >= 1 for w in info.get("workers", {}).values())


@dataclass
class _Bake:
    """The client side of one bake on Dask (runs on the session's loop)."""

    client: Any
    parcel: SceneParcel
    results: "queue.Queue[Any]"
    retries: int
    resources: dict[str, float] | None
    timeout_s: float
    where: str

    async def scatter(self) -> Any:
        """The parcel on every worker (a copy on each: losing a worker loses no scene)."""
        wait = self.timeout_s + self.parcel.nbytes / SCENE_RATE_BPS
        try:
            return await asyncio.wait_for(self.client.scatter(self.parcel, broadcast=True, hash=False), wait)
        except asyncio.TimeoutError:
            raise ClusterError(f"sending the scene ({format_bytes(self.parcel.nbytes)}) to the workers of {self.where}: "
                               f"no answer in {wait:g} s") from None

    def submit(self, jobs: Sequence[ShardJob], scene: Any, attempt: int) -> dict[Any, ShardJob]:
        return {self.client.submit(bake_on_worker, job, scene, key=f"envcap-shard-{job.task.key}-{attempt}",
                                   retries=self.retries, resources=self.resources, pure=False): job for job in jobs}

    async def collect(self, jobs: Sequence[ShardJob]) -> None:
        """Put ``(job, files)`` in ``results`` as shards finish.  A shard that fails raises; shards
        whose scene was lost with every worker holding it are sent again with the scene, up to
        :data:`SCENE_RESENDS` times, while the scheduler answers."""
        pending = self.submit(jobs, await self.scatter(), 0)
        for attempt in range(1, SCENE_RESENDS + 2):
            lost = []
            async for fut in distributed.as_completed(list(pending), loop=self.client.loop):
                job = pending[fut]
                if fut.status == "finished":
                    self.results.put((job, await fut.result()))
                    fut.release()
                elif fut.status == "error":
                    exc = await fut.exception()
                    raise ClusterError(f"shard {job.task.path} failed on a worker of {self.where} ({self.retries} "
                                       f"retries): {one_line(exc)}")
                else:
                    lost.append((job, fut.status))
            if not lost:
                return
            try:
                await asyncio.wait_for(self.client.scheduler.identity(), self.timeout_s)
            except Exception:
                raise ClusterError(f"{self.where} went away mid-bake (shard {lost[0][0].task.path}: {lost[0][1]})") from None
            if attempt > SCENE_RESENDS:
                raise ClusterError(f"{self.where} lost {len(lost)} shard(s) {attempt} times (their workers died)")
            pending = self.submit([job for job, _ in lost], await self.scatter(), attempt)


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


async def _bake_all(bake: _Bake, jobs: Sequence[ShardJob]) -> None:
    work = asyncio.ensure_future(bake.collect(jobs))
    dog = asyncio.ensure_future(_watch(bake.client, bake.timeout_s, bake.where))
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
    results: queue.Queue[Any] = queue.Queue()
    bake = _Bake(client, parcel, results, retries, {"GPU": 1} if run.gpu else None, session.timeout_s, where)
    done = 0
    bg = session.start(lambda: _bake_all(bake, jobs))
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
        run.workers = _stats_of(session)
    except ClusterError as exc:
        raise ClusterError(f"{exc}; {done} of {len(jobs)} shard(s) done and kept: rerun the same command to resume"
                           ) from None
    finally:
        bg.cancel()
    run.outcomes = ["baked"] * len(jobs)
    say(f"envcap: dask: {len(jobs)} shard(s) on {len(run.workers)} worker(s){' (GPU)' if run.gpu else ''}")
    return run
