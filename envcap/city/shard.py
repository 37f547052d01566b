"""Bake one shard: the streets of a :class:`~envcap.city.plan.ShardTask`, written atomically as a
probe-set directory named by the task's key.

A :class:`ShardBaker` is what a process keeps between shards: one OpenGL context (made on first
use, in the thread that bakes) and the scenes it has loaded (by content hash), so a Dask worker
or the single-process loop loads a scene once and reuses its context for every shard.

Bit-identical shards: the bytes of a shard depend only on its inputs (the key): its manifest
carries no timings (they would differ run to run; the city bake reports them instead), and the
capture and filters are deterministic for a given machine and driver (``tests/city``).
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from envcap.city.plan import BakeSettings, ShardTask, code_digest, scene_hash
from envcap.formats.writer import MANIFEST_FILE
from envcap.gpu.context import create_context
from envcap.outputs.marker import read_marker
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.manifest import Timings, read_manifest
from envcap.probeset.store import write_probe_set
from envcap.scene import load_scene
from envcap.scene.load import scene_from_dict
from envcap.scene.model import Scene

SceneSource = str | dict
"""A scene as a worker loads it: a bundled name or ``.toml`` path (``str``), or a scene table
(``dict``, the TOML document) built with :func:`envcap.scene.load.scene_from_dict`."""


def load_source(source: SceneSource) -> Scene:
    """The scene of ``source`` (see :data:`SceneSource`)."""
    return scene_from_dict(source) if isinstance(source, dict) else load_scene(source)


@dataclass(frozen=True)
class ShardJob:
    """Everything a worker needs for one shard: the scene (source and content hash), the task,
    the settings, the city directory (absolute; shared by the workers' file system) and the
    :func:`envcap.city.plan.code_digest` the plan was made with (checked by the worker)."""

    source: SceneSource
    digest: str
    task: ShardTask
    settings: BakeSettings
    city: str
    code: str = ""


def is_finished(city: str | os.PathLike[str], task: ShardTask) -> bool:
    """Whether the shard of ``task`` is on disk, complete: its directory (named by the key)
    carries envcap's marker and a manifest that reads (a shard is installed whole, atomically)."""
    d = Path(city) / task.path
    if read_marker(d) is None or not (d / MANIFEST_FILE).is_file():
        return False
    try:
        m = read_manifest(d / MANIFEST_FILE)
    except ValueError:
        return False
    return tuple(st.name for st in m.streets) == task.streets


class ShardBaker:
    """A process's shard baker: one GL context (``ctx``, or one made on first use and released
    by :meth:`release`), scenes cached by content hash (``scenes``: already loaded ones)."""

    def __init__(self, ctx: Any = None, scenes: dict[str, Scene] | None = None) -> None:
        self._ctx = ctx
        self._own = ctx is None
        self._scenes: dict[str, Scene] = dict(scenes or {})
        self._code: str | None = None
        self.loads = 0          # scenes loaded by this baker (tests check "once per worker")

    def scene(self, source: SceneSource, digest: str) -> Scene:
        """The scene of ``source``, loaded once; ``ValueError`` if its content hash is not
        ``digest`` (the file changed after the run was planned, or differs on this machine)."""
        if digest not in self._scenes:
            scene = load_source(source)
            got = scene_hash(scene)
            if got != digest:
                raise ValueError(f"scene {scene.name!r} on this worker has content {got[:12]}, the plan {digest[:12]}: "
                                 f"the scene changed while the city was baked")
            self._scenes[digest] = scene
            self.loads += 1
        return self._scenes[digest]

    def context(self) -> Any:
        """The baker's GL context, made current in the calling thread (a Dask worker may run
        tasks on a thread other than the one that made it)."""
        if self._ctx is None:
            self._ctx = create_context()
        self._ctx.__enter__()
        return self._ctx

    def bake(self, job: ShardJob) -> str:
        """Bake and write the shard of ``job`` unless it is finished; return ``"baked"`` or
        ``"skipped"``."""
        if is_finished(job.city, job.task):
            return "skipped"
        if self._code is None:
            self._code = code_digest()
        if job.code and job.code != self._code:
            raise ValueError(f"this worker runs other envcap code ({self._code[:12]}) than the plan ({job.code[:12]}): "
                             f"install the same envcap on every worker")
        scene = self.scene(job.source, job.digest)
        by_name = {st.name: st for st in scene.streets}
        part = dataclasses.replace(scene, streets=[by_name[n] for n in job.task.streets])
        s = job.settings
        ctx = self.context()
        ps = bake_probe_set(part, resolution=s.resolution, spacing=s.spacing, height=s.height, quality=s.quality,
                            filter_levels=s.filter_levels, sun_in_sky=s.sun_in_sky, ctx=ctx, progress=False)
        ps.manifest = dataclasses.replace(ps.manifest, timings=Timings())
        target = Path(job.city) / job.task.path
        target.parent.mkdir(parents=True, exist_ok=True)
        write_probe_set(target, ps, writers=s.writers)
        return "baked"

    def release(self) -> None:
        """Release the GL context this baker made (not one it was given)."""
        if self._own and self._ctx is not None:
            self._ctx.release()
        self._ctx = None
