"""Write an avatar's proxy spheres and per-vertex blockers into a new glTF 2.0 binary (``.glb``).

What is added (application-specific names start with ``_``, as glTF 2.0 requires):

* per vertex, on every primitive of the skinned mesh: ``_ENVCAP_BLOCKERS`` (VEC4, unsigned byte,
  or unsigned short past 255 joints: joint indices in the skin's order, like ``JOINTS_0``) and
  ``_ENVCAP_BLOCKER_WEIGHTS`` (VEC4 float: each blocker's score, the fraction of the
  cosine-weighted hemisphere it hides, reduced over the keyframes; 0 in unused slots);
* ``skins[i].extras["envcap_proxy_spheres"]``: ``centers`` (J x 3, m, each in its joint's bind
  frame, i.e. posed by the joint's global transform), ``radii`` (m), the rule;
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

from envcap.dynamic.avatar_blockers import Blockers, check_options, select_blockers
from envcap.dynamic.crowd_lod import NEAR_FACTOR, avatar_sphere
from envcap.dynamic.gltf_buffers import GltfError, append_accessor
from envcap.dynamic.gltf_skin import SkinnedAvatar, avatar_from_gltf
from envcap.dynamic.proxy_spheres import ProxySpheres, fit_proxy_spheres, pose_spheres
from envcap.probeset.progress import BakeProgress

BLOCKERS_ATTRIBUTE = "_ENVCAP_BLOCKERS"
BLOCKER_WEIGHTS_ATTRIBUTE = "_ENVCAP_BLOCKER_WEIGHTS"
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
    sk.extras["envcap_proxy_spheres"] = {"centers": spheres.centers.round(6).tolist(),
                                         "radii": spheres.radii.round(6).tolist(), "rule": SPHERE_RULE}
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
    try:
        gltf = pygltflib.GLTF2().load(str(source))
    except FileNotFoundError:
        raise
    except Exception as exc:  # pygltflib raises assorted errors on bad files
        raise GltfError(f"{source}: not a readable glTF 2.0 file ({type(exc).__name__}: {exc})") from None
    if gltf is None:
        raise GltfError(f"{source}: not a readable glTF 2.0 file")
    result = annotate(gltf, name=str(source), **options)
    report.start("write", 0)
    gltf.save_binary(str(target))
    report.finish()
    return result
