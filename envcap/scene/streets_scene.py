"""The scene file ``envcap streets`` writes (``DIR/scene.toml``): the streets it found, in a scene
that bakes as it is (``envcap capture DIR/scene.toml``).

What goes in, each choice on a comment line of its own in the file (``docs/scenes.md``, "The
scene `envcap streets` writes"):

* **geometry**: a mesh input as a ``[mesh]`` table with the import options given; a scene input
  (a bundled name or a ``.toml``) by its ``[[mesh]]`` tables copied (a ``glob`` / ``include`` /
  ``exclude`` selection expanded into the ``files`` it selected), or, when its streets build
  buildings or walls (which exist only with those streets), by ``[[mesh]] scene = ...``: the
  geometry that scene builds.  Paths are relative to the written file when it and the target
  share a folder below the file-system root, else absolute; either way they resolve wherever the
  user runs ``envcap capture`` from;
* **effects and sky**: a scene input's own; for a mesh, those of the bundled imported cities
  (:data:`DEFAULT_EFFECTS`, :data:`DEFAULT_SKY`);
* **ground**: off when the mesh has a surface of its own under most of the streets' centre lines
  (:data:`MESH_GROUND_SHARE`; the default plane at y = 0 would z-fight with a flat terrain or hide
  under a raised one); else a scene input's ``[ground]`` (its centre written out, since the found
  streets would move a computed one) or the default plane;
* **streets**: one ``[[streets]]`` per street found: along X or Z (``axis``, ``start``/``end``)
  within :data:`AXIS_TOL_DEG`, else by the ends of its centre line (``p0``/``p1``); with
  ``follow_terrain = true`` when the ground under it varies by more than :data:`FOLLOW_TERRAIN_M`.

Every string goes through :func:`envcap.scene.toml_text.toml_string`: a path with a quote, a
backslash or a newline still gives a valid file.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from envcap.scene.ground_height import GroundHeights
from envcap.scene.mesh_select import select_mesh_files
from envcap.scene.model import SceneMesh
from envcap.scene.street_detect import DetectedStreet
from envcap.scene.toml_text import toml_string, toml_table, toml_value

AXIS_TOL_DEG = 0.5
"""Streets within this angle of world X or Z are written as axis-aligned ``[[streets]]``
(``axis``, ``start``/``end``); others by their ends (``p0``/``p1``)."""
FOLLOW_TERRAIN_M = 0.5
"""A street whose ground varies by more than this (m) along its centre line gets ``follow_terrain = true``."""
GROUND_STEP_M = 2.0
"""Spacing (m) of the ground samples along each street's centre line."""
MESH_GROUND_SHARE = 0.5
"""The default ground is turned off when the mesh has an up-facing surface under at least this
share of the centre-line samples."""
DEFAULT_EFFECTS = ("sun_light", "sun_shadows", "sky_light")
"""Effects of a scene made from a mesh: those of the bundled imported cities (``generated_city``)."""
DEFAULT_SKY: dict[str, Any] = {"type": "preetham", "turbidity": 3.0, "sun_elevation_deg": 45.0, "sun_azimuth_deg": 140.0}
"""Sky of a scene made from a mesh: the bundled ``generated_city``'s clear day."""


@dataclass(frozen=True)
class StreetGround:
    """The mesh's own ground under the found streets: ``share`` of the centre-line samples (every
    :data:`GROUND_STEP_M`) with an up-facing surface under them (0..1; 0 without streets), and per
    street the ``spans`` (m) of those heights (max - min; 0 where it has none)."""

    share: float
    spans: tuple[float, ...]

    @property
    def mesh_has_ground(self) -> bool:
        """True when the default ground plane is to be turned off (:data:`MESH_GROUND_SHARE`)."""
        return self.share >= MESH_GROUND_SHARE


