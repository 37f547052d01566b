"""A small skinned glTF 2.0 test avatar, made here (deterministic): ``walker``.

Eleven joints (``hips`` root; ``spine``, ``head``; ``upper_arm_L/R``, ``forearm_L/R``;
``thigh_L/R``, ``shin_L/R``), one capsule per joint (a sphere for the head, a horizontal capsule for
the pelvis), joints + weights (4 per vertex: the own joint, blended with the parent joint over the
``BLEND`` m nearest the joint, the other two slots weight 0), and one looping animation ``walk`` of
1 s with keyframes every 0.25 s: legs and arms swing about X in opposite phase, knees and elbows
bend, the spine twists about Y, the hips bob in Y.  Rest pose: every rotation identity, so the
inverse bind matrix of a joint is the translation by minus its rest position.  Meters, +Y up,
facing +Z, feet at y = 0.  ``WALK`` gives every animated angle in closed form (the test reference).
The file is a few tens of kB (``city_scenes/avatars/walker.glb`` is made by its script beside it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pygltflib
from numpy.typing import NDArray

from envcap.dynamic.gltf_buffers import append_accessor


@dataclass(frozen=True)
class Bone:
    """A joint: ``offset`` from its parent's origin (m, rest pose), the capsule it carries from
    ``a`` to ``b`` (joint-local, m) of ``radius`` m (``a == b``: a sphere)."""

    name: str
    parent: str | None
    offset: tuple[float, float, float]
    a: tuple[float, float, float]
    b: tuple[float, float, float]
    radius: float


BONES = (
    Bone("hips", None, (0.0, 0.95, 0.0), (-0.09, 0.0, 0.0), (0.09, 0.0, 0.0), 0.11),
    Bone("spine", "hips", (0.0, 0.1, 0.0), (0.0, 0.12, 0.0), (0.0, 0.42, 0.0), 0.13),
    Bone("head", "spine", (0.0, 0.6, 0.0), (0.0, 0.12, 0.0), (0.0, 0.12, 0.0), 0.11),
    Bone("upper_arm_L", "spine", (0.21, 0.5, 0.0), (0.0, -0.03, 0.0), (0.0, -0.27, 0.0), 0.045),
    Bone("forearm_L", "upper_arm_L", (0.0, -0.3, 0.0), (0.0, -0.03, 0.0), (0.0, -0.25, 0.0), 0.04),
    Bone("upper_arm_R", "spine", (-0.21, 0.5, 0.0), (0.0, -0.03, 0.0), (0.0, -0.27, 0.0), 0.045),
    Bone("forearm_R", "upper_arm_R", (0.0, -0.3, 0.0), (0.0, -0.03, 0.0), (0.0, -0.25, 0.0), 0.04),
    Bone("thigh_L", "hips", (0.1, -0.05, 0.0), (0.0, -0.05, 0.0), (0.0, -0.4, 0.0), 0.07),
    Bone("shin_L", "thigh_L", (0.0, -0.45, 0.0), (0.0, -0.04, 0.0), (0.0, -0.4, 0.0), 0.055),
    Bone("thigh_R", "hips", (-0.1, -0.05, 0.0), (0.0, -0.05, 0.0), (0.0, -0.4, 0.0), 0.07),
    Bone("shin_R", "thigh_R", (0.0, -0.45, 0.0), (0.0, -0.04, 0.0), (0.0, -0.4, 0.0), 0.055),
)
BLEND = 0.08
"""Vertices within this distance (m) of their joint's origin blend with the parent joint
(weight to the parent ``0.5 (1 - d / BLEND)``)."""
KEYFRAMES = (0.0, 0.25, 0.5, 0.75, 1.0)
"""Keyframe times (s) of ``walk``."""


def walk_rotation(bone: str, time: float) -> tuple[str, float]:
    """``(axis, angle rad)`` of ``bone``'s rotation in ``walk`` at a keyframe ``time`` (s):
    phase ``p = 2 pi time``, side ``s = +1`` (L) or ``-1`` (R); about X: thighs ``-s 25 deg sin p``,
    shins ``20 deg (1 + s sin p)`` (knee bend, foot back), upper arms ``s 20 deg sin p`` (opposite
    the legs), forearms ``-(20 + 10 s sin p) deg`` (hand forward); spine ``6 deg sin p`` about Y.
    Other bones: no rotation."""
    p = 2 * math.pi * time
    deg = math.radians
    side = {"L": 1.0, "R": -1.0}
    name, _, s = bone.rpartition("_")
    if bone == "spine":
        return "y", deg(6) * math.sin(p)
    if name == "thigh":
        return "x", -side[s] * deg(25) * math.sin(p)
    if name == "shin":
        return "x", deg(20) * (1 + side[s] * math.sin(p))
    if name == "upper_arm":
        return "x", side[s] * deg(20) * math.sin(p)
    if name == "forearm":
        return "x", -deg(20 + 10 * side[s] * math.sin(p))
    return "x", 0.0


def walk_hips_height(time: float) -> float:
    """Hips height (m) in ``walk`` at a keyframe ``time`` (s): ``0.95 + 0.02 cos(4 pi time)``."""
    return 0.95 + 0.02 * math.cos(4 * math.pi * time)


def _quat(axis: str, angle: float) -> list[float]:
    q = [0.0, 0.0, 0.0, math.cos(angle / 2)]
    q["xyz".index(axis)] = math.sin(angle / 2)
    return q


def capsule(a: NDArray, b: NDArray, radius: float, around: int = 10, cap_rings: int = 3,
            body_rings: int = 4) -> tuple[NDArray, NDArray, NDArray]:
    """A closed capsule (or sphere when ``a == b``) from ``a`` to ``b``: ``(positions, normals,
    triangles)``, outward unit normals, counter-clockwise seen from outside."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    axis = b - a
    length = float(np.linalg.norm(axis))
    u = axis / length if length > 0 else np.array([0.0, 1.0, 0.0])
    body_rings = body_rings if length > 0 else 1
    ref = np.array([1.0, 0, 0]) if abs(u[0]) < 0.9 else np.array([0, 0, 1.0])
    e1 = np.cross(u, ref)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    rings = []  # (center, polar angle from -u) along the capsule
    for k in range(cap_rings):
        rings.append((a, math.pi * (k + 1) / (2 * cap_rings)))
    for k in range(1, body_rings):
        rings.append((a + axis * k / body_rings, math.pi / 2))
    for k in range(cap_rings):
        rings.append((b, math.pi / 2 + math.pi * k / (2 * cap_rings)))
    phi = 2 * math.pi * np.arange(around) / around
    radial = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2
    pos, nrm = [a - radius * u], [-u]
    for center, polar in rings:
        n = -math.cos(polar) * u + math.sin(polar) * radial
        pos.extend(center + radius * n)
        nrm.extend(n)
    pos.append(b + radius * u)
    nrm.append(u)
    tris = [[0, 1 + (i + 1) % around, 1 + i] for i in range(around)]
    for r in range(len(rings) - 1):
        s0, s1 = 1 + r * around, 1 + (r + 1) * around
        for i in range(around):
            j = (i + 1) % around
            tris += [[s0 + i, s0 + j, s1 + j], [s0 + i, s1 + j, s1 + i]]
    last, top = 1 + (len(rings) - 1) * around, 1 + len(rings) * around
    tris += [[last + i, last + (i + 1) % around, top] for i in range(around)]
    tris = np.asarray(tris, dtype=np.int64)
    pos, nrm = np.asarray(pos), np.asarray(nrm)
    # orient counter-clockwise outward
    f = np.cross(pos[tris[:, 1]] - pos[tris[:, 0]], pos[tris[:, 2]] - pos[tris[:, 0]])
    if np.sum(f * nrm[tris[:, 0]]) < 0:
        tris = tris[:, ::-1].copy()
    return pos, nrm, tris


