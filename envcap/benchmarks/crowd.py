"""The lit crowd's frame time per lighting term, as a multiple of an unlit crowd (same geometry and
skinning, a constant colour) in the same run, its GPU memory, and how both grow with the walker
count and the resolution; the paper's scene (1000 walkers of ~6,500 triangles on a ~100k-triangle
street at 1680x1050) as one frame.

    envcap bench crowd --out DIR [--quick] [--repeats R] [--no-paper]

Cases (:data:`CASES`): walker counts at one size, sizes at one count, then the paper's.  Each
case times :meth:`envcap.crowd.renderer.CrowdRenderer.draw` (``glFinish`` before and after; the
median of ``repeats`` draws after a warm-up draw of one walker, which compiles the shaders) for the unlit crowd and the terms ``probes``,
``self``, ``neighbours``.  The street is the canyon, baked here (16^2 faces, a probe every 50 m);
the paper's street is the canyon with every triangle split in two (98k triangles).  Prints the
renderer string (llvmpipe: a CPU rasterizer; ratios on a GPU differ).  Writes crowd.json and
crowd.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from typing import Any

import numpy as np

from envcap.crowd.inputs import CrowdAvatar, annotated_avatar, default_avatar
from envcap.crowd.instances import AvatarCycle, pose_crowd
from envcap.crowd.run import CrowdJob
from envcap.dynamic.avatar_synthetic import walker_gltf
from envcap.gpu.context import create_context
from envcap.outputs import atomic_output_dir
from envcap.probeset.bake import bake_probe_set
from envcap.scene import load_scene
from envcap.scene.model import Scene

PAPER = {"walkers": 1000, "size": (1680, 1050), "dense": True, "split": True}
"""The paper's scene."""
CASES = ({"walkers": 25, "size": (320, 200)}, {"walkers": 100, "size": (320, 200)}, {"walkers": 400, "size": (320, 200)},
         {"walkers": 100, "size": (640, 400)}, {"walkers": 100, "size": (960, 600)})
"""Walker counts at one size, then sizes at one count (the bundled 1,920-triangle walker)."""
QUICK = ({"walkers": 10, "size": (160, 100)}, {"walkers": 40, "size": (160, 100)}, {"walkers": 10, "size": (320, 200)})
"""``--quick``: a smoke run."""
DENSE = (20, 5, 6)
"""Capsule resolution of the paper's walker (:func:`envcap.dynamic.avatar_synthetic.walker_gltf`): 6,400 triangles."""
VARIANTS = ("unlit", "probes", "self", "neighbours")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (crowd.json, crowd.md)")
    p.add_argument("--repeats", type=int, default=3, help="timed draws per variant (median; default 3)")
    p.add_argument("--quick", action="store_true", help="small cases only (a smoke run)")
    p.add_argument("--no-paper", action="store_true", help="leave out the paper-scale frame")


def split_triangles(scene: Scene) -> Scene:
    """``scene`` with every triangle cut in two at the middle of its longest edge (same surface,
    twice the triangles: the canyon's 49k become the paper's ~100k)."""
    m = scene.mesh
    tri = m.indices.astype(np.int64)
    p = m.positions
    edges = np.stack([np.linalg.norm(p[tri[:, (k + 1) % 3]] - p[tri[:, k]], axis=1) for k in range(3)], axis=1)
    k = np.argmax(edges, axis=1)
    rows = np.arange(len(tri))
    a, b, c = tri[rows, k], tri[rows, (k + 1) % 3], tri[rows, (k + 2) % 3]
    mid = np.arange(len(p), len(p) + len(tri))

    def grow(v: np.ndarray) -> np.ndarray:
        return np.concatenate([v, ((v[a].astype(np.float64) + v[b]) / 2).astype(v.dtype)])

    extra = {f.name: grow(getattr(m, f.name)) for f in dataclasses.fields(m)
             if f.name in ("positions", "normals", "albedo", "emission", "uv_layer") and getattr(m, f.name) is not None}
    idx = np.concatenate([np.stack([a, mid, c], 1), np.stack([mid, b, c], 1)]).astype(np.uint32)
    return dataclasses.replace(scene, mesh=dataclasses.replace(m, indices=idx, **extra))


