"""Bake a city: plan shards, bake the missing ones (in this process or on Dask), then write the
street map and the index.  ``envcap capture CITY --workers N`` (``docs/scale.md``).

Steps, under the lock of the city directory (:func:`envcap.outputs.claim_output_dir`):

1. the scene is loaded once here, hashed (:func:`envcap.city.plan.scene_hash`) and split into
   shards (:func:`envcap.city.plan.plan_shards`);
2. the city directory gets envcap's marker (kind ``city-probe-set``) first, so that a killed run
   leaves a directory the next run may resume into;
3. every shard not yet on disk (:func:`envcap.city.shard.is_finished`) is baked and installed
   atomically under its key: ``workers=0`` in this process, else on a Dask ``LocalCluster`` of
   ``workers`` processes (at most what the machine holds, :mod:`envcap.city.capacity`, and no
   more than the shards to bake) or the cluster at ``scheduler`` (:mod:`envcap.city.dask_run`),
   which gets the built scene (:mod:`envcap.city.scene_parcel`) and returns each shard's files
   to this process, which writes them: workers need no shared disk;
4. ``street_map.ktx2`` (R16UI ids) and then ``city.json`` (with the map's origin and its cell,
   ``map_cell`` m) are written atomically; shard directories of other inputs (an older plan) are removed.

Before step 1, every option is checked, and before step 2 a ``scheduler`` is reached
(:class:`envcap.city.cluster.ClusterSession`: address, connection, a worker; every call under
``timeout_s``): a bad option or an unreachable cluster is one line and leaves nothing.  A run
that fails or is interrupted before any shard is on disk removes the city directory it created.

Resumable and identical: a run killed at any point leaves complete shards, the marker and
temporary names that the next claim removes; rerunning skips the complete shards.  Shard bytes
depend only on their keys, and the index and map only on the shards, so a resumed run, an
uninterrupted one, a Dask one and a single-process one give the same files.
"""

from __future__ import annotations

import json
import os
import re
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

from envcap import __version__
from envcap.city.plan import SHARDS_DIR, BakeSettings, ShardTask, code_digest, plan_shards, scene_hash
from envcap.city.shard import (SceneSource, ShardBaker, ShardJob, install_shard_files, is_finished, load_source,
                               write_shard)
from envcap.city.street_map_file import write_street_map
from envcap.formats.writer import MANIFEST_FILE
from envcap.outputs import OutputBusy, atomic_output_file, claim_output_dir
from envcap.outputs.atomic import report_moved_aside
from envcap.outputs.lock import OutputLock
from envcap.outputs.marker import MARKER_NAME, is_replaceable, read_marker
from envcap.outputs.swap import move_aside, remove_path
from envcap.probeset.bake_bounds import estimate_bake, format_seconds
from envcap.core.budget import format_bytes
from envcap.probeset.city_index import INDEX_FILE, StreetMapInfo, build_city_index, city_index_text
from envcap.probeset.manifest import Street, read_manifest
from envcap.probeset.planes import Planes
from envcap.runtime.street_map import street_map
from envcap.scene.model import Street as SceneStreet

KIND = "city-probe-set"
MAP_FILE = "street_map.ktx2"
DEFAULT_BUDGET_MB = 256.0
DEFAULT_MAP_CELL = 1.0
MAX_BUDGET_MB = 1e6
"""The largest ``--shard-mb`` (1 TB of ``probes.ktx2`` per shard)."""
DEFAULT_TIMEOUT_S = 10.0
"""Seconds to wait for any answer of a Dask scheduler (``--cluster-timeout``)."""


@dataclass
class CityBake:
    """What :func:`bake_city` did: the city directory, shards baked and skipped, wall time (s),
    per Dask worker its stats (peak RSS bytes, scene loads) and the cluster's start time (s)
    when Dask ran."""

    path: Path
    baked: int
    skipped: int
    wall_s: float
    workers: dict[str, dict[str, float]] = field(default_factory=dict)
    dask_start_s: float | None = None


def _write_marker(city: Path) -> None:
    if read_marker(city) is None:
        with atomic_output_file(city / MARKER_NAME) as tmp:
            tmp.write_text(json.dumps({"envcap_output": KIND, "envcap_version": __version__}) + "\n")


def _remove_stale(city: Path, tasks: Iterable[ShardTask]) -> None:
    """Remove what is not a current shard in ``shards/``: complete shard directories of other
    inputs (envcap's marker), temporary directories of interrupted shard writes and lock files
    no one holds."""
    root = city / SHARDS_DIR
    keep = {Path(t.path).name for t in tasks}
    temp = re.compile(r"\..+\.(tmp-[0-9a-f]{8}|old|swap)")
    lock = re.compile(r"\.(.+)\.lock")
    for entry in sorted(root.iterdir()) if root.is_dir() else []:
        if entry.name in keep:
            continue
        held = lock.fullmatch(entry.name)
        if held and entry.is_file():   # left by a writer killed after its shard was installed
            try:
                OutputLock(root / held.group(1)).release()   # takes the lock (if free) and removes the file
            except OutputBusy:
                pass
        elif temp.fullmatch(entry.name) or (entry.is_dir() and read_marker(entry) is not None):
            remove_path(entry)


