"""Sample a real samplerCube / samplerCubeArray at given directions in a compute shader (llvmpipe)."""

import numpy as np

SAMPLE_CUBE = """
#version 430
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Dirs { vec4 dirs[]; };
layout(std430, binding = 1) writeonly buffer Out { vec4 result[]; };
uniform samplerCube tex;
uniform uint count;
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= count) return;
    result[i] = textureLod(tex, dirs[i].xyz, 0.0);
}
"""

SAMPLE_CUBE_ARRAY = """
#version 430
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Dirs { vec4 dirs[]; };
layout(std430, binding = 1) writeonly buffer Out { vec4 result[]; };
layout(binding = 3) uniform samplerCubeArray tex;
uniform uint count;
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= count) return;
    result[i] = textureLod(tex, dirs[i], 0.0);   // w = layer
}
"""


def sample_with_gl(ctx, src, dirs4, bind):
    """Run sampler shader ``src`` over directions ``dirs4`` (M, 4) (w = layer); ``bind(unit)`` binds the texture."""
    prog = ctx.compute_shader(src)
    inp = ctx.buffer(np.ascontiguousarray(dirs4, dtype=np.float32).tobytes())
    out = ctx.buffer(reserve=dirs4.shape[0] * 16)
    inp.bind_to_storage_buffer(0)
    out.bind_to_storage_buffer(1)
    prog["count"].value = dirs4.shape[0]
    if "samplerCubeArray" not in src:
        prog["tex"].value = 3
    bind(3)
    prog.run(group_x=(dirs4.shape[0] + 63) // 64)
    res = np.frombuffer(out.read(), dtype=np.float32).reshape(-1, 4)
    for o in (prog, inp, out):
        o.release()
    return res