def time_case(ctx: Any, scene: Scene, probes: Any, avatar: CrowdAvatar, walkers: int, size: tuple[int, int],
              repeats: int) -> dict[str, Any]:
    """Median draw seconds per :data:`VARIANTS`, ratios to ``unlit``, GPU bytes, triangles."""
    job = CrowdJob.prepare("canyon", probes, walkers, avatar=avatar, size=size, seed=1, scene_obj=scene)
    r = job.renderer(ctx)
    try:
        pose = pose_crowd(job.walkers, AvatarCycle.of(avatar.avatar, avatar.spheres), 0.0, r.origin)
        cam = job.camera(r.origin)
        one = dataclasses.replace(pose, **{f.name: getattr(pose, f.name)[:1] for f in dataclasses.fields(pose)
                                           if f.name != "origin"})
        med = {}
        for v in VARIANTS:
            r.draw(one, cam, "neighbours" if v == "unlit" else v, constant=v == "unlit")   # warm-up: one walker
            ts = []
            for _ in range(repeats):
                ctx.finish()
                t0 = time.perf_counter()
                r.draw(pose, cam, "neighbours" if v == "unlit" else v, constant=v == "unlit")
                ctx.finish()
                ts.append(time.perf_counter() - t0)
            med[v] = float(np.median(ts))
        return {"walkers": walkers, "size": list(size), "avatar_triangles": r.triangles,
                "street_triangles": r.street_triangles, "gpu_bytes": r.gpu_bytes(), "median_s": med,
                "ratio_to_unlit": {v: med[v] / med["unlit"] for v in VARIANTS}}
    finally:
        r.release()


def run(args: argparse.Namespace) -> int:
    if args.repeats < 1:
        raise ValueError(f"--repeats must be >= 1, got {args.repeats}")
    ctx = create_context()
    device = ctx.info.get("GL_RENDERER", "?")
    print(f"renderer: {device}", flush=True)
    scene = load_scene("canyon")
    probes = bake_probe_set(scene, resolution=16, spacing=50.0, ctx=ctx, progress=False)
    avatar = default_avatar()
    cases = [dict(c) for c in (QUICK if args.quick else CASES)]
    if not args.no_paper:
        cases.append(dict(QUICK[0], dense=True, split=True) if args.quick else dict(PAPER))
    rows = []
    dense = annotated_avatar(walker_gltf(*DENSE), avatar.path.with_name("walker_dense")) if not args.no_paper else None
    for c in cases:
        t0 = time.perf_counter()
        sc = split_triangles(scene) if c.get("split") else scene
        av = dense if c.get("dense") else avatar
        repeats = 1 if c.get("dense") else args.repeats
        row = time_case(ctx, sc, probes, av, c["walkers"], tuple(c["size"]), repeats)
        row["paper"] = bool(c.get("dense"))
        rows.append(row)
        print(f"{row['walkers']:>5} walkers x {row['avatar_triangles']} tris, {c['size'][0]}x{c['size'][1]}: "
              + ", ".join(f"{v} {row['median_s'][v] * 1e3:.0f} ms ({row['ratio_to_unlit'][v]:.1f}x)" for v in VARIANTS)
              + f", GPU {row['gpu_bytes'] / 2**20:.1f} MiB ({time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    ctx.release()
    lines = [f"Renderer: {device}.  Frame time (ms, median of draws) per lighting term and its multiple of an unlit "
             f"crowd (same geometry, constant colour) in the same run.", "",
             "| walkers | avatar tris | street tris | size | unlit ms | probes | + self | + neighbours | GPU MiB |",
             "| ---: | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        m, q = r["median_s"], r["ratio_to_unlit"]
        lines.append(f"| {r['walkers']} | {r['avatar_triangles']} | {r['street_triangles']} | {r['size'][0]}x{r['size'][1]}"
                     f"{' (paper)' if r['paper'] else ''} | {m['unlit'] * 1e3:.0f} | {m['probes'] * 1e3:.0f} ms "
                     f"({q['probes']:.1f}x) | {m['self'] * 1e3:.0f} ms ({q['self']:.1f}x) | {m['neighbours'] * 1e3:.0f} ms "
                     f"({q['neighbours']:.1f}x) | {r['gpu_bytes'] / 2**20:.1f} |")
    with atomic_output_dir(args.out) as d:
        (d / "crowd.json").write_text(json.dumps({"renderer": device, "rows": rows}, indent=1) + "\n")
        (d / "crowd.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0