def _nominal(st: SceneStreet) -> Street:
    """A scene street as its manifest street before the bake (nominal planes, no probes), in its
    frame when it has one."""
    frame = dict(yaw_deg=st.yaw_deg, origin_xz=st.origin_xz) if st.framed else {}
    return Street(st.name, st.axis, st.start, st.end, st.center_line, Planes(st.facade_min, st.facade_max, st.ground),
                  (), **frame)


def finish_city(city: Path, tasks: list[ShardTask], digest: str, map_cell: float) -> None:
    """Write the street map and the index of the (complete) shards of ``tasks``."""
    manifests = [read_manifest(city / t.path / MANIFEST_FILE) for t in tasks]
    streets = [st for m in manifests for st in m.streets]
    sm = street_map(streets, map_cell)
    write_street_map(city / MAP_FILE, sm)
    info = StreetMapInfo(MAP_FILE, sm.origin, sm.cell, sm.size)
    index = build_city_index(manifests, [t.path for t in tasks], [t.key for t in tasks], digest, info)
    with atomic_output_file(city / INDEX_FILE) as tmp:
        tmp.write_text(city_index_text(index))
    _remove_stale(city, tasks)


def check_city_options(workers: int, scheduler: str | None, budget_mb: float, map_cell: float, retries: int,
                       timeout_s: float) -> None:
    """Refuse bad city options before any work (``ValueError``, one line each)."""
    if not isinstance(workers, int) or workers < 0:
        raise ValueError(f"--workers must be >= 0, got {workers}")
    if scheduler is not None and workers:
        raise ValueError("--workers starts a LocalCluster on this machine; with --scheduler the cluster's own "
                         "workers bake: give one of them")
    if not (map_cell > 0 and map_cell < float("inf")):
        raise ValueError(f"--map-cell must be a positive number of meters, got {map_cell}")
    if not (isinstance(budget_mb, (int, float)) and 0 <= budget_mb <= MAX_BUDGET_MB):
        raise ValueError(f"--shard-mb must be >= 0 and at most {MAX_BUDGET_MB:g} MB (0: one shard per street), "
                         f"got {budget_mb}")
    if not isinstance(retries, int) or retries < 0:
        raise ValueError(f"--retries must be >= 0, got {retries}")
    if not (isinstance(timeout_s, (int, float)) and 0 < timeout_s <= 3600):
        raise ValueError(f"--cluster-timeout must be a number of seconds in (0, 3600], got {timeout_s}")


def _describe(scene_name: str, tasks: list[ShardTask], done: int, settings: BakeSettings) -> str:
    """The plan line: shards, probes, what is done, and the bake estimate (the largest shard's
    peak memory, the whole bake's time in one process)."""
    est = [estimate_bake(t.probes, settings.resolution, filter_levels=settings.filter_levels,
                         quality=settings.quality, writers=settings.writers) for t in tasks]
    seconds = sum(e.seconds for e in est)
    took = f"{seconds:.1f} s" if seconds < 10 else format_seconds(seconds)
    return (f"envcap: {scene_name}: {len(tasks)} shard(s), {sum(t.probes for t in tasks)} probes; {done} already done;"
            f" ~{format_bytes(max(e.peak_bytes for e in est))} per shard, ~{took} of bake at llvmpipe rates")


def _remove_if_empty(city: Path) -> None:
    """Remove ``city`` (made by this run) if it holds nothing but the marker and an empty ``shards/``."""
    names = {p.name for p in city.iterdir()} if city.is_dir() else set()
    shards = city / SHARDS_DIR
    if names <= {MARKER_NAME, SHARDS_DIR} and not (shards.is_dir() and any(shards.iterdir())):
        remove_path(city)


