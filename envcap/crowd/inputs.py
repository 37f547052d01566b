"""What a crowd is rendered from, read and checked before any work: the probe set and the street
the walkers walk on, the avatar that ``envcap avatar`` wrote (mesh, skin, proxy spheres, per-vertex
blockers), the runtime lookup method and the Lafortune material.

The lookup (``--method``) is a registered parallax method whose GLSL function the crowd shader
can call (:data:`CROWD_METHODS`); the default (:func:`default_method`) is :data:`DISTANCE_METHOD`
where the set has the 1/distance texture, else :data:`DEFAULT_METHOD` (docs/crowd.md says why).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pygltflib
from numpy.typing import NDArray

from envcap.core.resources import city_scenes_dir
from envcap.dynamic.avatar_attributes import BLOCKER_WEIGHTS_ATTRIBUTE, BLOCKERS_ATTRIBUTE, annotate, read_annotated
from envcap.dynamic.gltf_buffers import read_accessor
from envcap.dynamic.gltf_skin import SkinnedAvatar, read_gltf
from envcap.dynamic.proxy_spheres import ProxySpheres
from envcap.evaluate.shading import MATERIALS, Material
from envcap.probeset.probe_set import ProbeSet
from envcap.core.contained_path import resolve_inside
from envcap.probeset.store import distance_from_inverse, read_probe_set
from envcap.runtime import methods
from envcap.runtime.methods import ParallaxMethod
from envcap.runtime.street import MAX_PROBES, RuntimeStreet, StreetProbes

DEFAULT_AVATAR = "avatars/walker.glb"
"""The bundled walker (under ``city_scenes/``), annotated in memory as ``envcap avatar`` would."""
CROWD_METHODS = ("planes_mip", "fitted_planes_mip", "blend", "planes_mip_oblique", "fitted_planes_oblique",
                 "planes_mip_footprint", "planes_mip_aniso", "planes_mip_sigma", "depth_refine")
"""Methods the crowd shader runs: those whose GLSL needs only the probes and the sky, and
``depth_refine``, which also reads the probes' 1/distance texture (``inverse_distance.ktx2``; the
renderer binds it when the method needs it)."""
DISTANCE_METHOD = "depth_refine"
"""The default lookup of a probe set with the 1/distance texture: the best pooled accuracy at
w >= 64 (docs/evaluation.md), at <= 3x the nearest lookup's cost in the crowd (docs/crowd.md)."""
DEFAULT_METHOD = "fitted_planes_oblique"
"""Best pooled accuracy at w >= 64 among the methods at <= 3x a plain lookup that need no more
textures (docs/evaluation.md)."""
MATERIAL = "plastic"
"""The avatars' Lafortune material (:data:`envcap.evaluate.shading.MATERIALS`)."""
ALBEDO = 0.4
"""What an avatar's sphere bounces (grey, linear)."""


@dataclass(frozen=True)
class CrowdAvatar:
    """The avatar: ``avatar`` (mesh and skin), ``spheres`` (its proxy spheres), ``blockers``
    ``(V, 4)`` joint indices and ``scores`` ``(V, 4)`` (``_ENVCAP_BLOCKERS`` / ``_WEIGHTS``,
    decreasing), ``path``."""

    avatar: SkinnedAvatar
    spheres: ProxySpheres
    blockers: NDArray[np.float32]
    scores: NDArray[np.float32]
    path: Path


def annotated_avatar(gltf: pygltflib.GLTF2, path: Path) -> CrowdAvatar:
    """A skinned glTF in memory with its proxy spheres and blockers computed here (``envcap
    avatar``'s defaults; nothing is written); ``path`` names it."""
    avatar, spheres, blockers = annotate(gltf, name=str(path))
    pad = 4 - blockers.joints.shape[1]
    return CrowdAvatar(avatar, spheres, np.pad(blockers.joints, ((0, 0), (0, pad))).astype(np.float32),
                       np.pad(blockers.scores, ((0, 0), (0, pad))).astype(np.float32), path)


@functools.lru_cache(maxsize=1)
def default_avatar() -> CrowdAvatar:
    """The bundled walker, annotated in memory (:func:`annotated_avatar`; once per process: it is
    immutable, do not modify its arrays)."""
    path = city_scenes_dir() / DEFAULT_AVATAR
    return annotated_avatar(read_gltf(path), path)