def rest_positions() -> dict[str, NDArray]:
    """Rest (bind) position of each joint's origin, m."""
    out: dict[str, NDArray] = {}
    for bone in BONES:
        base = out[bone.parent] if bone.parent else np.zeros(3)
        out[bone.name] = base + np.asarray(bone.offset)
    return out


def walker_gltf(around: int = 10, cap_rings: int = 3, body_rings: int = 4) -> pygltflib.GLTF2:
    """The ``walker`` avatar as an in-memory :class:`pygltflib.GLTF2` (binary blob buffer).
    ``around``, ``cap_rings``, ``body_rings``: each capsule's resolution (:func:`capsule`; the
    defaults make the bundled file; ``walker_gltf(20, 5, 6)`` has ~6,500 triangles, the paper's
    avatars)."""
    names = [b.name for b in BONES]
    index = {n: i for i, n in enumerate(names)}
    rest = rest_positions()
    pos, nrm, tris, jts, wts = [], [], [], [], []
    base = 0
    for j, bone in enumerate(BONES):
        p, n, t = capsule(np.asarray(bone.a), np.asarray(bone.b), bone.radius, around, cap_rings, body_rings)
        d = np.linalg.norm(p, axis=1)
        w_parent = np.where(d < BLEND, 0.5 * (1 - d / BLEND), 0.0) if bone.parent else np.zeros(len(p))
        parent = index[bone.parent] if bone.parent else 0
        parent_slot = np.where(w_parent > 0, parent, 0)  # glTF: a joint of weight 0 is written as 0
        jts.append(np.stack([np.full(len(p), j), parent_slot, np.zeros(len(p)), np.zeros(len(p))], 1))
        wts.append(np.stack([1 - w_parent, w_parent, np.zeros(len(p)), np.zeros(len(p))], 1))
        pos.append(p + rest[bone.name]), nrm.append(n), tris.append(t + base)
        base += len(p)
    gltf = pygltflib.GLTF2(asset=pygltflib.Asset(generator="envcap avatar_synthetic (walker)", version="2.0"))
    gltf.set_binary_blob(b"")
    attrs = pygltflib.Attributes(
        POSITION=append_accessor(gltf, np.concatenate(pos), pygltflib.FLOAT, target=pygltflib.ARRAY_BUFFER,
                                 with_bounds=True),
        NORMAL=append_accessor(gltf, np.concatenate(nrm), pygltflib.FLOAT, target=pygltflib.ARRAY_BUFFER),
        JOINTS_0=append_accessor(gltf, np.concatenate(jts), pygltflib.UNSIGNED_BYTE, target=pygltflib.ARRAY_BUFFER),
        WEIGHTS_0=append_accessor(gltf, np.concatenate(wts), pygltflib.FLOAT, target=pygltflib.ARRAY_BUFFER))
    indices = append_accessor(gltf, np.concatenate(tris).reshape(-1), pygltflib.UNSIGNED_SHORT,
                              target=pygltflib.ELEMENT_ARRAY_BUFFER)
    gltf.meshes.append(pygltflib.Mesh(name="walker", primitives=[pygltflib.Primitive(attributes=attrs, indices=indices)]))
    for bone in BONES:
        children = [index[b.name] for b in BONES if b.parent == bone.name]
        gltf.nodes.append(pygltflib.Node(name=bone.name, translation=list(bone.offset), children=children or []))
    ibm = np.stack([np.eye(4)] * len(BONES))
    ibm[:, :3, 3] = -np.asarray([rest[n] for n in names])
    gltf.skins.append(pygltflib.Skin(name="walker", joints=list(range(len(BONES))), skeleton=0,
                                     inverseBindMatrices=append_accessor(gltf, ibm, pygltflib.FLOAT)))
    gltf.nodes.append(pygltflib.Node(name="walker_mesh", mesh=0, skin=0))
    gltf.scenes.append(pygltflib.Scene(name="walker", nodes=[0, len(BONES)]))
    gltf.scene = 0
    times = append_accessor(gltf, np.asarray(KEYFRAMES), pygltflib.FLOAT, with_bounds=True)
    samplers, channels = [], []
    for bone in BONES[1:]:
        quats = np.array([_quat(*walk_rotation(bone.name, t)) for t in KEYFRAMES])
        if np.allclose(quats[:, :3], 0):
            continue
        samplers.append(pygltflib.AnimationSampler(input=times, output=append_accessor(gltf, quats, pygltflib.FLOAT),
                                                   interpolation="LINEAR"))
        channels.append(pygltflib.AnimationChannel(sampler=len(samplers) - 1, target=pygltflib.AnimationChannelTarget(
            node=index[bone.name], path="rotation")))
    hips = np.array([[0.0, walk_hips_height(t), 0.0] for t in KEYFRAMES])
    samplers.append(pygltflib.AnimationSampler(input=times, output=append_accessor(gltf, hips, pygltflib.FLOAT),
                                               interpolation="LINEAR"))
    channels.append(pygltflib.AnimationChannel(sampler=len(samplers) - 1, target=pygltflib.AnimationChannelTarget(
        node=0, path="translation")))
    gltf.animations.append(pygltflib.Animation(name="walk", samplers=samplers, channels=channels))
    return gltf


