"""Run GLSL functions over numpy arrays on the GPU driver at hand (Mesa llvmpipe here).

:func:`run_glsl` wraps a GLSL ``body`` in a compute shader: every input array of shape
``(n, k)`` (``k`` <= 4) is a read-only SSBO seen in GLSL as ``vec4 NAME[]`` (unused components
zero), every output a write-only ``vec4 NAME[]``; the body runs once per index ``i`` (a
``uint``) and writes ``NAME[i]``.  Textures: a probe cube-map array
(:class:`envcap.gpu.cube_array.CubeArrayTexture`) bound to ``samplerCubeArray probes`` at unit 3
and a sky cube (:func:`envcap.gpu.cube_array.cube_texture`) bound to ``samplerCube sky`` at
unit 4, both declared by the harness when given.  Uniforms are set by name with
:func:`envcap.gpu.uniforms.set_uniforms`: a name that the compiled source does not declare is an
error (one it declares but does not use is skipped).

Example::

    out = run_glsl(ctx, "o[i] = vec4(envcap_exit_distance(x[i].xyz, d[i].xyz, planes, 2));",
                   inputs={"x": xs, "d": ds}, outputs={"o": 1},
                   uniforms={"planes": (-5.0, 5.0, 0.0)}, declarations="uniform vec3 planes;")
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import moderngl
import numpy as np
from numpy.typing import NDArray

from envcap.core.resources import shader_source
from envcap.gpu.cube_array import CubeArrayTexture
from envcap.gpu.uniforms import set_uniforms

LOCAL_SIZE = 64
MAX_GROUPS = 65535
PROBES_UNIT = 3
SKY_UNIT = 4

_TEMPLATE = """#version 430
{defines}
layout(local_size_x = {local}) in;
{includes}
{buffers}
{samplers}
uniform uint envcap_base;
uniform uint envcap_count;
{declarations}
void main() {{
    uint i = gl_GlobalInvocationID.x + envcap_base;
    if (gl_GlobalInvocationID.x >= envcap_count) return;
{body}
}}
"""


def as_columns(name: str, a: Any) -> NDArray[np.float32]:
    """Input ``name`` as the harness stores it: ``(n,)`` or ``(n, k)`` (k <= 4) -> float32 ``(n, 4)``,
    zero-padded (one ``vec4`` per index in a std430 buffer)."""
    arr = np.asarray(a, dtype=np.float32)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or not 1 <= arr.shape[1] <= 4:
        raise ValueError(f"input '{name}' must have shape (n,) or (n, k) with k <= 4, got {arr.shape}")
    out = np.zeros((arr.shape[0], 4), dtype=np.float32)
    out[:, : arr.shape[1]] = arr
    return out


def build_source(body: str, inputs: Sequence[str], outputs: Sequence[str], *, includes: Sequence[str] = ("runtime/envcap_runtime.glsl",),
                 declarations: str = "", defines: Mapping[str, object] | None = None, probes: bool = False,
                 sky: bool = False) -> str:
    """The compute shader :func:`run_glsl` compiles (returned for inspection)."""
    inc = "".join(shader_source(name) + "\n" for name in includes)
    bufs = []
    for b, name in enumerate(list(inputs) + list(outputs)):
        ro = "readonly" if b < len(inputs) else "writeonly"
        bufs.append(f"layout(std430, binding = {b}) {ro} buffer Buf_{name} {{ vec4 {name}[]; }};")
    samp = []
    if probes:
        samp.append(f"layout(binding = {PROBES_UNIT}) uniform samplerCubeArray probes;")
    if sky:
        samp.append(f"layout(binding = {SKY_UNIT}) uniform samplerCube sky;")
    defs = "".join(f"#define {k} {v}\n" for k, v in (defines or {}).items())
    return _TEMPLATE.format(defines=defs, local=LOCAL_SIZE, includes=inc, buffers="\n".join(bufs),
                            samplers="\n".join(samp), declarations=declarations,
                            body="\n".join("    " + ln for ln in body.splitlines()))


def run_glsl(ctx: moderngl.Context, body: str, inputs: Mapping[str, Any], outputs: Mapping[str, int], *,
             uniforms: Mapping[str, Any] | None = None, declarations: str = "",
             includes: Sequence[str] = ("runtime/envcap_runtime.glsl",), defines: Mapping[str, object] | None = None,
             probes: CubeArrayTexture | None = None,
             sky: moderngl.TextureCube | None = None) -> dict[str, NDArray[np.float32]]:
    """Run ``body`` for every index of the inputs and return the outputs as float32 arrays.

    ``inputs``: name -> array ``(n,)`` or ``(n, k)`` (k <= 4), all of the same ``n`` >= 1.
    ``outputs``: name -> number of components to return (1..4); each comes back as ``(n, k)``.
    ``probes``: a :class:`envcap.gpu.cube_array.CubeArrayTexture` (declared ``probes``); ``sky``: a moderngl
    ``TextureCube`` (declared ``sky``).  Work larger than one dispatch is split.
    """
    if not inputs:
        raise ValueError("run_glsl needs at least one input array")
    cols = {k: as_columns(k, v) for k, v in inputs.items()}
    ns = {a.shape[0] for a in cols.values()}
    if len(ns) != 1:
        raise ValueError(f"inputs must all have the same length, got {sorted(ns)}")
    n = ns.pop()
    if n < 1:
        raise ValueError("inputs must not be empty")
    for k, c in outputs.items():
        if not 1 <= int(c) <= 4:
            raise ValueError(f"output '{k}' must have 1..4 components, got {c}")
    src = build_source(body, list(cols), list(outputs), includes=includes, declarations=declarations,
                       defines=defines, probes=probes is not None, sky=sky is not None)
    prog = ctx.compute_shader(src)
    bufs = []
    try:
        for b, a in enumerate(cols.values()):
            buf = ctx.buffer(a.tobytes())
            buf.bind_to_storage_buffer(b)
            bufs.append(buf)
        outs = []
        for b in range(len(outputs)):
            buf = ctx.buffer(reserve=n * 16)
            buf.bind_to_storage_buffer(len(cols) + b)
            outs.append(buf)
        bufs += outs
        set_uniforms(prog, uniforms or {}, sources=(src,))
        if probes is not None:
            probes.use(PROBES_UNIT)
        if sky is not None:
            sky.use(SKY_UNIT)
        step = LOCAL_SIZE * MAX_GROUPS
        for base in range(0, n, step):
            cnt = min(step, n - base)
            set_uniforms(prog, {"envcap_base": base, "envcap_count": cnt})
            prog.run(group_x=(cnt + LOCAL_SIZE - 1) // LOCAL_SIZE)
        result = {}
        for (name, c), buf in zip(outputs.items(), outs):
            result[name] = np.frombuffer(buf.read(), dtype=np.float32).reshape(n, 4)[:, : int(c)].copy()
        return result
    finally:
        for b in bufs:
            b.release()
        prog.release()
