"""shaders/crowd/: the crowd's vertex and fragment stages compile for desktop GL 4.50 and for
WebGL2 (GLSL ES 3.00) with the runtime's per-target prologue, checked by glslangValidator (the
reference compiler), for every lookup method the crowd runs; and for GL 4.50 with the test targets."""

import subprocess

import pytest

from envcap.crowd.inputs import CROWD_METHODS, crowd_function
from envcap.crowd.renderer import crowd_sources
from envcap.runtime import methods
from envcap.runtime.shader_matrix import tool


def _validate(tmp_path, name, stage, source):
    path = tmp_path / f"{name}.{stage}"
    path.write_text(source)
    out = subprocess.run([tool("glslangValidator"), "-S", stage, str(path)], capture_output=True, text=True, timeout=120)
    return out.returncode, out.stdout + out.stderr


@pytest.mark.parametrize("target", ["gl450", "webgl2"])
def test_crowd_stages_compile_for_desktop_and_webgl2(tmp_path, target):
    for name in ("fitted_planes_oblique", "blend"):
        vert, frag = crowd_sources(methods.get(name).glsl, target)
        for stage, src in (("vert", vert), ("frag", frag)):
            rc, log = _validate(tmp_path, f"{target}_{name}", stage, src)
            assert rc == 0, f"{target} {name} {stage}:\n{log[-2000:]}"
    if target == "webgl2":
        assert "#define ENVCAP_PROBES_SAMPLER sampler2DArray" in frag    # the probes as face atlases


def test_every_crowd_method_and_the_test_targets_compile_for_gl450(tmp_path):
    for name in CROWD_METHODS:
        _, frag = crowd_sources(crowd_function(methods.get(name)), "gl450", targets=name in ("fitted_planes_oblique",
                                                                                            "depth_refine"))
        rc, log = _validate(tmp_path, name, "frag", frag)
        assert rc == 0, f"{name}:\n{log[-2000:]}"


def test_a_shader_error_is_caught(tmp_path):
    vert, _ = crowd_sources("envcap_sample_oblique", "webgl2")
    rc, _ = _validate(tmp_path, "broken", "vert", vert.replace("texelFetch(", "texelFetchX("))
    assert rc != 0
