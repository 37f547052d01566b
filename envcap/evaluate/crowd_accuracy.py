"""Accuracy of the lit crowd per term, per material and per crowd density: the probes alone, plus
an avatar's own bones (``+self``), plus the other avatars' spheres (``+neighbours``), against fresh
captures with the posed crowd.

Per site (:mod:`envcap.evaluate.crowd_placement`: a host walker at the centre, neighbours at a
density, free points) every walker is posed by its skin at its phase, stood on the street's
ground and added to the scene (:func:`envcap.scene.extra_meshes.with_meshes`); a cube is captured
at each evaluation point with the crowd (the truth) and without it (``oracle``: the static part
with no parallax error).  Two kinds of point:

* ``self``: on the host's surface, at a vertex (:func:`envcap.evaluate.crowd_placement.self_vertices`)
  moved :data:`SELF_OFFSET_M` along its normal, shaded with that normal (two views, as
  :func:`envcap.evaluate.shading.shading_frames`).  Terms: ``probes`` (the static part alone),
  ``+self`` (the vertex's own blocker bones, :func:`envcap.dynamic.avatar_blockers.select_blockers`
  over the walk's keyframes, posed at the host's phase), ``+self+neighbours`` (those and the
  neighbours' spheres by the crowd LOD rule, :func:`envcap.evaluate.dynamic_avatars.lod_spheres`);
* ``free``: among the neighbours, :data:`envcap.evaluate.crowd_placement.FREE_HEIGHT_M` up, the
  evaluator's ten frames.  Terms: ``probes``, ``+neighbours`` (every walker's LOD spheres, the host's
  included).

The dynamic terms are those of the model ``envcap`` (:data:`envcap.evaluate.dynamic_terms.MODELS`)
with a :class:`TermConfig` (sphere cap per point, union rule); extra configurations give the last
term only.  Error: relative RMS of Eq. 3 luminance over the point's frames
(:func:`envcap.evaluate.dynamic_occluders.rel_err`), summarised as the RMS over the points of a
density (:func:`summarize`); the goal (:func:`goal_lines`): with every term, at most
:data:`GOAL_RATIO` times the error of the static part alone, at every density and material.
Results: ``docs/dynamic.md``, "The lit crowd: accuracy per density".
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.capture.renderer import CubeCapture
from envcap.core.checks import positive_int
from envcap.dynamic.avatar_blockers import Blockers, select_blockers
from envcap.dynamic.spheres import DEFAULT_RULE, SPHERE_CAP, SphereBuffer, check_rule
from envcap.dynamic.terms import dynamic_terms
from envcap.evaluate.crowd_placement import (
    DENSITIES,
    FREE_HEIGHT_M,
    RADIUS_M,
    CrowdSite,
    Inside,
    place_crowd,
    self_vertices,
)
from envcap.dynamic.crowd_lod import AvatarSphere
from envcap.evaluate.dynamic_avatars import (
    PosedAvatar,
    load_rigged,
    lod_spheres,
    pose_avatar,
    walker_path,
    yaw_matrix,
)
from envcap.evaluate.dynamic_occluders import ALBEDOS, rel_err, upper_sky, visible_sky_hidden
from envcap.evaluate.dynamic_terms import MODELS, clamped, lafortune
from envcap.evaluate.predict import Predictor
from envcap.evaluate.shading import MATERIALS, Material, exact_environment, shade, shading_frames
from envcap.evaluate.sweep import street_extent
from envcap.evaluate.truth import with_alpha
from envcap.runtime.sampling import composite
from envcap.runtime.shading import EnvironmentFn
from envcap.scene.extra_meshes import ExtraMesh, with_meshes

MODEL = "envcap"
"""The dynamic-terms model evaluated."""
SELF_OFFSET_M = 0.02
"""A self point stands this far (m) off the host's surface, along the vertex normal (the capture's
camera must be outside the body)."""
CAPTURE_NEAR_M = 0.01
"""Near plane (m) of the fresh captures (below the self points' offset)."""
GOAL_RATIO = 0.5
"""The goal: error with every term <= this times the error of the static part alone."""
TERMS: dict[str, tuple[str, ...]] = {"self": ("probes", "+self", "+self+neighbours"),
                                     "free": ("probes", "+neighbours")}
"""Terms per kind of point, the static part alone first and every term last."""
STATICS = ("probes", "oracle")


@dataclass(frozen=True)
class TermConfig:
    """The runtime's choices for the dynamic terms: ``cap`` spheres per point (``0``: every sphere
    of the buffer), the union ``rule`` (:data:`envcap.dynamic.spheres.CombineRule`) and
    ``self_scale``, a factor on the radii of a vertex's own blocker spheres (1: the proxy spheres
    as fitted), and ``self_clamp``: when > 0, each of those radii at most ``self_clamp`` times the
    sphere centre's distance from the point (a cap of half-angle ``asin(self_clamp)`` at most: a
    fitted sphere of a neighbouring limb can contain a point on the body's surface, and then hides
    its whole sky); ``self_exclude``: the blockers' ``exclude_weight``
    (:func:`envcap.dynamic.avatar_blockers.select_blockers`: a vertex's joints of larger skinning
    weight are not its blockers; 0, ``envcap avatar``'s default: any joint it is skinned to)."""

    cap: int = SPHERE_CAP
    rule: str = DEFAULT_RULE
    self_scale: float = 1.0
    self_clamp: float = 0.0
    self_exclude: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.cap, int) or self.cap < 0:
            raise ValueError(f"sphere cap must be an integer >= 0 (0: all), got {self.cap!r}")
        check_rule(self.rule)
        if not (math.isfinite(self.self_scale) and 0 < self.self_scale <= 2):
            raise ValueError(f"self sphere scale must be in (0, 2], got {self.self_scale!r}")
        if not (math.isfinite(self.self_clamp) and 0 <= self.self_clamp < 1):
            raise ValueError(f"self sphere clamp must be in [0, 1) (0: none), got {self.self_clamp!r}")
        if not (math.isfinite(self.self_exclude) and 0 <= self.self_exclude < 1):
            raise ValueError(f"self blockers' exclude weight must be in [0, 1), got {self.self_exclude!r}")

    @property
    def label(self) -> str:
        scale = f", self radii x{self.self_scale:g}" if self.self_scale != 1 else ""
        clamp = f", self radii <= {self.self_clamp:g} l" if self.self_clamp > 0 else ""
        excl = f", own joints above weight {self.self_exclude:g}" if self.self_exclude > 0 else ""
        return f"cap {self.cap or 'all'}, {self.rule}{scale}{clamp}{excl}"

    def cap_for(self, spheres: SphereBuffer) -> int:
        """The cap to pass for ``spheres`` (all of them when ``cap`` is 0)."""
        return self.cap if self.cap > 0 else max(1, len(spheres))


