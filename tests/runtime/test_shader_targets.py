"""envcap.runtime.shader_targets / shader_matrix: the runtime library compiles for GLSL 4.50 core,
GLSL ES 3.20, WebGL2 (GLSL ES 3.00) and Vulkan (SPIR-V), and translates to HLSL and MSL, with
the reference tools (glslangValidator, spirv-cross); docs/engines.md shows that matrix."""

import re
from dataclasses import replace
from pathlib import Path

import pytest

from envcap.core.resources import shader_path, shaders_dir
from envcap.runtime.shader_matrix import compile_cell, compile_matrix, matrix_markdown
from envcap.runtime.shader_targets import RUNTIME_UNITS, TARGETS, prologue, unit_source

ENGINES_DOC = Path(__file__).resolve().parents[2] / "docs" / "engines.md"
_FUNCTION = re.compile(r"^[a-z]\w*\s+(envcap_\w+)\s*\(", re.MULTILINE)


def test_compile_matrix_every_target_every_unit_and_the_docs_table(tmp_path):
    cells = compile_matrix(tmp_path)
    assert len(cells) == len(RUNTIME_UNITS) * (len(TARGETS) + 2)  # + HLSL and MSL of the Vulkan SPIR-V
    failed = [f"{c.target} x {c.unit}:\n{c.log[-1500:]}" for c in cells if not c.ok]
    assert not failed, "\n\n".join(failed)
    assert (tmp_path / "vulkan_envcap_runtime.hlsl").read_text().count("TextureCubeArray") >= 1
    assert "texturecube_array" in (tmp_path / "vulkan_envcap_runtime.msl").read_text()
    assert matrix_markdown(cells) in ENGINES_DOC.read_text(), (
        "docs/engines.md: the compile matrix is out of date; paste:\n" + matrix_markdown(cells))


def _definitions(src: str) -> dict[str, str]:
    """Function name -> the text up to the next definition (its body and comments); the bodies of
    all overloads of a name (GLSL overloads: the vec3-planes forms call the vec4 ones)."""
    ms = list(_FUNCTION.finditer(src))
    out: dict[str, str] = {}
    for i, m in enumerate(ms):
        out[m.group(1)] = out.get(m.group(1), "") + src[m.end(): ms[i + 1].start() if i + 1 < len(ms) else len(src)]
    return out


@pytest.mark.parametrize("unit", sorted(RUNTIME_UNITS))
def test_each_unit_reaches_every_function_of_its_file(unit):
    # SPIR-V keeps only functions reachable from main: a function the unit never reaches would
    # be translated by no cell of the matrix.
    defs = _definitions(unit_source("gl450", unit))
    seen, todo = set(), [RUNTIME_UNITS[unit].body]
    while todo:
        for name in re.findall(r"\b(envcap_\w+)\s*\(", todo.pop()):
            if name in defs and name not in seen:
                seen.add(name)
                todo.append(defs[name])
    own = set(_FUNCTION.findall(shader_path(f"runtime/{unit}.glsl").read_text()))
    assert own <= seen, f"{unit}: main never reaches {sorted(own - seen)}"


def test_every_runtime_file_is_in_the_matrix():
    files = {p.stem for p in (shaders_dir() / "runtime").glob("*.glsl")}
    assert files == set(RUNTIME_UNITS), "add a RuntimeUnit for each shaders/runtime file (envcap/runtime/shader_targets.py)"


def test_without_the_prologue_the_es_targets_fail(tmp_path):
    # Controls: the validator does check the ES rules, and the prologue is what satisfies them.
    bare_webgl = replace(TARGETS["webgl2"], name="webgl2_cube", defines=TARGETS["webgl2"].defines[:3], includes=())
    [cell] = compile_cell(bare_webgl, "envcap_runtime", tmp_path)
    assert not cell.ok and "samplerCubeArray" in cell.log
    bare_es = replace(TARGETS["es320"], name="es320_noprec", es=False)
    [cell] = compile_cell(bare_es, "envcap_lobes", tmp_path)
    assert not cell.ok and "precision" in cell.log.lower()


def test_prologues():
    assert prologue("gl450").startswith("#version 450 core\n")
    assert "precision highp samplerCube;" in prologue("es320") and "precision highp samplerCubeArray;" in prologue("es320")
    assert "samplerCubeArray" not in prologue("webgl2")
    src = unit_source("webgl2", "envcap_runtime")
    assert src.startswith("#version 300 es\n") and "binding" not in src
    assert "layout(std430, set = 0, binding = 8) readonly buffer" in unit_source("vulkan", "envcap_street_uniforms")
    kept = unit_source("vulkan", "envcap_runtime", expand=False)
    assert '#include "runtime/envcap_runtime.glsl"' in kept and "GL_GOOGLE_include_directive" in kept
