"""The scenes bundled with envcap (``city_scenes/*.toml``): listing them and resolving a name."""

from __future__ import annotations

import os
from pathlib import Path

from envcap.core.input_path import require_file
from envcap.core.resources import city_scenes_dir
from envcap.scene.parse import read_toml


def list_scenes() -> list[tuple[str, str]]:
    """``(name, description)`` of every bundled scene (``city_scenes/*.toml``), sorted by name.

    Only the TOML text is parsed (no geometry is built), so this is fast.
    """
    out = []
    for path in sorted(city_scenes_dir().glob("*.toml")):
        data = read_toml(path)
        desc = data.get("description", "")
        out.append((path.stem, " ".join(str(desc).split())))
    return out


def scene_path(name_or_path: str | Path) -> Path:
    """Resolve a bundled scene name (``"canyon"``) or a path to a ``.toml`` file.

    Raises ``FileNotFoundError`` naming the bundled scenes when neither exists.
    """
    p = Path(name_or_path)
    looks_like_path = isinstance(name_or_path, Path) or p.suffix == ".toml" or len(p.parts) > 1
    if looks_like_path:
        return require_file(p, "scene file", f"scene file {p} not found")
    bundled = city_scenes_dir() / f"{name_or_path}.toml"
    if bundled.is_file():
        return bundled
    if os.path.lexists(p):   # not a bundled name, but something is there: a file, or say what it is
        return require_file(p, "scene file", f"scene file {p} not found")
    names = [n for n, _ in list_scenes()]
    raise FileNotFoundError(f"no bundled scene named '{name_or_path}' (bundled: {', '.join(names)}) and no such .toml file")