def write_walker(path) -> None:
    """Write ``walker`` as a ``.glb`` at ``path`` (the caller chooses and guards the path)."""
    walker_gltf().save_binary(str(path))


def many_bone_gltf(joints: int, keyframes: int = 5, spacing: float = 0.3, radius: float = 0.05,
                   length: float = 0.2) -> pygltflib.GLTF2:
    """A stress avatar with ``joints`` joints (>= 2): a root joint (no vertices) and ``joints - 1``
    children on a square grid ``spacing`` m apart in the X-Z plane, each carrying one vertical
    capsule (:func:`capsule`, ``radius`` m, ``length`` m: 92 vertices) skinned to it alone; one
    animation of ``keyframes`` keyframes 1/4 s apart in which each child swings about X by up to
    30 deg.  Cost of ``envcap avatar`` grows as joints x vertices x keyframes, i.e. with the
    square of ``joints`` (issue 20); ``JOINTS_0`` is unsigned short past 255 joints, indices
    unsigned int past 65,535 vertices."""
    if joints < 2 or keyframes < 1:
        raise ValueError(f"many_bone_gltf needs joints >= 2 and keyframes >= 1, got {joints}, {keyframes}")
    side = math.ceil(math.sqrt(joints - 1))
    p, n, t = capsule(np.zeros(3), np.array([0.0, length, 0.0]), radius)
    grid = np.array([[(i % side) * spacing, 0.0, (i // side) * spacing] for i in range(joints - 1)])
    count = len(p)
    pos = (p[None] + grid[:, None]).reshape(-1, 3)
    nrm = np.broadcast_to(n, (joints - 1, count, 3)).reshape(-1, 3)
    tris = (t[None] + count * np.arange(joints - 1)[:, None, None]).reshape(-1)
    jts = np.zeros((len(pos), 4))
    jts[:, 0] = np.repeat(np.arange(1, joints), count)
    wts = np.zeros((len(pos), 4))
    wts[:, 0] = 1.0
    gltf = pygltflib.GLTF2(asset=pygltflib.Asset(generator="envcap avatar_synthetic (many_bone)", version="2.0"))
    gltf.set_binary_blob(b"")
    attrs = pygltflib.Attributes(
        POSITION=append_accessor(gltf, pos, pygltflib.FLOAT, target=pygltflib.ARRAY_BUFFER, with_bounds=True),
        NORMAL=append_accessor(gltf, nrm, pygltflib.FLOAT, target=pygltflib.ARRAY_BUFFER),
        JOINTS_0=append_accessor(gltf, jts, pygltflib.UNSIGNED_BYTE if joints <= 256 else pygltflib.UNSIGNED_SHORT,
                                 target=pygltflib.ARRAY_BUFFER),
        WEIGHTS_0=append_accessor(gltf, wts, pygltflib.FLOAT, target=pygltflib.ARRAY_BUFFER))
    index_type = pygltflib.UNSIGNED_SHORT if len(pos) <= 65535 else pygltflib.UNSIGNED_INT
    indices = append_accessor(gltf, tris, index_type, target=pygltflib.ELEMENT_ARRAY_BUFFER)
    gltf.meshes.append(pygltflib.Mesh(name="bones", primitives=[pygltflib.Primitive(attributes=attrs, indices=indices)]))
    gltf.nodes.append(pygltflib.Node(name="root", children=list(range(1, joints))))
    for i in range(joints - 1):
        gltf.nodes.append(pygltflib.Node(name=f"bone_{i}", translation=grid[i].tolist()))
    ibm = np.stack([np.eye(4)] * joints)
    ibm[1:, :3, 3] = -grid
    gltf.skins.append(pygltflib.Skin(name="bones", joints=list(range(joints)), skeleton=0,
                                     inverseBindMatrices=append_accessor(gltf, ibm, pygltflib.FLOAT)))
    gltf.nodes.append(pygltflib.Node(name="bones_mesh", mesh=0, skin=0))
    gltf.scenes.append(pygltflib.Scene(name="bones", nodes=[0, joints]))
    gltf.scene = 0
    times = append_accessor(gltf, 0.25 * np.arange(keyframes), pygltflib.FLOAT, with_bounds=True)
    phase = 2 * math.pi * np.arange(keyframes) / max(keyframes, 2)
    samplers, channels = [], []
    for i in range(1, joints):
        quats = np.array([_quat("x", math.radians(30) * math.sin(ph + i)) for ph in phase])
        samplers.append(pygltflib.AnimationSampler(input=times, output=append_accessor(gltf, quats, pygltflib.FLOAT),
                                                   interpolation="LINEAR"))
        channels.append(pygltflib.AnimationChannel(sampler=len(samplers) - 1, target=pygltflib.AnimationChannelTarget(
            node=i, path="rotation")))
    gltf.animations.append(pygltflib.Animation(name="swing", samplers=samplers, channels=channels))
    return gltf
