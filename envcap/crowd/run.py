"""One crowd run, end to end: read and check the inputs (:meth:`CrowdJob.prepare`, before any
output is claimed), estimate its memory (:func:`estimate_bytes`, checked against the limit of
:mod:`envcap.core.budget`), then render and write every frame (:func:`run_crowd`)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from envcap.core.budget import check_bytes, format_bytes
from envcap.crowd.camera import Camera, street_camera
from envcap.crowd.frames import write_description, write_frame
from envcap.crowd.inputs import (MATERIAL, CrowdAvatar, crowd_method, default_avatar, default_method, material,
                                 pick_street, read_avatar, read_probes, runtime_street)
from envcap.crowd.instances import TEXELS_PER_JOINT, AvatarCycle, pose_crowd
from envcap.crowd.renderer import TARGETS, CrowdRenderer
from envcap.crowd.sphere_buffer import NEIGHBOURS
from envcap.crowd.walkers import Walkers, describe, place_walkers
from envcap.formats.png_preview import auto_exposure
from envcap.gpu.context import create_context
from envcap.probeset.probe_set import ProbeSet
from envcap.runtime.methods import ParallaxMethod
from envcap.scene import load_scene
from envcap.scene.ground_height import GroundHeights
from envcap.scene.model import Scene


SECONDS_PER_PIXEL = 8e-6
SECONDS_PER_TRIANGLE = 2.5e-6
"""A frame's time with every term on llvmpipe (2 shared cores), ~ pixels x the first + walker
triangles x the second: fitted to ``envcap bench crowd`` (docs/crowd.md, "Cost"); a GPU is far faster."""


def estimate_seconds(size: tuple[int, int], walkers: int, triangles: int) -> float:
    """Seconds a frame takes on llvmpipe, roughly (:data:`SECONDS_PER_PIXEL`, :data:`SECONDS_PER_TRIANGLE`)."""
    return size[0] * size[1] * SECONDS_PER_PIXEL + walkers * triangles * SECONDS_PER_TRIANGLE


def estimate_bytes(size: tuple[int, int], walkers: int, joints: int, vertices: int, street_triangles: int,
                   probe_bytes: int, targets: bool = False) -> int:
    """Peak bytes of a run: the probe and sky textures, the frame's float targets and depth, the
    avatar and street buffers, the per-frame instance and neighbour textures (and their host
    copies), with the host's copy of each frame."""
    w, h = size
    frame = w * h * (16 * (len(TARGETS) if targets else 1) + 4) + w * h * 16
    per_walker = (TEXELS_PER_JOINT * joints + 2 * NEIGHBOURS) * 16 * 2 + joints * 16 * 8 * 3
    search = 8 * min(walkers, 512) * walkers            # one block of the neighbour search's distances
    return int(probe_bytes + frame + vertices * 88 + street_triangles * 3 * 60 + walkers * per_walker + search)


