"""Precision far from the origin: a scene moved by 10^6 m against the same scene at the origin.

The scene (bundled ``canyon`` by default) is built twice from its TOML: as it is, and with every
horizontal coordinate moved by ``--offset`` (:func:`offset_scene_dict`: streets, ground center,
mesh offset).  Probes at the same street-relative places are captured in both and compared texel
by texel (:func:`compare_captures`): alpha flips (sky in one, geometry in the other), the share
of texels whose luminance differs by more than 1 % (relative, where the alphas agree), the
largest relative luminance and distance differences.  Two offsets: one on the kilometer grid of
:func:`envcap.scene.model.local_origin` (the moved scene's vertices relative to its origin are
then the very float32 numbers of the scene at the origin) and one off it (they differ by float32
rounding at the scene's own size).  Two uploads of the moved scene, in the same run:

* ``relative``: as shipped, vertices float32 relative to the mesh origin (float64), the probe's
  offset from it rounded to float32 once (:class:`~envcap.capture.renderer.CubeCapture`);
* ``absolute``: the mesh rebased to the world origin (``SceneMesh.rebased((0, 0, 0))``), i.e.
  absolute float32 vertices (~6 cm steps at 10^6 m): what envcap did before.

Each with all the scene's effects and without ``sun_shadows``.  Writes ``precision.json`` and
``precision.md`` (the table of ``docs/reliability.md``, "Precision") to ``--out``.
"""

from __future__ import annotations

import argparse
import copy
import json
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.capture.renderer import CubeCapture
from envcap.core.color import luminance
from envcap.gpu.context import create_context
from envcap.outputs import atomic_output_dir
from envcap.scene import Scene, scene_from_dict, scene_path
from envcap.scene.parse import read_toml

DEFAULT_OFFSETS = ((1e6, 1e6), (1e6 + 123.456, 1e6 - 77.7))
"""(x, z) offsets in meters: on the 1 km origin grid, and off it."""


def offset_scene_dict(data: dict[str, Any], dx: float, dz: float) -> dict[str, Any]:
    """A copy of a scene document (the TOML as a dict) with everything moved by ``(dx, 0, dz)``
    meters: each street's along coordinates (``start``/``end`` or ``along_center``), ``cross``
    and ``probe_line`` (a street by its ends: ``p0`` and ``p1``); ``[ground] center`` if given;
    each ``[mesh]`` / ``[[mesh]]`` table's ``offset`` and ``crop`` box.  (The scene format has its
    ground at y = 0, so there is no vertical offset.)"""
    out = copy.deepcopy(data)
    for s in out.get("streets", []):
        if "p0" in s or "p1" in s:     # a street by its ends (world plan points): its frame moves with them
            for k in ("p0", "p1"):
                if k in s:
                    s[k] = [s[k][0] + dx, s[k][1] + dz]
            continue
        da, dc = (dx, dz) if s.get("axis") == "x" else (dz, dx)
        if "start" in s or "end" in s:
            s["start"], s["end"] = s["start"] + da, s["end"] + da
        else:
            s["along_center"] = s.get("along_center", 0.0) + da
        s["cross"] = s.get("cross", 0.0) + dc
        if "probe_line" in s:
            s["probe_line"] += dc
    ground = out.get("ground")
    if isinstance(ground, dict) and "center" in ground:
        ground["center"] = [ground["center"][0] + dx, ground["center"][1] + dz]
    mesh = out.get("mesh")
    for m in [mesh] if isinstance(mesh, dict) else mesh if isinstance(mesh, list) else []:   # [mesh] or [[mesh]]
        o = m.get("offset", [0.0, 0.0, 0.0])
        m["offset"] = [o[0] + dx, o[1], o[2] + dz]
        for k in ("min", "max") if isinstance(m.get("crop"), dict) else ():   # a world box
            c = m["crop"][k]
            m["crop"][k] = [c[0] + dx, c[1], c[2] + dz]
    return out


def street_probes(scene: Scene, count: int) -> NDArray[np.float64]:
    """``count`` world probe positions (count, 3) m along the first street: spread along it, at
    heights 1.7 to 12 m and up to a third of its width off its probe line (in its frame, for a
    street at an angle)."""
    st = scene.streets[0]
    k = np.arange(count)
    along = st.start + st.length * (k + 0.5) / count
    cross = st.center_line + st.width * np.array([0.0, 0.15, -0.2, 0.3])[k % 4]
    height = np.array([2.0, 1.7, 6.0, 12.0])[k % 4]
    out = np.zeros((count, 3))
    out[:, st.along_index], out[:, st.cross_index], out[:, 1] = along, cross, height
    return st.to_world(out)      # a street at an angle: its frame to the world (a copy otherwise)


