"""envcap.gpu.uniforms: the strict uniform setter, checked by reading the values back in GLSL."""

import numpy as np
import pytest

from envcap.gpu.uniforms import declared_uniforms, set_uniforms

SRC = """#version 430
layout(local_size_x = 1) in;
layout(std430, binding = 0) writeonly buffer Out { float o[]; };
uniform mat4 m;            // read back as m * (1, 2, 3, 4)
uniform vec3 a[3];
uniform uint n;
uniform int k;
uniform float unused;      // declared, optimized away
void main() {
    vec4 r = m * vec4(1.0, 2.0, 3.0, 4.0);
    for (int j = 0; j < 4; ++j) o[j] = r[j];
    for (int j = 0; j < 3; ++j) { o[4 + 3 * j] = a[j].x; o[5 + 3 * j] = a[j].y; o[6 + 3 * j] = a[j].z; }
    o[13] = float(n);
    o[14] = float(k);
}
"""


@pytest.fixture
def prog(gl_ctx):
    p = gl_ctx.compute_shader(SRC)
    yield p
    p.release()


def _run(gl_ctx, prog):
    buf = gl_ctx.buffer(reserve=15 * 4)
    buf.bind_to_storage_buffer(0)
    prog.run(1)
    out = np.frombuffer(buf.read(), np.float32).copy()
    buf.release()
    return out


def test_values_arrive_as_numpy_means_them(gl_ctx, prog):
    m = np.arange(16, dtype=np.float64).reshape(4, 4) - 5.0   # row-major numpy matrix
    set_uniforms(prog, {"m": m.T, "a": [[1, 2, 3], [4, 5, 6]], "n": 7, "k": -3}, sources=[SRC])
    out = _run(gl_ctx, prog)
    np.testing.assert_array_equal(out[:4], m @ [1.0, 2.0, 3.0, 4.0])   # m.T passed = column-major
    np.testing.assert_array_equal(out[4:13], [1, 2, 3, 4, 5, 6, 0, 0, 0])  # the rest of the array is 0
    assert out[13] == 7 and out[14] == -3


def test_unknown_names_are_errors_declared_unused_ones_are_skipped(prog):
    with pytest.raises(KeyError, match="'nn' is not in the program"):
        set_uniforms(prog, {"nn": 1})
    with pytest.raises(KeyError, match="unused"):
        set_uniforms(prog, {"unused": 1.0})          # without the source it is unknown
    set_uniforms(prog, {"unused": 1.0}, sources=[SRC])
    with pytest.raises(KeyError, match="not in the program"):
        set_uniforms(prog, {"nn": 1}, sources=[SRC])
    with pytest.raises(KeyError, match="StorageBlock"):
        set_uniforms(prog, {"Out": 1})


@pytest.mark.parametrize("name, value, words", [
    ("n", 2.5, "non-integral"),
    ("k", np.nan, "non-integral"),
    ("m", np.zeros((3, 3)), "holds 16"),
    ("a", np.zeros(4), "array of 3 x 3"),
    ("a", np.zeros(12), "array of 3 x 3"),
    ("k", "3", "expected numbers"),
])
def test_bad_values_are_errors(prog, name, value, words):
    with pytest.raises(ValueError, match=words):
        set_uniforms(prog, {name: value})


def test_declared_uniforms_parses_declarations_not_comments():
    src = """layout(binding = 3) uniform samplerCubeArray probes;
    uniform highp vec3 a, b[4];   // uniform float c;
    /* uniform float d; */ uniform Block { float e; } blk;
    uniform float f[ENVCAP_MAX];"""
    assert declared_uniforms(src) == {"probes", "a", "b", "f"}
