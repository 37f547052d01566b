"""Export targets by name: what ``envcap export TARGET`` can write.

A target is a name, a one-line summary, the ``kind`` its output directory's marker carries and a
function ``write(source, out_dir, report) -> str`` that fills ``out_dir`` (an empty temporary
directory that becomes the output only when ``write`` returns: :func:`envcap.outputs.atomic_output_dir`)
from the probe set the user named ``source`` (as typed) and an optional evaluation ``report``
directory, and returns what to do next (one line or a few, printed by the command; ``{out}`` in
it becomes the output's final path).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from envcap.export import web


@dataclass(frozen=True)
class ExportTarget:
    """One export target (module docstring)."""

    name: str
    summary: str
    kind: str
    write: Callable[[Path, Path, "Path | None"], str]


BUILTIN_TARGETS: tuple[ExportTarget, ...] = (
    ExportTarget("web", web.SUMMARY, web.KIND, web.write_web_site),
)
"""The targets envcap ships, in the order ``envcap export --help`` lists them."""

_TARGETS: dict[str, ExportTarget] = {}


def register_target(target: ExportTarget) -> ExportTarget:
    """Add ``target`` (``ValueError`` if its name is taken); returns it."""
    if not target.name or not target.name.replace("_", "").replace("-", "").isalnum():
        raise ValueError(f"export target name must be letters, digits, '-' or '_', got {target.name!r}")
    if target.name in _TARGETS:
        raise ValueError(f"export target {target.name!r} is already registered")
    _TARGETS[target.name] = target
    return target


def unregister_target(name: str) -> None:
    """Remove the target ``name`` (no error if absent)."""
    _TARGETS.pop(name, None)


def get_target(name: str) -> ExportTarget:
    """The target ``name`` (``ValueError`` naming the known ones)."""
    if name not in _TARGETS:
        raise ValueError(f"unknown export target {name!r}; known: {', '.join(target_names())}")
    return _TARGETS[name]


def target_names() -> list[str]:
    """Registered target names, in registration order."""
    return list(_TARGETS)


for _t in BUILTIN_TARGETS:
    register_target(_t)