def street_ground(mesh: SceneMesh, streets: Sequence[DetectedStreet],
                  progress: Callable[[str], None] | None = None) -> StreetGround:
    """Sample ``mesh``'s highest up-facing surface (:class:`~envcap.scene.ground_height.GroundHeights`)
    along each street's centre line (``progress(text)`` after each street).  ``mesh`` must not
    hold the default ground plane."""
    if not streets:
        return StreetGround(0.0, ())
    ground = GroundHeights(mesh)
    spans, found, total = [], 0, 0
    for k, s in enumerate(streets):
        if progress is not None:
            progress(f"street {k + 1} of {len(streets)}")
        t = np.linspace(0.0, 1.0, max(2, int(np.ceil(s.length / GROUND_STEP_M)) + 1))
        xz = np.asarray(s.p0) + t[:, None] * (np.asarray(s.p1) - np.asarray(s.p0))
        h = ground(xz)
        h = h[np.isfinite(h)]
        found, total = found + h.size, total + t.size
        spans.append(float(h.max() - h.min()) if h.size else 0.0)
    return StreetGround(found / total, tuple(spans))


def path_text(target: Path, folder: Path) -> str:
    """``target`` as written in a file in ``folder``: relative to it when both lie below a common
    folder other than the file-system root, else absolute (both resolved first)."""
    target, folder = Path(os.path.abspath(target)), Path(os.path.abspath(folder))
    try:
        common = Path(os.path.commonpath([target, folder]))
    except ValueError:                       # different drives
        return str(target)
    if common == Path(common.anchor):
        return str(target)
    return os.path.relpath(target, folder)


def street_table(s: DetectedStreet, terrain_span: float = 0.0) -> str:
    """A ``[[streets]]`` table: along X or Z (``axis``, ``start``/``end``) for a street within
    AXIS_TOL_DEG of them, else by its centre line's ends (``p0``/``p1``, any angle); with
    ``follow_terrain = true`` when the ground under it varies by more than FOLLOW_TERRAIN_M."""
    a = s.angle_deg % 180.0
    axis = "x" if min(a, 180.0 - a) <= AXIS_TOL_DEG else ("z" if abs(a - 90.0) <= AXIS_TOL_DEG else None)
    # the facades' middle, offset from the centre line along its plan normal (-sin a, cos a)
    cross = 0.5 * (s.facade_offsets[0] + s.facade_offsets[1])
    if axis is None:
        text = (f"[[streets]]\nname = {toml_string(s.name)}  # {s.angle_deg:.2f} deg from +X\n"
                f"p0 = [{s.p0[0]:.2f}, {s.p0[1]:.2f}]\np1 = [{s.p1[0]:.2f}, {s.p1[1]:.2f}]\nwidth = {s.width:.2f}\n")
        if abs(cross) >= 0.005:
            text += f"cross = {cross:.2f}\n"
    else:
        k = 0 if axis == "x" else 1
        lo, hi = sorted((s.p0[k], s.p1[k]))
        # the middle of the centre line (the street may be up to AXIS_TOL_DEG off the axis); the
        # facades lie symmetrically about it (street_detect centres the line between them)
        mid = 0.5 * (s.p0[1 - k] + s.p1[1 - k])
        text = (f"[[streets]]\nname = {toml_string(s.name)}\naxis = \"{axis}\"\nstart = {lo:.2f}\nend = {hi:.2f}\n"
                f"width = {s.width:.2f}\ncross = {mid if abs(mid) >= 0.005 else 0.0:.2f}\n")
    if terrain_span > FOLLOW_TERRAIN_M:
        text += f"follow_terrain = true  # the ground under it varies by {terrain_span:.2f} m\n"
    return text


def _streets_text(streets: Sequence[DetectedStreet], ground: StreetGround) -> list[str]:
    head = (f"# streets: {len(streets)} found, each probe line midway between its facades; follow_terrain where the "
            f"ground under a street varies by more than {FOLLOW_TERRAIN_M:g} m\n")
    tables = [street_table(s, span) for s, span in zip(streets, ground.spans or (0.0,) * len(streets))]
    if not tables:
        return ["# streets: none found (a scene needs at least one [[streets]] to capture)\n"]
    return [head + tables[0], *tables[1:]]


