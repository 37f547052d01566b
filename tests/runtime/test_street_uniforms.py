"""The GLSL struct EnvcapStreet (shaders/runtime/envcap_runtime.glsl) and its Python mirror
envcap.runtime.street.StreetUniforms: same members in the same order, same GLSL types and array
lengths (from the compiled program), and values that arrive where the runtime reads them.
(``StreetUniforms.origin``, the street-local frame's world position, is no struct member.)"""

import re

import numpy as np

from envcap.core.resources import shader_source
from envcap.gpu.glsl_harness import run_glsl
from envcap.runtime import synthetic_street as ss
from envcap.runtime.limits import MAX_LEVELS, MAX_PROBES
from envcap.runtime.mip import lobe_table
from envcap.runtime.street import GLSL_STRUCT, GLSL_UNIFORM, StreetUniforms

DECL = shader_source("runtime/envcap_street_uniforms.glsl")
GL_TYPES = {"float": 0x1406, "vec2": 0x8B50, "vec4": 0x8B52, "int": 0x1404}   # GL_FLOAT, GL_FLOAT_VEC2/4, GL_INT
# Reads every member, so that the compiler keeps them all active.
TOUCH = """
int k = int(i);
o[i] = vec4(envcap_street.along_s[k], envcap_street.pos[k].w + envcap_street.planes[k].y,
            envcap_street.xk[k % ENVCAP_MAX_LEVELS] + envcap_street.frame.x * envcap_street.frame.y,
            float(envcap_street.count + envcap_street.along + envcap_street.nlevels));
"""


def _struct_members(src: str) -> list[tuple[str, str, str]]:
    body = re.search(r"struct\s+" + GLSL_STRUCT + r"\s*\{(.*?)\};", src, re.DOTALL).group(1)
    body = re.sub(r"//[^\n]*", "", body)
    return re.findall(r"(\w+)\s+(\w+)\s*(?:\[(\w+)\])?\s*;", body)


def test_mirror_has_the_struct_members_in_order():
    members = _struct_members(shader_source("runtime/envcap_runtime.glsl"))
    fields = StreetUniforms.glsl_fields()
    assert [m[1] for m in members] == [f.name for f in fields]
    lengths = {"ENVCAP_MAX_PROBES": MAX_PROBES, "ENVCAP_MAX_LEVELS": MAX_LEVELS, "": 1}
    assert [(t, lengths[n]) for t, _, n in members] == [(f.metadata["glsl"], f.metadata["length"]) for f in fields]


def test_compiled_struct_matches_the_mirror(gl_ctx):
    src = "#version 430\nlayout(local_size_x = 1) in;\nlayout(std430, binding = 0) writeonly buffer O { vec4 o[]; };\n" \
          + DECL + "\nvoid main() { uint i = gl_GlobalInvocationID.x;" + TOUCH + "}\n"
    prog = gl_ctx.compute_shader(src)
    try:
        got = {name[len(GLSL_UNIFORM) + 1:]: (prog[name].gl_type, prog[name].array_length)
               for name in prog if name.startswith(GLSL_UNIFORM + ".")}
    finally:
        prog.release()
    want = {f.name: (GL_TYPES[f.metadata["glsl"]], f.metadata["length"]) for f in StreetUniforms.glsl_fields()}
    assert got == want


def test_values_arrive_where_glsl_reads_them(gl_ctx):
    probes, sky, street, powers = ss.synthetic_probe_set(8, count=5, along=2, planes=(-4.0, 7.0, 0.5), start=-3.0, end=21.0)
    uni = street.uniforms(powers)
    for f in StreetUniforms.glsl_fields():
        v = getattr(uni, f.name)
        assert np.shape(v) == (() if f.metadata["length"] == 1 else (f.metadata["length"],)) + \
            {"vec4": (4,), "vec2": (2,)}.get(f.metadata["glsl"], ())
    out = run_glsl(gl_ctx, TOUCH, {"a": np.zeros(MAX_PROBES)}, {"o": 4}, uniforms=uni.values(), declarations=DECL)["o"]
    P = street.positions.shape[0]
    # independent of StreetUniforms: the street's own arrays and the lobe table
    np.testing.assert_array_equal(out[:P, 0], street.positions[:, 2].astype(np.float32))
    np.testing.assert_array_equal(out[:P, 1], (street.layers + street.planes[:, 1]).astype(np.float32))
    np.testing.assert_array_equal(out[P:, :2], 0.0)                  # padding
    xk = lobe_table(powers).astype(np.float32)
    np.testing.assert_array_equal(out[: len(xk), 2], xk)
    assert np.all(out[:, 3] == P + 2 + len(powers))
