"""``envcap streets``: find straight streets in a scene or a city mesh (``envcap.scene.street_detect``).

Writes ``DIR/streets.json`` (every street: centre line, direction, facade offsets, frontage,
heights, crossings; the intersections), ``DIR/streets_map.png`` (top-down map) and
``DIR/scene.toml``: a scene that bakes as it is (``envcap capture DIR/scene.toml``): the input's
geometry, a sky and effects, the ground, the streets found (``envcap.scene.streets_scene``).

Order of work: the options are checked and the output claimed (``--out`` refused, locked) before
the mesh is read, so a bad option or output costs nothing on a city of millions of triangles;
then import, detection, the ground under the streets and the writing, each a ``progress:`` line
on stderr (``--quiet``: none).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from envcap.cli.output_options import add_force_argument, scene_input_files
from envcap.core.resources import city_scenes_dir
from envcap.outputs import atomic_output_dir, claim_output_dir
from envcap.probeset.progress import PREFIX
from envcap.scene import build_scene, scene_path
from envcap.scene.limits import ANGLE_LIMIT_DEG, COORDINATE_LIMIT_M
from envcap.scene.mesh_import import WINDING_MODES, import_meshes
from envcap.scene.mesh_select import MESH_SUFFIXES, mesh_files
from envcap.scene.model import SceneMesh
from envcap.scene.parse import parse_scene, read_toml
from envcap.scene.street_detect import DetectedStreet, NoWalls, StreetSearch, detect_streets, intersections
from envcap.scene.street_detect_figure import save_street_map
from envcap.scene.streets_scene import check_copyable, mesh_scene_text, scene_scene_text, street_ground

SPACING_RANGE_M = (0.5, 1000.0)
"""``--spacing`` (m): the map's probe dots along each street."""
MIN_LENGTH_RANGE_M = (1.0, 100000.0)
"""``--min-length`` (m): at least the detection's 1 m sampling step."""
PROGRESS_EVERY_S = (1.0, 10.0)
"""A running stage says how far it got at most this often (s): on a terminal (one line, rewritten),
elsewhere (a line each: logs, pipes)."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("streets", help="find straight streets in a scene or a city mesh; write a scene file and a map")
    p.add_argument("source", help="a bundled scene name, a scene .toml, or a mesh file / directory of .ply files")
    p.add_argument("--out", required=True, type=Path, help="output directory (streets.json, streets_map.png, scene.toml)")
    p.add_argument("--up-axis", choices=("y", "z"), default="y", help="mesh input: the file's up axis (default y)")
    p.add_argument("--offset", type=float, nargs=3, default=(0.0, 0.0, 0.0), metavar=("X", "Y", "Z"),
                   help="mesh input: meters added after the up-axis turn (projected coordinates -> near the origin)")
    p.add_argument("--rotation", type=float, default=0.0, help="mesh input: degrees about +Y after the up-axis turn")
    p.add_argument("--winding", choices=WINDING_MODES, default="auto", help="mesh input: fix inward-wound parts (default auto)")
    p.add_argument("--spacing", type=float, default=10.0,
                   help=f"probe spacing along each street for the map (m, default 10; "
                        f"{SPACING_RANGE_M[0]:g} to {SPACING_RANGE_M[1]:g})")
    p.add_argument("--min-length", type=float, default=30.0,
                   help=f"shortest street reported (m, default 30; {MIN_LENGTH_RANGE_M[0]:g} to {MIN_LENGTH_RANGE_M[1]:g})")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr (warnings and errors still)")
    add_force_argument(p)
    p.set_defaults(func=run)


def check_arguments(args: argparse.Namespace) -> StreetSearch:
    """The options checked before anything is read or claimed (``ValueError`` naming the option)."""
    for option, value, (lo, hi) in (("--spacing", args.spacing, SPACING_RANGE_M),
                                    ("--min-length", args.min_length, MIN_LENGTH_RANGE_M)):
        if not (math.isfinite(value) and lo <= value <= hi):
            raise ValueError(f"{option} must be a number of meters from {lo:g} to {hi:g}, got {value:g}")
    if not (math.isfinite(args.rotation) and abs(args.rotation) <= ANGLE_LIMIT_DEG):
        raise ValueError(f"--rotation must be a number of degrees within +-{ANGLE_LIMIT_DEG:g}, got {args.rotation:g}")
    if not all(math.isfinite(v) and abs(v) <= COORDINATE_LIMIT_M for v in args.offset):
        raise ValueError(f"--offset must be three numbers of meters within +-{COORDINATE_LIMIT_M:g}, "
                         f"got {' '.join(f'{v:g}' for v in args.offset)}")
    return StreetSearch(min_length=args.min_length)


class Progress:
    """``progress: STAGE: ...`` lines on stderr (nothing when ``quiet``): one when a stage starts,
    one when it ends with its seconds, and between them how far it got, at most every
    :data:`PROGRESS_EVERY_S` (on a terminal rewriting one line)."""

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet
        self.tty = bool(getattr(sys.stderr, "isatty", lambda: False)())
        self.every = PROGRESS_EVERY_S[0] if self.tty else PROGRESS_EVERY_S[1]
        self.stage = ""
        self.t0 = self.last = time.perf_counter()

    def _say(self, text: str, running: bool = False) -> None:
        if self.quiet:
            return
        line = f"{PREFIX}{self.stage}: {text}"
        if self.tty:
            print(f"\r{line}\x1b[K", end="" if running else "\n", file=sys.stderr, flush=True)
        else:
            print(line, file=sys.stderr, flush=True)

    def begin(self, stage: str, text: str) -> None:
        self.stage, self.t0 = stage, time.perf_counter()
        self.last = self.t0
        self._say(text)

    def tick(self, text: str) -> None:
        now = time.perf_counter()
        if now - self.last >= self.every:
            self.last = now
            self._say(f"{text} ({now - self.t0:.0f} s)", running=True)

    def end(self, text: str) -> None:
        self._say(f"{text} in {time.perf_counter() - self.t0:.1f} s")


@dataclass
class Source:
    """What ``envcap streets`` reads: a mesh (``files``) or a scene (``scene``: its file)."""

    text: str
    files: list[Path] | None = None
    scene: Path | None = None
    bundled: bool = False

    @classmethod
    def open(cls, text: str) -> "Source":
        """Which input ``text`` names (cheap: no mesh is read); ``FileNotFoundError`` / ``ValueError``."""
        path = Path(text)
        if path.suffix.lower() in MESH_SUFFIXES or (path.exists() and path.suffix.lower() != ".toml"):
            return cls(text, files=mesh_files(path))          # a missing mesh file: "mesh file ... not found"
        scene = scene_path(text)
        return cls(text, scene=scene, bundled=scene == city_scenes_dir() / f"{text}.toml")

    @property
    def inputs(self) -> list[Path]:
        """The files the output may not replace."""
        return list(self.files) if self.files is not None else scene_input_files(self.text)


def _import_mesh(args: argparse.Namespace, source: Source, say: Progress) -> SceneMesh:
    files = source.files or []
    size = sum(f.stat().st_size for f in files)
    amount = f"{size / 1e6:.1f} MB" if size >= 1e5 else f"{size / 1e3:.1f} kB"
    say.begin("import", f"reading {len(files)} file(s), {amount} ({files[0].name}{', ...' if len(files) > 1 else ''})")
    count = [0, 0]

    def read(name: str, triangles: int) -> None:
        count[0], count[1] = count[0] + 1, count[1] + triangles
        say.tick(f"{count[0]} mesh(es) read, {count[1]:,} triangles, last {name}")

    mesh, report = import_meshes(files, up_axis=args.up_axis, rotation_deg=args.rotation, offset=args.offset,
                                 winding=args.winding, where=source.text, progress=read)
    say.end(f"{mesh.triangle_count:,} triangles from {report.parts:,} parts")
    if report.flipped:
        print(f"envcap: note: {source.text}: flipped {report.flipped} of {report.parts} parts wound inward "
              f"({len(report.flipped_files)} file(s))", file=sys.stderr)
    return mesh


def _build_source_scene(source: Source, say: Progress) -> tuple[SceneMesh, tuple[float, float], dict]:
    """The source scene's geometry without its ground, its ground's centre, and its TOML document."""
    path = source.scene
    assert path is not None
    say.begin("import", f"building the geometry of {source.text}")
    raw = read_toml(path)
    check_copyable(raw, source.text)
    try:
        spec = parse_scene(raw, base_dir=path.parent.resolve(), default_name=path.stem, source=str(path))
        scene = build_scene(replace(spec, ground=None))
    except FileNotFoundError as exc:
        raise FileNotFoundError(f"{path}: {exc}") from None
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    say.end(f"{scene.mesh.triangle_count:,} triangles")
    return scene.mesh, scene.meta["ground_center"], raw


def _detect(mesh: SceneMesh, search: StreetSearch, say: Progress, where: str,
            up_axis: str | None = None) -> tuple[np.ndarray, list[DetectedStreet]]:
    """The streets of ``mesh`` (read from ``where``); ``up_axis``: the ``--up-axis`` a mesh file was
    read with (named in the error when no wall stands up), None for a scene."""
    tri = (mesh.positions.astype(np.float64) + mesh.origin)[mesh.indices.astype(np.int64)]
    say.begin("streets", f"searching {tri.shape[0]:,} triangles for facades that face each other")
    try:
        streets = detect_streets(tri, search, progress=say.tick)
    except NoWalls:
        hint = "" if up_axis is None else f" when read with --up-axis {up_axis}; is that the file's up axis?"
        raise NoWalls(f"{where}: no walls found: the mesh has no near-vertical triangles{hint}") from None
    say.end(f"{len(streets)} found")
    return tri, streets


def run(args: argparse.Namespace) -> int:
    search = check_arguments(args)
    source = Source.open(args.source)
    say = Progress(args.quiet)
    with claim_output_dir(args.out, kind="streets", inputs=source.inputs, force=args.force) as claim:
        if source.files is not None:
            mesh = _import_mesh(args, source, say)
            center, raw = (0.0, 0.0), {}
        else:
            mesh, center, raw = _build_source_scene(source, say)
        tri, streets = _detect(mesh, search, say, source.text, args.up_axis if source.files is not None else None)
        say.begin("ground", "sampling the mesh's ground under the streets' centre lines")
        ground = street_ground(mesh, streets, progress=say.tick)
        say.end(f"a surface under {ground.share:.0%} of them")
        crossings = intersections(streets)
        if source.files is not None:
            transform = {"up_axis": args.up_axis, "rotation_deg": float(args.rotation),
                         "offset": [float(v) for v in args.offset], "winding": args.winding}
            text = mesh_scene_text(Path(args.source), claim.path, transform, streets, ground)
        else:
            assert source.scene is not None
            text = scene_scene_text(args.source, source.scene, raw, claim.path, streets, ground, center, source.bundled)
        say.begin("write", "streets.json, scene.toml, streets_map.png")
        with atomic_output_dir(claim) as tmp:
            doc = {"source": args.source, "search": asdict(search),
                   "streets": [{**asdict(s), "width": s.width, "length": s.length} for s in streets],
                   "intersections": [list(p) for p in crossings]}
            (tmp / "streets.json").write_text(json.dumps(doc, indent=1) + "\n")
            (tmp / "scene.toml").write_text(text, encoding="utf-8")
            save_street_map(tri, streets, tmp / "streets_map.png", args.spacing)
        say.end("written")
    for s in streets:
        print(f"{s.name}: {s.angle_deg:6.2f} deg, {s.length:6.1f} m long, {s.width:5.1f} m wide, "
              f"frontage {s.frontage[0]:.0%} / {s.frontage[1]:.0%}")
    print(f"{len(streets)} streets, {len(crossings)} intersections: {args.out}")
    return 0
