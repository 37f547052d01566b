"""Loading a scene: a bundled name or a ``.toml`` path -> parse (:mod:`envcap.scene.parse`) ->
build (:mod:`envcap.scene.build`) -> :class:`~envcap.scene.model.Scene`."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from envcap.scene.build import build_scene
from envcap.scene.bundled import scene_path
from envcap.scene.model import Scene
from envcap.scene.parse import parse_scene, read_toml
from envcap.scene.spec import SceneSpec


def check_scene(name_or_path: str | Path) -> SceneSpec:
    """Read and check a scene (a bundled name or a ``.toml`` path) without building it: the TOML,
    every key and its range, the sky (its file read), as :func:`load_scene` does before building.
    Same errors as :func:`load_scene`; meshes are read only when the scene is built."""
    path = scene_path(name_or_path)
    data = read_toml(path)
    try:
        return parse_scene(data, base_dir=path.parent.resolve(), default_name=path.stem, source=str(path))
    except FileNotFoundError as exc:
        raise FileNotFoundError(f"{path}: {exc}") from None
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def load_scene(name_or_path: str | Path) -> Scene:
    """Load a bundled scene by name (``"canyon"``) or a scene ``.toml`` file by path.

    Errors in the file raise ``ValueError`` (or ``FileNotFoundError`` for missing files) with a
    message that starts with the file name and names the offending key.
    """
    path = scene_path(name_or_path)
    data = read_toml(path)
    try:
        return scene_from_dict(data, base_dir=path.parent.resolve(), default_name=path.stem, source=str(path))
    except FileNotFoundError as exc:
        raise FileNotFoundError(f"{path}: {exc}") from None
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def scene_from_dict(
    data: dict[str, Any],
    base_dir: Path | None = None,
    default_name: str = "scene",
    source: str = "",
) -> Scene:
    """Build a :class:`Scene` from a parsed scene table (the TOML document as a dict).

    ``base_dir`` resolves relative file names (``[mesh] file``, ``[sky] file``).
    """
    return build_scene(parse_scene(data, base_dir=base_dir, default_name=default_name, source=source))
