"""Measure the crowd's draw time per lookup method (docs/crowd.md, "Cost"): 64 walkers at 480x300
in the canyon (probes 8² every 100 m with inverse_distance.ktx2), no street mesh, `--terms probes`
and `neighbours`, median of 5 draws each, as a multiple of the nearest lookup (planes_mip).

Run: PYTHONPATH=/path/to/envcap python3 docs/images/crowd_lookup_cost.py   (~30 s on llvmpipe)
"""

from __future__ import annotations

import tempfile
import time

import numpy as np

from envcap.crowd.instances import AvatarCycle, pose_crowd
from envcap.crowd.run import CrowdJob
from envcap.gpu.context import create_context
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.store import write_probe_set
from envcap.scene import load_scene

METHODS = ("planes_mip", "fitted_planes_oblique", "depth_refine")


def main() -> None:
    ctx = create_context()
    res: dict[tuple[str, str], float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        ps = bake_probe_set(load_scene("canyon"), resolution=8, spacing=100.0, ctx=ctx, progress=False)
        write_probe_set(f"{tmp}/probes", ps, writers=["inverse_distance"])
        for method in METHODS:
            job = CrowdJob.prepare("canyon", f"{tmp}/probes", 64, size=(480, 300), seed=1, method=method)
            r = job.renderer(ctx, street_mesh=False)
            try:
                pose = pose_crowd(job.walkers, AvatarCycle.of(job.avatar.avatar, job.avatar.spheres), 0.0, r.origin)
                cam = job.camera(r.origin)
                for terms in ("probes", "neighbours"):
                    r.draw(pose, cam, terms)
                    ts = []
                    for _ in range(5):
                        ctx.finish()
                        t0 = time.perf_counter()
                        r.draw(pose, cam, terms)
                        ctx.finish()
                        ts.append(time.perf_counter() - t0)
                    res[(method, terms)] = float(np.median(ts))
            finally:
                r.release()
    print("| method | --terms probes | --terms neighbours |\n| --- | ---: | ---: |")
    for m in METHODS:
        cells = [f"{res[(m, t)] * 1e3:.0f} ms ({res[(m, t)] / res[('planes_mip', t)]:.2f}x)"
                 for t in ("probes", "neighbours")]
        print(f"| {m} | {' | '.join(cells)} |")


if __name__ == "__main__":
    main()
