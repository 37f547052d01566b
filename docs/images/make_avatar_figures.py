"""Regenerate docs/images/avatar_proxy_spheres.png (the test avatar's proxy spheres over its mesh,
its per-vertex blockers, its one-sphere LOD) and print the crowd-LOD error table of docs/dynamic.md.

Run: PYTHONPATH=/path/to/envcap python3 docs/images/make_avatar_figures.py [--no-table]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from matplotlib.patches import Circle  # noqa: E402

from envcap.dynamic.avatar_blockers import select_blockers, sphere_form_factor  # noqa: E402
from envcap.dynamic.avatar_synthetic import walker_gltf  # noqa: E402
from envcap.dynamic.crowd_lod import NEAR_FACTOR, avatar_sphere  # noqa: E402
from envcap.dynamic.gltf_skin import avatar_from_gltf, joint_matrices, skin  # noqa: E402
from envcap.dynamic.proxy_spheres import fit_proxy_spheres, pose_spheres  # noqa: E402

OUT = Path(__file__).resolve().parent / "avatar_proxy_spheres.png"
TIME = 0.25
VIEWS = {  # (screen right, screen up, towards the viewer): orthographic views
    "front (from +Z)": (np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0])),
    "side (from +X)": (np.array([0, 0, -1.0]), np.array([0, 1.0, 0]), np.array([1.0, 0, 0])),
}


def project(p, view):
    right, up, _ = view
    return np.stack([p @ right, p @ up], axis=-1)


def draw_mesh(ax, pts, nrm, tris, view, colors=None) -> None:
    tri = pts[tris]
    order = np.argsort(tri.mean(axis=1) @ view[2])  # painter's algorithm, far first
    face_n = nrm[tris].mean(axis=1)
    key = view[2] + 0.6 * view[1] + 0.4 * view[0]
    light = np.clip(face_n @ (key / np.linalg.norm(key)), 0, 1)
    base = np.full((len(tri), 3), 0.75) if colors is None else colors[tris].mean(axis=1)[:, :3]
    fc = np.c_[base * (0.45 + 0.55 * light)[:, None], np.ones(len(tri))]
    ax.add_collection(PolyCollection(project(tri, view)[order], facecolors=fc[order], edgecolors="none", zorder=1))


def finish(ax, title) -> None:
    ax.set_aspect("equal")
    ax.set_xlim(-1.0, 1.0)
    ax.set_ylim(-0.05, 2.0)
    ax.set_title(title, fontsize=9)
    ax.tick_params(labelsize=7)
    ax.set_xlabel("m", fontsize=7)


def make_picture() -> None:
    av = avatar_from_gltf(walker_gltf())
    sp = fit_proxy_spheres(av)
    pts, nrm = skin(joint_matrices(av, 0, TIME), av)
    centers, radii = pose_spheres(sp, av, 0, TIME)
    one = avatar_sphere(centers, radii)
    blk = select_blockers(av, sp, k=4)
    cmap = plt.get_cmap("tab20")
    fig, axs = plt.subplots(1, 3, figsize=(11.5, 4.6), dpi=110)
    for ax, (name, view) in zip(axs[:2], VIEWS.items()):
        draw_mesh(ax, pts, nrm, av.triangles, view)
        for j, (c, r) in enumerate(zip(centers, radii)):
            xy = project(c, view)
            ax.add_patch(Circle(xy, r, facecolor=(*cmap(j)[:3], 0.25), edgecolor=cmap(j), lw=1.2, zorder=2))
            ax.plot(*xy, "+", color=cmap(j), ms=5, zorder=3)
        finish(ax, f"{name}, walk t = {TIME} s: bone proxy spheres")
    for j, name in enumerate(av.joint_names):
        axs[0].plot([], [], "o", color=cmap(j), label=name, ms=5)
    axs[0].legend(fontsize=6, loc="lower left", ncol=2, frameon=False)
    side = VIEWS["side (from +X)"]
    for r, style, col in ((one.radius, "--", "k"), (one.enclosing, ":", "0.4")):
        axs[1].add_patch(Circle(project(one.center, side), r, fill=False, ls=style, color=col, lw=1.2, zorder=4))
    axs[1].plot([], [], "--", color="k", label=f"far LOD: one sphere, r = {one.radius:.2f} m")
    axs[1].plot([], [], ":", color="0.4", label=f"enclosing R = {one.enclosing:.2f} m (bone spheres if d < {NEAR_FACTOR:g} R)")
    axs[1].legend(fontsize=6, loc="lower left", frameon=False)
    total = np.clip(blk.scores.sum(axis=1), 0, 1)
    heat = plt.get_cmap("YlOrRd")
    draw_mesh(axs[2], pts, nrm, av.triangles, side, colors=heat(total))
    torso = sp.owner == av.joint_names.index("spine")
    v = int(np.argmax(np.where(torso & (blk.scores[:, 0] < 0.9), blk.scores[:, 2], -1)))
    axs[2].plot(*project(pts[v], side), "o", color="cyan", ms=6, mec="k", zorder=5)
    lines = []
    for j, s_ in zip(blk.joints[v], blk.scores[v]):
        if s_ > 0:
            axs[2].add_patch(Circle(project(centers[j], side), radii[j], fill=False, color="tab:blue", lw=1.2, zorder=4))
            lines.append(f"{av.joint_names[j]}: F = {s_:.3f}")
    axs[2].text(-0.95, 0.02, "blockers of the cyan vertex\n(mean over keyframes)\n" + "\n".join(lines), fontsize=6,
                va="bottom", color="tab:blue")
    sm = plt.cm.ScalarMappable(cmap=heat, norm=plt.Normalize(0, 1))
    fig.colorbar(sm, ax=axs[2], fraction=0.04, pad=0.02).set_label("sum of the 4 blockers' F (mean over keyframes)", fontsize=7)
    finish(axs[2], "per-vertex blocking by its 4 chosen bones")
    fig.tight_layout()
    fig.savefig(OUT)
    print(OUT)


def blocker_table() -> None:
    """How much of a vertex's blocking (sum over every other bone of its mean F) k bones keep."""
    av = avatar_from_gltf(walker_gltf())
    sp = fit_proxy_spheres(av)
    full = select_blockers(av, sp, k=1, keep_frames=True)
    total = full.per_frame.sum(axis=2).mean(axis=0)
    some = total > 0
    inside = (full.per_frame >= 1).any(axis=(0, 2)).mean()
    print(f"vertices inside another bone's sphere at some keyframe: {inside:.3f}")
    print("| k | blocking kept, mean | kept, worst vertex | F left out, mean | F left out, max |")
    print("| --- | --- | --- | --- | --- |")
    for k in (1, 2, 3, 4):
        kept = select_blockers(av, sp, k=k).scores.sum(axis=1)
        frac = kept[some] / total[some]
        print(f"| {k} | {frac.mean():.3f} | {frac.min():.3f} | {(total - kept).mean():.4f} | {(total - kept).max():.3f} |")


