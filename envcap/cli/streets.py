"""``envcap streets``: find straight streets in a scene or a city mesh (``envcap.scene.street_detect``).

Writes ``DIR/streets.json`` (every street: centre line, direction, facade offsets, frontage,
heights, crossings; the intersections), ``DIR/streets_map.png`` (top-down map) and
``DIR/scene.toml`` (the input as a ``[mesh]`` table and the streets as ``[[streets]]``).
"""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict
from pathlib import Path

import numpy as np

from envcap.cli.output_options import add_force_argument, scene_input_files
from envcap.outputs import atomic_output_dir, claim_output_dir
from envcap.scene import load_scene
from envcap.scene.ground_height import GroundHeights
from envcap.scene.mesh_import import WINDING_MODES, import_meshes
from envcap.scene.mesh_select import mesh_files
from envcap.scene.model import SceneMesh
from envcap.scene.street_detect import DetectedStreet, StreetSearch, detect_streets, intersections
from envcap.scene.street_detect_figure import save_street_map

AXIS_TOL_DEG = 0.5
"""Streets within this angle of world X or Z are written as axis-aligned ``[[streets]]``
(``axis``, ``start``/``end``); others by their ends (``p0``/``p1``)."""
FOLLOW_TERRAIN_M = 0.5
"""A street whose ground varies by more than this (m) along its centre line gets ``follow_terrain = true``."""
TERRAIN_STEP_M = 2.0
"""Spacing (m) of the ground samples along a street's centre line for :data:`FOLLOW_TERRAIN_M`."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("streets", help="find straight streets in a scene or a city mesh; write a scene file and a map")
    p.add_argument("source", help="a bundled scene name, a scene .toml, or a mesh file / directory of .ply files")
    p.add_argument("--out", required=True, type=Path, help="output directory (streets.json, streets_map.png, scene.toml)")
    p.add_argument("--up-axis", choices=("y", "z"), default="y", help="mesh input: the file's up axis (default y)")
    p.add_argument("--offset", type=float, nargs=3, default=(0.0, 0.0, 0.0), metavar=("X", "Y", "Z"),
                   help="mesh input: meters added after the up-axis turn (projected coordinates -> near the origin)")
    p.add_argument("--rotation", type=float, default=0.0, help="mesh input: degrees about +Y after the up-axis turn")
    p.add_argument("--winding", choices=WINDING_MODES, default="auto", help="mesh input: fix inward-wound parts (default auto)")
    p.add_argument("--spacing", type=float, default=10.0, help="probe spacing along each street for the map (m, default 10)")
    p.add_argument("--min-length", type=float, default=30.0, help="shortest street reported (m, default 30)")
    add_force_argument(p)
    p.set_defaults(func=run)


def _terrain_spans(mesh: SceneMesh, streets: list[DetectedStreet]) -> list[float]:
    """Per street: how much the ground under its centre line varies (max - min height, m; the
    highest up-facing surface every ~:data:`TERRAIN_STEP_M` along it, points without one left
    out; 0 when none has one)."""
    if not streets:
        return []
    ground = GroundHeights(mesh)
    out = []
    for s in streets:
        t = np.linspace(0.0, 1.0, max(2, int(np.ceil(s.length / TERRAIN_STEP_M)) + 1))
        xz = np.asarray(s.p0) + t[:, None] * (np.asarray(s.p1) - np.asarray(s.p0))
        h = ground(xz)
        h = h[np.isfinite(h)]
        out.append(float(h.max() - h.min()) if h.size else 0.0)
    return out


def _triangles(args: argparse.Namespace) -> tuple[np.ndarray, list[Path], dict[str, object], SceneMesh]:
    source = Path(args.source)
    if source.exists() and source.suffix.lower() != ".toml":
        files = mesh_files(source)
        mesh, report = import_meshes(files, up_axis=args.up_axis, rotation_deg=args.rotation, offset=args.offset,
                                     winding=args.winding, where=str(source))
        if report.flipped:
            print(f"winding: flipped {report.flipped} inward part(s) in {len(report.flipped_files)} file(s)")
        mesh_table = {"file": str(source.resolve()), "up_axis": args.up_axis, "rotation_deg": args.rotation,
                      "offset": list(args.offset)}
        inputs = files
    else:
        mesh = load_scene(args.source).mesh
        mesh_table = {}
        inputs = scene_input_files(args.source)
    tri = (mesh.positions.astype(np.float64) + mesh.origin)[mesh.indices.astype(np.int64)]
    return tri, inputs, mesh_table, mesh


def _street_table(s: DetectedStreet, terrain_span: float = 0.0) -> str:
    """A ``[[streets]]`` table: along X or Z (``axis``, ``start``/``end``) for a street within
    AXIS_TOL_DEG of them, else by its centre line's ends (``p0``/``p1``, any angle); with
    ``follow_terrain = true`` when the ground under it varies by more than FOLLOW_TERRAIN_M."""
    a = s.angle_deg % 180.0
    axis = "x" if min(a, 180.0 - a) <= AXIS_TOL_DEG else ("z" if abs(a - 90.0) <= AXIS_TOL_DEG else None)
    # the facades' middle, offset from the centre line along its plan normal (-sin a, cos a)
    cross = 0.5 * (s.facade_offsets[0] + s.facade_offsets[1])
    if axis is None:
        text = (f"[[streets]]\nname = \"{s.name}\"  # {s.angle_deg:.2f} deg from +X\n"
                f"p0 = [{s.p0[0]:.2f}, {s.p0[1]:.2f}]\np1 = [{s.p1[0]:.2f}, {s.p1[1]:.2f}]\nwidth = {s.width:.2f}\n")
        if abs(cross) >= 0.005:
            text += f"cross = {cross:.2f}\n"
    else:
        k = 0 if axis == "x" else 1
        lo, hi = sorted((s.p0[k], s.p1[k]))
        # the middle of the centre line (the street may be up to AXIS_TOL_DEG off the axis); the
        # facades lie symmetrically about it (street_detect centres the line between them)
        mid = 0.5 * (s.p0[1 - k] + s.p1[1 - k])
        text = (f"[[streets]]\nname = \"{s.name}\"\naxis = \"{axis}\"\nstart = {lo:.2f}\nend = {hi:.2f}\n"
                f"width = {s.width:.2f}\ncross = {mid + 0.0:.2f}\n")
    if terrain_span > FOLLOW_TERRAIN_M:
        text += f"follow_terrain = true  # the ground under it varies by {terrain_span:.2f} m\n"
    return text


def _scene_toml(name: str, mesh_table: dict[str, object], streets: list[DetectedStreet],
                terrain_spans: list[float] | None = None) -> str:
    lines = [f"# Streets found by `envcap streets` in {name}.\nname = \"{Path(name).stem}_streets\"\n"]
    if mesh_table:
        off = ", ".join(f"{v + 0.0:.3f}" for v in mesh_table["offset"])  # type: ignore[union-attr]
        lines.append(f"[mesh]\nfile = \"{mesh_table['file']}\"\nup_axis = \"{mesh_table['up_axis']}\"\n"
                     f"rotation_deg = {mesh_table['rotation_deg']}\noffset = [{off}]\n")
    else:
        lines.append(f"# the geometry is the scene {name!r}: copy its [mesh] / buildings tables here to bake these streets\n")
    spans = terrain_spans if terrain_spans is not None else [0.0] * len(streets)
    lines += [_street_table(s, span) for s, span in zip(streets, spans)]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    search = StreetSearch(min_length=args.min_length)
    tri, inputs, mesh_table, mesh = _triangles(args)
    streets = detect_streets(tri, search)
    spans = _terrain_spans(mesh, streets)
    crossings = intersections(streets)
    with claim_output_dir(args.out, kind="streets", inputs=inputs, force=args.force) as claim, \
            atomic_output_dir(claim) as tmp:
        doc = {"source": args.source, "search": asdict(search),
               "streets": [{**asdict(s), "width": s.width, "length": s.length} for s in streets],
               "intersections": [list(p) for p in crossings]}
        (tmp / "streets.json").write_text(json.dumps(doc, indent=1) + "\n")
        (tmp / "scene.toml").write_text(_scene_toml(args.source, mesh_table, streets, spans))
        save_street_map(tri, streets, tmp / "streets_map.png", args.spacing)
    for s in streets:
        print(f"{s.name}: {s.angle_deg:6.2f} deg, {s.length:6.1f} m long, {s.width:5.1f} m wide, "
              f"frontage {s.frontage[0]:.0%} / {s.frontage[1]:.0%}")
    print(f"{len(streets)} streets, {len(crossings)} intersections: {args.out}")
    return 0
