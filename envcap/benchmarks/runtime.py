"""runtime: cost of the full probe lookup (parallax + mip shift + sky) vs a plain cube-array lookup.

Fragment passes over the same full-screen grid of shading points and directions, on the
current GL driver (llvmpipe here), timed in the same run:

* ``plain``: ``textureLod(probes, vec4(d, layer), z)`` (the simplest correct lookup, no parallax);
* ``full``: ``envcap_sample_nearest`` (probe selection, three-plane parallax, mip shift in
  w-space, z(w) from the lobe table, sky composite);
* ``blended``: ``envcap_sample_blended`` (two probes, each parallax-corrected, + sky);
* ``oblique``, ``footprint``, ``aniso``, ``sigma``: ``envcap_sample_oblique`` / ``_footprint`` /
  ``_aniso`` / ``_sigma`` (the oblique mip shift in closed form; the traced footprint, four sigma
  rays; the traced footprint with 2 taps along its long axis; 4 taps where the sigma rays land);
* ``depth``: ``envcap_sample_depth_refine`` (``shaders/runtime/envcap_depth_refine.glsl``, method
  ``depth_refine``): the plane hit checked against a nearest-filtered inverse-distance cube array
  and refined where it disagrees.  The distances are those of the synthetic street with its +cross
  facade set back :data:`SET_BACK` m behind the uploaded plane, so that the refinement branch runs
  for part of the pixels (``depth_refined_share`` in the JSON).

Reports median times, ratios to ``plain``, and texture fetches per lobe (``textureLod`` calls
on each path, counted in the shader source).  Writes ``runtime.json`` and ``runtime_cost.png``
to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import re
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from envcap.core.resources import expand_includes, shader_source
from envcap.gpu.context import create_context
from envcap.gpu.cube_array import CubeArrayTexture, cube_texture
from envcap.gpu.uniforms import set_uniforms
from envcap.outputs import atomic_output_dir
from envcap.runtime import synthetic_street as ss
from envcap.runtime.street import RuntimeStreet

VERT = """#version 430
// one triangle covering the viewport: uv in [0, 1]^2 over the screen (shared by the GLSL cost passes)
out vec2 uv;
void main() {
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    uv = p;
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
"""

FRAG = """#version 430
#define MODE {mode}
in vec2 uv;
out vec4 color;
layout(binding = 3) uniform samplerCubeArray probes;
layout(binding = 4) uniform samplerCube sky;
layout(binding = 5) uniform samplerCubeArray dist;
#include "runtime/envcap_runtime.glsl"
#include "runtime/envcap_depth_refine.glsl"
#include "runtime/envcap_street_uniforms.glsl"
uniform float w;
void main() {
    // a shading point on a grid along the street and a direction over the whole sphere
    vec3 x = vec3(uv.x * 20.0, 0.5 + 6.0 * uv.y, 4.0 * sin(40.0 * uv.x));
    float th = uv.y * 3.14159265, ph = uv.x * 6.2831853 * 3.0;
    vec3 d = vec3(sin(th) * cos(ph), cos(th), sin(th) * sin(ph));
#if MODE == 0
    color = textureLod(probes, vec4(d, 0.0), envcap_z_of_w(w, envcap_street.xk, envcap_street.nlevels));
#elif MODE == 1
    color = vec4(envcap_sample_nearest(probes, sky, x, d, w, envcap_street), 1.0);
#elif MODE == 2
    color = vec4(envcap_sample_blended(probes, sky, x, d, w, envcap_street), 1.0);
#elif MODE == 3
    color = vec4(envcap_sample_oblique(probes, sky, x, d, w, envcap_street), 1.0);
#elif MODE == 4
    color = vec4(envcap_sample_footprint(probes, sky, x, d, w, envcap_street), 1.0);
#elif MODE == 5
    color = vec4(envcap_sample_aniso(probes, sky, x, d, w, envcap_street), 1.0);
#elif MODE == 6
    color = vec4(envcap_sample_sigma(probes, sky, x, d, w, envcap_street), 1.0);
#elif MODE == 7
    color = vec4(envcap_sample_depth_refine(probes, sky, dist, x, d, w, envcap_street), 1.0);
#else
    // the share of lookups whose plane hit the depth check sends to refinement (the same x, d)
    int i = envcap_nearest_probe(x[envcap_street.along], envcap_street.along_s, envcap_street.count);
    vec3 xc = envcap_clamp_to_street(x, envcap_street.planes[i], envcap_street.along);
    float t = envcap_exit_distance(xc, d, envcap_street.planes[i], envcap_street.along);
    float hl;
    vec3 u = envcap_depth_towards(xc - envcap_street.pos[i].xyz, d, t, hl);
    float s = textureLod(dist, vec4(u, envcap_street.pos[i].w), 0.0).r;
    color = vec4((s > ENVCAP_MIN_INV_DISTANCE && abs(hl * s - 1.0) > ENVCAP_DEPTH_TOL) ? 1.0 : 0.0);
#endif
}
"""

MODES = {"plain": 0, "full": 1, "blended": 2, "oblique": 3, "footprint": 4, "aniso": 5, "sigma": 6, "depth": 7}
"""Passes: plain lookup, then the GLSL of the methods planes_mip, blend, planes_mip_oblique,
planes_mip_footprint, planes_mip_aniso, planes_mip_sigma and depth_refine (docs/runtime.md, "Cost")."""

REFINED_MODE = 8
"""An untimed pass: 1 where ``depth``'s check refines the lookup, else 0."""

SET_BACK = 3.0
"""Metres by which the distance texture's +cross facade stands behind the uploaded plane."""

DEPTH_STEPS = 2
"""Distance fetches of ``envcap_sample_depth_refine`` where it refines (its default ``ENVCAP_DEPTH_STEPS``)."""


ANISO_TAPS = 2
"""Taps of ``envcap_sample_aniso`` (its default ``ENVCAP_ANISO_TAPS``)."""


def fetches_per_lobe() -> dict[str, int]:
    """``textureLod`` calls on each path, counted in the runtime GLSL source."""
    src = shader_source("runtime/envcap_runtime.glsl")

    def body(name: str) -> str:
        m = re.search(r"\b" + name + r"\s*\([^{]*\{", src)
        if not m:
            raise RuntimeError(f"function {name} not found in envcap_runtime.glsl")
        i, depth = m.end(), 1
        while depth:
            depth += {"{": 1, "}": -1}.get(src[i], 0)
            i += 1
        return src[m.end():i]

    def fetches(fn: str) -> int:  # sky lookups plus probe lookups (ENVCAP_PROBES_LOD, ENVCAP_SKY_LOD: one textureLod)
        b = body(fn)
        return b.count("textureLod(") + b.count("ENVCAP_PROBES_LOD(") + b.count("ENVCAP_SKY_LOD(")

    aniso = fetches("envcap_sample_aniso") - 1 + ANISO_TAPS     # its probe fetch is in a loop of ENVCAP_ANISO_TAPS
    return {"plain": 1, "full": fetches("envcap_sample_probe"), "blended": fetches("envcap_sample_blended"),
            "oblique": fetches("envcap_sample_oblique") + fetches("envcap_over_sky"),
            "footprint": fetches("envcap_sample_footprint") + fetches("envcap_over_sky"),
            "aniso": aniso + fetches("envcap_over_sky"),
            "sigma": fetches("envcap_sample_sigma") - 1 + 4 + fetches("envcap_over_sky"),   # its 4 taps are a loop
            # its probe and sky, + the distance reads where it refines (1 where the planes' hit passes the check)
            "depth": fetches("envcap_sample_oblique") + fetches("envcap_over_sky") + DEPTH_STEPS}


def distance_texture(street: RuntimeStreet, face: int) -> CubeArrayTexture:
    """The inverse-distance cube array (NEAREST, 1/m in .r) of the synthetic street's probes with
    the +cross facade :data:`SET_BACK` m behind the uploaded plane (the sky above 12 m)."""
    from envcap.core import cube
    from envcap.runtime.methods.depth_refine import inverse_distance
    from envcap.runtime.parallax import exit_distance

    d = cube.texel_directions(face).reshape(-1, 3)
    true = street.planes[0] + np.array([0.0, SET_BACK, 0.0])
    out = []
    for p in street.positions:
        t = exit_distance(np.broadcast_to(p, d.shape), d, true, street.along)
        out.append(np.where((t < 1e5) & (p[1] + t * d[:, 1] <= 12.0), t, 0.0).reshape(6, face, face))
    inv = inverse_distance(np.stack(out))
    return CubeArrayTexture([np.concatenate([inv[..., None], np.zeros(inv.shape + (3,), np.float32)], axis=-1)],
                            filter="nearest")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", required=True, help="output directory (JSON + PNG)")
    parser.add_argument("--size", type=int, default=512, help="framebuffer width = height in pixels (default 512)")
    parser.add_argument("--repeats", type=int, default=9, help="timed passes per mode (default 9)")
    parser.add_argument("--face", type=int, default=64, help="probe face size in texels (default 64)")
    parser.add_argument("--w", type=float, default=50.0, help="lobe power of the lookups (default 50)")


def run(args: argparse.Namespace) -> int:
    if args.size < 1 or args.repeats < 1 or args.face < 1 or not np.isfinite(args.w) or args.w < 0:
        raise ValueError("--size, --repeats and --face must be >= 1 and --w finite and >= 0")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    probes, sky, street, powers = ss.synthetic_probe_set(args.face, count=3, start=0.0, end=20.0)

    ctx = create_context()
    pt = CubeArrayTexture(probes)
    st = cube_texture(ctx, sky)
    dt = distance_texture(street, args.face)
    fbo = ctx.framebuffer([ctx.renderbuffer((args.size, args.size), 4, dtype="f4")])
    progs = {}
    for name, mode in {**MODES, "refined": REFINED_MODE}.items():
        frag = expand_includes(FRAG.replace("{mode}", str(mode)))
        prog = ctx.program(vertex_shader=VERT, fragment_shader=frag)
        set_uniforms(prog, {**street.uniforms(powers).values(), "w": float(args.w)}, sources=(frag,))
        progs[name] = (prog, ctx.vertex_array(prog, []))
    fbo.use()
    pt.use(3)
    st.use(4)
    dt.use(5)

    def one(name: str) -> float:
        vao = progs[name][1]
        ctx.finish()
        t0 = time.perf_counter()
        vao.render(vertices=3)
        ctx.finish()
        return time.perf_counter() - t0

    for name in MODES:          # warm-up (shader compile, first touch)
        one(name)
    times: dict[str, list[float]] = {k: [] for k in MODES}
    for _ in tqdm(range(args.repeats), desc="runtime bench", disable=None):
        for name in MODES:      # interleaved, so that load changes hit all modes alike
            times[name].append(one(name))
    med = {k: float(np.median(v)) for k, v in times.items()}
    images = {}
    for name in MODES:
        progs[name][1].render(vertices=3)
        images[name] = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(args.size, args.size, 4)
    finite = {k: bool(np.all(np.isfinite(v))) for k, v in images.items()}
    progs["refined"][1].render(vertices=3)
    refined = float(np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(-1, 4)[:, 0].mean())
    result = {
        "device": ctx.info.get("GL_RENDERER", "?"),
        "pixels": args.size * args.size,
        "face": args.face,
        "levels": len(powers),
        "w": args.w,
        "repeats": args.repeats,
        "median_s": med,
        "ns_per_pixel": {k: v / (args.size * args.size) * 1e9 for k, v in med.items()},
        "ratio_to_plain": {k: med[k] / med["plain"] for k in MODES},
        "texture_fetches_per_lobe": fetches_per_lobe(),
        "all_finite": finite,
        "depth_refined_share": refined,
        "times_s": times,
    }
    with atomic_output_dir(args.out) as tmp:
        (Path(tmp) / "runtime.json").write_text(json.dumps(result, indent=2))
        fig, ax = plt.subplots(figsize=(7, 3))
        names = list(MODES)
        ax.bar(names, [result["ratio_to_plain"][k] for k in names], color=["#888", "#4a7", "#47a", "#a74", "#a47", "#7a4", "#74a", "#a44"])
        ax.axhline(2.0, color="r", ls="--", lw=1, label="goal: 2x plain")
        ax.set_ylabel("time / plain lookup")
        ax.set_title(f"runtime lookup cost, {args.size}^2 px, {result['device'][:30]}", fontsize=8)
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(Path(tmp) / "runtime_cost.png", dpi=120)
        plt.close(fig)
    for prog, vao in progs.values():
        vao.release()
        prog.release()
    pt.release()
    st.release()
    dt.release()
    fbo.release()
    print(json.dumps({k: result[k] for k in ("ratio_to_plain", "ns_per_pixel", "texture_fetches_per_lobe", "all_finite",
                                             "depth_refined_share")}))
    return 0