def lod_table() -> None:
    """|F(one sphere) - F(union of bone spheres)| at d = f R, normal facing the avatar."""
    av = avatar_from_gltf(walker_gltf())
    sp = fit_proxy_spheres(av)
    n = 40000
    i = np.arange(n) + 0.5
    r, phi = np.sqrt(i / n), np.pi * (3 - 5**0.5) * i
    local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - r * r)], axis=1)
    print("| d / R | max abs error | mean error | max relative error | F (union), median |")
    print("| --- | --- | --- | --- | --- |")
    for f in (1.5, 2.0, 3.0, 4.0, 6.0, 10.0):
        err, rel, fu_all = [], [], []
        for t in av.animations[0].keyframes[:4]:
            centers, radii = pose_spheres(sp, av, 0, float(t))
            one = avatar_sphere(centers, radii)
            for az in np.linspace(0, 2 * np.pi, 8, endpoint=False):
                for el in (0.0, 0.6):
                    out = np.array([np.cos(az) * np.cos(el), np.sin(el), np.sin(az) * np.cos(el)])
                    p, nrm = one.center + f * one.enclosing * out, -out
                    t1 = np.cross(nrm, [0.0, 1.0, 0.0])
                    t1 /= np.linalg.norm(t1)
                    rays = local[:, :1] * t1 + local[:, 1:2] * np.cross(nrm, t1) + local[:, 2:] * nrm
                    v = centers - p
                    ell = np.linalg.norm(v, axis=1)
                    fu = (rays @ (v / ell[:, None]).T >= np.sqrt(1 - (radii / ell) ** 2)).any(axis=1).mean()
                    fo = float(sphere_form_factor(p, nrm, one.center, one.radius))
                    err.append(fo - fu), rel.append((fo - fu) / fu), fu_all.append(fu)
        err, rel = np.array(err), np.array(rel)
        print(f"| {f:g} | {np.abs(err).max():.4f} | {err.mean():+.4f} | {np.abs(rel).max():.2f} | {np.median(fu_all):.4f} |")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--no-table", action="store_true", help="only the picture")
    args = parser.parse_args()
    make_picture()
    if not args.no_table:
        blocker_table()
        lod_table()
