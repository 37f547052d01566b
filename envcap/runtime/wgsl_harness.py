"""Run runtime GLSL, translated to WGSL, over numpy arrays on WebGPU (``wgpu``; Mesa's lavapipe here).

The WGSL twin of :mod:`envcap.gpu.glsl_harness`: :func:`run_wgsl` wraps a GLSL ``body`` in a
Vulkan-GLSL compute shader (the :data:`envcap.runtime.wgsl.WGSL_TARGET` prologue, then the
runtime includes), translates it with :func:`envcap.runtime.wgsl.translate` (Slang) and runs the
WGSL with ``wgpu``.  Every input array ``(n, k)`` (``k`` <= 4) is a read-only storage buffer seen
in GLSL as ``vec4 NAME[]``, every output a ``vec4 NAME[]``; the body runs once per index ``i``
(a ``uint``).  Resources, by the runtime's texture units (``ENVCAP_BINDING(n)``):

* ``probes``: mip levels ``(L, 6, N_k, N_k, 4)`` -> a ``texture_cube_array`` (``samplerCubeArray
  probes``, unit 3, declared by the harness), trilinear, clamp to edge (Vulkan / WebGPU cube
  filtering is seamless);
* ``sky``: levels ``(6, N_k, N_k, 4)`` -> a ``texture_cube`` (``samplerCube sky``, unit 4);
* ``textures``: unit -> a 2D array ``(H, W)`` of ``uint16`` (``r16uint``, ``usampler2D``) or
  ``(H, W, 4)`` float (``rgba32float``, ``sampler2D``), declared by the caller;
* ``blocks``: storage binding -> bytes (:func:`std430`), e.g. the street at 8 (``ENVCAP_STREET_BLOCK``)
  and the spheres at 9, declared by the library or the caller.

Only the bindings the translated WGSL declares are bound (WebGPU's automatic layout).
"""

from __future__ import annotations

import re
from typing import Any, Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from envcap.core.resources import expand_includes
from envcap.gpu.glsl_harness import as_columns
from envcap.runtime.wgsl import WGSL_TARGET, texture_binding, translate
from envcap.runtime.shader_targets import prologue

LOCAL_SIZE = 64
MAX_GROUPS = 65535
PROBES_UNIT = 3
SKY_UNIT = 4
IO_BINDING = 64
"""Storage binding of the first input array (then the other inputs, then the outputs)."""

_TEMPLATE = """{prologue}{defines}
layout(local_size_x = {local}) in;
{includes}
{buffers}
{samplers}
layout(std430, set = 0, binding = {count_binding}) readonly buffer EnvcapCount {{ uint envcap_count; }};
{declarations}
void main() {{
    uint i = gl_GlobalInvocationID.x;
    if (i >= envcap_count) return;
{body}
}}
"""

_STD430 = {"float": (4, 4, "f4"), "int": (4, 4, "i4"), "uint": (4, 4, "u4"), "vec2": (8, 8, "f4"),
           "vec3": (12, 16, "f4"), "vec4": (16, 16, "f4")}


