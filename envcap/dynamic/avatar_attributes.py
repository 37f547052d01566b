"""An avatar's proxy spheres and per-vertex blockers in a glTF 2.0 binary (``.glb``): written into a
new file (``envcap avatar``), read back by the commands that take such a file (``envcap evaluate
--avatar``, :func:`read_annotated`).

What is added (application-specific names start with ``_``, as glTF 2.0 requires):

* per vertex, on every primitive of the skinned mesh: ``_ENVCAP_BLOCKERS`` (VEC4, unsigned byte,
  or unsigned short past 255 joints: joint indices in the skin's order, like ``JOINTS_0``) and
  ``_ENVCAP_BLOCKER_WEIGHTS`` (VEC4 float: each blocker's score, the fraction of the
  cosine-weighted hemisphere it hides, reduced over the keyframes; 0 in unused slots);
* ``skins[i].extras["envcap_proxy_spheres"]``: ``centers`` (J x 3, m, each in its joint's bind
  frame, i.e. posed by the joint's global transform), ``radii`` (m), both at full float64
  precision, the rule;
* ``skins[i].extras["envcap_blockers"]``: ``k``, ``reduce``, ``exclude_weight``, the measure;
* ``animations[a].extras["envcap_avatar_sphere"]``: per keyframe ``times`` (s), ``centers``
  (m, scene frame), ``radii`` and ``enclosing`` radii (m) of the one-sphere LOD, and
  ``near_factor`` (:mod:`envcap.dynamic.crowd_lod`);
* ``asset.extras["envcap"] = "avatar"``: the mark of a file envcap wrote (what it may replace).

The input is never modified; the caller writes through :mod:`envcap.outputs` (``envcap avatar``).
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pygltflib

from envcap.core.input_path import require_file
from envcap.dynamic.avatar_blockers import Blockers, check_options, select_blockers
from envcap.dynamic.crowd_lod import NEAR_FACTOR, avatar_sphere
from envcap.dynamic.gltf_buffers import GltfError, append_accessor
from envcap.dynamic.gltf_skin import SkinnedAvatar, avatar_from_gltf, read_gltf
from envcap.dynamic.proxy_spheres import ProxySpheres, fit_proxy_spheres, owner_joints, pose_spheres
from envcap.probeset.progress import BakeProgress

BLOCKERS_ATTRIBUTE = "_ENVCAP_BLOCKERS"
BLOCKER_WEIGHTS_ATTRIBUTE = "_ENVCAP_BLOCKER_WEIGHTS"
SPHERES_KEY = "envcap_proxy_spheres"
"""``skins[i].extras`` key of the proxy spheres (module docstring)."""
MARK = ("envcap", "avatar")
"""``asset.extras[MARK[0]] == MARK[1]`` in a file envcap wrote."""
SPHERE_RULE = ("vertices of largest weight to the joint, in its bind frame; centre = convex hull volume "
               "centroid, radius = sqrt(hull area / 4 pi) (equal mean projected area)")
MEASURE = "sphere form factor: fraction of the cosine-weighted hemisphere hidden (docs/dynamic.md, Avatars)"


def is_envcap_avatar(path: str | Path) -> bool:
    """True when ``path`` is a glTF file envcap wrote (it carries :data:`MARK`); reads only the
    JSON (a ``.glb``'s first chunk)."""
    try:
        with open(path, "rb") as f:
            head = f.read(20)
            if head[:4] == b"glTF":
                length, kind = struct.unpack("<I4s", head[12:20])
                if kind != b"JSON" or length > 64 * 2**20:
                    return False
                doc = json.loads(f.read(length))
            else:
                doc = json.loads(head + f.read(64 * 2**20))
        extras = doc["asset"].get("extras", {})
    except (OSError, ValueError, KeyError, TypeError, AttributeError, struct.error):  # unreadable: not ours
        return False
    return isinstance(extras, dict) and extras.get(MARK[0]) == MARK[1]


def annotate(gltf: pygltflib.GLTF2, k: int = 4, animation: int | None = 0, reduce: str = "mean",
             exclude_weight: float = 0.0, name: str = "glTF",
             report: BakeProgress | None = None) -> tuple[SkinnedAvatar, ProxySpheres, Blockers]:
    """Add the attributes and extras (module docstring) to ``gltf`` in memory; returns what was
    computed (``name``: the file, for messages).  Refuses a file that already has ``_ENVCAP_BLOCKERS``.
    ``report``: stages ``spheres``, ``blockers`` (counting vertices) and ``one sphere``."""
    report = BakeProgress("off") if report is None else report
    avatar = avatar_from_gltf(gltf, name)
    report.start("spheres", 0)
    spheres = fit_proxy_spheres(avatar)
    if not np.any(spheres.radii > 0):
        raise GltfError("no joint has enough vertices (>= 4, not flat) for a proxy sphere")
    if animation is not None and not avatar.animations:
        animation = None
    report.start("blockers", len(avatar.positions))
    blockers = select_blockers(avatar, spheres, k, animation, reduce, exclude_weight, progress=report.advance)
    report.finish()
    joint_type = pygltflib.UNSIGNED_BYTE if avatar.joint_count <= 256 else pygltflib.UNSIGNED_SHORT
    pad = 4 - blockers.joints.shape[1]
    joints = np.pad(blockers.joints, ((0, 0), (0, pad)))
    scores = np.pad(blockers.scores, ((0, 0), (0, pad)))
    start = 0
    for prim, size in zip(gltf.meshes[avatar.mesh_index].primitives, avatar.primitive_sizes):
        if getattr(prim.attributes, BLOCKERS_ATTRIBUTE, None) is not None:
            raise GltfError(f"the mesh already has {BLOCKERS_ATTRIBUTE} (annotated before?)")
        setattr(prim.attributes, BLOCKERS_ATTRIBUTE,
                append_accessor(gltf, joints[start:start + size], joint_type, target=pygltflib.ARRAY_BUFFER))
        setattr(prim.attributes, BLOCKER_WEIGHTS_ATTRIBUTE,
                append_accessor(gltf, scores[start:start + size], pygltflib.FLOAT, target=pygltflib.ARRAY_BUFFER))
        start += size
    sk = gltf.skins[avatar.skin_index]
    sk.extras = dict(sk.extras or {})
    # full float64 (JSON keeps every bit): read back (read_annotated), they pose exactly as the fit
    sk.extras[SPHERES_KEY] = {"centers": spheres.centers.tolist(), "radii": spheres.radii.tolist(), "rule": SPHERE_RULE}
    sk.extras["envcap_blockers"] = {"k": int(k), "reduce": reduce, "exclude_weight": float(exclude_weight),
                                    "animation": animation, "measure": MEASURE}
    if animation is not None:
        ones = []
        report.start("one sphere", 0)
        for t in blockers.keyframes:
            ones.append(avatar_sphere(*pose_spheres(spheres, avatar, animation, float(t))))
        report.finish()
        anim = gltf.animations[animation]
        anim.extras = dict(anim.extras or {})
        anim.extras["envcap_avatar_sphere"] = {
            "times": blockers.keyframes.round(6).tolist(), "centers": [o.center.round(6).tolist() for o in ones],
            "radii": [round(o.radius, 6) for o in ones], "enclosing": [round(o.enclosing, 6) for o in ones],
            "near_factor": NEAR_FACTOR}
    gltf.asset.extras = dict(gltf.asset.extras or {})
    gltf.asset.extras[MARK[0]] = MARK[1]
    return avatar, spheres, blockers


def write_annotated(source: str | Path, target: str | Path, **options) -> tuple[SkinnedAvatar, ProxySpheres, Blockers]:
    """Read ``source`` (``.glb``/``.gltf``), :func:`annotate` it, save a ``.glb`` at ``target``
    (a path the caller has guarded; see ``envcap avatar``).  ``options``: those of :func:`annotate`
    (``report`` included).  The caller estimates the cost first (:mod:`envcap.dynamic.avatar_cost`)."""
    check_options(options.get("k", 4), options.get("reduce", "mean"), options.get("exclude_weight", 0.0))
    report = options.get("report") or BakeProgress("off")
    report.start("read", 0)
    gltf = read_gltf(source)
    result = annotate(gltf, name=str(source), **options)
    report.start("write", 0)
    gltf.save_binary(str(target))
    report.finish()
    return result


def read_annotated(path: str | Path) -> tuple[SkinnedAvatar, ProxySpheres]:
    """The avatar of a file ``envcap avatar`` wrote and the proxy spheres stored in it
    (``skins[i].extras.envcap_proxy_spheres``: centres ``(J, 3)`` in each joint's bind frame, m,
    radii ``(J,)`` m), not fitted again; each vertex belongs to the joint of its largest weight
    (:func:`~envcap.dynamic.proxy_spheres.owner_joints`).  ``FileNotFoundError`` when ``path`` is
    missing; ``ValueError`` (one line naming the file) when it is not such a file: another glTF
    (no :data:`MARK`: its spheres were never computed), or spheres that do not fit its skin."""
    require_file(path, "avatar file", f"avatar file {path} does not exist")
    if not is_envcap_avatar(path):
        raise ValueError(f"{path} was not written by envcap avatar (it has no asset.extras.envcap = \"avatar\"); "
                         f"make one with: envcap avatar {path} --out NAME.glb")
    gltf = read_gltf(path)
    avatar = avatar_from_gltf(gltf, str(path))
    extras = gltf.skins[avatar.skin_index].extras or {}
    stored = extras.get(SPHERES_KEY) if isinstance(extras, dict) else None
    j = avatar.joint_count
    try:
        centers = np.asarray(stored["centers"], np.float64)
        radii = np.asarray(stored["radii"], np.float64)
    except (TypeError, KeyError, ValueError):
        raise GltfError(f"{path}: skins[{avatar.skin_index}].extras.{SPHERES_KEY} is missing or not centers and "
                        f"radii lists (write the file again with envcap avatar)") from None
    fits = centers.shape == (j, 3) and radii.shape == (j,)
    if not (fits and np.all(np.isfinite(centers)) and np.all(np.isfinite(radii)) and np.all(radii >= 0)
            and np.any(radii > 0)):
        raise GltfError(f"{path}: skins[{avatar.skin_index}].extras.{SPHERES_KEY} does not fit the skin's {j} joints "
                        f"(centers {centers.shape}, radii {radii.shape}; finite, radii >= 0, one > 0)")
    owner = owner_joints(avatar)
    return avatar, ProxySpheres(centers, radii, np.bincount(owner, minlength=j).astype(np.int64), owner)