def bake_city(source: SceneSource, out: str | os.PathLike[str], settings: BakeSettings, *, workers: int = 0,
              scheduler: str | None = None, budget_mb: float = DEFAULT_BUDGET_MB, map_cell: float = DEFAULT_MAP_CELL,
              retries: int = 2, inputs: Iterable[str | os.PathLike[str]] = (), force: bool = False,
              ctx: Any = None, quiet: bool = False, timeout_s: float = DEFAULT_TIMEOUT_S) -> CityBake:
    """Bake the city probe set of ``source`` into directory ``out`` (see the module docstring).

    ``workers``: 0 bakes in this process (with ``ctx`` when given), N >= 1 on a Dask
    ``LocalCluster`` of N processes; ``scheduler``: an existing Dask cluster's address instead.
    ``budget_mb``: shard size budget (MB of ``probes.ktx2``; 0: one shard per street).
    ``map_cell``: street-map cell (m).  ``retries``: Dask retries of a failing shard.
    ``inputs``: files the output must not contain (the scene's).  ``quiet``: no progress lines on
    stderr.  ``timeout_s``: the longest wait for any answer of the Dask scheduler (s).  Raises
    ``ValueError`` for bad arguments and :class:`envcap.city.cluster.ClusterError` for an
    unreachable cluster, before any output is claimed."""
    t0 = time.perf_counter()
    check_city_options(workers, scheduler, budget_mb, map_cell, retries, timeout_s)
    say = (lambda line: None) if quiet else (lambda line: print(line, file=sys.stderr, flush=True))
    dask = workers >= 1 or scheduler is not None
    address = None
    if dask:
        try:  # dask[distributed]: ~0.6 s to import
            from envcap.city import cluster as cl, dask_run
        except ImportError as exc:
            raise RuntimeError(f"baking on Dask (--workers N, --scheduler) needs dask[distributed] ({exc}): "
                               f"pip install 'envcap[city]', or bake in this process with --workers 0") from None
        from envcap.city.capacity import check_local_workers
        from envcap.city.scene_parcel import pack_scene
        address = None if scheduler is None else cl.check_address(scheduler)
    scene = load_source(source)
    digest = scene_hash(scene)
    code = code_digest()
    tasks = plan_shards(scene, settings, int(budget_mb * 1e6), digest, code)
    street_map([_nominal(st) for st in scene.streets], map_cell)   # the map's cell fits every street
    parcel = pack_scene(scene, digest) if dask else None
    if workers >= 1:
        check_local_workers(workers, tasks, settings, parcel.nbytes)
    session = None
    stats: dict[str, dict[str, float]] = {}
    start = None
    try:
        info: dict[str, Any] = {}
        if address is not None:
            session = cl.ClusterSession(timeout_s)
            info = session.connect(address)
            start = time.perf_counter() - t0
        with claim_output_dir(out, kind=KIND, inputs=inputs, force=force) as claim:
            city = claim.path
            fresh = not city.exists()
            if not is_replaceable(city):        # only with force: a city bakes in place, so set it aside now
                claim.moved_aside = move_aside(city)
                report_moved_aside(city, claim.moved_aside)
                fresh = True
            try:
                city.mkdir(exist_ok=True)
                _write_marker(city)
                (city / SHARDS_DIR).mkdir(exist_ok=True)
                pending = [t for t in tasks if not is_finished(city, t)]
                jobs = [ShardJob(digest, t, settings, code) for t in pending]
                say(_describe(scene.name, tasks, len(tasks) - len(pending), settings))

                def done(job: ShardJob, files: dict[str, bytes]) -> None:
                    install_shard_files(city, job.task, files)
                    say(f"envcap: shard {job.task.index + 1}/{len(tasks)} {job.task.path} (baked)")

                if jobs and dask:
                    if session is None:
                        n = min(workers, len(jobs))
                        if n < workers:
                            say(f"envcap: {len(jobs)} shard(s) to bake: starting {n} of the {workers} workers asked for")
                        t1 = time.perf_counter()
                        session = cl.ClusterSession(timeout_s)
                        gpu = dask_run.has_gpu()
                        session.start_local(n, {"GPU": 1} if gpu else None)
                        start = time.perf_counter() - t1
                    else:
                        gpu = None
                        idle = len(info.get("workers", {})) - len(jobs)
                        if idle > 0:
                            say(f"envcap: {len(jobs)} shard(s) for {len(jobs) + idle} Dask workers: {idle} will idle "
                                f"(a smaller --shard-mb makes more shards)")
                    dr = dask_run.run_on_dask(session, jobs, parcel, retries=retries, on_done=done, gpu=gpu, say=say)
                    stats = dr.workers
                elif jobs:
                    baker = ShardBaker(ctx, scenes={digest: scene})
                    try:
                        for job in jobs:
                            write_shard(city, job, baker.bake(job))
                            say(f"envcap: shard {job.task.index + 1}/{len(tasks)} {job.task.path}")
                    finally:
                        baker.release()
                finish_city(city, tasks, digest, map_cell)
            except BaseException:
                if fresh:
                    _remove_if_empty(city)
                raise
    finally:
        if session is not None:
            session.close()
    return CityBake(city, len(jobs), len(tasks) - len(jobs), time.perf_counter() - t0, stats, start)
