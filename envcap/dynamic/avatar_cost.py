"""Bounds before work for ``envcap avatar``: the input's counts read from its glTF JSON alone,
and the memory and time they will cost, before any buffer is decoded.

The work grows as vertices x joints x keyframes (every vertex against every joint's sphere at
every keyframe: :func:`envcap.dynamic.avatar_blockers.select_blockers`), i.e. with the square of
the bone count for an avatar whose bones carry similar meshes; since issue 20 it runs in blocks
of vertices, so its memory stays bounded (``BLOCK_PAIRS`` pairs at a time) and only its *time*
grows that way.  Memory is then the file and its decoded arrays, linear in the file's size and
vertex count, and is checked against :func:`envcap.core.budget.memory_limit` (available memory,
or ``ENVCAP_MAX_MEMORY``); the time is printed first when it is long.

The model (``estimate_avatar``) was fitted to ``envcap avatar`` on the many-bone avatars of
:func:`envcap.dynamic.avatar_synthetic.many_bone_gltf` (50 to 5,000 joints, 92 vertices each,
5 keyframes) and the ``walker`` (2 CPU cores shared with other jobs): peak resident memory 72 MB
(walker), 91 MB (200 joints), 139 MiB (1,000 joints, 33 s in all), 353 MiB (5,000 joints, 7.8
min in all); per vertex-joint-keyframe 40-140 ns, per keyframe-joint of the one-sphere LOD
2.6-3.1 ms, per glTF object (accessor, node, sampler, channel) ~1 ms to decode.  The estimate
stays above those (1,000 joints: 240 MiB, 98 s; 5,000: 680 MiB, 31 min).
"""

from __future__ import annotations

import json
import os
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from envcap.core.budget import check_bytes, format_bytes
from envcap.dynamic.avatar_blockers import BLOCK_PAIRS, BYTES_PER_PAIR
from envcap.probeset.bake_bounds import BIG_BYTES, BIG_SECONDS, format_seconds

_BASE_BYTES = 110e6          # Python, numpy, scipy, pygltflib (walker: 72 MB in all)
_FILE_FACTOR = 4.0           # the file's bytes, its blob, the output blob, the decoded JSON
_VERTEX_BYTES = 600.0        # float64 positions, normals, weights, int64 joints, posed copies, results
_OBJECT_BYTES = 8e3          # a pygltflib dataclass per accessor, node, sampler, channel
_BASE_S = 1.0
_PAIR_S = 150e-9             # one vertex against one joint at one keyframe
_LOD_S = 4e-3                # one joint at one keyframe of the one-sphere LOD (32 directions)
_OBJECT_S = 1.5e-3           # decoding one glTF object (dataclasses_json)
_VERTEX_S = 2e-5             # reading, fitting the proxy spheres, writing


@dataclass(frozen=True)
class AvatarCounts:
    """What an avatar file holds, read from its JSON: ``vertices`` of the skinned mesh,
    ``joints`` of its skin, ``keyframes`` of the chosen animation (its longest sampler: the union
    of the samplers' times when they share them, as exporters write them; 1 without animation),
    ``objects`` (accessors, nodes, samplers, channels), ``file_bytes``, ``animations`` in the file."""

    vertices: int
    joints: int
    keyframes: int
    objects: int
    file_bytes: int
    animations: int = 0


@dataclass(frozen=True)
class AvatarEstimate:
    """``peak_bytes`` of the process and rough wall ``seconds`` (2 shared CPU cores) of ``envcap avatar``."""

    counts: AvatarCounts
    peak_bytes: float
    seconds: float

    @property
    def big(self) -> bool:
        """Whether the estimate is worth printing before the work starts (as a bake's:
        :data:`~envcap.probeset.bake_bounds.BIG_BYTES`, :data:`~envcap.probeset.bake_bounds.BIG_SECONDS`)."""
        return self.peak_bytes > BIG_BYTES or self.seconds > BIG_SECONDS

    def describe(self) -> str:
        """``"91,908 vertices x 1,000 joints x 5 keyframes: peak memory ~190 MiB, roughly 2 min"``."""
        c = self.counts
        return (f"{c.vertices:,} vertices x {c.joints:,} joints x {c.keyframes:,} keyframes: peak memory "
                f"~{format_bytes(self.peak_bytes)}, roughly {format_seconds(self.seconds)}")


def _json_of(path: Path) -> Any:
    with open(path, "rb") as f:
        head = f.read(20)
        if head[:4] == b"glTF":
            length, kind = struct.unpack("<I4s", head[12:20])
            if kind != b"JSON":
                return None
            return json.loads(f.read(length))
        return json.loads(head + f.read())


def _count(doc: dict, accessor: Any) -> int:
    return int(doc["accessors"][accessor]["count"])


def read_counts(path: str | os.PathLike[str], animation: int | None = 0) -> AvatarCounts | None:
    """The counts of the avatar file ``path`` (``.glb`` or ``.gltf``) from its JSON alone, or
    ``None`` when the JSON is not a readable skinned glTF (the loader then says what is wrong)."""
    path = Path(path)
    size = path.stat().st_size
    if path.suffix.lower() != ".glb":   # a .gltf's JSON (buffers maybe embedded as base64) is read whole
        check_bytes(f"avatar {path} ({format_bytes(size)} of JSON)", _BASE_BYTES + 6.0 * size, "the input file")
    try:
        doc = _json_of(path)
        node = next(n for n in doc["nodes"] if "mesh" in n and "skin" in n)
        prims = doc["meshes"][node["mesh"]]["primitives"]
        vertices = sum(_count(doc, p["attributes"]["POSITION"]) for p in prims)
        joints = len(doc["skins"][node["skin"]]["joints"])
        anims = doc.get("animations") or []
        keyframes = 1
        if animation is not None and 0 <= animation < len(anims):
            inputs = {s["input"] for s in anims[animation]["samplers"]}
            keyframes = max([_count(doc, i) for i in inputs] or [1])
        objects = (len(doc.get("accessors", [])) + len(doc.get("nodes", []))
                   + sum(len(a.get("samplers", [])) + len(a.get("channels", [])) for a in anims))
    except (OSError, ValueError, KeyError, IndexError, TypeError, AttributeError, StopIteration, struct.error):
        return None
    return AvatarCounts(int(vertices), int(joints), int(keyframes), int(objects), int(size), len(anims))


def estimate_avatar(counts: AvatarCounts) -> AvatarEstimate:
    """Peak memory and rough time of ``envcap avatar`` on an input of ``counts`` (module docstring)."""
    c = counts
    block = min(float(BLOCK_PAIRS), float(max(c.joints, 1)) * max(c.vertices, 1)) * BYTES_PER_PAIR
    peak = _BASE_BYTES + _FILE_FACTOR * c.file_bytes + _VERTEX_BYTES * c.vertices + _OBJECT_BYTES * c.objects + block
    seconds = (_BASE_S + _PAIR_S * float(c.vertices) * c.joints * c.keyframes + _LOD_S * float(c.keyframes) * c.joints
               + _OBJECT_S * c.objects + _VERTEX_S * c.vertices)
    return AvatarEstimate(c, peak, seconds)


def check_avatar_cost(est: AvatarEstimate, path: str | os.PathLike[str]) -> None:
    """Refuse (:class:`~envcap.core.budget.BudgetError`, one line) an avatar whose estimated peak
    memory exceeds the memory limit, naming the input and the estimate."""
    check_bytes(f"avatar {path} ({est.describe()})", est.peak_bytes, "the input (fewer vertices or joints)")
