"""How a subcommand claims its ``--out`` directory: the ``--force`` option and the input files
that an output may never contain (see :mod:`envcap.outputs`)."""

from __future__ import annotations

import argparse
import tomllib
from pathlib import Path
from typing import Any

from envcap.scene import scene_path

FORCE_HELP = ("replace an existing non-empty --out directory even if envcap did not write it: that "
              "directory is renamed to NAME.envcap-replaced-YYYYmmdd-HHMMSS beside it, never deleted "
              "(an input, the working directory, the home directory, a mount point or a top-level "
              "system directory is never an output)")


def add_force_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("--force", action="store_true", help=FORCE_HELP)


def _strings(value: Any) -> list[str]:
    if isinstance(value, str):
        return [value]
    if isinstance(value, dict):
        return [s for v in value.values() for s in _strings(v)]
    if isinstance(value, list):
        return [s for v in value for s in _strings(v)]
    return []


def scene_input_files(name_or_path: str) -> list[Path]:
    """The scene file of a bundled scene name or a ``.toml`` path, and every existing file that a
    string in it names relative to its folder (meshes, lat-long skies).

    Raises ``FileNotFoundError`` for an unknown scene.  An unreadable TOML gives just the scene
    file (loading the scene reports the error).
    """
    path = scene_path(name_or_path).resolve()
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return [path]
    found = [path]
    for text in _strings(data):
        try:
            candidate = path.parent / text
            if text and "\n" not in text and candidate.exists():
                found.append(candidate.resolve())
        except (OSError, ValueError):
            continue
    return found
