"""The compile matrix of the runtime library: every target x every library file, compiled by the
reference tools.

Each cell compiles :func:`envcap.runtime.shader_targets.unit_source` (the unit of one
``shaders/runtime/`` file, wrapped for one target) as a fragment shader with
``glslangValidator`` (Debian ``glslang-tools``): GLSL 4.50 core, GLSL ES 3.20 and GLSL ES 3.00
are validated for their API; the Vulkan unit is compiled to SPIR-V (``-V``), which
``spirv-cross`` (Debian ``spirv-cross``) then translates to HLSL (shader model 5.0) and MSL.
:func:`matrix_markdown` is the table in ``docs/engines.md`` (a test keeps the two equal).
"""

from __future__ import annotations

import shutil
import subprocess
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from envcap.runtime.shader_targets import RUNTIME_UNITS, TARGETS, ShaderTarget, unit_source

TOOLS = {"glslangValidator": "glslang-tools", "spirv-cross": "spirv-cross"}
"""Tool -> the Debian package that has it."""

TRANSLATIONS = {"hlsl": ("--hlsl", "--shader-model", "50"), "msl": ("--msl",)}
"""spirv-cross languages and their options."""


def tool(name: str) -> str:
    """Path of compiler ``name`` (a key of :data:`TOOLS`); ``FileNotFoundError`` naming the
    package to install when it is missing."""
    exe = shutil.which(name)
    if exe is None:
        raise FileNotFoundError(f"{name} not found: install the Debian/Ubuntu package {TOOLS[name]} (.ci/run does)")
    return exe


@dataclass(frozen=True)
class Cell:
    """One compile: ``target`` x ``unit`` (a language: ``target`` is ``"hlsl"`` or ``"msl"``
    for the spirv-cross translations of the Vulkan SPIR-V).  ``ok``; ``log``: the tool's output
    when it failed."""

    target: str
    unit: str
    ok: bool
    log: str = ""


def _run(args: list[str]) -> tuple[bool, str]:
    out = subprocess.run(args, capture_output=True, text=True, timeout=60)
    return out.returncode == 0, (out.stdout + out.stderr).strip()


def compile_cell(target: str | ShaderTarget, unit: str, workdir: Path) -> list[Cell]:
    """Compile ``unit`` for ``target`` (a :data:`TARGETS` name or a :class:`ShaderTarget`) under
    ``workdir`` (files ``TARGET_UNIT.frag`` / ``.spv``); for a SPIR-V target also translate it
    (one more :class:`Cell` per :data:`TRANSLATIONS`)."""
    t = TARGETS[target] if isinstance(target, str) else target
    src = Path(workdir) / f"{t.name}_{unit}.frag"
    src.write_text(unit_source(t, unit))
    spv = src.with_suffix(".spv")
    args = [tool("glslangValidator"), "-S", "frag"]
    if t.spirv:
        args += ["-V", "-o", str(spv)]
    ok, log = _run(args + [str(src)])
    cells = [Cell(t.name, unit, ok, "" if ok else log)]
    if t.spirv:
        for lang, opts in TRANSLATIONS.items():
            if not ok:
                cells.append(Cell(lang, unit, False, "no SPIR-V"))
                continue
            lok, llog = _run([tool("spirv-cross"), *opts, str(spv), "--output", str(src.with_suffix("." + lang))])
            cells.append(Cell(lang, unit, lok, "" if lok else llog))
    return cells


def compile_matrix(workdir: Path, targets: list[str] | None = None, units: list[str] | None = None) -> list[Cell]:
    """Every cell of ``targets`` (default all, :data:`TARGETS` order) x ``units`` (default all)."""
    Path(workdir).mkdir(parents=True, exist_ok=True)
    jobs = [(t, u) for t in (targets or list(TARGETS)) for u in (units or list(RUNTIME_UNITS))]
    with ThreadPoolExecutor(max_workers=4) as pool:  # the tools are separate processes
        done = list(pool.map(lambda tu: compile_cell(tu[0], tu[1], Path(workdir)), jobs))
    return [c for cells in done for c in cells]


def columns() -> list[tuple[str, str]]:
    """(key, heading) of the matrix columns: the targets, with HLSL and MSL after Vulkan."""
    cols = []
    for t in TARGETS.values():
        cols.append((t.name, t.title))
        if t.spirv:
            cols += [("hlsl", "HLSL SM 5.0 (spirv-cross)"), ("msl", "MSL (spirv-cross)")]
    return cols


def matrix_markdown(cells: list[Cell]) -> str:
    """The matrix as a Markdown table: one row per unit (``shaders/runtime/NAME.glsl``), one
    column per target, ``ok`` or ``FAIL``."""
    cols = columns()
    by = {(c.target, c.unit): c.ok for c in cells}
    units = list(dict.fromkeys(c.unit for c in cells))
    lines = ["| unit | " + " | ".join(h for _, h in cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for u in units:
        marks = ["ok" if by.get((k, u)) else ("FAIL" if (k, u) in by else "-") for k, _ in cols]
        lines.append(f"| `{u}` | " + " | ".join(marks) + " |")
    return "\n".join(lines) + "\n"