@lru_cache(maxsize=8)
def avatar_blockers(path: str, exclude_weight: float = 0.0) -> Blockers:
    """The per-vertex blocker bones of the avatar at ``path`` (``envcap avatar``'s defaults: 4
    joints, mean over the first animation's keyframes; own joints of weight > ``exclude_weight``
    excluded), computed once."""
    avatar, proxies = load_rigged(path)
    return select_blockers(avatar, proxies, exclude_weight=exclude_weight)


def normal_frames(normal: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Frames ``(2, 3, 3)`` (rows T, B, N) about the unit ``normal`` (3,) and local views ``(2, 3)``
    at 30 and 70 degrees from it (azimuths 20 and 200 degrees), as :func:`shading_frames`."""
    n = np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    helper = np.array([0.0, 1.0, 0.0]) if abs(n[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    t = np.cross(helper, n)
    t /= np.linalg.norm(t)
    frame = np.stack([t, np.cross(n, t), n])
    views = [[math.sin(math.radians(a)) * math.cos(math.radians(f)), math.sin(math.radians(a)) * math.sin(math.radians(f)),
              math.cos(math.radians(a))] for a, f in ((30.0, 20.0), (70.0, 200.0))]
    return np.stack([frame, frame]), np.array(views)


def site_avatars(site: CrowdSite, ground: Any, path: str) -> list[PosedAvatar]:
    """The walkers of ``site`` posed (host first), each on ``ground(root)`` m; albedos alternate
    over :data:`ALBEDOS`.  Each phase is posed once (:func:`pose_avatar` at the origin) and moved
    rigidly: the skin, the bone spheres and the one sphere turn and translate with the walker."""
    avatar, proxies = load_rigged(path)
    poses: dict[float, PosedAvatar] = {}
    out = []
    for i, w in enumerate(site.walkers):
        if w.time not in poses:
            poses[w.time] = pose_avatar(avatar, proxies, (0.0, 0.0, 0.0), 0.0, w.time)
        p0 = poses[w.time]
        root = np.array([w.root_xz[0], 0.0, w.root_xz[1]])
        root[1] = ground(root)
        rot = yaw_matrix(w.yaw_deg)
        albedo = ALBEDOS[i % len(ALBEDOS)]
        mesh = ExtraMesh(p0.mesh.positions @ rot.T + root, p0.mesh.normals @ rot.T, p0.mesh.triangles, albedo)
        one = AvatarSphere(p0.one.center @ rot.T + root, p0.one.radius, p0.one.enclosing)
        out.append(PosedAvatar(mesh, p0.bone_centers @ rot.T + root, p0.bone_radii, one, albedo))
    return out


def self_spheres(host: PosedAvatar, blockers: Blockers, vertex: int, scale: float = 1.0, clamp: float = 0.0,
                 point: ArrayLike | None = None) -> SphereBuffer:
    """The posed spheres of the blocker bones of ``vertex`` of ``host`` (those with a score > 0),
    radii times ``scale``, and with ``clamp`` > 0 at most ``clamp`` times their centres' distance
    from ``point`` (3,) m (default: the vertex)."""
    j = blockers.joints[vertex][blockers.scores[vertex] > 0]
    j = j[host.bone_radii[j] > 0]
    c, r = host.bone_centers[j], scale * host.bone_radii[j]
    if clamp > 0:
        x = host.mesh.positions[vertex] if point is None else np.asarray(point, np.float64)
        r = np.minimum(r, clamp * np.linalg.norm(c - x, axis=1))
    return SphereBuffer(c, r, np.tile(host.albedo, (len(j), 1)))


def joined(*buffers: SphereBuffer) -> SphereBuffer:
    """The spheres of ``buffers`` in one buffer, in order."""
    return SphereBuffer(np.concatenate([b.centers.reshape(-1, 3) for b in buffers]),
                        np.concatenate([b.radii.reshape(-1) for b in buffers]),
                        np.concatenate([b.albedo.reshape(-1, 3) for b in buffers]))


def animation_phases(avatar: Any) -> tuple[float, ...]:
    """The distinct keyframe times (s) of the avatar's first animation, a loop's end left out
    (it repeats the start); ``(0.0,)`` without an animation."""
    if not avatar.animations or not len(avatar.animations[0].keyframes):
        return (0.0,)
    keys = np.asarray(avatar.animations[0].keyframes, np.float64)
    return tuple(float(t) for t in (keys[:-1] if len(keys) > 1 else keys))


def lit_crowd(alone: dict[str, NDArray], statics: dict[str, EnvironmentFn], light: EnvironmentFn, x: ArrayLike,
              frames: NDArray, views: NDArray, mat: Material, spheres: SphereBuffer,
              config: TermConfig) -> dict[str, NDArray[np.float64]]:
    """Per static part, Eq. 3 radiance ``(F, 3)`` with the dynamic terms of ``spheres`` under
    ``config``: ``alone[name] - blocked(static) + bounced(light)`` (the model :data:`MODEL`, as
    :func:`envcap.evaluate.dynamic_terms.shade_model`; the bounced light, lit by ``light``, is
    computed once for every static part)."""
    m = MODELS[MODEL]
    laf = lafortune(mat)
    xs = np.broadcast_to(np.asarray(x, np.float64), frames.shape[:-2] + (3,))
    opts = {"form": m.form, "bounce": m.bounce, "cap": config.cap_for(spheres), "rule": config.rule}
    bounced = dynamic_terms(xs, frames, views, laf, spheres, clamped(light), **opts).bounced  # type: ignore[arg-type]
    return {k: alone[k] - dynamic_terms(xs, frames, views, laf, spheres, clamped(env), **opts).blocked  # type: ignore[arg-type]
            + bounced for k, env in statics.items()}


def evaluation_points(site: CrowdSite, host: PosedAvatar, ground: Any, self_count: int,
                      ) -> list[tuple[str, int, NDArray[np.float64], NDArray[np.float64] | None]]:
    """``(kind, vertex or -1, point (3,) m, normal (3,) or None)`` of the site's self points (on
    ``host``) and free points."""
    out: list[tuple[str, int, NDArray[np.float64], NDArray[np.float64] | None]] = []
    root_y = ground(np.array([site.host.root_xz[0], 0.0, site.host.root_xz[1]]))
    for v in self_vertices(host.mesh.positions, host.mesh.normals, host.mesh.triangles, root_y, self_count, site.seed,
                           SELF_OFFSET_M):
        n = np.asarray(host.mesh.normals[v], np.float64)
        n = n / np.linalg.norm(n)
        out.append(("self", int(v), np.asarray(host.mesh.positions[v], np.float64) + SELF_OFFSET_M * n, n))
    for xz in site.free_xz:
        p = np.array([xz[0], 0.0, xz[1]])
        p[1] = ground(p) + FREE_HEIGHT_M
        out.append(("free", -1, p, None))
    return out


def evaluate_crowd_accuracy(scene: Any, predictor: Predictor, street: str, centers: Sequence[Sequence[float]], *,
                            ctx: Any, densities: Sequence[float] = DENSITIES, resolution: int = 32,
                            materials: Sequence[Material] = MATERIALS, seed: int = 0, self_count: int = 3,
                            free_count: int = 2, configs: Sequence[TermConfig] = (TermConfig(),),
                            radius: float = RADIUS_M, inside: Inside | None = None, method: str = "planes_mip",
                            avatar_path: Any = None) -> list[dict[str, Any]]:
    """Rows ``{site, density, neighbours, area, kind, point, vertex, xyz, sky_hidden, spheres,
    static, term, config, material, rel_err}``, one per site x density x point x static x term x
    material (module docstring), and for each configuration past the first one more row per
    point x static x material with the last term.  ``centers``: the sites' centres (world m, on
    ``street`` of ``predictor``'s probe set; their height is ignored); site ``i`` is placed with
    seed ``seed + i``; ``inside``: where walkers may stand (default anywhere);
    ``resolution``: face size of the fresh captures; ``spheres``: spheres of the last term."""
    if positive_int(resolution, "capture resolution") < 4:
        raise ValueError(f"capture resolution must be >= 4 texels per face, got {resolution}")
    if not configs:
        raise ValueError("at least one term configuration is needed")
    path = str(avatar_path if avatar_path is not None else walker_path())
    avatar, _ = load_rigged(path)
    phases = animation_phases(avatar)
    extent = street_extent(predictor.manifest, street)
    heading = (90.0 if extent.along == 0 else 0.0) - extent.yaw_deg
    sky = scene.sky.build()
    sky_rgba = with_alpha(sky.cube(resolution, include_sun=False))
    light = upper_sky(sky_rgba)
    street_frames = shading_frames(predictor.streets[street].along)
    rows: list[dict[str, Any]] = []

    def captures(sc: Any, pts: Sequence[NDArray]) -> list[Any]:
        with CubeCapture.from_scene(sc, resolution, sky=sky, ctx=ctx, near=CAPTURE_NEAR_M) as cap:
            return [cap.capture(p) for p in pts]

    for si, c in enumerate(centers):
        base_site = place_crowd(c, 0.0, heading_deg=heading, phases=phases, seed=seed + si, radius=radius,
                                free_points=free_count, inside=inside)
        host = site_avatars(base_site, extent.ground_under, path)[0]
        points = evaluation_points(base_site, host, extent.ground_under, self_count)
        plains = captures(scene, [p for _, _, p, _ in points])
        oracles = [exact_environment(composite(pl.rgba.astype(np.float64), sky_rgba)) for pl in plains]
        for d in densities:
            site = place_crowd(c, d, heading_deg=heading, phases=phases, seed=seed + si, radius=radius,
                               free_points=free_count, inside=inside)
            avatars = site_avatars(site, extent.ground_under, path)
            withs = captures(with_meshes(scene, [a.mesh for a in avatars]), [p for _, _, p, _ in points])
            for pi, ((kind, vertex, x, nrm), plain, withc, oracle) in enumerate(zip(points, plains, withs, oracles)):
                if kind == "self":
                    frames, views = normal_frames(nrm)
                    others = lod_spheres(x, avatars[1:])[0]

                    def buffers(cfg: TermConfig, vertex: int = vertex, others: SphereBuffer = others,
                                x: NDArray = x) -> dict[str, SphereBuffer]:
                        own = self_spheres(avatars[0], avatar_blockers(path, cfg.self_exclude), vertex, cfg.self_scale,
                                           cfg.self_clamp, x)
                        return {"+self": own, "+self+neighbours": joined(own, others)}
                else:
                    frames, views = street_frames
                    crowd = lod_spheres(x, avatars)[0]

                    def buffers(cfg: TermConfig, crowd: SphereBuffer = crowd) -> dict[str, SphereBuffer]:
                        return {"+neighbours": crowd}
                last = TERMS[kind][-1]
                per_config = [buffers(cfg) for cfg in configs]
                truth_env = exact_environment(composite(withc.rgba.astype(np.float64), sky_rgba))

                def probes(dd: NDArray, w: NDArray, x: NDArray = x) -> NDArray:
                    return predictor.predict(method, street, x, dd.reshape(-1, 3), np.ravel(w), False).reshape(
                        dd.shape[:-1] + (3,))
                statics = {"probes": probes, "oracle": oracle}
                base = {"site": si, "density": float(d), "neighbours": len(site.neighbours), "area": site.area,
                        "kind": kind, "point": pi, "vertex": vertex, "xyz": [float(v) for v in x],
                        "sky_hidden": visible_sky_hidden(plain.rgba, withc.rgba), "spheres": len(per_config[0][last])}
                for mat in materials:
                    truth = shade(truth_env, mat, frames, views)
                    alone = {k: shade(env, mat, frames, views) for k, env in statics.items()}
                    for sname in statics:
                        rows.append({**base, "static": sname, "material": mat.name, "term": "probes",
                                     "config": configs[0].label, "rel_err": rel_err(alone[sname], truth)})
                    for ci, (cfg, bufs) in enumerate(zip(configs, per_config)):
                        for term, buf in bufs.items():
                            if ci > 0 and term != last:
                                continue
                            preds = lit_crowd(alone, statics, light, x, frames, views, mat, buf, cfg)
                            for sname, pred in preds.items():
                                rows.append({**base, "static": sname, "material": mat.name, "term": term,
                                             "config": cfg.label, "rel_err": rel_err(pred, truth)})
    return rows


def rms(values: Sequence[float]) -> float:
    """Root mean square (nan for no values)."""
    return float(np.sqrt(np.mean(np.square(values)))) if len(values) else float("nan")


def summarize(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per (config, static, kind, density, term, material): ``rms`` (RMS of ``rel_err`` over the
    points), ``n`` points, ``ratio`` to the static part alone (``term == "probes"``) at the same
    density, kind, static and material, and the mean ``sky_hidden``."""
    groups: dict[tuple, list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault((r["config"], r["static"], r["kind"], r["density"], r["term"], r["material"]), []).append(r)
    alone = {(k[1], k[2], k[3], k[5]): rms([r["rel_err"] for r in v]) for k, v in groups.items() if k[4] == "probes"}
    out = []
    for (cfg, st, kind, d, term, mat), v in groups.items():
        e = rms([r["rel_err"] for r in v])
        b = alone.get((st, kind, d, mat), float("nan"))
        out.append({"config": cfg, "static": st, "kind": kind, "density": d, "term": term, "material": mat,
                    "rms": e, "n": len(v), "ratio": e / b if b > 0 else float("nan"),
                    "sky_hidden": float(np.mean([r["sky_hidden"] for r in v]))})
    return out


def goal_lines(summary: Sequence[dict[str, Any]], config: str, static: str = "probes") -> list[str]:
    """``PASS``/``FAIL`` lines: per kind of point, density and material, the error with every term
    (the kind's last term, ``config``) against :data:`GOAL_RATIO` times that of ``static`` alone."""
    out = []
    for s in summary:
        if s["config"] != config or s["static"] != static or s["term"] != TERMS[s["kind"]][-1]:
            continue
        ok = s["ratio"] <= GOAL_RATIO
        out.append(f"{'PASS' if ok else 'FAIL'} {static} {s['kind']:4s} density {s['density']:g}/m^2 {s['material']:8s} "
                   f"{100 * s['rms']:.1f} % vs {static} alone {100 * s['rms'] / s['ratio']:.1f} % "
                   f"(ratio {s['ratio']:.2f}, goal <= {GOAL_RATIO:g}; {config})")
    return out


def summary_table(summary: Sequence[dict[str, Any]], config: str, static: str, materials: Sequence[str]) -> str:
    """Markdown: one row per kind x density x term, per material the error (%) and its ratio to the
    static part alone."""
    sel = {(s["kind"], s["density"], s["term"], s["material"]): s for s in summary
           if (s["config"] == config or s["term"] == "probes") and s["static"] == static}
    keys = sorted({(k, d) for k, d, _, _ in sel}, key=lambda kd: (kd[0] != "self", kd[1]))
    head = ("| point | density (/m²) | sky hidden | term | " + " | ".join(f"{m} % (ratio)" for m in materials) + " |\n"
            + "| --- " * (4 + len(materials)) + "|\n")
    body = ""
    for kind, d in keys:
        for term in TERMS[kind]:
            cells = [f"{100 * sel[(kind, d, term, m)]['rms']:.1f} ({sel[(kind, d, term, m)]['ratio']:.2f})"
                     if (kind, d, term, m) in sel else "" for m in materials]
            hid = sel.get((kind, d, term, materials[0]), {}).get("sky_hidden", float("nan"))
            body += f"| {kind} | {d:g} | {100 * hid:.0f} % | {term} | " + " | ".join(cells) + " |\n"
    return head + body