def std430(members: Sequence[tuple[str, int, Any]]) -> bytes:
    """std430 bytes of a block of ``members`` ``(glsl type, array length (1: not an array), value)``
    in order (types ``float int uint vec2 vec3 vec4``; arrays of ``vec3`` have a 16-byte stride);
    the size is rounded up to 16 bytes."""
    out = bytearray()
    for ty, length, value in members:
        size, align, dt = _STD430[ty]
        pad = (16 - size) if length > 1 and ty == "vec3" else 0     # array elements: vec3 strides 16
        out += bytes(-len(out) % align)
        for row in np.asarray(value, dtype=dt).reshape(length, size // 4):
            out += row.tobytes() + bytes(pad)
    out += bytes(-len(out) % 16)
    return bytes(out)


def build_source(body: str, inputs: Sequence[str], outputs: Sequence[str], *, includes: Sequence[str] = ("runtime/envcap_runtime.glsl",),
                 declarations: str = "", defines: Mapping[str, object] | None = None, probes: bool = False,
                 sky: bool = False) -> str:
    """The GLSL compute shader :func:`run_wgsl` translates (returned for inspection)."""
    inc = "".join(f'#include "{name}"\n' for name in includes)
    bufs = []
    for b, name in enumerate(list(inputs) + list(outputs)):
        ro = "readonly" if b < len(inputs) else "writeonly"
        bufs.append(f"layout(std430, set = 0, binding = {IO_BINDING + b}) {ro} buffer Buf_{name} {{ vec4 {name}[]; }};")
    samp = []
    if probes:
        samp.append(f"ENVCAP_BINDING({PROBES_UNIT}) uniform samplerCubeArray probes;")
    if sky:
        samp.append(f"ENVCAP_BINDING({SKY_UNIT}) uniform samplerCube sky;")
    defs = "".join(f"#define {k} {v}\n" for k, v in (defines or {}).items())
    src = _TEMPLATE.format(prologue=prologue(WGSL_TARGET), defines=defs, local=LOCAL_SIZE, includes=inc,
                           buffers="\n".join(bufs), samplers="\n".join(samp), declarations=declarations,
                           count_binding=IO_BINDING - 1, body="\n".join("    " + ln for ln in body.splitlines()))
    return expand_includes(src)


_device = None


def device() -> Any:
    """The ``wgpu`` device the harness runs on (made once; ``float32-filterable`` required, so
    RGBA32F cube arrays filter linearly)."""
    global _device
    if _device is None:
        import wgpu  # noqa: PLC0415 - optional dependency (the [test] extra)
        adapter = wgpu.gpu.request_adapter_sync(power_preference="high-performance")
        if adapter is None:
            raise RuntimeError("no WebGPU adapter: install Mesa's Vulkan drivers (Debian mesa-vulkan-drivers)")
        _device = adapter.request_device_sync(required_features=["float32-filterable"])
    return _device


def adapter_info() -> dict[str, Any]:
    """The adapter's info (``device``, ``adapter_type``, ``backend_type``, ...)."""
    return dict(device().adapter.info)


def _cube_texture(dev: Any, levels: Sequence[NDArray[np.floating]], layers: int) -> Any:
    import wgpu  # noqa: PLC0415
    n = levels[0].shape[-2]
    tex = dev.create_texture(size=(n, n, 6 * layers), format=wgpu.TextureFormat.rgba32float, mip_level_count=len(levels),
                             usage=wgpu.TextureUsage.TEXTURE_BINDING | wgpu.TextureUsage.COPY_DST)
    for k, lv in enumerate(levels):
        a = np.ascontiguousarray(np.asarray(lv, np.float32).reshape(6 * layers, lv.shape[-2], lv.shape[-2], 4))
        nk = a.shape[1]
        dev.queue.write_texture({"texture": tex, "mip_level": k, "origin": (0, 0, 0)}, a,
                                {"offset": 0, "bytes_per_row": nk * 16, "rows_per_image": nk}, (nk, nk, 6 * layers))
    return tex.create_view(dimension="cube-array" if layers > 1 or levels[0].ndim == 5 else "cube")


def _plain_texture(dev: Any, a: NDArray[Any]) -> Any:
    import wgpu  # noqa: PLC0415
    if a.ndim == 2:
        data, fmt, bpp = np.ascontiguousarray(a, np.uint16), wgpu.TextureFormat.r16uint, 2
    else:
        data, fmt, bpp = np.ascontiguousarray(a, np.float32), wgpu.TextureFormat.rgba32float, 16
    h, w = data.shape[:2]
    tex = dev.create_texture(size=(w, h, 1), format=fmt, usage=wgpu.TextureUsage.TEXTURE_BINDING | wgpu.TextureUsage.COPY_DST)
    dev.queue.write_texture({"texture": tex}, data, {"bytes_per_row": w * bpp, "rows_per_image": h}, (w, h, 1))
    return tex.create_view()


_BINDING = re.compile(r"@binding\((\d+)\)\s*@group\(0\)\s*var(?:<[^>]*>)?\s+\w+\s*:\s*([^;]+);")


def run_wgsl(body: str, inputs: Mapping[str, Any], outputs: Mapping[str, int], *, declarations: str = "",
             includes: Sequence[str] = ("runtime/envcap_runtime.glsl",), defines: Mapping[str, object] | None = None,
             probes: Sequence[NDArray[np.floating]] | None = None, sky: Sequence[NDArray[np.floating]] | None = None,
             textures: Mapping[int, NDArray[Any]] | None = None,
             blocks: Mapping[int, bytes] | None = None) -> dict[str, NDArray[np.float32]]:
    """Run ``body`` for every index of the inputs on WebGPU and return the outputs as float32
    arrays ``(n, k)`` (see the module docstring for the arguments); ``n`` <= 64 x 65535."""
    import wgpu  # noqa: PLC0415
    if not inputs:
        raise ValueError("run_wgsl needs at least one input array")
    cols = {k: as_columns(k, v) for k, v in inputs.items()}
    ns = {a.shape[0] for a in cols.values()}
    if len(ns) != 1 or min(ns) < 1 or max(ns) > LOCAL_SIZE * MAX_GROUPS:
        raise ValueError(f"inputs must all have the same length in 1..{LOCAL_SIZE * MAX_GROUPS}, got {sorted(ns)}")
    n = ns.pop()
    src = build_source(body, list(cols), list(outputs), includes=includes, declarations=declarations, defines=defines,
                       probes=probes is not None, sky=sky is not None)
    code = translate(src, "compute")
    declared = {int(b): ty.strip() for b, ty in _BINDING.findall(code)}
    dev = device()
    S = wgpu.BufferUsage
    res: dict[int, Any] = {}
    sampler = dev.create_sampler(mag_filter="linear", min_filter="linear", mipmap_filter="linear")
    for unit, levels in ((PROBES_UNIT, probes), (SKY_UNIT, sky)):
        if levels is not None:
            t, s = texture_binding(unit)
            res[t] = _cube_texture(dev, levels, levels[0].shape[0] if unit == PROBES_UNIT else 1)
            res[s] = sampler
    for unit, a in (textures or {}).items():
        t, s = texture_binding(unit)
        res[t], res[s] = _plain_texture(dev, np.asarray(a)), sampler
    for b, data in (blocks or {}).items():
        res[b] = dev.create_buffer_with_data(data=data, usage=S.STORAGE)
    res[IO_BINDING - 1] = dev.create_buffer_with_data(data=np.array([n, 0, 0, 0], np.uint32).tobytes(), usage=S.STORAGE)
    for b, a in enumerate(cols.values()):
        res[IO_BINDING + b] = dev.create_buffer_with_data(data=a.tobytes(), usage=S.STORAGE)
    outs = []
    for b in range(len(outputs)):
        buf = dev.create_buffer(size=n * 16, usage=S.STORAGE | S.COPY_SRC)
        res[IO_BINDING + len(cols) + b] = buf
        outs.append(buf)
    missing = sorted(set(declared) - set(res))
    if missing:
        raise ValueError(f"the shader declares bindings {missing} ({[declared[b] for b in missing]}) that were not given")
    pipe = dev.create_compute_pipeline(layout="auto", compute={"module": dev.create_shader_module(code=code), "entry_point": "main"})
    entries = []
    for b in sorted(declared):
        r = res[b]
        entries.append({"binding": b, "resource": {"buffer": r, "offset": 0, "size": r.size} if isinstance(r, wgpu.GPUBuffer) else r})
    group = dev.create_bind_group(layout=pipe.get_bind_group_layout(0), entries=entries)
    enc = dev.create_command_encoder()
    cp = enc.begin_compute_pass()
    cp.set_pipeline(pipe)
    cp.set_bind_group(0, group)
    cp.dispatch_workgroups((n + LOCAL_SIZE - 1) // LOCAL_SIZE)
    cp.end()
    dev.queue.submit([enc.finish()])
    return {name: np.frombuffer(dev.queue.read_buffer(buf), np.float32).reshape(n, 4)[:, : int(c)].copy()
            for (name, c), buf in zip(outputs.items(), outs)}