def _ground_off(ground: StreetGround, was: str = "") -> str:
    return (f"# ground: off: the mesh has a surface of its own under {ground.share:.0%} of the streets' centre lines "
            f"(the default plane at y = 0 would z-fight with it){was}\n[ground]\nenabled = false\n")


def _document(source: str, name: str, effects: tuple[list[str], str], sky: tuple[dict[str, Any], str],
              blocks: list[str], streets: Sequence[DetectedStreet], ground: StreetGround) -> str:
    head = (f"# Streets found by `envcap streets` in {toml_string(source)}: a scene that bakes as it is; one comment\n"
            f"# line per choice made for it.\n"
            f"name = {toml_string(name)}\n"
            f"description = {toml_string(f'Streets found by envcap streets in {source}')}\n"
            f"# effects: {effects[1]}\n"
            f"effects = {toml_value(list(effects[0]))}\n")
    sky_block = f"# sky: {sky[1]}\n" + toml_table("[sky]", sky[0])
    return "\n".join([head, sky_block, *blocks, *_streets_text(streets, ground)])


def mesh_scene_text(mesh_path: Path, out_dir: Path, transform: dict[str, Any], streets: Sequence[DetectedStreet],
                    ground: StreetGround) -> str:
    """The scene of streets found in the mesh file (or PLY directory) ``mesh_path``, to be written
    into ``out_dir``; ``transform``: the ``[mesh]`` keys given (up_axis, rotation_deg, offset, winding)."""
    file = path_text(mesh_path, out_dir)
    how = "relative to this file" if not os.path.isabs(file) else "by its absolute path"
    mesh = (f"# mesh: the input, {how}, with the import options given to `envcap streets`\n"
            + toml_table("[mesh]", {"file": file, **transform}))
    if ground.mesh_has_ground:
        ground_block = _ground_off(ground)
    else:
        ground_block = (f"# ground: the default plane at y = 0 (the mesh has a surface under only {ground.share:.0%} of "
                        f"the streets' centre lines)\n[ground]\nenabled = true\n")
    return _document(str(mesh_path), f"{Path(mesh_path).stem}_streets",
                     (list(DEFAULT_EFFECTS), "sun light, sun shadows and sky light, as the bundled imported cities "
                                             "(add \"emissive_windows\" for lit windows)"),
                     (dict(DEFAULT_SKY), "a clear day (Preetham, turbidity 3, sun 45 deg high at azimuth 140 deg), "
                                         "as the bundled imported cities"),
                     [mesh, ground_block], streets, ground)


def _copied_mesh(table: dict[str, Any], base: Path, out_dir: Path, where: str, source: str) -> str:
    """One of the source's mesh tables with its paths rewritten for ``out_dir``."""
    t = dict(table)
    if "scene" in t:
        ref = Path(str(t["scene"]))
        if ref.suffix.lower() == ".toml" or len(ref.parts) > 1 or ref.is_absolute():
            t["scene"] = path_text(base / ref, out_dir)
        return f"# {where}: {source}'s {where}, its scene path rewritten for this file\n" + toml_table("[[mesh]]", t)
    patterns = [k for k in ("glob", "include", "exclude") if k in t]

    def strings(v: Any) -> tuple[str, ...]:
        return (v,) if isinstance(v, str) else tuple(str(x) for x in v)

    if patterns:
        chosen = select_mesh_files(base, file=base / str(t["file"]) if "file" in t else None,
                                   files=tuple(base / f for f in strings(t.get("files", ()))),
                                   globs=strings(t.get("glob", ())), include=strings(t.get("include", ())),
                                   exclude=strings(t.get("exclude", ())))
        for k in ("file", "files", *patterns):
            t.pop(k, None)
        t = {"files": [path_text(f, out_dir) for f in chosen], **t}
        how = f"its {'/'.join(patterns)} selection expanded into the {len(chosen)} files it selects now, "
    else:
        if "file" in t:
            t["file"] = path_text(base / str(t["file"]), out_dir)
        if "files" in t:
            t["files"] = [path_text(base / f, out_dir) for f in strings(t["files"])]
        how = "its "
    written = ([t["file"]] if "file" in t else []) + list(t.get("files", []))
    absolute = [os.path.isabs(f) for f in written]
    how += ("paths absolute" if all(absolute) else "paths relative to this file" if not any(absolute)
            else "paths rewritten for this file")
    return f"# {where}: {source}'s {where}, {how}\n" + toml_table("[[mesh]]", t)


