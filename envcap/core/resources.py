"""Locate envcap's data files (GLSL shaders, bundled city scenes) in a checkout or an install.

In the repository they live at the top level (``shaders/``, ``city_scenes/``); an installed
envcap carries them as ``envcap/shaders`` and ``envcap/city_scenes`` (see ``pyproject.toml``).
"""

from __future__ import annotations

import re
from pathlib import Path

_PKG = Path(__file__).resolve().parents[1]  # the envcap package directory


def _data_dir(name: str) -> Path:
    for cand in (_PKG / name, _PKG.parent / name):
        if cand.is_dir():
            return cand
    raise FileNotFoundError(f"envcap data directory '{name}' not found next to {_PKG}; is envcap installed correctly?")


def shaders_dir() -> Path:
    """Directory holding the GLSL sources."""
    return _data_dir("shaders")


def city_scenes_dir() -> Path:
    """Directory holding the bundled city scenes (``*.toml``)."""
    return _data_dir("city_scenes")


_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.MULTILINE)


def expand_includes(source: str, _seen: set[str] | None = None) -> str:
    """Resolve ``#include "file"`` lines of GLSL ``source`` against ``shaders/``, recursively.

    Each file is included at most once (later includes of it expand to nothing)."""
    seen = set() if _seen is None else _seen

    def load(match: re.Match[str]) -> str:
        fname = match.group(1)
        if fname in seen:
            return ""
        seen.add(fname)
        path = shaders_dir() / fname
        if not path.is_file():
            raise FileNotFoundError(f"shader '{fname}' not found in {shaders_dir()}")
        return expand_includes(path.read_text(), seen)

    return _INCLUDE.sub(load, source)


def shader_source(name: str, defines: dict[str, object] | None = None) -> str:
    """Read GLSL file ``name`` from ``shaders/``, resolving ``#include "file"`` lines.

    Each file is included at most once.  ``defines`` become ``#define KEY VALUE`` lines inserted
    right after the ``#version`` line (the file must start with one if defines are given).
    """
    src = expand_includes(f'#include "{name}"\n')
    if defines:
        lines = src.splitlines(keepends=True)
        if not lines or not lines[0].lstrip().startswith("#version"):
            raise ValueError(f"shader '{name}' must start with #version to take defines")
        extra = "".join(f"#define {k} {v}\n" for k, v in defines.items())
        src = lines[0] + extra + "".join(lines[1:])
    return src
