"""Regenerate docs/images/crowd_frame.png (a crowd in the bundled canyon, lit by its probes with
every term) and docs/images/crowd_terms.png (a close-up of a few walkers: probes only, + own
blocker bones, + neighbours, one exposure) for docs/crowd.md and the README.

Run: PYTHONPATH=/path/to/envcap python3 docs/images/make_crowd_figures.py   (~1 min on llvmpipe)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from envcap.crowd.camera import Camera
from envcap.crowd.instances import AvatarCycle, pose_crowd
from envcap.crowd.run import CrowdJob
from envcap.formats.png_preview import auto_exposure, tonemap
from envcap.gpu.context import create_context
from envcap.probeset.bake import bake_probe_set
from envcap.scene import load_scene

HERE = Path(__file__).resolve().parent


def main() -> None:
    ctx = create_context()
    scene = load_scene("canyon")
    probes = bake_probe_set(scene, resolution=32, spacing=25.0, ctx=ctx, progress=False)
    job = CrowdJob.prepare("canyon", probes, 60, size=(640, 400), seed=3, scene_obj=scene)
    r = job.renderer(ctx)
    try:
        pose = pose_crowd(job.walkers, AvatarCycle.of(job.avatar.avatar, job.avatar.spheres), 0.4, r.origin)
        frame = r.render(pose, job.camera(r.origin), "neighbours")["color"]
        Image.fromarray(tonemap(frame, auto_exposure(frame))).save(HERE / "crowd_frame.png")
        hips = pose.feet - r.origin + [0.0, 1.0, 0.0]
        k = int(np.argmin(np.linalg.norm(hips - hips.mean(axis=0), axis=1)))
        close = Camera(hips[k] + [3.5, 0.4, 2.5], hips[k] + [-1.0, -0.2, 0.0], 320 / 400)
        r.release()
        job = CrowdJob.prepare("canyon", probes, 60, size=(320, 400), seed=3, scene_obj=scene)
        r = job.renderer(ctx)
        panels = [r.render(pose, close, t)["color"] for t in ("probes", "self", "neighbours")]
        e = auto_exposure(panels[0])
        Image.fromarray(np.concatenate([tonemap(p, e) for p in panels], axis=1)).save(HERE / "crowd_terms.png")
    finally:
        r.release()
        ctx.release()
    print(f"wrote {HERE / 'crowd_frame.png'} and {HERE / 'crowd_terms.png'}")


if __name__ == "__main__":
    main()
