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
    """Directory holding the GLSL sources, one subfolder per stage: ``capture/``, ``prefilter/``,
    ``runtime/`` (the sampling library) and ``preview/``."""
    return _data_dir("shaders")


def city_scenes_dir() -> Path:
    """Directory holding the bundled city scenes (``*.toml``)."""
    return _data_dir("city_scenes")


_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.MULTILINE)
# The directive that lets glslang accept #include; expand_includes resolves the includes itself,
# and GL drivers do not know this extension, so its line is dropped.
_INCLUDE_EXTENSION = re.compile(r'^\s*#extension\s+GL_GOOGLE_include_directive\s*:\s*\w+\s*\n?', re.MULTILINE)


def shader_path(name: str) -> Path:
    """The file of GLSL shader ``name``, a ``/``-separated path relative to ``shaders/``.

    Names are those a standard include would use with ``shaders/`` on the include path
    (``glslangValidator -I shaders``, or ``GL_ARB_shading_language_include`` named strings under
    ``/``): e.g. ``"runtime/envcap_runtime.glsl"``, also inside ``#include`` lines of files in
    subfolders.  Absolute names and ``..`` are refused."""
    parts = name.split("/")
    if not name or name.startswith("/") or any(p in ("", ".", "..") for p in parts):
        raise ValueError(f"shader name '{name}' must be a relative path under shaders/ without '.' or '..'")
    path = shaders_dir().joinpath(*parts)
    if not path.is_file():
        raise FileNotFoundError(f"shader '{name}' not found in {shaders_dir()}")
    return path


def expand_includes(source: str, _seen: set[str] | None = None) -> str:
    """Resolve ``#include "name"`` lines of GLSL ``source`` recursively (names: :func:`shader_path`).

    Each file is included at most once (later includes of it expand to nothing); the library
    files also carry include guards, so a standard ``#include`` gives the same program.  A line
    ``#extension GL_GOOGLE_include_directive : require`` (which glslang needs for ``#include``) is
    dropped, so one source compiles both ways."""
    seen = set() if _seen is None else _seen

    def load(match: re.Match[str]) -> str:
        name = match.group(1)
        if name in seen:
            return ""
        seen.add(name)
        return expand_includes(shader_path(name).read_text(), seen)

    return _INCLUDE.sub(load, _INCLUDE_EXTENSION.sub("", source))


def shader_source(name: str, defines: dict[str, object] | None = None) -> str:
    """Read GLSL file ``name`` (e.g. ``"capture/capture_frag.glsl"``, see :func:`shader_path`),
    resolving ``#include "name"`` lines.

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
