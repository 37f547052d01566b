"""Which shards a city bake makes, and the key that names each shard's inputs.

Sharding (``docs/scale.md``): streets are packed in scene order into shards of at most
``budget_bytes`` of ``probes.ktx2`` texels (:func:`probe_bytes` per probe: 6 faces, every level,
RGBA16F); a street larger than the budget is a shard of its own (a street is never split: its
probes share one layer range, which the runtime uploads as one street); ``budget_bytes <= 0``
makes one shard per street.  Scene order keeps the plan stable when streets are appended.

Shards for parallel workers (issue 19): a shard also holds at most the larger of
``1 / PARALLEL_SHARDS`` of the city's probes and :data:`MIN_SHARD_SECONDS` of estimated bake (the
bake estimate's llvmpipe rates, :func:`shard_probe_cap`), streets never split: a city of over
``PARALLEL_SHARDS x MIN_SHARD_SECONDS`` (64 s) of estimated bake gets at least 16 shards, a
smaller one shards of about 4 s (1,150 probes at 32^2: ~13), so 2-16 workers each get shards to
bake and a small city is not scattered into shards that cost more to set up than to bake.  The plan
depends on the scene and the settings only, never on the cluster: a city baked by 2 workers, by
64, or by one process has the same shards and bytes, and a bake killed on one cluster resumes
on another with every finished shard kept.

Keys (:func:`shard_key`): SHA-256 over the scene's content (:func:`scene_hash`: mesh arrays,
streets, sky, effects, the bytes of files the sky reads), the shard's streets, the bake settings
(:class:`BakeSettings`, output writers included), the envcap version and its code
(:func:`code_digest`: every module and shader).  Streets enter the scene hash and the key whole,
frame included (``yaw_deg``, ``origin_xz`` of a street at any angle): a turned or moved street is
another shard, and its frame reaches the probe-set bake unchanged.  A shard directory is
named by its key, so a finished shard is found again by a rerun with the same inputs and never
mistaken for one of other inputs.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from envcap import __version__
from envcap.core.checks import positive_int
from envcap.core.lobes import lobe_ladder
from envcap.core.resources import shaders_dir
from envcap.probeset.bake_bounds import estimate_bake
from envcap.probeset.placement import check_spacing, probe_count
from envcap.scene.model import Scene, Street

SHARDS_DIR = "shards"
KEY_IN_NAME = 20
"""Hex digits of the key in a shard's directory name (80 bits)."""
PARALLEL_SHARDS = 16
"""A city with enough work is planned in at least this many shards (streets allowing)."""
MIN_SHARD_SECONDS = 4.0
"""The smallest shard the parallel cut makes, in estimated seconds of bake (llvmpipe rates): below
it a shard's fixed costs (its sky, mesh upload, a task) outweigh the parallelism."""


@dataclass(frozen=True)
class BakeSettings:
    """What a shard's bytes depend on besides the scene: face size N (texels), probe spacing and
    height (m), prefilter quality, the sun in the sky map, whether levels are filtered, and the
    names of the output writers that run (:mod:`envcap.formats.registry`)."""

    resolution: int = 256
    spacing: float = 5.0
    height: float = 2.0
    quality: str = "default"
    sun_in_sky: bool = False
    filter_levels: bool = True
    writers: tuple[str, ...] = ("ktx2",)

    def __post_init__(self) -> None:
        # normalized, so that equal settings give equal keys (5 and 5.0, writer order)
        set_ = object.__setattr__
        set_(self, "resolution", positive_int(self.resolution, "probe resolution (--resolution)"))
        set_(self, "spacing", check_spacing(self.spacing))
        if not (isinstance(self.height, (int, float)) and math.isfinite(self.height) and self.height > 0):
            raise ValueError(f"probe height must be a positive number of meters, got {self.height!r}")
        set_(self, "height", float(self.height))
        set_(self, "sun_in_sky", bool(self.sun_in_sky))
        set_(self, "filter_levels", bool(self.filter_levels))
        set_(self, "writers", tuple(sorted(set(self.writers))))

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class ShardTask:
    """One shard to bake: its position in the city, its streets (names, scene order), its
    probe count, the key of its inputs and its directory relative to the city (``shards/...``)."""

    index: int
    streets: tuple[str, ...]
    probes: int
    key: str
    path: str


def probe_bytes(resolution: int) -> int:
    """Bytes of one probe in ``probes.ktx2``: 6 faces x every level of the ladder x RGBA16F."""
    levels = len(lobe_ladder(resolution).powers)
    return 6 * 8 * sum(max(1, resolution >> k) ** 2 for k in range(levels))


def _update_file(h: Any, value: Any) -> None:
    """Hash the bytes of a file a sky parameter names (a lat-long image), so that editing the
    image changes the key."""
    if isinstance(value, Path) and value.is_file():
        h.update(value.read_bytes())


