"""Street evaluation of the dynamic terms with avatars: skinned walkers posed at keyframes around a
point, fresh captures with their meshes in the scene as truth, Eq. 3 shading from the probes
without and with the dynamic terms of their proxy spheres (the paper's Sections V-VI).

Per position ``x`` and :class:`Crowd` (rings of :class:`AvatarRing`): every avatar (the test
avatar ``city_scenes/avatars/walker.glb`` unless another is given: a file ``envcap avatar`` wrote,
with the proxy spheres stored in it) is posed at a keyframe of its
animation by its skin (:func:`envcap.dynamic.gltf_skin.skin`), turned about +Y and stood on the
ground under its feet around ``x``; the posed meshes are added to the scene
(:func:`envcap.scene.extra_meshes.with_meshes`) and a cube is captured at ``x`` (the truth).  The
prediction sees the same avatars as spheres, by the crowd LOD rule
(:func:`envcap.dynamic.crowd_lod.use_bone_spheres`): an avatar whose one sphere is within
``NEAR_FACTOR`` enclosing radii of ``x`` contributes its posed bone spheres
(:func:`envcap.dynamic.proxy_spheres.pose_spheres`), a farther one its one sphere
(:func:`envcap.dynamic.crowd_lod.avatar_sphere`); each with the avatar's albedo.  Variants, error
metric and models are those of the ring-of-spheres evaluation
(:func:`envcap.evaluate.dynamic_occluders.evaluate_rings`): ``static``, ``static+MODEL``,
``oracle``, ``oracle+MODEL``, relative RMS of Eq. 3 luminance over the evaluator's frames.
Results: ``docs/dynamic.md``, "Street evaluation".
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.capture.renderer import CubeCapture
from envcap.core.checks import positive_int
from envcap.core.resources import city_scenes_dir
from envcap.dynamic.avatar_attributes import is_envcap_avatar, read_annotated
from envcap.dynamic.crowd_lod import (
    NEAR_FACTOR,
    AvatarSphere,
    avatar_sphere,
    use_bone_spheres,
)
from envcap.dynamic.gltf_skin import SkinnedAvatar, joint_matrices, load_avatar, skin
from envcap.dynamic.proxy_spheres import ProxySpheres, fit_proxy_spheres, pose_spheres
from envcap.dynamic.spheres import SphereBuffer
from envcap.evaluate.dynamic_occluders import (
    ALBEDOS,
    rel_err,
    sky_coverage,
    upper_sky,
    visible_sky_hidden,
)
from envcap.evaluate.dynamic_terms import DEFAULT_MODELS, MODELS, shade_model
from envcap.evaluate.predict import Predictor
from envcap.evaluate.shading import (
    MATERIALS,
    Material,
    exact_environment,
    shade,
    shading_frames,
)
from envcap.evaluate.sweep import street_extent
from envcap.evaluate.truth import with_alpha
from envcap.runtime.sampling import composite
from envcap.runtime.shading import EnvironmentFn
from envcap.scene.extra_meshes import ExtraMesh, with_meshes
from envcap.scene.occluder_spheres import OccluderSphere

KEY_STEP_S = 0.25
"""Time step (s) between the keyframes given to successive avatars of a ring (the walker's keys)."""


def walker_path() -> Any:
    """Path of the bundled test avatar (``city_scenes/avatars/walker.glb``)."""
    return city_scenes_dir() / "avatars" / "walker.glb"


@lru_cache(maxsize=4)
def load_rigged(path: str) -> tuple[SkinnedAvatar, ProxySpheres]:
    """The avatar at ``path`` and its proxy spheres (one per joint), read once per path: those
    stored in a file ``envcap avatar`` wrote (:func:`envcap.dynamic.avatar_attributes.read_annotated`),
    else fitted (:func:`envcap.dynamic.proxy_spheres.fit_proxy_spheres`: the bundled walker)."""
    if is_envcap_avatar(path):
        return read_annotated(path)
    avatar = load_avatar(path)
    return avatar, fit_proxy_spheres(avatar)


@dataclass(frozen=True)
class AvatarRing:
    """``count`` avatars standing ``distance`` m (horizontally) from the point, evenly spaced in
    azimuth from ``azimuth_deg`` (from +X toward +Z), each facing the point turned by ``turn_deg``
    about +Y; avatar ``i`` posed at ``time + i * KEY_STEP_S`` s of the animation (looped)."""

    count: int
    distance: float
    turn_deg: float = 0.0
    time: float = 0.0
    azimuth_deg: float = 22.5

    def __post_init__(self) -> None:
        positive_int(self.count, "avatar ring count")
        if not (math.isfinite(self.distance) and self.distance > 0):
            raise ValueError(f"avatar ring distance must be a finite number > 0 m, got {self.distance!r}")

    @property
    def label(self) -> str:
        turn = f", turned {self.turn_deg:g}°" if self.turn_deg else ""
        return f"{self.count} at {self.distance:g} m{turn}"


@dataclass(frozen=True)
class Crowd:
    """Avatars around a point: one or more rings."""

    rings: tuple[AvatarRing, ...]

    @property
    def label(self) -> str:
        return " + ".join(r.label for r in self.rings)


DEFAULT_CROWDS: tuple[Crowd, ...] = (
    Crowd((AvatarRing(4, 0.7),)), Crowd((AvatarRing(6, 0.6),)), Crowd((AvatarRing(6, 1.0),)),
    Crowd((AvatarRing(6, 1.4, 90.0, 0.25),)), Crowd((AvatarRing(8, 2.2),)), Crowd((AvatarRing(10, 4.5),)),
    Crowd((AvatarRing(6, 0.6, 0.0, 0.5), AvatarRing(10, 4.5, 0.0, 0.0, 5.0))),
)
"""Walkers 0.6-4.5 m from the point (their feet; arms reach 0.2 m closer): near rings (bone spheres), a far one (one sphere each: beyond
``NEAR_FACTOR`` enclosing radii) and one crowd with both."""


@dataclass(frozen=True)
class PosedAvatar:
    """An avatar in the world: its skinned ``mesh`` (world m), posed bone spheres ``bone_centers``
    ``(J, 3)`` m and ``bone_radii`` ``(J,)`` m (0: no sphere), its ``one`` sphere, and ``albedo``."""

    mesh: ExtraMesh
    bone_centers: NDArray[np.float64]
    bone_radii: NDArray[np.float64]
    one: AvatarSphere
    albedo: tuple[float, float, float]


def yaw_matrix(yaw_deg: float) -> NDArray[np.float64]:
    """Rotation ``(3, 3)`` by ``yaw_deg`` about +Y (right-handed: +Z turns toward +X)."""
    a = math.radians(yaw_deg)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def pose_avatar(avatar: SkinnedAvatar, proxies: ProxySpheres, root: ArrayLike, yaw_deg: float, time: float,
                albedo: tuple[float, float, float] = ALBEDOS[0], animation: int | None = 0) -> PosedAvatar:
    """``avatar`` posed at ``time`` s of ``animation`` (None: rest pose), turned by ``yaw_deg``
    about +Y and moved so that its frame's origin (the walker's feet) is at ``root`` (3,) world m."""
    if animation is not None and not avatar.animations:
        animation = None
    rot, t = yaw_matrix(yaw_deg), np.asarray(root, np.float64)
    pos, nrm = skin(joint_matrices(avatar, animation, time), avatar)
    keep = np.linalg.norm(nrm, axis=1) > 0          # a collapsed normal (degenerate blend): use the radial one
    nrm = np.where(keep[:, None], nrm, pos - pos.mean(axis=0))
    mesh = ExtraMesh(pos @ rot.T + t, nrm @ rot.T, avatar.triangles, albedo)
    c, r = pose_spheres(proxies, avatar, animation, time)
    c = c @ rot.T + t
    return PosedAvatar(mesh, c, r, avatar_sphere(c, r), albedo)


def crowd_avatars(crowd: Crowd, point: ArrayLike, ground: float | Callable[[NDArray[np.float64]], float],
                  avatar: SkinnedAvatar, proxies: ProxySpheres) -> list[PosedAvatar]:
    """The avatars of ``crowd`` around ``point`` (3,) m, each standing on the ground under its feet:
    ``ground(root)`` m for a function of the world point (3,) (e.g.
    :meth:`envcap.evaluate.sweep.StreetExtent.ground_under`), else the plane ``y = ground`` m;
    albedos alternate over :data:`ALBEDOS`."""
    p = np.asarray(point, np.float64)
    span = 0.0
    if avatar.animations and len(avatar.animations[0].keyframes):
        span = float(avatar.animations[0].keyframes[-1])
    out: list[PosedAvatar] = []
    for ring in crowd.rings:
        for i in range(ring.count):
            az = math.radians(ring.azimuth_deg) + 2 * math.pi * i / ring.count
            d = np.array([math.cos(az), 0.0, math.sin(az)])
            root = p + ring.distance * d
            root[1] = ground(root) if callable(ground) else ground
            yaw = math.degrees(math.atan2(-d[0], -d[2])) + ring.turn_deg    # +Z (forward) toward the point
            time = (ring.time + i * KEY_STEP_S) % span if span > 0 else 0.0
            out.append(pose_avatar(avatar, proxies, root, yaw, time, ALBEDOS[len(out) % len(ALBEDOS)]))
    return out


def lod_spheres(point: ArrayLike, avatars: Sequence[PosedAvatar],
                near_factor: float = NEAR_FACTOR) -> tuple[SphereBuffer, int]:
    """The spheres a shading point at ``point`` (3,) m sees of ``avatars`` by the crowd LOD rule
    (module docstring; bone spheres of radius 0 left out), with each avatar's albedo, and how many
    avatars were near (bone spheres)."""
    cs, rs, al, near = [np.zeros((0, 3))], [np.zeros(0)], [np.zeros((0, 3))], 0
    for a in avatars:
        if bool(use_bone_spheres(point, a.one, near_factor)):
            k = a.bone_radii > 0
            cs.append(a.bone_centers[k]), rs.append(a.bone_radii[k])
            al.append(np.tile(a.albedo, (int(k.sum()), 1)))
            near += 1
        else:
            cs.append(a.one.center[None]), rs.append(np.array([a.one.radius])), al.append(np.array([a.albedo]))
    return SphereBuffer(np.concatenate(cs), np.concatenate(rs), np.concatenate(al)), near


def evaluate_avatar_crowds(scene: Any, predictor: Predictor, street: str, positions: Sequence[Sequence[float]], *,
                           crowds: Sequence[Crowd] = DEFAULT_CROWDS, ctx: Any, resolution: int = 32,
                           method: str = "planes_mip", materials: Sequence[Material] = MATERIALS,
                           models: Sequence[str] = DEFAULT_MODELS, oracle: bool = True, sun: bool = False,
                           avatar_path: Any = None) -> list[dict[str, Any]]:
    """Rows ``{position, xyz, ring, avatars, near, spheres, coverage, sky_hidden, sun, material,
    variant, rel_err}``, one per position x crowd x material x variant (module docstring).
    ``predictor`` holds the probe set of ``scene``; ``street``: the street the positions are on (the
    avatars stand on its ground under their feet, :meth:`envcap.evaluate.sweep.StreetExtent.ground_under`:
    on a street that follows the terrain, the nearest probe's ground plane with its slope);
    ``resolution``: face size of the fresh captures;
    ``coverage``: upper hemisphere covered by the predicted spheres
    (:func:`envcap.evaluate.dynamic_occluders.sky_coverage`); ``sky_hidden``: visible sky the
    meshes hide in the captures; ``near``: avatars seen as bone spheres; ``spheres``: spheres in
    the buffer (the runtime considers at most its cap of them per point)."""
    bad = [m for m in models if m not in MODELS]
    if bad:
        raise ValueError(f"unknown dynamic model(s) {bad}; known: {', '.join(MODELS)}")
    if positive_int(resolution, "capture resolution") < 4:
        raise ValueError(f"capture resolution must be >= 4 texels per face, got {resolution}")
    avatar, proxies = load_rigged(str(avatar_path if avatar_path is not None else walker_path()))
    sky = scene.sky.build()
    sky_rgba = with_alpha(sky.cube(resolution, include_sun=sun))
    sky_light = upper_sky(sky_rgba)
    ground = street_extent(predictor.manifest, street).ground_under
    frames, views = shading_frames(predictor.streets[street].along)
    rows: list[dict[str, Any]] = []

    def capture(sc: Any, x: NDArray) -> Any:
        with CubeCapture.from_scene(sc, resolution, sky=sky, ctx=ctx) as cap:
            return cap.capture(x)

    for pi, pos in enumerate(positions):
        x = np.asarray(pos, np.float64)
        plain = capture(scene, x)
        o_env = exact_environment(composite(plain.rgba.astype(np.float64), sky_rgba))

        def probes(d: NDArray, w: NDArray, x: NDArray = x) -> NDArray:
            return predictor.predict(method, street, x, d.reshape(-1, 3), np.ravel(w), sun).reshape(d.shape[:-1] + (3,))
        statics: dict[str, EnvironmentFn] = {"static": probes}
        if oracle:
            statics["oracle"] = o_env
        for crowd in crowds:
            avatars = crowd_avatars(crowd, x, ground, avatar, proxies)
            buf, near = lod_spheres(x, avatars)
            withs = capture(with_meshes(scene, [a.mesh for a in avatars]), x)
            t_env = exact_environment(composite(withs.rgba.astype(np.float64), sky_rgba))
            occ = [OccluderSphere(tuple(c), float(r)) for c, r in zip(buf.centers, buf.radii) if r > 0]
            base = {"position": pi, "xyz": [float(v) for v in x], "ring": crowd.label, "avatars": len(avatars),
                    "near": near, "spheres": len(occ), "coverage": sky_coverage(x, occ),
                    "sky_hidden": visible_sky_hidden(plain.rgba, withs.rgba), "sun": sun}
            for mat in materials:
                truth = shade(t_env, mat, frames, views)
                for sname, senv in statics.items():
                    rows.append({**base, "material": mat.name, "variant": sname,
                                 "rel_err": rel_err(shade(senv, mat, frames, views), truth)})
                    for name in models:
                        pred = shade_model(name, senv, sky_light, x, frames, views, mat, buf)
                        rows.append({**base, "material": mat.name, "variant": f"{sname}+{name}",
                                     "rel_err": rel_err(pred, truth)})
    return rows


def crowd_table(rows: Sequence[dict[str, Any]], variants: Sequence[str]) -> str:
    """Markdown: one row per (crowd, material), the RMS over positions of ``rel_err`` (%) per
    variant, with the mean visible sky hidden and the avatars near / all."""
    keyed: dict[tuple[str, str], dict[str, list[float]]] = {}
    meta: dict[str, dict[str, list[float]]] = {}
    for r in rows:
        keyed.setdefault((r["ring"], r["material"]), {}).setdefault(r["variant"], []).append(r["rel_err"])
        m = meta.setdefault(r["ring"], {"hidden": [], "near": [], "avatars": []})
        m["hidden"].append(r["sky_hidden"]), m["near"].append(r["near"]), m["avatars"].append(r["avatars"])
    head = ("| avatars (crowd) | near / all | visible sky hidden | material | "
            + " | ".join(variants) + " |\n" + "| --- " * (4 + len(variants)) + "|\n")
    body = ""
    for (ring, mat), v in keyed.items():
        m = meta[ring]
        cells = " | ".join(f"{100 * float(np.sqrt(np.mean(np.square(v[k])))):.1f}" if k in v else "" for k in variants)
        body += (f"| {ring} | {np.mean(m['near']):g} / {np.mean(m['avatars']):g} | {100 * np.mean(m['hidden']):.0f} % "
                 f"| {mat} | {cells} |\n")
    return head + body


def material_summary(rows: Sequence[dict[str, Any]], variants: Sequence[str], min_hidden: float = 0.1) -> str:
    """Markdown: per material, the RMS of ``rel_err`` (%) per variant over the positions x crowds
    hiding at least ``min_hidden`` of the visible sky (and over all of them)."""
    head = "| material | cases | n | " + " | ".join(variants) + " |\n" + "| --- " * (3 + len(variants)) + "|\n"
    body = ""
    mats = list(dict.fromkeys(r["material"] for r in rows))
    for label, lo in ((f"≥ {100 * min_hidden:g} % sky hidden", min_hidden), ("all", -1.0)):
        for mat in mats:
            sel = [r for r in rows if r["material"] == mat and r["sky_hidden"] >= lo]
            n = len({(r["position"], r["ring"]) for r in sel})
            cells = []
            for k in variants:
                e = [r["rel_err"] for r in sel if r["variant"] == k]
                cells.append(f"{100 * float(np.sqrt(np.mean(np.square(e)))):.1f}" if e else "")
            body += f"| {mat} | {label} | {n} | " + " | ".join(cells) + " |\n"
    return head + body

