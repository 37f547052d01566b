"""Bake one shard: the streets of a :class:`~envcap.city.plan.ShardTask`, written atomically as a
probe-set directory named by the task's key.

A :class:`ShardBaker` is what a process keeps between shards: one OpenGL context (made on first
use, in the thread that bakes) and the scenes it has (by content hash), so a Dask worker or the
single-process loop has a scene once and reuses its context for every shard.

Where the files are written: in one process, straight into the city (:func:`write_shard`).  On
Dask, the worker writes the shard's files into a temporary folder of its own machine, reads them
back and returns their bytes (:func:`shard_files`), and the client installs them under the
shard's name (:func:`install_shard_files`): a worker needs no access to the city directory
(issue 19: a cluster without a shared disk), and both ways give the same bytes (the same
writers, the same marker).

Bit-identical shards: the bytes of a shard depend only on its inputs (the key): its manifest
carries no timings (they would differ run to run; the city bake reports them instead), and the
capture and filters are deterministic for a given machine and driver (``tests/city``).
"""

from __future__ import annotations

import dataclasses
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any

from envcap.city.plan import BakeSettings, ShardTask, code_digest
from envcap.city.scene_parcel import SceneParcel, unpack_scene
from envcap.formats.registry import select_writers
from envcap.formats.writer import MANIFEST_FILE
from envcap.gpu.context import create_context
from envcap.outputs import atomic_output_dir
from envcap.outputs.marker import read_marker
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.manifest import Timings, read_manifest
from envcap.probeset.probe_set import ProbeSet
from envcap.probeset.store import fill_probe_set_dir, write_probe_set
from envcap.scene import load_scene
from envcap.scene.load import scene_from_dict
from envcap.scene.model import Scene

SceneSource = str | dict
"""A scene as :func:`envcap.city.bake.bake_city` takes it: a bundled name or ``.toml`` path
(``str``), or a scene table (``dict``, the TOML document) built with
:func:`envcap.scene.load.scene_from_dict`."""

ShardFiles = dict[str, bytes]
"""A shard's files as a worker returns them: POSIX path relative to the shard directory -> bytes."""


def load_source(source: SceneSource) -> Scene:
    """The scene of ``source`` (see :data:`SceneSource`)."""
    return scene_from_dict(source) if isinstance(source, dict) else load_scene(source)


@dataclass(frozen=True)
class ShardJob:
    """What a baker needs for one shard besides the scene: the scene's content hash, the task,
    the settings and the :func:`envcap.city.plan.code_digest` the plan was made with (checked by
    the worker).  No path: a job means the same on any machine."""

    digest: str
    task: ShardTask
    settings: BakeSettings
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
        self.loads = 0          # scenes unpacked by this baker (tests check "once per worker")

    def scene(self, digest: str) -> Scene:
        """The scene of content hash ``digest`` (given or unpacked before)."""
        return self._scenes[digest]

    def unpack(self, parcel: SceneParcel, folder: str | os.PathLike[str]) -> Scene:
        """The scene of ``parcel``, unpacked once (its files under ``folder``)."""
        if parcel.digest not in self._scenes:
            self._scenes[parcel.digest] = unpack_scene(parcel, folder)
            self.loads += 1
        return self._scenes[parcel.digest]

    def context(self) -> Any:
        """The baker's GL context, made current in the calling thread (a Dask worker may run
        tasks on a thread other than the one that made it)."""
        if self._ctx is None:
            self._ctx = create_context()
        self._ctx.__enter__()
        return self._ctx

    def bake(self, job: ShardJob) -> ProbeSet:
        """The probe set of ``job``'s shard (its manifest without timings), from the scene of
        ``job.digest`` (:meth:`unpack` it first on a worker)."""
        if self._code is None:
            self._code = code_digest()
        if job.code and job.code != self._code:
            raise ValueError(f"this worker runs other envcap code ({self._code[:12]}) than the plan ({job.code[:12]}): "
                             f"install the same envcap on every worker")
        scene = self.scene(job.digest)
        by_name = {st.name: st for st in scene.streets}
        part = dataclasses.replace(scene, streets=[by_name[n] for n in job.task.streets])
        s = job.settings
        ctx = self.context()
        ps = bake_probe_set(part, resolution=s.resolution, spacing=s.spacing, height=s.height, quality=s.quality,
                            filter_levels=s.filter_levels, sun_in_sky=s.sun_in_sky, ctx=ctx, progress=False)
        ps.manifest = dataclasses.replace(ps.manifest, timings=Timings())
        return ps

    def release(self) -> None:
        """Release the GL context this baker made (not one it was given)."""
        if self._own and self._ctx is not None:
            self._ctx.release()
        self._ctx = None


def write_shard(city: str | os.PathLike[str], job: ShardJob, ps: ProbeSet) -> Path:
    """Write the shard ``ps`` of ``job`` into the city directory (atomically, as a probe set)."""
    target = Path(city) / job.task.path
    target.parent.mkdir(parents=True, exist_ok=True)
    return write_probe_set(target, ps, writers=job.settings.writers)


def shard_files(ps: ProbeSet, settings: BakeSettings) -> ShardFiles:
    """The files :func:`write_shard` would write for ``ps`` (the marker aside), as bytes: written
    into a temporary folder of this machine, read back, removed."""
    names = [w.name for w in select_writers(settings.writers)]
    with tempfile.TemporaryDirectory(prefix="envcap-shard-") as tmp:
        fill_probe_set_dir(Path(tmp), ps, names)
        return {p.relative_to(tmp).as_posix(): p.read_bytes() for p in sorted(Path(tmp).rglob("*")) if p.is_file()}


def _checked(rel: str) -> PurePosixPath:
    p = PurePosixPath(rel)
    if not rel or p.is_absolute() or any(part in ("", ".", "..") for part in p.parts) or "\\" in rel:
        raise ValueError(f"a worker returned a shard file named {rel!r}: not a plain relative path")
    return p


def install_shard_files(city: str | os.PathLike[str], task: ShardTask, files: ShardFiles) -> Path:
    """Install a shard's ``files`` (from :func:`shard_files`) as the shard of ``task`` in the city
    directory, atomically, with the probe-set marker, as :func:`write_shard` would."""
    target = Path(city) / task.path
    rels = [_checked(rel) for rel in files]
    target.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output_dir(target, kind="probe-set") as tmp:
        for rel, data in zip(rels, files.values()):
            (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
            (tmp / rel).write_bytes(data)
    return target