def builds_buildings(raw: dict[str, Any]) -> bool:
    """Whether the scene document ``raw`` has streets that build buildings or walls (``side_min`` /
    ``side_max``): its geometry can then only be taken whole (``[[mesh]] scene = ...``)."""
    return any(isinstance(s, dict) and ("side_min" in s or "side_max" in s) for s in raw.get("streets", []))


def check_copyable(raw: dict[str, Any], label: str) -> None:
    """``ValueError`` when the scene ``raw`` can be written neither way: its streets build buildings
    (taken whole by ``scene = ...``) and it takes geometry from another scene itself (one level only)."""
    meshes = raw.get("mesh", [])
    meshes = [meshes] if isinstance(meshes, dict) else list(meshes)
    if builds_buildings(raw) and any(isinstance(t, dict) and "scene" in t for t in meshes):
        raise ValueError(f"{label}: its streets build buildings, which a written scene can only take with "
                         f"[[mesh]] scene = ..., and it takes geometry from another scene itself (one level only): "
                         f"give {label} its meshes directly")


def scene_scene_text(source: str, path: Path, raw: dict[str, Any], out_dir: Path, streets: Sequence[DetectedStreet],
                     ground: StreetGround, ground_center: tuple[float, float], bundled: bool) -> str:
    """The scene of streets found in the scene ``source`` (a bundled name when ``bundled``, else a
    ``.toml`` path), read from ``path`` as ``raw`` (its TOML document); ``ground_center``: the plan
    centre (x, z) of its ground as it builds it."""
    base = path.parent.resolve()
    label = source if bundled else toml_string(path.name)      # comments hold no raw control character
    meshes = raw.get("mesh", [])
    meshes = [meshes] if isinstance(meshes, dict) else list(meshes)
    check_copyable(raw, label)
    if builds_buildings(raw):
        ref = source if bundled else path_text(path, out_dir)
        blocks = [f"# mesh: the geometry {label} builds (its streets' buildings and walls exist only with those streets, "
                  f"so it is taken whole; not its ground or probes)\n" + toml_table("[[mesh]]", {"scene": ref})]
    else:
        blocks = [_copied_mesh(t, base, out_dir, f"mesh[{i}]" if len(meshes) > 1 else "mesh", label)
                  for i, t in enumerate(meshes)]
    sky = dict(raw.get("sky", {}))
    if "file" in sky:
        sky["file"] = path_text(base / str(sky["file"]), out_dir)
    if "shadows" in raw:
        blocks.append(f"# shadows: those of {label}\n" + toml_table("[shadows]", dict(raw["shadows"])))
    source_ground = dict(raw.get("ground", {}))
    if source_ground.get("enabled", True) is False:
        blocks.append(f"# ground: off, as in {label}\n[ground]\nenabled = false\n")
    elif ground.mesh_has_ground:
        blocks.append(_ground_off(ground, f"; it is on in {label}"))
    else:
        source_ground.setdefault("center", [float(ground_center[0]), float(ground_center[1])])
        blocks.append(f"# ground: that of {label}, its centre written out (the streets found would move a computed one)\n"
                      + toml_table("[ground]", source_ground))
    stem = source if bundled else path.stem
    return _document(source, f"{stem}_streets", (list(raw.get("effects", [])), f"those of {label}"),
                     (sky, f"that of {label}" + (", its file's path rewritten for this file" if "file" in sky else "")),
                     blocks, streets, ground)
