"""Cost of the dynamic terms per shading point, against a plain Eq. 3 (helper of
``envcap bench dynamic-street``; not a benchmark by itself).

* numpy: :func:`envcap.runtime.shading.shade_lafortune` over ``P`` shading points with the probe
  lookups of :class:`envcap.evaluate.predict.Predictor` as ``E_w``, without and with the dynamic
  terms of ``S`` spheres (:func:`envcap.evaluate.dynamic_terms.shade_model`), per model;
* GLSL: a full-screen fragment pass on the synthetic street of :mod:`envcap.runtime.synthetic_street`
  running ``envcap_shade_lafortune`` (``plain``), and the same plus the runtime's
  ``envcap_dynamic_terms`` (``shaders/runtime/envcap_dynamic_spheres.glsl``) over ``S`` spheres
  with the probe lookup as its environment: the paper's form and bounce
  (``ENVCAP_DYNAMIC_PAPER_FORM``, ``ENVCAP_DYNAMIC_BOUNCE_PAPER``) with the overlap rule, envcap's
  defaults (the rings rule), and envcap's with the overlap rule (:data:`GL_MODES`).

Times are medians of interleaved passes; the figures that matter are the ratios to the plain Eq. 3
measured in the same run (llvmpipe: a CPU rasterizer; ratios of fetch-bound GPU passes differ).
"""

from __future__ import annotations

import time
from typing import Any, Callable

import numpy as np

from envcap.benchmarks.runtime import VERT
from envcap.core.resources import expand_includes
from envcap.dynamic.spheres import SphereBuffer
from envcap.evaluate.dynamic_terms import MODELS, shade_model
from envcap.evaluate.shading import MATERIALS, shade
from envcap.gpu.context import create_context
from envcap.gpu.cube_array import CubeArrayTexture, cube_texture
from envcap.gpu.uniforms import set_uniforms
from envcap.runtime import synthetic_street as ss
from envcap.runtime.shading import EnvironmentFn

MAX_SPHERES = 16
"""Spheres in the GLSL pass's uniform array."""


def median_time(fn: Callable[[], Any], repeats: int) -> float:
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts))


def numpy_cost(static_env: EnvironmentFn, light_env: EnvironmentFn, x: np.ndarray, spheres: SphereBuffer,
               points: int = 2048, repeats: int = 5, material: str = "plastic", seed: int = 1) -> dict[str, Any]:
    """Median seconds of Eq. 3 for ``points`` random frames at ``x`` (one diffuse + one specular
    lookup per point for ``plastic``), plain and per model of
    :data:`envcap.evaluate.dynamic_terms.MODELS` (:func:`envcap.evaluate.dynamic_terms.shade_model`:
    the runtime twin :func:`envcap.dynamic.terms.dynamic_terms`, twice for the sky-lit models);
    ratios to plain."""
    rng = np.random.default_rng(seed)
    N = rng.normal(size=(points, 3))
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    T = np.cross(N, np.where(np.abs(N[:, 1:2]) < 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]]))
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    frames = np.stack([T, np.cross(N, T), N], axis=1)
    th, ph = rng.uniform(0.2, 1.3, points), rng.uniform(0, 2 * np.pi, points)
    views = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1)
    mat = next(m for m in MATERIALS if m.name == material)
    out = {"plain": median_time(lambda: shade(static_env, mat, frames, views), repeats)}
    for name in MODELS:
        out[name] = median_time(lambda name=name: shade_model(name, static_env, light_env, x, frames, views, mat, spheres),
                                repeats)
    return {"points": points, "spheres": len(spheres), "material": material, "median_s": out,
            "us_per_point": {k: 1e6 * v / points for k, v in out.items()},
            "ratio_to_plain": {k: v / out["plain"] for k, v in out.items()}}