def read_avatar(path: str | Path) -> CrowdAvatar:
    """An avatar file ``envcap avatar`` wrote (``ValueError`` naming the file otherwise)."""
    avatar, spheres = read_annotated(path)
    gltf = read_gltf(path)
    bl, sc = [], []
    for i, prim in enumerate(gltf.meshes[avatar.mesh_index].primitives):
        a, b = getattr(prim.attributes, BLOCKERS_ATTRIBUTE, None), getattr(prim.attributes, BLOCKER_WEIGHTS_ATTRIBUTE, None)
        if a is None or b is None:
            raise ValueError(f"{path}: primitive {i} has no {BLOCKERS_ATTRIBUTE} (write it with envcap avatar)")
        bl.append(read_accessor(gltf, a).astype(np.float32))
        sc.append(read_accessor(gltf, b).astype(np.float32))
    return CrowdAvatar(avatar, spheres, np.concatenate(bl), np.concatenate(sc), Path(path))


def material(name: str = MATERIAL) -> Material:
    """The Lafortune material ``name`` of :data:`envcap.evaluate.shading.MATERIALS`."""
    return next(m for m in MATERIALS if m.name == name)


def crowd_method(name: str, ps: ProbeSet | None = None) -> ParallaxMethod:
    """The registered method ``name`` (one of :data:`CROWD_METHODS`); with ``ps``, a method that
    reads the distance texture needs ``ps`` to have one (``ValueError`` naming the file)."""
    if name not in CROWD_METHODS:
        raise ValueError(f"--method {name!r}: the crowd shader runs one of {', '.join(CROWD_METHODS)}")
    m = methods.get(name)
    if not crowd_function(m):
        raise ValueError(f"--method {name!r} has no GLSL function")
    if ps is not None and m.needs_distance and ps.distance is None:
        raise ValueError(f"--method {name!r} reads the probes' inverse_distance.ktx2, which this probe set "
                         f"lacks (envcap capture writes it by default)")
    return m


def crowd_function(m: ParallaxMethod) -> str | None:
    """The GLSL function ``vec3 NAME(probes, sky, x, d, w, street)`` the crowd shader calls for
    ``m``: the method's own, or for ``depth_refine`` the crowd's wrapper
    (``crowd_sample_depth_refine`` in ``shaders/crowd/crowd_frag.glsl``, which passes it the
    bound distance texture)."""
    return "crowd_sample_depth_refine" if m.name == "depth_refine" else m.glsl


def default_method(ps: ProbeSet) -> str:
    """The crowd's lookup when ``--method`` is not given: :data:`DISTANCE_METHOD` when the set has
    the distance texture, else :data:`DEFAULT_METHOD`."""
    return DISTANCE_METHOD if ps.distance is not None else DEFAULT_METHOD


def read_probes(path: str | Path) -> ProbeSet:
    """The probe set in directory ``path`` (``FileNotFoundError`` / ``ValueError`` naming it), its
    distance from ``inverse_distance.ktx2`` where the set has that file (else none)."""
    p = Path(path)
    if not p.is_dir():
        raise FileNotFoundError(f"probe set {p} does not exist (make one with: envcap capture SCENE --out {p})")
    ps = read_probe_set(p, distance=False)
    if ps.rungs is not None:
        raise ValueError(f"probe set {p} was baked with a rung ladder; the crowd shader reads a plain lobe chain")
    name = ps.manifest.files.extra.get("inverse_distance") if ps.manifest.files is not None else None
    if name:     # the distance from inverse_distance.ktx2 only (depth_refine's texture), not from the EXRs
        f = resolve_inside(p, name, f"{p / 'manifest.json'}: files.inverse_distance")
        ps = replace(ps, distance=distance_from_inverse(f, tuple(np.asarray(ps.levels[0]).shape[:4])))
    return ps


def pick_street(ps: ProbeSet, name: str | None) -> StreetProbes:
    """The street ``name`` of the probe set (default: its first)."""
    streets = ps.manifest.streets
    if not streets:
        raise ValueError("the probe set has no streets")
    if name is None:
        return StreetProbes.from_manifest(streets[0])
    for st in streets:
        if st.name == name:
            return StreetProbes.from_manifest(st)
    raise ValueError(f"--street {name!r}: the probe set's streets are {', '.join(s.name for s in streets)}")


def runtime_street(street: StreetProbes, method: ParallaxMethod, centre_s: float) -> RuntimeStreet:
    """The runtime street of ``street`` with the plane set of ``method``: every probe, or the
    ``MAX_PROBES`` nearest the along coordinate ``centre_s`` on a longer street."""
    s = street.positions[:, street.along]
    if len(s) <= MAX_PROBES:
        return street.runtime_street(method.planes)
    idx = np.sort(np.argsort(np.abs(s - centre_s), kind="stable")[:MAX_PROBES])
    return street.runtime_street(method.planes, idx)
