"""Bake a city: plan shards, bake the missing ones (in this process or on Dask), then write the
street map and the index.  ``envcap capture CITY --workers N`` (``docs/scale.md``).

Steps, under the lock of the city directory (:func:`envcap.outputs.claim_output_dir`):

1. the scene is loaded once here, hashed (:func:`envcap.city.plan.scene_hash`) and split into
   shards (:func:`envcap.city.plan.plan_shards`);
2. the city directory gets envcap's marker (kind ``city-probe-set``) first, so that a killed run
   leaves a directory the next run may resume into;
3. every shard not yet on disk (:func:`envcap.city.shard.is_finished`) is baked and installed
   atomically under its key: ``workers=0`` in this process, else on a Dask ``LocalCluster`` of
   ``workers`` processes or the cluster at ``scheduler`` (:mod:`envcap.city.dask_run`);
4. ``street_map.ktx2`` (R16UI ids) and then ``city.json`` (with the map's origin and its cell,
   ``map_cell`` m) are written atomically; shard directories of other inputs (an older plan) are
   removed.

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
from envcap.city.shard import SceneSource, ShardBaker, ShardJob, is_finished, load_source
from envcap.city.street_map_file import write_street_map
from envcap.formats.writer import MANIFEST_FILE
from envcap.outputs import OutputBusy, atomic_output_file, claim_output_dir
from envcap.outputs.atomic import report_moved_aside
from envcap.outputs.lock import OutputLock
from envcap.outputs.marker import MARKER_NAME, is_replaceable, read_marker
from envcap.outputs.swap import move_aside, remove_path
from envcap.probeset.city_index import INDEX_FILE, StreetMapInfo, build_city_index, city_index_text
from envcap.probeset.manifest import Street, read_manifest
from envcap.probeset.planes import Planes
from envcap.runtime.street_map import street_map
from envcap.scene.model import Street as SceneStreet

KIND = "city-probe-set"
MAP_FILE = "street_map.ktx2"
DEFAULT_BUDGET_MB = 256.0
DEFAULT_MAP_CELL = 1.0


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


def bake_city(source: SceneSource, out: str | os.PathLike[str], settings: BakeSettings, *, workers: int = 0,
              scheduler: str | None = None, budget_mb: float = DEFAULT_BUDGET_MB, map_cell: float = DEFAULT_MAP_CELL,
              retries: int = 2, inputs: Iterable[str | os.PathLike[str]] = (), force: bool = False,
              ctx: Any = None) -> CityBake:
    """Bake the city probe set of ``source`` into directory ``out`` (see the module docstring).

    ``workers``: 0 bakes in this process (with ``ctx`` when given), N >= 1 on a Dask
    ``LocalCluster`` of N processes; ``scheduler``: an existing Dask cluster's address instead.
    ``budget_mb``: shard size budget (MB of ``probes.ktx2``; 0: one shard per street).
    ``map_cell``: street-map cell (m).  ``retries``: Dask retries of a failing shard.
    ``inputs``: files the output must not contain (the scene's).  Raises ``ValueError`` for bad
    arguments before any work."""
    t0 = time.perf_counter()
    if workers < 0:
        raise ValueError(f"--workers must be >= 0, got {workers}")
    if not (map_cell > 0 and map_cell < float("inf")):
        raise ValueError(f"--map-cell must be a positive number of meters, got {map_cell}")
    if not budget_mb >= 0:
        raise ValueError(f"--shard-mb must be >= 0, got {budget_mb}")
    dask_runner = None
    if workers >= 1 or scheduler is not None:
        try:
            from envcap.city.dask_run import run_on_dask as dask_runner  # dask[distributed]: ~0.6 s to import
        except ImportError as exc:
            raise RuntimeError(f"baking on Dask (--workers N, --scheduler) needs dask[distributed] ({exc}): "
                               f"pip install 'envcap[city]', or bake in this process with --workers 0") from None
    scene = load_source(source)
    digest = scene_hash(scene)
    code = code_digest()
    tasks = plan_shards(scene, settings, int(budget_mb * 1e6), digest, code)
    street_map([_nominal(st) for st in scene.streets], map_cell)   # the map's cell fits every street
    with claim_output_dir(out, kind=KIND, inputs=inputs, force=force) as claim:
        city = claim.path
        if not is_replaceable(city):        # only with force: a city bakes in place, so set it aside now
            claim.moved_aside = move_aside(city)
            report_moved_aside(city, claim.moved_aside)
        city.mkdir(exist_ok=True)
        _write_marker(city)
        (city / SHARDS_DIR).mkdir(exist_ok=True)
        pending = [t for t in tasks if not is_finished(city, t)]
        jobs = [ShardJob(source, digest, t, settings, str(city), code) for t in pending]
        print(f"envcap: {scene.name}: {len(tasks)} shard(s), {sum(t.probes for t in tasks)} probes; "
              f"{len(tasks) - len(pending)} already done", file=sys.stderr, flush=True)
        stats: dict[str, dict[str, float]] = {}
        start = None
        if jobs and dask_runner is not None:
            def done(job: ShardJob, outcome: str) -> None:
                print(f"envcap: shard {job.task.index + 1}/{len(tasks)} {job.task.path} ({outcome})", file=sys.stderr,
                      flush=True)
            dr = dask_runner(jobs, workers=max(workers, 1), scheduler=scheduler, retries=retries, on_done=done)
            stats, start = dr.workers, dr.start_s
        elif jobs:
            baker = ShardBaker(ctx, scenes={digest: scene})
            try:
                for job in jobs:
                    baker.bake(job)
                    print(f"envcap: shard {job.task.index + 1}/{len(tasks)} {job.task.path}", file=sys.stderr, flush=True)
            finally:
                baker.release()
        finish_city(city, tasks, digest, map_cell)
    return CityBake(city, len(jobs), len(tasks) - len(jobs), time.perf_counter() - t0, stats, start)