FRAG = """#version 430
#define MODE {mode}
#if MODE == 1
#define ENVCAP_DYNAMIC_PAPER_FORM
#define ENVCAP_DYNAMIC_BOUNCE_PAPER
#endif
#if MODE == 1 || MODE == 3
#define ENVCAP_DYNAMIC_COMBINE 0
#endif
#define ENVCAP_MAX_SPHERES 16
#define ENVCAP_DYNAMIC_ENVIRONMENT bench_env
in vec2 uv;
out vec4 color;
layout(binding = 3) uniform samplerCubeArray probes;
layout(binding = 4) uniform samplerCube sky;
#include "runtime/envcap_runtime.glsl"
#include "runtime/envcap_street_uniforms.glsl"
#include "runtime/envcap_dynamic_spheres.glsl"
vec3 g_x;
vec3 bench_env(vec3 dir, float w) { return envcap_sample_nearest(probes, sky, g_x, dir, w, envcap_street); }

void main() {
    vec3 x = vec3(uv.x * 20.0, 0.5 + 2.0 * uv.y, 4.0 * sin(40.0 * uv.x));
    g_x = x;
    float th = uv.y * 3.14159265, ph = uv.x * 6.2831853 * 3.0;
    vec3 N = vec3(sin(th) * cos(ph), cos(th), sin(th) * sin(ph));
    vec3 T = normalize(cross(abs(N.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0), N));
    vec3 B = cross(N, T);
    vec3 v = normalize(N + 0.5 * T);
    vec4 C[ENVCAP_MAX_LOBES];
    vec3 rho_s[ENVCAP_MAX_LOBES];
    C[0] = vec4(-1.0, -1.0, 1.0, 20.0);
    rho_s[0] = vec3(0.3);
    vec3 L = envcap_shade_lafortune(probes, sky, x, T, B, N, v, vec3(0.4), C, rho_s, 1, envcap_street);
#if MODE > 0
    vec3 blocked, bounced;
    envcap_dynamic_terms(x, T, B, N, v, vec3(0.4), C, rho_s, 1, blocked, bounced);
    L += bounced - blocked;
#endif
    color = vec4(L, 1.0);
}
"""

GL_MODES = {"plain": 0, "paper": 1, "envcap": 2, "envcap_overlap": 3}
"""``paper``: the paper's form and bounce, the overlap rule; ``envcap``: envcap's defaults (the rings
rule); ``envcap_overlap``: envcap's form and bounce with the overlap rule (``ENVCAP_DYNAMIC_COMBINE 0``)."""


def gl_cost(size: int = 256, spheres: int = 8, repeats: int = 7, face: int = 32) -> dict[str, Any]:
    """Median seconds of the fragment pass (``size^2`` shading points, plastic: one diffuse and
    one specular lobe) per mode of :data:`GL_MODES` with ``spheres`` spheres around each point;
    ratios to ``plain`` and whether every pixel is finite."""
    if not 0 <= spheres <= MAX_SPHERES:
        raise ValueError(f"spheres must be in 0..{MAX_SPHERES}, got {spheres}")
    probes, sky, street, powers = ss.synthetic_probe_set(face, count=3, start=0.0, end=20.0)
    ctx = create_context()
    pt = CubeArrayTexture(probes)
    st = cube_texture(ctx, sky)
    fbo = ctx.framebuffer([ctx.renderbuffer((size, size), 4, dtype="f4")])
    ang = 2 * np.pi * np.arange(MAX_SPHERES) / max(spheres, 1)
    sph = np.stack([10 + 1.5 * np.cos(ang), np.full(MAX_SPHERES, 1.5), 1.5 * np.sin(ang), np.full(MAX_SPHERES, 0.5)], 1)
    sph[spheres:, 3] = 0.0
    progs = {}
    try:
        for name, mode in GL_MODES.items():
            frag = expand_includes(FRAG.replace("{mode}", str(mode)))
            prog = ctx.program(vertex_shader=VERT, fragment_shader=frag)
            extra = {} if mode == 0 else {"envcap_spheres": sph.astype(np.float32),
                                          "envcap_sphere_albedo": np.full((MAX_SPHERES, 3), 0.4, np.float32),
                                          "envcap_sphere_count": int(spheres)}
            set_uniforms(prog, {**street.uniforms(powers).values(), **extra}, sources=(frag,))
            progs[name] = (prog, ctx.vertex_array(prog, []))
        fbo.use()
        pt.use(3)
        st.use(4)

        def one(name: str) -> float:
            ctx.finish()
            t0 = time.perf_counter()
            progs[name][1].render(vertices=3)
            ctx.finish()
            return time.perf_counter() - t0

        for name in GL_MODES:
            one(name)
        times: dict[str, list[float]] = {k: [] for k in GL_MODES}
        for _ in range(repeats):
            for name in GL_MODES:
                times[name].append(one(name))
        finite = {}
        for name in GL_MODES:
            progs[name][1].render(vertices=3)
            img = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32)
            finite[name] = bool(np.all(np.isfinite(img)))
        med = {k: float(np.median(v)) for k, v in times.items()}
        return {"device": ctx.info.get("GL_RENDERER", "?"), "pixels": size * size, "spheres": spheres, "median_s": med,
                "ns_per_point": {k: 1e9 * v / (size * size) for k, v in med.items()},
                "ratio_to_plain": {k: v / med["plain"] for k, v in med.items()}, "all_finite": finite}
    finally:
        for prog, vao in progs.values():
            vao.release()
            prog.release()
        pt.release()
        st.release()
        fbo.release()
        ctx.release()