def compare_captures(rgba_a: NDArray[np.floating], distance_a: NDArray[np.floating],
                     rgba_b: NDArray[np.floating], distance_b: NDArray[np.floating],
                     threshold: float = 0.01) -> dict[str, float]:
    """Texel differences between two captures of the same probe, ``rgba`` (..., 4) and
    ``distance`` (...) in the layout of :mod:`envcap.capture.outputs`.

    ``flips``: texels whose alpha differs.  ``share_over``: fraction of all texels where the
    alphas agree and the luminances differ by more than ``threshold`` relative to the larger.
    ``max_rel_luminance``: largest such relative difference (agreeing alphas); ``max_rel_distance``:
    largest relative distance difference where both see geometry; ``identical``: 1 if the arrays
    are bit-identical, else 0.
    """
    a_alpha, b_alpha = rgba_a[..., 3], rgba_b[..., 3]
    agree = a_alpha == b_alpha
    ya, yb = luminance(rgba_a), luminance(rgba_b)
    top = np.maximum(ya, yb)
    rel = np.where(agree & (top > 0), np.abs(ya - yb) / np.where(top > 0, top, 1.0), 0.0)
    both = agree & (a_alpha > 0)
    da, db = np.asarray(distance_a, np.float64), np.asarray(distance_b, np.float64)
    rel_d = np.where(both, np.abs(da - db) / np.where(both, da, 1.0), 0.0)
    return {"flips": float(np.count_nonzero(~agree)),
            "share_over": float(np.count_nonzero(rel > threshold)) / a_alpha.size,
            "max_rel_luminance": float(rel.max()), "max_rel_distance": float(rel_d.max()),
            "identical": float(np.array_equal(rgba_a, rgba_b) and np.array_equal(distance_a, distance_b))}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", required=True, help="output directory (JSON + Markdown table)")
    parser.add_argument("--scene", default="canyon", help="bundled scene name or .toml path (default canyon)")
    parser.add_argument("--size", type=int, default=64, help="probe face resolution N (default 64)")
    parser.add_argument("--probes", type=int, default=4, help="probes compared (default 4)")


def run(args: argparse.Namespace) -> int:
    if args.size < 1 or args.probes < 1:
        raise ValueError("--size and --probes must be >= 1")
    path = scene_path(args.scene)
    data = read_toml(path)
    base_dir = path.parent.resolve()
    home = scene_from_dict(data, base_dir=base_dir, default_name=path.stem)
    if not home.streets:
        raise ValueError(f"scene '{home.name}' has no street to place probes on")
    probes = street_probes(home, args.probes)
    yaw = home.streets[0].yaw_deg       # cubes along the street's frame, as the bake captures them
    sky = home.sky.build()
    effect_sets = {"all effects": home.effects, "no sun_shadows": home.effects - {"sun_shadows"}}
    rows: list[dict[str, Any]] = []
    ctx = create_context()
    try:
        for dx, dz in DEFAULT_OFFSETS:
            offset = np.array([dx, 0.0, dz])
            moved = scene_from_dict(offset_scene_dict(data, dx, dz), base_dir=base_dir, default_name=path.stem)
            uploads = {"relative": moved.mesh, "absolute": moved.mesh.rebased(np.zeros(3))}
            for effects_name, effects in effect_sets.items():
                with CubeCapture(home.mesh, args.size, sky=sky, effects=effects, ctx=ctx) as cap:
                    ref = [cap.capture(p, yaw) for p in probes]
                for upload, mesh in uploads.items():
                    with CubeCapture(mesh, args.size, sky=sky, effects=effects, ctx=ctx) as cap:
                        per = [compare_captures(r.rgba, r.distance, c.rgba, c.distance)
                               for r, c in zip(ref, (cap.capture(p + offset, yaw) for p in probes))]
                    rows.append({"offset": [dx, 0.0, dz], "origin": moved.mesh.origin.tolist(), "upload": upload,
                                 "effects": effects_name, "probes": per,
                                 "max_flips": max(p["flips"] for p in per),
                                 "share_over_1pct": [p["share_over"] for p in per],
                                 "max_rel_luminance": max(p["max_rel_luminance"] for p in per),
                                 "max_rel_distance": max(p["max_rel_distance"] for p in per),
                                 "identical": all(p["identical"] for p in per)})
                    print(_line(rows[-1]))
    finally:
        ctx.release()
    result = {"scene": home.name, "size": args.size, "probes": probes.tolist(), "rows": rows}
    with atomic_output_dir(args.out) as out:
        Path(out, "precision.json").write_text(json.dumps(result, indent=1))
        Path(out, "precision.md").write_text(_table(result))
    print(f"wrote {Path(args.out) / 'precision.json'}")
    return 0


def _line(r: dict[str, Any]) -> str:
    share = r["share_over_1pct"]
    return (f"offset ({r['offset'][0]:.3f}, {r['offset'][2]:.3f}) {r['upload']:<8} {r['effects']:<15} "
            f"flips max {r['max_flips']:.0f}  >1%: {100 * min(share):.2f}-{100 * max(share):.2f} %  "
            f"lum {r['max_rel_luminance']:.1e}  dist {r['max_rel_distance']:.1e}  identical {r['identical']}")


def _table(result: dict[str, Any]) -> str:
    intro = (f"Scene `{result['scene']}`, {len(result['probes'])} probes at {result['size']}^2, "
             "each against the same probe of the scene at the origin.")
    header = ("| offset (m) | upload | effects | texels > 1 % (per probe) | alpha flips (max/probe) "
              "| max rel. luminance | max rel. distance | bit-identical |")
    lines = [intro, "", header, "|---|---|---|---|---|---|---|---|"]
    for r in result["rows"]:
        share = r["share_over_1pct"]
        lines.append(f"| ({r['offset'][0]:.3f}, 0, {r['offset'][2]:.3f}) | {r['upload']} | {r['effects']} "
                     f"| {100 * min(share):.2f}-{100 * max(share):.2f} % | {r['max_flips']:.0f} "
                     f"| {r['max_rel_luminance']:.1e} | {r['max_rel_distance']:.1e} | {'yes' if r['identical'] else 'no'} |")
    return "\n".join(lines) + "\n"
