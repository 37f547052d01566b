"""``envcap scenes``: list the bundled city scenes (``--details`` builds them; ``--preview`` renders)."""

from __future__ import annotations

import argparse
from pathlib import Path

from envcap.gpu.context import create_context
from envcap.outputs.guard import check_file_replaceable, check_file_target, check_writable, resolve_output
from envcap.scene import list_scenes, load_scene
from envcap.scene.load import check_scene
from envcap.scene.scene_preview import save_previews


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("scenes", help="list the bundled city scenes (name, description)")
    p.add_argument("scene", nargs="*", help="scene names or .toml paths to show, each read and checked "
                                            "(default: all bundled scenes)")
    p.add_argument("--details", action="store_true",
                   help="build each scene and print triangles, bounding box, streets and effects")
    p.add_argument("--preview", metavar="DIR", type=Path,
                   help="also write DIR/scenes_NAME.png (street-level view above a top view)")
    p.add_argument("--force", action="store_true",
                   help="overwrite DIR/scenes_NAME.png even if envcap did not write it (it has no envcap PNG mark)")
    p.set_defaults(func=run)


def _preview_path(folder: Path, scene_name: str) -> Path:
    return Path(folder) / f"scenes_{Path(scene_name).stem}.png"


def run(args: argparse.Namespace) -> int:
    if args.scene:   # each named scene is read and checked (not built): a bad file is an error, exit 2
        names = [(s, " ".join(check_scene(s).description.split())) for s in args.scene]
    else:
        names = list_scenes()
    if not (args.details or args.preview):
        for name, desc in names:
            print(f"{name:<12} {desc}" if desc else name)
        return 0
    ctx = None
    if args.preview:
        check_writable(resolve_output(args.preview))  # before any scene is built: DIR a folder, or can be one,
        for name, _ in names:                          # each PNG's folder takes files, no foreign PNG there
            check_file_target(resolve_output(_preview_path(args.preview, name)))
            check_file_replaceable(_preview_path(args.preview, name), args.force)
        ctx = create_context()
    try:
        for name, _ in names:
            scene = load_scene(name)
            m = scene.mesh
            lo, hi = m.world_bounds()
            print(f"{scene.name:<12} {scene.description}")
            print(f"    triangles {m.triangle_count}, buildings {scene.meta.get('buildings', 0)}, "
                  f"windows {scene.meta.get('windows', 0)} ({scene.meta.get('lit_windows', 0)} lit)")
            print(f"    bbox min ({lo[0]:.1f}, {lo[1]:.1f}, {lo[2]:.1f}) max ({hi[0]:.1f}, {hi[1]:.1f}, {hi[2]:.1f}) m")
            print(f"    effects {', '.join(sorted(scene.effects))}; sky {scene.sky.type}")
            for st in scene.streets:
                print(f"    street {st.name}: along {st.axis} [{st.start:g}, {st.end:g}] m, facade planes "
                      f"{'z' if st.axis == 'x' else 'x'} = {st.facade_min:g} / {st.facade_max:g} m, probe line {st.center_line:g}"
                      + (f" (its frame: yaw {st.yaw_deg:g} deg, origin x, z = {st.origin_xz[0]:g}, {st.origin_xz[1]:g})"
                         if st.framed else ""))
            if args.preview:
                out = save_previews(ctx, scene, _preview_path(args.preview, name), force=args.force)
                print(f"    preview {out}")
    finally:
        if ctx is not None:
            ctx.release()
    return 0
