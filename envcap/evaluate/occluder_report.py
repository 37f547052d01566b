"""Dynamic occluders in the evaluator's report (``envcap evaluate ... --occluders KIND``): the street
evaluation of the dynamic terms run for the evaluated scene and its probe set, written as a section
of ``report.md`` with its figure and JSON.

KIND ``ring``: the rings of spheres of :data:`envcap.evaluate.dynamic_occluders.DEFAULT_RINGS`
(:func:`~envcap.evaluate.dynamic_occluders.evaluate_rings`); ``avatars``: the walker crowds of
:data:`envcap.evaluate.dynamic_avatars.DEFAULT_CROWDS`
(:func:`~envcap.evaluate.dynamic_avatars.evaluate_avatar_crowds`), or crowds of the avatar a file
``envcap avatar`` wrote (``--avatar FILE``: its skin, animation and stored proxy spheres); ``all``: both.  Positions: on
the probe set's first street, at its middle probe and half way to the next one, on the probe line,
:data:`RING_HEIGHT_M` (rings) or :data:`AVATAR_HEIGHT_M` (avatars) above the ground under them.
Truth captures at the evaluation's face size, at most :data:`MAX_RESOLUTION`; sun: the analytic
variant; models :data:`REPORT_MODELS`.  Tables: per material, the RMS over positions x rings of
the relative Eq. 3 error, over those hiding >= 10 % of the visible sky and over all, for
``static`` (the probes), ``static+MODEL``, ``oracle`` and ``oracle+MODEL``
(``docs/dynamic.md``, "Street evaluation").
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from envcap.evaluate.dynamic_avatars import (
    DEFAULT_CROWDS,
    evaluate_avatar_crowds,
    load_rigged,
    material_summary,
    walker_path,
)
from envcap.evaluate.dynamic_occluders import DEFAULT_RINGS, evaluate_rings
from envcap.evaluate.predict import Predictor
from envcap.evaluate.sweep import StreetExtent

OCCLUDER_KINDS: tuple[str, ...] = ("none", "ring", "avatars", "all")
"""Values of ``envcap evaluate --occluders``."""
REPORT_MODELS: tuple[str, ...] = ("paper", "envcap")
"""Dynamic-terms models reported (:data:`envcap.evaluate.dynamic_terms.MODELS`)."""
MAX_RESOLUTION = 32
"""Largest face size of the occluder truth captures (12 rings x 2 positions: 26 captures)."""
RING_HEIGHT_M = 1.5
AVATAR_HEIGHT_M = 1.0
"""Heights (m above the ground under them) of the shading points among spheres and among avatars."""


def occluder_positions(manifest: Any, height: float) -> tuple[str, list[list[float]]]:
    """``(street name, positions)``: the first street's middle probe and the point half way to the
    next probe (the previous one for a single-probe street), ``height`` m above the ground under
    each (:meth:`envcap.evaluate.sweep.StreetExtent.ground_under`: on a street that follows the
    terrain, the nearest probe's ground plane with its slope)."""
    st = manifest.streets[0]
    extent = StreetExtent.from_manifest(st)
    k = len(st.probes) // 2
    a = np.asarray(st.probes[k].position, np.float64)
    b = np.asarray(st.probes[k + 1 if k + 1 < len(st.probes) else max(k - 1, 0)].position, np.float64)
    out = []
    for p in (a, 0.5 * (a + b)):
        q = p.copy()
        q[1] = extent.ground_under(p) + height
        out.append([float(v) for v in q])
    return st.name, out


def avatar_summary(avatar: str | os.PathLike[str] | None) -> dict[str, Any]:
    """``{"file", "joints", "sphere_radii"}`` of the avatar the crowds are made of: ``avatar`` (a
    file ``envcap avatar`` wrote; its stored proxy spheres) or, for ``None``, the bundled walker
    (``file`` None; spheres fitted).  Radii in m, skin order; 0: a joint without a sphere."""
    avatar_, spheres = load_rigged(str(avatar if avatar is not None else walker_path()))
    return {"file": None if avatar is None else str(avatar), "joints": avatar_.joint_count,
            "sphere_radii": [round(float(r), 6) for r in spheres.radii]}


def evaluate_occluders(scene: Any, probe_set: Any, kind: str, *, resolution: int = MAX_RESOLUTION,
                       ctx: Any = None, models: Sequence[str] = REPORT_MODELS,
                       avatar: str | os.PathLike[str] | None = None) -> dict[str, Any]:
    """``{"scene", "kind", "resolution", "ring": rows | None, "avatars": rows | None, "positions",
    "avatar"}`` for ``kind`` in :data:`OCCLUDER_KINDS` (not ``"none"``); ``avatar``: the crowds'
    avatar, a file ``envcap avatar`` wrote (default: the bundled walker), described by
    :func:`avatar_summary` under ``"avatar"`` (``None`` without avatar crowds)."""
    if kind not in OCCLUDER_KINDS or kind == "none":
        raise ValueError(f"--occluders must be one of {', '.join(OCCLUDER_KINDS[1:])} (or none), got {kind!r}")
    if avatar is not None and kind not in ("avatars", "all"):
        raise ValueError(f"--avatar goes with --occluders avatars or all, not {kind}")
    res = min(int(resolution), MAX_RESOLUTION)
    own = ctx is None
    if own:
        from envcap.gpu.context import create_context
        ctx = create_context()
    out: dict[str, Any] = {"scene": scene.name, "kind": kind, "resolution": res, "ring": None, "avatars": None,
                           "positions": {}, "avatar": None}
    try:
        predictor = Predictor(probe_set, sky=scene.sky.build(), ctx=ctx)
        if kind in ("ring", "all"):
            street, pts = occluder_positions(probe_set.manifest, RING_HEIGHT_M)
            out["positions"]["ring"] = pts
            out["ring"], _ = evaluate_rings(scene, predictor, street, pts, rings=DEFAULT_RINGS, ctx=ctx, resolution=res,
                                            models=models)
        if kind in ("avatars", "all"):
            street, pts = occluder_positions(probe_set.manifest, AVATAR_HEIGHT_M)
            out["positions"]["avatars"] = pts
            out["avatar"] = avatar_summary(avatar)
            out["avatars"] = evaluate_avatar_crowds(scene, predictor, street, pts, crowds=DEFAULT_CROWDS, ctx=ctx,
                                                    resolution=res, models=models, avatar_path=avatar)
    finally:
        if own:
            ctx.release()
    out["models"] = list(models)
    return out


def section_markdown(results: Sequence[dict[str, Any]], figures: Sequence[str] = ()) -> str:
    """The ``## Dynamic occluders`` section of ``report.md`` for ``results`` of :func:`evaluate_occluders`."""
    md = ("\n## Dynamic occluders (spheres and avatars around crowd positions)\n\n"
          "Truth: a fresh capture with the occluders in the scene; `static`: the probes; `+paper` / `+envcap`: with the "
          "dynamic terms of the spheres (avatars: their proxy spheres, bone spheres near, one sphere far); `oracle`: a "
          "fresh occluder-free capture as the static part.  Relative RMS of Eq. 3 luminance over the frames (%), "
          "RMS over positions x rings (`docs/dynamic.md`, \"Street evaluation\").\n")
    for r in results:
        variants = [f"{s}{'' if m is None else '+' + m}" for s in ("static", "oracle") for m in [None, *r["models"]]]
        for key, title in (("ring", "rings of spheres"), ("avatars", crowd_title(r.get("avatar")))):
            if r[key] is not None:
                md += (f"\n### {r['scene']}: {title} ({len(r['positions'][key])} positions, {r['resolution']}² truth)\n\n"
                       + material_summary(r[key], variants))
    for f in figures:
        md += f"\n![dynamic occluders]({f})\n"
    return md


def crowd_title(avatar: dict[str, Any] | None) -> str:
    """The avatar crowds' title: "walker crowds" (the bundled walker), else "crowds of NAME" (the
    ``--avatar`` file's name)."""
    if avatar is None or avatar.get("file") is None:
        return "walker crowds"
    return f"crowds of {Path(avatar['file']).name}"


def plot_occluders(result: dict[str, Any], path: Path) -> None:
    """Error (%) against visible sky hidden (%) with the probes as the static part, one panel per kind."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kinds = [k for k in ("ring", "avatars") if result[k] is not None]
    fig, axes = plt.subplots(1, len(kinds), figsize=(5 * len(kinds), 4), sharey=True, squeeze=False)
    colors = ["#d62728", "#2ca02c", "#1f77b4", "#ff7f0e"]
    for ax, key in zip(axes[0], kinds):
        for j, v in enumerate(["static"] + [f"static+{m}" for m in result["models"]]):
            sel = [r for r in result[key] if r["variant"] == v]
            ax.scatter([100 * r["sky_hidden"] for r in sel], [100 * r["rel_err"] for r in sel], s=14, alpha=0.6,
                       color="#444" if j == 0 else colors[(j - 1) % len(colors)], marker="x" if j == 0 else "o", label=v)
        ax.axvline(10, color="k", ls=":", lw=1)
        ax.set_xlabel("visible sky hidden (%)")
        ax.set_title(f"{result['scene']}: {'rings of spheres' if key == 'ring' else crowd_title(result.get('avatar'))}",
                     fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    axes[0][0].set_ylabel("Eq. 3 luminance error (%)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def append_occluder_report(out_dir: str | Path, results: Sequence[dict[str, Any]], *, images: bool = True) -> list[str]:
    """Add the section to ``report.md`` in ``out_dir`` (written by :func:`envcap.evaluate.report.write_report`
    just before, in the same claimed directory; replaced atomically), and write ``occluders.json``
    and, with ``images``, ``occluders_SCENE.png``; returns the files written."""
    out = Path(out_dir)
    report = out / "report.md"
    if not report.is_file():
        raise FileNotFoundError(f"{report}: no report to add the dynamic occluders to")
    figures = []
    if images:
        for k, r in enumerate(results):
            name = f"occluders_{k}_{''.join(c if c.isalnum() else '_' for c in r['scene'])}.png"
            plot_occluders(r, out / name)
            figures.append(name)
    (out / "occluders.json").write_text(json.dumps(list(results), indent=1, allow_nan=False) + "\n")
    tmp = out / "report.md.occluders-tmp"
    tmp.write_text(report.read_text() + section_markdown(results, figures))
    os.replace(tmp, report)
    return ["occluders.json", *figures]