def scene_hash(scene: Scene) -> str:
    """Hex SHA-256 of what a bake reads from ``scene``: name, mesh arrays (dtype, shape, bytes,
    origin; texture coordinates and images of a textured mesh), streets, the shadow settings, sky
    table (and files it names), effects."""
    h = hashlib.sha256()
    h.update(json.dumps([scene.name, sorted(scene.effects)]).encode())
    m = scene.mesh
    textures = (m.uv_layer, m.textures) if m.uv_layer is not None and m.textures is not None else ()
    for a in (m.positions, m.normals, m.albedo, m.emission, m.indices, m.origin, *textures):
        arr = np.ascontiguousarray(a)
        h.update(f"{arr.dtype.str}{arr.shape}".encode())
        h.update(arr.tobytes())
    h.update(repr([dataclasses.astuple(st) for st in scene.streets]).encode())
    h.update(repr(scene.shadows).encode())
    h.update(repr(scene.sky).encode())
    params = scene.sky.params
    if dataclasses.is_dataclass(params):
        for f in dataclasses.fields(params):
            _update_file(h, getattr(params, f.name))
    return h.hexdigest()


@functools.cache
def code_digest() -> str:
    """Hex SHA-256 of envcap's code as this process runs it: the relative path and bytes of
    every ``.py`` of the package and every ``.glsl`` under ``shaders/`` (~300 files, ~20 ms),
    read once per process (the code it imported, not later edits).  Part of every key, so that
    a changed filter or shader (the version string is not bumped by every change) never passes
    for a finished shard, and a worker running other code refuses the task."""
    h = hashlib.sha256()
    for root, pattern in ((Path(__file__).resolve().parents[1], "*.py"), (shaders_dir(), "*.glsl")):
        for f in sorted(root.rglob(pattern)):
            h.update(f"{f.relative_to(root).as_posix()}\0{f.stat().st_size}\0".encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def shard_key(scene_digest: str, streets: Sequence[Street], settings: BakeSettings, code: str,
              version: str = __version__) -> str:
    """Hex SHA-256 of a shard's inputs (see the module docstring); ``code``: :func:`code_digest`."""
    doc = {"scene": scene_digest, "streets": [dataclasses.asdict(st) for st in streets],
           "settings": settings.to_json(), "envcap": version, "code": code}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("._")[:32] or "street"


def shard_probe_cap(total_probes: int, settings: BakeSettings) -> int:
    """The most probes the parallel cut lets a shard hold (see the module docstring): a
    :data:`PARALLEL_SHARDS`-th of ``total_probes``, but at least the probes of
    :data:`MIN_SHARD_SECONDS` of estimated bake at ``settings``."""
    est = functools.partial(estimate_bake, resolution=settings.resolution, filter_levels=settings.filter_levels,
                            quality=settings.quality)
    per_probe_s = est(1).seconds - est(0).seconds
    floor = math.ceil(MIN_SHARD_SECONDS / per_probe_s) if per_probe_s > 0 and math.isfinite(per_probe_s) else 1
    return max(1, math.ceil(total_probes / PARALLEL_SHARDS), floor)


def plan_shards(scene: Scene, settings: BakeSettings, budget_bytes: int, digest: str | None = None,
                code: str | None = None) -> list[ShardTask]:
    """The shards of ``scene`` under a size budget (bytes of ``probes.ktx2`` per shard; see the
    module docstring); ``digest``: :func:`scene_hash` of ``scene`` and ``code``:
    :func:`code_digest`, when already known."""
    if not scene.streets:
        raise ValueError(f"scene '{scene.name}' has no streets: nothing to place probes along")
    digest = scene_hash(scene) if digest is None else digest
    code = code_digest() if code is None else code
    per = probe_bytes(settings.resolution)
    counts = []
    for st in scene.streets:
        count = probe_count(st, settings.spacing)
        if not math.isfinite(count):
            raise ValueError(f"street '{st.name}': {st.length} m at {settings.spacing} m spacing is too many probes")
        counts.append(int(count))
    cap = shard_probe_cap(sum(counts), settings)
    groups: list[list[tuple[Street, int]]] = []
    size = probes = 0
    for st, n in zip(scene.streets, counts):
        if groups and budget_bytes > 0 and size + n * per <= budget_bytes and probes + n <= cap:
            groups[-1].append((st, n))
            size += n * per
            probes += n
        else:
            groups.append([(st, n)])
            size, probes = n * per, n
    tasks = []
    for i, group in enumerate(groups):
        streets = [st for st, _ in group]
        key = shard_key(digest, streets, settings, code)
        path = f"{SHARDS_DIR}/{i:04d}-{_slug(streets[0].name)}-{key[:KEY_IN_NAME]}"
        tasks.append(ShardTask(i, tuple(st.name for st in streets), sum(n for _, n in group), key, path))
    return tasks
