"""A skinned glTF 2.0 avatar read with pygltflib: the bind-pose mesh, its skin (joints, inverse
bind matrices, ``JOINTS_0``/``WEIGHTS_0``), the node hierarchy and its animations, posed at any time.

Conventions (glTF 2.0): meters, +Y up, right-handed.  A joint's *joint matrix* at time ``t`` is
``G_j(t) @ IBM_j`` (``G_j`` its node's global transform, ``IBM_j`` its inverse bind matrix); a
vertex's posed position is ``sum_i w_i J_{j_i}(t) v`` (linear blend skinning).  As the spec says,
the transform of the skinned mesh's own node is ignored: posed points are in the scene's frame.
Quaternions are ``(x, y, z, w)``.  Animation samplers: ``LINEAR`` (slerp for rotations), ``STEP``,
``CUBICSPLINE`` (Hermite, spec Appendix C); times are clamped to the sampler's range.  Only the
first skinned mesh node is read (an error names the problem when there is none); all its triangle
primitives are concatenated (``primitive_sizes`` splits them back).  Morph-target ``weights``
channels are ignored.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pygltflib
from numpy.typing import NDArray

from envcap.dynamic.gltf_buffers import GltfError, read_accessor


@dataclass(frozen=True)
class NodeChannel:
    """One animated property: ``path`` in translation / rotation / scale of ``node``; ``times``
    ``(K,)`` s; ``values`` ``(K, c)`` or ``(3K, c)`` for CUBICSPLINE (in-tangent, value, out-tangent)."""

    node: int
    path: str
    times: NDArray[np.float64]
    values: NDArray[np.float64]
    interpolation: str


@dataclass(frozen=True)
class SkinAnimation:
    """A glTF animation: its channels and ``keyframes`` (sorted union of the input times, s)."""

    name: str
    channels: tuple[NodeChannel, ...]
    keyframes: NDArray[np.float64]


@dataclass(frozen=True)
class SkinnedAvatar:
    """The bind pose: ``positions``, ``normals`` ``(V, 3)`` (mesh space, m, unit normals),
    ``triangles`` ``(T, 3)``, ``joints`` ``(V, 4)`` (indices into the skin's joint list),
    ``weights`` ``(V, 4)`` (sum 1); the skin: ``joint_nodes``, ``joint_names`` ``(J,)``,
    ``inverse_bind`` ``(J, 4, 4)``; the hierarchy: ``parents`` ``(N,)`` (-1 for roots), rest
    ``translations`` ``(N, 3)``, ``rotations`` ``(N, 4)``, ``scales`` ``(N, 3)``, fixed ``matrices``
    ``(N, 4, 4)`` (identity where TRS is used); ``animations``; ``primitive_sizes`` (vertices per
    primitive), ``mesh_index``, ``skin_index``."""

    positions: NDArray[np.float64]
    normals: NDArray[np.float64]
    triangles: NDArray[np.int64]
    joints: NDArray[np.int64]
    weights: NDArray[np.float64]
    joint_nodes: NDArray[np.int64]
    joint_names: tuple[str, ...]
    inverse_bind: NDArray[np.float64]
    parents: NDArray[np.int64]
    translations: NDArray[np.float64]
    rotations: NDArray[np.float64]
    scales: NDArray[np.float64]
    matrices: NDArray[np.float64]
    animations: tuple[SkinAnimation, ...]
    primitive_sizes: tuple[int, ...]
    mesh_index: int
    skin_index: int

    @property
    def joint_count(self) -> int:
        return len(self.joint_nodes)


def quaternion_matrix(q: NDArray) -> NDArray[np.float64]:
    """Rotation matrices ``(..., 3, 3)`` of quaternions ``(..., 4)`` ``(x, y, z, w)`` (normalized here)."""
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


def trs_matrix(t: NDArray, r: NDArray, s: NDArray) -> NDArray[np.float64]:
    """``T @ R @ S`` as ``(..., 4, 4)`` from translations ``(..., 3)``, quaternions, scales."""
    t = np.asarray(t, dtype=np.float64)
    m = np.zeros(t.shape[:-1] + (4, 4))
    m[..., :3, :3] = quaternion_matrix(r) * np.asarray(s, dtype=np.float64)[..., None, :]
    m[..., :3, 3] = t
    m[..., 3, 3] = 1.0
    return m


def slerp(q0: NDArray, q1: NDArray, u: float) -> NDArray[np.float64]:
    """Spherical interpolation of unit quaternions (shortest arc), ``u`` in [0, 1]."""
    q0 = q0 / np.linalg.norm(q0)
    q1 = q1 / np.linalg.norm(q1)
    d = float(np.dot(q0, q1))
    if d < 0:
        q1, d = -q1, -d
    if d > 1 - 1e-12:
        q = q0 + u * (q1 - q0)
    else:
        a = np.arccos(min(d, 1.0))
        q = (np.sin((1 - u) * a) * q0 + np.sin(u * a) * q1) / np.sin(a)
    return q / np.linalg.norm(q)


def sample_channel(ch: NodeChannel, time: float) -> NDArray[np.float64]:
    """The channel's value at ``time`` (s), clamped to its keyframe range."""
    times = ch.times
    cubic = ch.interpolation == "CUBICSPLINE"
    vals = ch.values[1::3] if cubic else ch.values
    if time <= times[0] or len(times) == 1:
        return vals[0].copy()
    if time >= times[-1]:
        return vals[-1].copy()
    k = int(np.searchsorted(times, time, side="right") - 1)
    dt = times[k + 1] - times[k]
    u = (time - times[k]) / dt
    if ch.interpolation == "STEP":
        return vals[k].copy()
    if cubic:
        b0, a1 = ch.values[3 * k + 2], ch.values[3 * (k + 1)]
        v = ((2 * u**3 - 3 * u**2 + 1) * vals[k] + dt * (u**3 - 2 * u**2 + u) * b0
             + (-2 * u**3 + 3 * u**2) * vals[k + 1] + dt * (u**3 - u**2) * a1)
        return v / np.linalg.norm(v) if ch.path == "rotation" else v
    if ch.path == "rotation":
        return slerp(vals[k], vals[k + 1], u)
    return (1 - u) * vals[k] + u * vals[k + 1]


def global_matrices(avatar: SkinnedAvatar, animation: int | None = None, time: float = 0.0) -> NDArray[np.float64]:
    """Global transforms ``(N, 4, 4)`` of every node at ``time`` s of ``animation`` (None: rest pose)."""
    t, r, s = avatar.translations.copy(), avatar.rotations.copy(), avatar.scales.copy()
    if animation is not None:
        if not 0 <= animation < len(avatar.animations):
            raise ValueError(f"animation {animation} does not exist (the avatar has {len(avatar.animations)})")
        for ch in avatar.animations[animation].channels:
            {"translation": t, "rotation": r, "scale": s}[ch.path][ch.node] = sample_channel(ch, time)
    local = np.where(np.all(avatar.matrices == np.eye(4), axis=(1, 2))[:, None, None], trs_matrix(t, r, s),
                     avatar.matrices)
    out = np.full_like(local, np.nan)
    for node in range(len(local)):
        chain = [node]
        while avatar.parents[chain[-1]] >= 0 and np.isnan(out[chain[-1], 0, 0]):
            chain.append(int(avatar.parents[chain[-1]]))
        for n in reversed(chain):
            if np.isnan(out[n, 0, 0]):
                p = avatar.parents[n]
                out[n] = local[n] if p < 0 else out[p] @ local[n]
    return out


def joint_matrices(avatar: SkinnedAvatar, animation: int | None = None, time: float = 0.0) -> NDArray[np.float64]:
    """Joint matrices ``(J, 4, 4)``: ``G_j(time) @ IBM_j`` (identity for every joint in the bind pose)."""
    return global_matrices(avatar, animation, time)[avatar.joint_nodes] @ avatar.inverse_bind


def skin(joint_mats: NDArray, avatar: SkinnedAvatar, rows: slice = slice(None)) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Posed ``(positions, unit normals)`` ``(n, 3)`` of the vertices ``rows`` (default all) by
    linear blend skinning with ``joint_mats`` ``(J, 4, 4)``.  Normals go through the blended
    matrix's cofactor matrix (its inverse transpose times its determinant, defined for singular
    matrices too; a normal that collapses to 0 stays 0)."""
    blend = np.einsum("vi,vijk->vjk", avatar.weights[rows], joint_mats[avatar.joints[rows]])
    pos = np.einsum("vjk,vk->vj", blend[:, :3, :3], avatar.positions[rows]) + blend[:, :3, 3]
    a, b, c = blend[:, :3, 0], blend[:, :3, 1], blend[:, :3, 2]
    cof = np.stack([np.cross(b, c), np.cross(c, a), np.cross(a, b)], axis=2)
    nrm = np.einsum("vjk,vk->vj", cof, avatar.normals[rows]) * np.sign(np.einsum("vj,vj->v", a, np.cross(b, c)))[:, None]
    length = np.linalg.norm(nrm, axis=1, keepdims=True)
    return pos, nrm / np.where(length > 0, length, 1.0)


def _parents(gltf: pygltflib.GLTF2) -> NDArray[np.int64]:
    parents = np.full(len(gltf.nodes), -1, dtype=np.int64)
    for i, node in enumerate(gltf.nodes):
        for c in node.children or []:
            if not 0 <= c < len(gltf.nodes) or parents[c] >= 0 or c == i:
                raise GltfError(f"node {i} has a bad child {c} (out of range, or a node with two parents)")
            parents[c] = i
    for i in range(len(parents)):  # a cycle never reaches a root
        seen, n = 0, i
        while n >= 0:
            n, seen = int(parents[n]), seen + 1
            if seen > len(parents):
                raise GltfError(f"the node hierarchy has a cycle through node {i}")
    return parents


def _vertex_normals(pos: NDArray, tris: NDArray) -> NDArray[np.float64]:
    n = np.zeros_like(pos)
    face = np.cross(pos[tris[:, 1]] - pos[tris[:, 0]], pos[tris[:, 2]] - pos[tris[:, 0]])
    for k in range(3):
        np.add.at(n, tris[:, k], face)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(length > 0, n / np.where(length > 0, length, 1), [0.0, 1.0, 0.0])


def _animations(gltf: pygltflib.GLTF2) -> tuple[SkinAnimation, ...]:
    out = []
    for a_i, anim in enumerate(gltf.animations):
        chans = []
        for ch in anim.channels:
            path = ch.target.path
            if path not in ("translation", "rotation", "scale") or ch.target.node is None:
                continue
            smp = anim.samplers[ch.sampler]
            times = read_accessor(gltf, smp.input).astype(np.float64)
            values = read_accessor(gltf, smp.output).astype(np.float64).reshape(-1, 4 if path == "rotation" else 3)
            interp = smp.interpolation or "LINEAR"
            per = 3 if interp == "CUBICSPLINE" else 1
            if interp not in ("LINEAR", "STEP", "CUBICSPLINE") or len(values) != per * len(times) or len(times) == 0:
                raise GltfError(f"animation {a_i}: sampler {ch.sampler} has {len(times)} times and {len(values)} "
                                f"values ({interp!r})")
            if np.any(np.diff(times) <= 0):
                raise GltfError(f"animation {a_i}: sampler {ch.sampler} times are not strictly increasing")
            if gltf.nodes[ch.target.node].matrix is not None:
                raise GltfError(f"animation {a_i} targets node {ch.target.node}, which has a matrix (spec: not animatable)")
            chans.append(NodeChannel(int(ch.target.node), path, times, values, interp))
        keys = np.unique(np.concatenate([c.times for c in chans])) if chans else np.zeros(1)
        out.append(SkinAnimation(anim.name or f"animation_{a_i}", tuple(chans), keys))
    return tuple(out)


def read_gltf(path: str | Path) -> pygltflib.GLTF2:
    """The glTF document of a ``.glb`` / ``.gltf`` file; :class:`GltfError` naming the file when it
    is not one (``FileNotFoundError`` when it is missing)."""
    try:
        gltf = pygltflib.GLTF2().load(str(path))
    except FileNotFoundError:
        raise
    except Exception as exc:  # pygltflib raises assorted errors on bad files
        raise GltfError(f"{path}: not a readable glTF 2.0 file ({type(exc).__name__}: {exc})") from None
    if gltf is None:
        raise GltfError(f"{path}: not a readable glTF 2.0 file")
    return gltf


def load_avatar(path: str | Path) -> SkinnedAvatar:
    """Read the first skinned mesh node of a ``.glb`` / ``.gltf`` file (buffers embedded or beside it)."""
    return avatar_from_gltf(read_gltf(path), str(path))


def avatar_from_gltf(gltf: pygltflib.GLTF2, name: str = "glTF") -> SkinnedAvatar:
    """:func:`load_avatar` on a loaded :class:`pygltflib.GLTF2` (``name`` for messages)."""
    if gltf.buffers and gltf.buffers[0].uri is not None:
        with warnings.catch_warnings():  # pygltflib warns that the .bin is left beside: it is, untouched
            warnings.simplefilter("ignore", UserWarning)
            try:
                gltf.convert_buffers(pygltflib.BufferFormat.BINARYBLOB)
            except (OSError, ValueError) as exc:
                raise GltfError(f"{name}: cannot read its buffer {gltf.buffers[0].uri!r} ({exc})") from None
    if gltf.buffers and len(gltf.binary_blob() or b"") < (gltf.buffers[0].byteLength or 0):
        raise GltfError(f"{name}: its binary buffer is missing or shorter than the {gltf.buffers[0].byteLength} "
                        f"bytes it declares (a .gltf whose .bin is not beside it?)")
    node_i = next((i for i, n in enumerate(gltf.nodes) if n.mesh is not None and n.skin is not None), None)
    if node_i is None:
        raise GltfError(f"{name}: no node has both a mesh and a skin (not a skinned avatar)")
    mesh_i, skin_i = gltf.nodes[node_i].mesh, gltf.nodes[node_i].skin
    sk = gltf.skins[skin_i]
    joint_nodes = np.asarray(sk.joints, dtype=np.int64)
    if len(joint_nodes) == 0 or np.any((joint_nodes < 0) | (joint_nodes >= len(gltf.nodes))):
        raise GltfError(f"{name}: skin {skin_i} has no joints or a joint that is not a node")
    ibm = (read_accessor(gltf, sk.inverseBindMatrices) if sk.inverseBindMatrices is not None
           else np.broadcast_to(np.eye(4), (len(joint_nodes), 4, 4)).copy())
    if ibm.shape != (len(joint_nodes), 4, 4):
        raise GltfError(f"{name}: skin {skin_i} has {len(ibm)} inverse bind matrices for {len(joint_nodes)} joints")
    pos, nrm, tris, jts, wts, sizes, base = [], [], [], [], [], [], 0
    for p_i, prim in enumerate(gltf.meshes[mesh_i].primitives):
        a = prim.attributes
        where = f"{name}: mesh {mesh_i} primitive {p_i}"
        if prim.mode not in (None, pygltflib.TRIANGLES):
            raise GltfError(f"{where}: mode {prim.mode} is not TRIANGLES")
        if a.POSITION is None or a.JOINTS_0 is None or a.WEIGHTS_0 is None:
            raise GltfError(f"{where}: needs POSITION, JOINTS_0 and WEIGHTS_0")
        p = read_accessor(gltf, a.POSITION)
        t = (read_accessor(gltf, prim.indices).reshape(-1, 3) if prim.indices is not None
             else np.arange(len(p) - len(p) % 3).reshape(-1, 3))
        j, w = read_accessor(gltf, a.JOINTS_0), read_accessor(gltf, a.WEIGHTS_0)
        if p.shape[1:] != (3,) or j.shape != (len(p), 4) or w.shape != (len(p), 4):
            raise GltfError(f"{where}: POSITION/JOINTS_0/WEIGHTS_0 shapes {p.shape}, {j.shape}, {w.shape}")
        if t.size and (t.min() < 0 or t.max() >= len(p)):
            raise GltfError(f"{where}: an index points past the {len(p)} vertices")
        if np.any((j < 0) | (j >= len(joint_nodes))):
            raise GltfError(f"{where}: JOINTS_0 names a joint past the skin's {len(joint_nodes)}")
        total = w.sum(axis=1, keepdims=True)
        if np.any(w < 0) or np.any(total <= 0):
            raise GltfError(f"{where}: WEIGHTS_0 has a negative weight or a vertex with no weight")
        n = read_accessor(gltf, a.NORMAL) if a.NORMAL is not None else _vertex_normals(p, t)
        n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
        pos.append(p), nrm.append(n), tris.append(t + base), jts.append(j), wts.append(w / total)
        sizes.append(len(p))
        base += len(p)
    if base == 0:
        raise GltfError(f"{name}: the skinned mesh {mesh_i} has no vertices")
    nodes = gltf.nodes
    rot = np.array([n.rotation if n.rotation is not None else [0, 0, 0, 1] for n in nodes], dtype=np.float64)
    mats = np.array([np.asarray(n.matrix, dtype=np.float64).reshape(4, 4).T if n.matrix is not None else np.eye(4)
                     for n in nodes])
    if np.any(np.linalg.norm(rot, axis=1) == 0) or not np.all(np.isfinite(mats)):
        raise GltfError(f"{name}: a node has a zero rotation quaternion or a non-finite matrix")
    return SkinnedAvatar(
        positions=np.concatenate(pos), normals=np.concatenate(nrm), triangles=np.concatenate(tris).astype(np.int64),
        joints=np.concatenate(jts), weights=np.concatenate(wts), joint_nodes=joint_nodes,
        joint_names=tuple(nodes[j].name or f"joint_{k}" for k, j in enumerate(joint_nodes)),
        inverse_bind=ibm, parents=_parents(gltf),
        translations=np.array([n.translation if n.translation is not None else [0, 0, 0] for n in nodes], np.float64),
        rotations=rot,
        scales=np.array([n.scale if n.scale is not None else [1, 1, 1] for n in nodes], dtype=np.float64),
        matrices=mats, animations=_animations(gltf), primitive_sizes=tuple(sizes), mesh_index=int(mesh_i),
        skin_index=int(skin_i))
