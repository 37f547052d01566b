"""Which files a mesh table imports: ``file``, ``files``, ``glob``, then ``include`` / ``exclude``.

Selection (``docs/scenes.md``, "Imported meshes"), all paths relative to the scene file's directory:

1. ``file``: one mesh file, or a directory whose ``*.ply`` are taken (sorted);
2. ``files``: a list of such files or directories;
3. ``glob``: patterns (:meth:`pathlib.Path.glob`, ``**`` recurses) of which every matching file
   with a mesh suffix (:data:`GLOB_SUFFIXES`: not ``.xml``) is taken, sorted per pattern;

joined in that order, each file once; then ``include`` patterns keep only the files that match one
of them and ``exclude`` patterns drop the files that match one.  A pattern (:func:`fnmatch.fnmatch`)
matches a file when it matches its name or its path relative to the scene directory (``/``).

Every way of naming nothing is a one-line ``ValueError`` (``FileNotFoundError`` for a missing
file): a glob or include/exclude pattern that matches no file, or no file left at the end.
"""

from __future__ import annotations

import fnmatch
from pathlib import Path
from typing import Sequence

from envcap.core.input_path import require_file

GLOB_SUFFIXES = (".glb", ".gltf", ".obj", ".ply", ".stl", ".off")
"""Mesh file suffixes (lower case, read through trimesh) that a ``glob`` picks up."""

MESH_SUFFIXES = (*GLOB_SUFFIXES, ".xml")
"""File suffixes the importer reads when a file is named: also Mitsuba 3 scene XML, which a glob
does not pick up (it names meshes of its own, which the glob would take a second time)."""


def mesh_files(path: Path) -> list[Path]:
    """The mesh files one name stands for: the file itself, or a directory's ``*.ply`` sorted."""
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() == ".ply" and p.is_file())
        if not files:
            raise ValueError(f"mesh directory {path} contains no .ply files")
        return files
    require_file(path, "mesh file", f"mesh file {path} not found")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise ValueError(f"mesh file {path}: unsupported type '{path.suffix}' (use one of {', '.join(MESH_SUFFIXES)})")
    return [path]


def _relative(path: Path, base_dir: Path) -> str:
    try:
        return path.relative_to(base_dir).as_posix()
    except ValueError:
        return path.as_posix()


def _matches(pattern: str, path: Path, base_dir: Path) -> bool:
    return fnmatch.fnmatch(path.name, pattern) or fnmatch.fnmatch(_relative(path, base_dir), pattern)


def select_mesh_files(
    base_dir: Path,
    *,
    file: Path | None = None,
    files: Sequence[Path] = (),
    globs: Sequence[str] = (),
    include: Sequence[str] = (),
    exclude: Sequence[str] = (),
    where: str = "mesh",
) -> list[Path]:
    """The mesh files a mesh table names (see the module docstring), in order, each once.

    ``file`` and ``files`` are paths (relative ones resolved against ``base_dir``); ``globs``,
    ``include`` and ``exclude`` are patterns; ``where`` names the table in errors.
    """
    named = ([] if file is None else [file]) + list(files)
    if not named and not globs:
        raise ValueError(f"{where}: give the mesh files with 'file', 'files' or 'glob'")
    picked: list[Path] = []
    for p in named:
        picked += mesh_files(p if p.is_absolute() else base_dir / p)
    for pattern in globs:
        if Path(pattern).is_absolute():
            raise ValueError(f"{where}.glob: {pattern!r}: patterns are relative to the scene's directory {base_dir}")
        hits = sorted(p for p in base_dir.glob(pattern) if p.is_file() and p.suffix.lower() in GLOB_SUFFIXES)
        if not hits:
            raise ValueError(f"{where}.glob: {pattern!r} matches no mesh file ({', '.join(GLOB_SUFFIXES)}) "
                             f"under {base_dir}")
        picked += hits
    unique = list(dict.fromkeys(picked))
    for key, patterns in (("include", include), ("exclude", exclude)):
        for pattern in patterns:
            if not any(_matches(pattern, p, base_dir) for p in unique):
                raise ValueError(f"{where}.{key}: {pattern!r} matches none of the {len(unique)} selected file(s) "
                                 f"(patterns match a file's name or its path relative to {base_dir})")
    if include:
        unique = [p for p in unique if any(_matches(pat, p, base_dir) for pat in include)]
    kept = [p for p in unique if not any(_matches(pat, p, base_dir) for pat in exclude)]
    if not kept:
        raise ValueError(f"{where}: include/exclude leave no file of the {len(unique)} selected")
    return kept