@dataclass
class CrowdJob:
    """Everything a run needs, read and checked."""

    scene: Scene
    probes: ProbeSet
    avatar: CrowdAvatar
    method: ParallaxMethod
    walkers: Walkers
    frames: int
    fps: float
    size: tuple[int, int]
    terms: str
    estimate: int

    @staticmethod
    def prepare(scene: str, probes: str | Path | ProbeSet, count: int, *, avatar: str | CrowdAvatar | None = None,
                seed: int = 0,
                frames: int = 1, fps: float = 10.0, size: tuple[int, int] = (640, 400), terms: str = "neighbours",
                street: str | None = None, method: str | None = None, scene_obj: Scene | None = None) -> "CrowdJob":
        """Read the probe set, the avatar and the scene (``scene_obj`` instead of loading
        ``scene``; a :class:`ProbeSet` or :class:`CrowdAvatar` in memory is taken as is), place
        ``count`` walkers; ``ValueError`` / ``FileNotFoundError`` naming the
        problem (before any output exists)."""
        if count < 0:
            raise ValueError(f"--avatars must be >= 0, got {count}")
        if method is not None:
            crowd_method(method)                    # a bad name fails before the set is read
        ps = probes if isinstance(probes, ProbeSet) else read_probes(probes)
        m = crowd_method(method or default_method(ps), ps)
        av = (avatar if isinstance(avatar, CrowdAvatar) else
              default_avatar() if avatar is None else read_avatar(avatar))
        sc = scene_obj if scene_obj is not None else load_scene(scene)
        st = pick_street(ps, street)
        ground = GroundHeights(sc.mesh) if len(sc.mesh.indices) else None
        wk = place_walkers(st, count, seed, ground)
        probe_bytes = sum(int(np.prod(lv.shape)) * 4 for lv in [*ps.levels, *ps.sky_levels])
        est = estimate_bytes(size, count, av.avatar.joint_count, len(av.avatar.positions), len(sc.mesh.indices),
                             probe_bytes)
        check_bytes(f"crowd of {count} walkers at {size[0]}x{size[1]}", est, "--avatars or --size")
        return CrowdJob(sc, ps, av, m, wk, frames, fps, size, terms, est)

    def describe(self) -> str:
        """One line: the crowd, the size, the lookup and the estimate."""
        secs = estimate_seconds(self.size, len(self.walkers), len(self.avatar.avatar.triangles))
        return (f"{describe(self.walkers)}, {self.size[0]}x{self.size[1]}, {self.frames} frame(s), terms {self.terms}, "
                f"method {self.method.name}; estimate: {format_bytes(self.estimate)}, ~{secs:.1g} s a frame on llvmpipe "
                f"(~{secs * self.frames:.2g} s in all)")

    def camera(self, origin: np.ndarray) -> Camera:
        """The camera over the walkers' span (:func:`envcap.crowd.camera.street_camera`)."""
        ends = self.walkers.on_street(np.array(self.walkers.span), np.zeros(2, np.int64), np.zeros(2)) - origin
        return street_camera(ends[0], ends[1], self.size[0] / self.size[1])

    def renderer(self, ctx: Any, targets: bool = False, street_mesh: bool = True) -> CrowdRenderer:
        """The GL state of this run on ``ctx``."""
        rs = runtime_street(self.walkers.street, self.method, sum(self.walkers.span) / 2)
        return CrowdRenderer(ctx, self.probes, rs, self.method, self.avatar, material(), 
                             self.scene.mesh if street_mesh else None, self.size, len(self.walkers), targets)


def run_crowd(job: CrowdJob, out: Path, progress: Callable[[int, int, float], None] | None = None) -> str:
    """Render ``job``'s frames into the (staged) directory ``out``; returns a one-line summary."""
    ctx = create_context()
    r = None
    try:
        r = job.renderer(ctx)
        cycle = AvatarCycle.of(job.avatar.avatar, job.avatar.spheres)
        cam = job.camera(r.origin)
        exposure, feet, times = None, [], []
        for i in range(job.frames):
            t0 = time.perf_counter()
            pose = pose_crowd(job.walkers, cycle, i / job.fps, r.origin)
            rgb = r.render(pose, cam, job.terms)["color"]
            if exposure is None:
                exposure = auto_exposure(rgb)
            write_frame(out, i, rgb, exposure)
            feet.append(np.round(pose.feet, 4).tolist())
            times.append(time.perf_counter() - t0)
            if progress:
                progress(i, job.frames, times[-1])
        write_description(out, {
            "seed": job.walkers.seed, "avatars": len(job.walkers), "frames": job.frames, "fps": job.fps,
            "size": list(job.size), "terms": job.terms, "method": job.method.name, "material": MATERIAL,
            "avatar": str(job.avatar.path), "street": job.walkers.street.name, "span_m": list(job.walkers.span),
            "renderer": ctx.info.get("GL_RENDERER", "?"), "exposure": exposure,
            "camera": {"eye": (cam.eye + r.origin).tolist(), "target": (cam.target + r.origin).tolist(),
                       "fov_y_deg": cam.fov_y_deg},
            "walkers": {"side": job.walkers.side.tolist(), "direction": job.walkers.direction.tolist(),
                        "speed_m_s": job.walkers.speed.round(4).tolist()},
            "feet_m": feet, "frame_s": [round(t, 4) for t in times]})
        return f"{np.median(times):.2f} s a frame ({ctx.info.get('GL_RENDERER', '?')})"
    finally:
        if r is not None:
            r.release()
        ctx.release()
