"""The city index (``city.json``): a sharded probe set, its typed dataclasses, reader, writer and
the merge of its shards into one :class:`~envcap.probeset.probe_set.ProbeSet`.

A city probe set is a directory (``docs/scale.md``, ``docs/formats.md``)::

    city.json               format "envcap-city", version 1 (docs/city_index.schema.json)
    street_map.ktx2         top-down street ids, R16UI (envcap.city.street_map_file)
    shards/NNNN-NAME-KEY/   one probe-set directory per shard (manifest.json, probes.ktx2, ...)

Each shard is a complete probe set of today's format (readable alone by
:func:`envcap.probeset.store.read_probe_set`) holding one street or a run of consecutive
streets.  Layers are global over the city in shard order: shard ``s`` holds city layers
``[layers[0], layers[0] + layers[1])``; a street's ``layers`` (first, count) are city layers too,
so its layer ``l`` is layer ``l - shard.layers[0]`` of its shard's ``probes.ktx2``.  Every shard
shares the index's resolution, levels, lobe ladder, probe height and spacing, sky and scene.

Street frames (issue 10: streets at any angle).  A street with its own frame carries, as in
its shard's manifest, ``yaw_deg`` and ``origin_xz`` (world -> frame is ``R(yaw) (p - (ox, 0,
oz))``, :mod:`envcap.core.street_frame`); it has axis "x" and its ``start``/``end``/``center``
and planes are frame coordinates.  Both keys are absent for a street in the world frame, so an
index of axis-aligned streets has the bytes it had before they existed (still version 1).
``frame_origin`` (3,) m is the origin of the street's *local* float32 coordinates, in the
street's frame coordinates (the world's for a street without a frame): the box centre of its
probes' frame positions rounded to whole km, what :func:`envcap.runtime.street.street_origin`
gives; an engine takes ``R (p - O) - frame_origin`` in float64 and uploads float32.  ``bounds``
``(x_min, x_max, z_min, z_max)`` (m) is the WORLD box of the street's rectangle (ends and
nominal facades, turned by its yaw), the region in which the street map may give the street.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from envcap import __version__
from envcap.core.contained_path import name_problem
from envcap.core.street_frame import OptionalFrame, frame_to_world
from envcap.probeset.float32_range import check_number_ranges
from envcap.probeset.json_codec import ManifestError, from_json, json_text, read_json_file, to_json
from envcap.probeset.manifest import Files, Level, LobeTable, Manifest, SceneInfo, SkyInfo, Street, Timings
from envcap.probeset.planes import Planes
from envcap.probeset.probe_set import ProbeSet
from envcap.scene.model import local_origin

FORMAT = "envcap-city"
VERSION = 1
INDEX_FILE = "city.json"
_OMIT = {"json": "omit_none"}


@dataclass(frozen=True)
class CityStreet(OptionalFrame):
    """One street of the city: its description (as in a shard's manifest), world box ``bounds``
    (x_min, x_max, z_min, z_max) m, local origin ``frame_origin`` (3,) m (frame coordinates), its
    shard (index into ``CityIndex.shards``), its city layers ``(first, count)`` and, for a street
    with its own frame, ``yaw_deg`` and ``origin_xz`` (absent from the JSON when ``None``; see
    the module docstring)."""

    name: str
    axis: str
    start: float
    end: float
    center: float
    planes: Planes
    bounds: tuple[float, float, float, float]
    frame_origin: tuple[float, float, float]
    shard: int
    layers: tuple[int, int]
    yaw_deg: float | None = field(default=None, metadata=_OMIT)
    origin_xz: tuple[float, float] | None = field(default=None, metadata=_OMIT)


@dataclass(frozen=True)
class Shard:
    """One shard: its directory ``path`` relative to the index (``/``-separated), the ``key``
    that names its inputs (hex SHA-256, :func:`envcap.city.plan.shard_key`), its streets by name
    (in layer order) and its city layers ``(first, count)``."""

    path: str
    key: str
    streets: tuple[str, ...]
    layers: tuple[int, int]


@dataclass(frozen=True)
class StreetMapInfo:
    """The street-map texture: ``file`` relative to the index, the world (x, z) of its low corner
    ``origin`` (m), the ``cell`` size (m) and ``size`` (columns, rows); ids are the index of the
    street in ``CityIndex.streets`` plus 1, 0 = no street (:mod:`envcap.runtime.street_map`)."""

    file: str
    origin: tuple[float, float]
    cell: float
    size: tuple[int, int]


@dataclass(frozen=True, kw_only=True)
class CityIndex:
    """``city.json``, version 1: what every shard shares, the streets and the shards."""

    format: str = FORMAT
    version: int = VERSION
    units: str = "meters"
    up_axis: str = "+Y"
    envcap_version: str = __version__
    scene: SceneInfo
    scene_hash: str
    resolution: int
    levels: tuple[Level, ...]
    lobes: LobeTable | None = None
    probe_height: float
    probe_spacing: float
    sky: SkyInfo
    layer_count: int
    streets: tuple[CityStreet, ...]
    shards: tuple[Shard, ...]
    street_map: StreetMapInfo | None = None

    def to_json(self) -> dict[str, Any]:
        """Plain-JSON dict, checked by :func:`check_city_index` through :meth:`from_json`."""
        obj = to_json(self)
        obj["lobes"] = {} if self.lobes is None else obj["lobes"]
        obj["street_map"] = {} if self.street_map is None else obj["street_map"]
        CityIndex.from_json(obj)
        return obj

    @staticmethod
    def from_json(obj: Any, where: str = INDEX_FILE) -> "CityIndex":
        """The index of parsed JSON ``obj``, checked (``ValueError`` naming the field)."""
        if isinstance(obj, dict):
            if obj.get("format") != FORMAT:
                raise ManifestError(f"{where}: format is {obj.get('format')!r}, expected {FORMAT!r}")
            if obj.get("version") != VERSION:
                raise ManifestError(f"{where}: version {obj.get('version')!r} not supported (this envcap reads {VERSION})")
            obj = dict(obj)
            for key in ("lobes", "street_map"):
                if obj.get(key) == {}:
                    obj[key] = None
        try:
            index = from_json(CityIndex, obj)
        except ManifestError as e:
            raise ManifestError(f"{where}: {e}") from None
        check_city_index(index, where)
        return index


def check_city_index(ix: CityIndex, where: str = INDEX_FILE) -> None:
    """Rules beyond types: fixed fields, numbers in float32/int32 range, unique street names,
    shards covering city layers ``0..layer_count-1`` in order without gaps, each street inside
    its shard's layer range and listed by it, shard paths and the street map's file relative and
    inside the index (:func:`envcap.core.contained_path.name_problem`)."""
    for name, want in (("units", "meters"), ("up_axis", "+Y")):
        if getattr(ix, name) != want:
            raise ManifestError(f"{where}: {name} is {getattr(ix, name)!r}, expected {want!r}")
    check_number_ranges(ix, where)
    if not ix.shards or not ix.streets:
        raise ManifestError(f"{where}: a city needs at least one shard and one street")
    first = 0
    paths = set()
    for i, sh in enumerate(ix.shards):
        if sh.layers != (first, sh.layers[1]) or sh.layers[1] < 1:
            raise ManifestError(f"{where}: shards[{i}].layers must start at {first} and hold >= 1 layer, got {list(sh.layers)}")
        first += sh.layers[1]
        if name_problem(sh.path) is not None or sh.path in paths:
            raise ManifestError(f"{where}: shards[{i}].path must be a unique relative path inside the city, got {sh.path!r}"
                                + (f" ({name_problem(sh.path)})" if name_problem(sh.path) else ""))
        paths.add(sh.path)
    if ix.street_map is not None and (problem := name_problem(ix.street_map.file)) is not None:
        raise ManifestError(f"{where}: street_map.file: {ix.street_map.file!r} is not a path inside the city: {problem}")
    if first != ix.layer_count:
        raise ManifestError(f"{where}: shards hold {first} layers, layer_count says {ix.layer_count}")
    names = set()
    for i, st in enumerate(ix.streets):
        sw = f"{where}: streets[{i}]"
        if st.name in names:
            raise ManifestError(f"{sw}.name: {st.name!r} is not unique")
        names.add(st.name)
        if st.axis not in ("x", "z"):
            raise ManifestError(f"{sw}.axis: must be 'x' or 'z', got {st.axis!r}")
        if st.framed and st.axis != "x":
            raise ManifestError(f"{sw}.axis: a street with yaw_deg/origin_xz runs along its frame's x, got {st.axis!r}")
        if not (st.end > st.start and st.planes.facade_max > st.planes.facade_min):
            raise ManifestError(f"{sw}: needs start < end and facade_min < facade_max")
        if not 0 <= st.shard < len(ix.shards):
            raise ManifestError(f"{sw}.shard: {st.shard} is not a shard index (0..{len(ix.shards) - 1})")
        sh = ix.shards[st.shard]
        if st.name not in sh.streets:
            raise ManifestError(f"{sw}: shard {st.shard} does not list street {st.name!r}")
        lo, n = st.layers
        if n < 1 or lo < sh.layers[0] or lo + n > sh.layers[0] + sh.layers[1]:
            raise ManifestError(f"{sw}.layers {list(st.layers)} lie outside shard {st.shard}'s {list(sh.layers)}")
    listed = [n for sh in ix.shards for n in sh.streets]
    if sorted(listed) != sorted(names):
        raise ManifestError(f"{where}: the shards list the streets {listed}, the index {sorted(names)}")


def read_city_index(path: str | os.PathLike[str]) -> CityIndex:
    """Read and check ``city.json`` (a file, or the city directory holding it)."""
    p = Path(path)
    p = p / INDEX_FILE if p.is_dir() else p
    return CityIndex.from_json(read_json_file(p, "city index"), str(p))


def city_index_text(ix: CityIndex) -> str:
    """The file content of ``ix``: 2-space indented strict JSON and a final newline."""
    return json_text(ix.to_json())


def street_frame_origin(st: Street) -> tuple[float, float, float]:
    """The origin (m) of a street's local float32 coordinates, in its frame coordinates (the
    world's for a street without a frame): its probes' frame-coordinate box centre rounded to
    whole kilometres (:func:`envcap.scene.model.local_origin`, as the runtime's
    ``street_origin`` of the street's frame positions)."""
    pos = st.frame_positions()
    o = local_origin(pos.min(axis=0), pos.max(axis=0))
    return float(o[0]), float(o[1]), float(o[2])


def street_bounds(st: Street | CityStreet) -> tuple[float, float, float, float]:
    """``(x_min, x_max, z_min, z_max)`` (m): the world box of a street's rectangle (its ends and
    nominal facades; for a street with its own frame, the rectangle's four corners taken to the
    world by :func:`envcap.core.street_frame.frame_to_world`, float64)."""
    lo, hi = st.planes.facade_min, st.planes.facade_max
    if not st.framed:
        return (st.start, st.end, lo, hi) if st.axis == "x" else (lo, hi, st.start, st.end)
    corners = np.array([[st.start, 0.0, lo], [st.end, 0.0, lo], [st.end, 0.0, hi], [st.start, 0.0, hi]])
    w = frame_to_world(corners, st.frame_yaw_deg, st.frame_origin_xz)
    return float(w[:, 0].min()), float(w[:, 0].max()), float(w[:, 2].min()), float(w[:, 2].max())


def build_city_index(manifests: Sequence[Manifest], paths: Sequence[str], keys: Sequence[str], scene_hash: str,
                     street_map: StreetMapInfo | None) -> CityIndex:
    """The index of shards with manifests ``manifests`` (in shard order), stored at ``paths``
    under ``keys``; ``ValueError`` when the shards disagree on what they must share."""
    m0 = manifests[0]
    streets, shards, first = [], [], 0
    for s, (m, path, key) in enumerate(zip(manifests, paths, keys)):
        check_shard_agrees(m, m0, path)
        for st in m.streets:
            layers = sorted(p.layer for p in st.probes)
            streets.append(CityStreet(st.name, st.axis, st.start, st.end, st.center, st.planes, street_bounds(st),
                                      street_frame_origin(st), s, (first + layers[0], len(layers)),
                                      st.yaw_deg, st.origin_xz))
        shards.append(Shard(path, key, tuple(st.name for st in m.streets), (first, m.layer_count)))
        first += m.layer_count
    return CityIndex(scene=m0.scene or SceneInfo("", "", 0), scene_hash=scene_hash, resolution=m0.resolution,
                     levels=m0.levels, lobes=m0.lobes, probe_height=m0.probe_height, probe_spacing=m0.probe_spacing,
                     sky=m0.sky, layer_count=first, streets=tuple(streets), shards=tuple(shards), street_map=street_map)


_SHARED = ("resolution", "levels", "lobes", "probe_height", "probe_spacing", "sky", "scene", "effects")


def check_shard_agrees(m: Manifest, ref: Manifest | CityIndex, what: str) -> None:
    """``ValueError`` naming shard ``what`` and the field when its manifest ``m`` differs from
    ``ref`` (the first shard's manifest, or the index) in what every shard shares."""
    for name in _SHARED:
        if not hasattr(ref, name):
            continue
        a, b = getattr(m, name), getattr(ref, name)
        if name == "scene" and isinstance(ref, CityIndex):
            a = a or SceneInfo("", "", 0)
        if a != b:
            raise ValueError(f"shard {what}: {name} {a!r} differs from the city's {b!r}")


def merge_shards(ix: CityIndex, shards: Sequence[ProbeSet], where: str = INDEX_FILE) -> ProbeSet:
    """One probe set of all the shards of ``ix`` (read in index order): layers are city layers,
    streets in index order, sky and shared fields from the index, ``distance`` only when every
    shard has it.  ``ValueError`` when a shard disagrees with the index."""
    if len(shards) != len(ix.shards):
        raise ValueError(f"{where}: {len(ix.shards)} shards listed, {len(shards)} given")
    streets: list[Street] = []
    passes: dict[str, None] = {}
    for sh, ps in zip(ix.shards, shards):
        m = ps.manifest
        check_shard_agrees(m, ix, sh.path)
        if tuple(st.name for st in m.streets) != sh.streets or m.layer_count != sh.layers[1]:
            raise ValueError(f"{where}: shard {sh.path} holds streets {[st.name for st in m.streets]} with "
                             f"{m.layer_count} layers, the index says {list(sh.streets)} with {sh.layers[1]}")
        passes.update(dict.fromkeys(m.passes_run))
        if not np.array_equal(ps.sky_levels[0], shards[0].sky_levels[0]):
            raise ValueError(f"{where}: shard {sh.path} has another sky map than shard {ix.shards[0].path}")
        for st in m.streets:
            moved = tuple(replace(p, layer=p.layer + sh.layers[0]) for p in st.probes)
            streets.append(replace(st, probes=moved))
    m0 = shards[0].manifest
    manifest = replace(m0, streets=tuple(streets), passes_run=tuple(passes), timings=Timings(), files=Files())
    levels = [np.concatenate([ps.levels[k] for ps in shards], axis=0) for k in range(len(ix.levels))]
    dist = None if any(ps.distance is None for ps in shards) else np.concatenate([ps.distance for ps in shards])
    return ProbeSet(manifest=manifest, levels=levels, distance=dist,
                    sky_levels=shards[0].sky_levels)

