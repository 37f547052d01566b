"""envcap.core.resources: shader names relative to shaders/, include guards that make a standard
#include (glslang's GL_GOOGLE_include_directive with -I shaders) give the same program as ours."""

import re
import shutil
import subprocess

import numpy as np
import pytest

from envcap.core.resources import expand_includes, shader_path, shader_source, shaders_dir
from envcap.gpu.glsl_harness import run_glsl

STAGES = {"capture", "prefilter", "runtime", "preview", "crowd"}


def _library_files():
    """The GLSL files meant to be included: those without a #version line."""
    return [p for p in sorted(shaders_dir().rglob("*.glsl"))
            if not re.search(r"^\s*#version", p.read_text(), re.MULTILINE)]


def _glslang() -> str:
    exe = shutil.which("glslangValidator")
    if exe is None:
        pytest.fail("glslangValidator not found: install Debian/Ubuntu package glslang-tools (.ci/run does)")
    return exe


# A unit in the standard form: the library included twice (directly and through the runtime).
UNIT = """#version 430
#extension GL_GOOGLE_include_directive : require
#include "runtime/envcap_street.glsl"
#include "runtime/envcap_runtime.glsl"
#include "runtime/envcap_runtime.glsl"
#include "runtime/envcap_lobes.glsl"
#include "runtime/envcap_street_uniforms.glsl"
#include "runtime/envcap_street_uniforms.glsl"
#include "capture/shadow_lookup.glsl"
#include "capture/shadow_lookup.glsl"
layout(local_size_x = 1) in;
layout(std430, binding = 0) writeonly buffer Out { vec4 o[]; };
void main() {
    o[0] = vec4(envcap_clamp_level(2.5, envcap_street.nlevels), ENVCAP_PI, float(envcap_street.count), sun_visibility(vec3(0.0), vec3(0.0, 1.0, 0.0), 1.0));
}
"""


def _validate(unit_text: str, include_dir, tmp_path):
    """Compile ``unit_text`` to SPIR-V for OpenGL (-G; --aml gives the default-block uniforms
    locations, which SPIR-V needs and GL 4.3 assigns itself) with ``include_dir`` on the path."""
    unit = tmp_path / "unit.comp"
    unit.write_text(unit_text)
    return subprocess.run([_glslang(), "-G", "--aml", f"-I{include_dir}", "-o", str(tmp_path / "unit.spv"), str(unit)],
                          capture_output=True, text=True, timeout=60)


def test_shader_tree_has_one_folder_per_stage():
    folders = {p.parent.relative_to(shaders_dir()).as_posix() for p in shaders_dir().rglob("*.glsl")}
    assert folders == STAGES


def test_every_library_file_has_an_include_guard():
    libs = _library_files()
    assert {p.name for p in libs} >= {"envcap_runtime.glsl", "envcap_street.glsl", "envcap_lobes.glsl",
                                      "envcap_street_uniforms.glsl", "shadow_lookup.glsl"}
    macros = set()
    for p in libs:
        lines = [ln.strip() for ln in p.read_text().splitlines() if ln.strip()]
        m = re.fullmatch(r"#ifndef (ENVCAP_\w+_GLSL)", lines[0])
        assert m, f"{p}: must start with #ifndef ENVCAP_..._GLSL"
        assert lines[1] == f"#define {m.group(1)}", p
        assert lines[-1].startswith("#endif"), p
        macros.add(m.group(1))
    assert len(macros) == len(libs), "include guard macros must be unique"


def test_standard_include_of_the_library_twice_compiles_with_glslang(tmp_path):
    out = _validate(UNIT, shaders_dir(), tmp_path)
    assert out.returncode == 0, out.stdout + out.stderr
    assert (tmp_path / "unit.spv").stat().st_size > 0


def test_glslang_rejects_the_same_unit_without_guards(tmp_path):
    # Control: the guards are what makes the double include legal for a standard preprocessor.
    bare = tmp_path / "shaders"
    shutil.copytree(shaders_dir(), bare)
    for p in bare.rglob("*.glsl"):
        p.write_text(re.sub(r"^#(ifndef|define|endif)\s+(//\s*)?ENVCAP_\w+_GLSL\n", "", p.read_text(), flags=re.MULTILINE))
    out = _validate(UNIT, bare, tmp_path)
    assert out.returncode != 0 and "redefinition" in (out.stdout + out.stderr).lower(), out.stdout


def test_our_expansion_of_the_standard_unit_runs_on_gl(gl_ctx):
    src = expand_includes(UNIT)
    assert "GL_GOOGLE_include_directive" not in src
    assert src.count("float envcap_clamp_level(") == 1
    prog = gl_ctx.compute_shader(src)
    prog.release()
    # and the library included twice through the harness (one shader_source per include) runs
    got = run_glsl(gl_ctx, "o[i] = vec4(envcap_clamp_level(a[i].x, 4));", {"a": np.array([-1.0, 1.5, 9.0])}, {"o": 1},
                   includes=("runtime/envcap_street.glsl", "runtime/envcap_runtime.glsl"))
    np.testing.assert_array_equal(got["o"][:, 0], [0.0, 1.5, 3.0])


def test_shader_names_are_paths_under_shaders():
    assert shader_path("runtime/envcap_runtime.glsl") == shaders_dir() / "runtime" / "envcap_runtime.glsl"
    assert shader_source("capture/capture_frag.glsl", {"SUN_LIGHT": 1}).startswith("#version 430\n#define SUN_LIGHT 1\n")
    for bad in ("../README.md", "/runtime/envcap_runtime.glsl", "runtime//envcap_runtime.glsl", ""):
        with pytest.raises(ValueError):
            shader_path(bad)
    with pytest.raises(FileNotFoundError, match="envcap_runtime.glsl"):
        shader_path("envcap_runtime.glsl")  # the old flat name
    with pytest.raises(FileNotFoundError):
        expand_includes('#include "runtime/no_such.glsl"\n')
