"""One runtime GLSL source for every target: a per-target prologue in front of ``shaders/runtime/``.

The files of ``shaders/runtime/`` are written once, in the common subset of GLSL 4.50 core,
GLSL ES 3.20, GLSL ES 3.00 (WebGL2) and Vulkan GLSL.  What differs between targets is said
before the library, by :func:`prologue`:

* ``#version``, and for the ES targets default ``highp`` precision for ``float``, ``int`` and
  every sampler type the library takes (ES gives ``samplerCube`` ``lowp`` by default, which
  would clip HDR texels, and has no default for the others);
* ``ENVCAP_BINDING(n)`` (a sampler's texture unit: ``layout(binding = n)``, or
  ``layout(set = 0, binding = n)`` on Vulkan, nothing on WebGL2, which has no binding
  qualifier), ``ENVCAP_IN(n)`` / ``ENVCAP_OUT(n)`` (stage input / output locations; WebGL2
  fragment inputs take none);
* Vulkan: ``ENVCAP_STREET_BLOCK`` and ``ENVCAP_SPHERES_BLOCK``
  (``runtime/envcap_street_uniforms.glsl`` and ``runtime/envcap_dynamic_spheres.glsl`` then
  declare the street and the spheres in std430 read-only storage buffers: Vulkan takes no loose
  non-opaque uniforms, and a std140 uniform block of the street has no HLSL packing);
* WebGL2 (no cube-map arrays; ``samplerCubeArray`` is a reserved word there):
  ``ENVCAP_PROBES_SAMPLER`` = ``sampler2DArray`` and ``ENVCAP_PROBES_LOD`` =
  ``envcap_face_atlas_lod`` from ``runtime/envcap_face_atlas.glsl``: the probes as face atlases
  (``envcap.formats.face_atlas``), sampled with the same seamless trilinear result (the
  hooks' cube-array defaults: ``runtime/envcap_probe_texture.glsl``).

:data:`RUNTIME_UNITS` are small fragment shaders, one per library file, whose ``main`` calls
every function of that file; :func:`unit_source` wraps one for a target.  They are what the
compile matrix (:mod:`envcap.runtime.shader_matrix`, ``docs/engines.md``) compiles.
"""

from __future__ import annotations

from dataclasses import dataclass

from envcap.core.resources import expand_includes


@dataclass(frozen=True)
class ShaderTarget:
    """A GLSL dialect the runtime library compiles for.

    ``name``: short key; ``title``: for tables; ``version``: the ``#version`` line;
    ``defines``: prologue macros (name or ``NAME(args)`` -> replacement), in order;
    ``es``: GLSL ES (needs default precisions); ``spirv``: compiled to SPIR-V (Vulkan) and
    translated from it to HLSL / MSL; ``probes``: the probe texture layout it samples,
    ``"cube_array"`` or ``"face_atlas"``; ``includes``: library files the prologue includes."""

    name: str
    title: str
    version: str
    defines: tuple[tuple[str, str], ...]
    es: bool = False
    spirv: bool = False
    probes: str = "cube_array"
    includes: tuple[str, ...] = ()


ES_PRECISION = ("float", "int", "sampler2D", "samplerCube", "sampler2DArray", "usampler2D")
"""Types given a ``highp`` default precision on the ES targets (ES 3.20 adds ``samplerCubeArray``)."""

_LOCATIONS = (("ENVCAP_IN(n)", "layout(location = n)"), ("ENVCAP_OUT(n)", "layout(location = n)"))

TARGETS: dict[str, ShaderTarget] = {
    t.name: t for t in (
        ShaderTarget("gl450", "GLSL 4.50 core", "#version 450 core",
                     (("ENVCAP_BINDING(n)", "layout(binding = n)"),) + _LOCATIONS),
        ShaderTarget("es320", "GLSL ES 3.20", "#version 320 es",
                     (("ENVCAP_BINDING(n)", "layout(binding = n)"),) + _LOCATIONS, es=True),
        ShaderTarget("webgl2", "GLSL ES 3.00 (WebGL2)", "#version 300 es",
                     (("ENVCAP_BINDING(n)", ""), ("ENVCAP_IN(n)", ""), ("ENVCAP_OUT(n)", "layout(location = n)"),
                      ("ENVCAP_PROBES_SAMPLER", "sampler2DArray"),
                      ("ENVCAP_PROBES_LOD(probes, dir, layer, lod)", "envcap_face_atlas_lod(probes, dir, layer, lod)"),
                      ("ENVCAP_PROBES_FACE_SIZE(probes)", "envcap_face_atlas_size(textureSize(probes, 0).x)")),
                     es=True, probes="face_atlas", includes=("runtime/envcap_face_atlas.glsl",)),
        ShaderTarget("vulkan", "Vulkan GLSL 4.50 (SPIR-V)", "#version 450 core",
                     (("ENVCAP_BINDING(n)", "layout(set = 0, binding = n)"),) + _LOCATIONS
                     + (("ENVCAP_STREET_BLOCK", "layout(std430, set = 0, binding = 8) readonly buffer"),
                        ("ENVCAP_SPHERES_BLOCK", "layout(std430, set = 0, binding = 9) readonly buffer")), spirv=True),
    )
}
"""The targets, by name: desktop GL, GL ES 3.2, WebGL2 and Vulkan (whose SPIR-V spirv-cross
turns into HLSL and MSL)."""


def prologue(target: str | ShaderTarget) -> str:
    """The text a shader for ``target`` starts with (``#version`` line first), before any
    ``#include`` of the runtime library.  Includes are left as ``#include`` lines."""
    t = TARGETS[target] if isinstance(target, str) else target
    lines = [t.version]
    if t.es:
        types = ES_PRECISION + (("samplerCubeArray",) if t.probes == "cube_array" else ())
        lines += [f"precision highp {ty};" for ty in types]
    lines += [f"#define {k} {v}".rstrip() for k, v in t.defines]
    lines += [f'#include "{name}"' for name in t.includes]
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class RuntimeUnit:
    """A fragment shader that exercises one library file: ``includes`` (runtime files),
    ``declarations`` (after the includes), ``body`` (inside ``main``, writes ``vec4 o`` from the
    inputs ``vec4 a, b, c``) and ``defines`` (macros set before the includes)."""

    includes: tuple[str, ...]
    declarations: str
    body: str
    defines: tuple[tuple[str, str], ...] = ()


_SAMPLERS = """ENVCAP_BINDING(3) uniform ENVCAP_PROBES_SAMPLER probes;
ENVCAP_BINDING(4) uniform samplerCube sky;
"""

_LOCAL_STREET = """EnvcapStreet s;
for (int k = 0; k < ENVCAP_MAX_PROBES; ++k) {
    s.along_s[k] = float(k) * 5.0; s.pos[k] = vec4(float(k) * 5.0, 2.0, 0.0, float(k)); s.planes[k] = vec4(-5.0, 5.0, 0.0, 0.0);
}
for (int k = 0; k < ENVCAP_MAX_LEVELS; ++k) s.xk[k] = 16.0 - float(k);
s.count = 4; s.along = 0; s.nlevels = 5; s.frame = normalize(vec2(1.0, c.z));
"""

RUNTIME_UNITS: dict[str, RuntimeUnit] = {
    "envcap_street": RuntimeUnit(("runtime/envcap_street.glsl",), "", """
float along[ENVCAP_MAX_PROBES];
for (int k = 0; k < ENVCAP_MAX_PROBES; ++k) along[k] = float(k) * c.w;
vec4 par = envcap_parallax(a.xyz, envcap_frame_dir(normalize(b.xyz), normalize(c.xy)), c.xyz, vec3(-5.0, 5.0, 0.0), 2);
par += envcap_parallax(a.xyz, normalize(b.xyz), c.xyz, vec4(-5.0, 5.0, 0.0, c.z), 0);
vec3 pr = envcap_probe_pair(a.w, along, 8);
float t = envcap_exit_distance(envcap_clamp_to_street(a.xyz, vec3(-5.0, 5.0, 0.0), 0), b.xyz, vec3(-5.0, 5.0, 0.0), 0);
o = par + vec4(pr, t) + vec4(float(envcap_nearest_probe(a.w, along, 8)) + envcap_shift_power(b.w, par.w));
vec3 r;
vec3 m;
vec2 v = envcap_sigma_footprint(a.xyz, normalize(b.xyz), b.w, c.xyz, vec3(-5.0, 5.0, 0.0), 2, r, m);
o += envcap_parallax_oblique(a.xyz, normalize(b.xyz), c.xyz, vec3(-5.0, 5.0, 0.0), 2) + vec4(r + m, envcap_footprint_power(v.x));"""),
    "envcap_lobes": RuntimeUnit(("runtime/envcap_lobes.glsl",), "ENVCAP_BINDING(3) uniform ENVCAP_PROBES_SAMPLER probes;\n", """
float xk[ENVCAP_MAX_LEVELS];
for (int k = 0; k < ENVCAP_MAX_LEVELS; ++k) xk[k] = 16.0 - float(k);
float xr[ENVCAP_MAX_RUNGS];
for (int k = 0; k < ENVCAP_MAX_RUNGS; ++k) xr[k] = 48.0 - float(k);
o = envcap_lafortune_lobe(normalize(a.xyz), b.xyz, b.w) + vec4(envcap_z_of_w(a.w, xk, 5));
o += envcap_rung_fetch(probes, normalize(b.xyz), 0.0, a.w, xr, 8, 2);"""),
    "envcap_rung_street": RuntimeUnit(("runtime/envcap_rung_street.glsl",), """ENVCAP_BINDING(3) uniform ENVCAP_PROBES_SAMPLER probes;
ENVCAP_BINDING(4) uniform ENVCAP_SKY_SAMPLER sky;
""", _LOCAL_STREET + """
vec3 n = normalize(b.xyz);
o = vec4(envcap_sample_nearest(probes, sky, a.xyz, n, c.w, s) + envcap_sample_blended(probes, sky, a.xyz, n, c.w, s), 1.0);"""),
    "envcap_probe_texture": RuntimeUnit(("runtime/envcap_probe_texture.glsl",),
                                        "ENVCAP_BINDING(3) uniform ENVCAP_PROBES_SAMPLER probes;\n", """
o = ENVCAP_PROBES_LOD(probes, normalize(b.xyz), a.w, c.w);"""),
    "envcap_runtime": RuntimeUnit(("runtime/envcap_runtime.glsl",), _SAMPLERS, _LOCAL_STREET + """
vec4 C[ENVCAP_MAX_LOBES];
vec3 rho[ENVCAP_MAX_LOBES];
for (int k = 0; k < ENVCAP_MAX_LOBES; ++k) { C[k] = vec4(-1.0, -1.0, 1.0, 20.0 * float(k + 1)); rho[k] = vec3(0.1); }
vec3 n = normalize(b.xyz);
vec3 L = envcap_shade_lafortune(probes, sky, a.xyz, vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, 1.0), n, n, vec3(0.5), C, rho, 2, s);
L += envcap_sample_blended(probes, sky, a.xyz, n, c.w, s) + envcap_sample_oblique(probes, sky, a.xyz, n, c.w, s);
L += envcap_sample_footprint(probes, sky, a.xyz, n, c.w, s) + envcap_sample_aniso(probes, sky, a.xyz, n, c.w, s);
L += envcap_sample_sigma(probes, sky, a.xyz, n, c.w, s);
o = vec4(L, 1.0);"""),
    "envcap_depth_refine": RuntimeUnit(("runtime/envcap_depth_refine.glsl",),
                                       _SAMPLERS + "ENVCAP_BINDING(5) uniform ENVCAP_DISTANCE_SAMPLER dist;\n",
                                       _LOCAL_STREET + """
o = vec4(envcap_sample_depth_refine(probes, sky, dist, a.xyz, normalize(b.xyz), c.w, s), 1.0);"""),
    "envcap_crossing": RuntimeUnit(("runtime/envcap_crossing.glsl",), _SAMPLERS, _LOCAL_STREET + """
EnvcapStreet cs = envcap_crossing_street(s, vec4(c.w, 2.0, 0.0, 9.0));
EnvcapStreet one = envcap_probe_street(cs, 9.0);
vec3 n = normalize(b.xyz);
o = vec4(envcap_sample_nearest(probes, sky, a.xyz, n, c.w, cs) + envcap_sample_nearest(probes, sky, a.xyz, n, c.w, one), 1.0);
o.w = envcap_facade_exit(cs, a.xyz, n) > envcap_facade_exit(one, b.xyz, n) ? 1.0 : 0.0;"""),
    "envcap_street_uniforms": RuntimeUnit(("runtime/envcap_street_uniforms.glsl",), _SAMPLERS, """
vec3 n = normalize(b.xyz);
o = vec4(envcap_sample_nearest(probes, sky, a.xyz, n, c.w, envcap_street)
         + envcap_sample_blended(probes, sky, a.xyz, n, c.w, envcap_street), 1.0);"""),
    "envcap_street_map": RuntimeUnit(("runtime/envcap_street_map.glsl",), "ENVCAP_BINDING(5) uniform usampler2D street_map;\n"
                                     "ENVCAP_BINDING(6) uniform sampler2D frames;\nENVCAP_BINDING(7) uniform usampler2D ranges;\n", """
uvec4 range;
vec3 local;
uint id = envcap_city_locate(street_map, c.xy, c.z, frames, ranges, a.xyz, range, local);
o = vec4(float(envcap_street_map_id(street_map, c.xy, c.z, a.xz) + id + range.w)
         + float(envcap_street_map_crossing(id, range.x)), local);"""),
    "envcap_dynamic": RuntimeUnit(("runtime/envcap_dynamic.glsl",), "", """
vec4 lobe = envcap_sphere_lobe(a.xyz, c);
o = envcap_lobe_product(lobe.xyz, b.xyz, lobe.w, b.w) + envcap_occlusion(lobe.xyz, b.xyz, lobe.w, b.w);"""),
    "envcap_dynamic_spheres": RuntimeUnit(
        ("runtime/envcap_dynamic_spheres.glsl",), "vec3 unit_environment(vec3 dir, float w) { return dir * w; }\n", """
vec4 C[ENVCAP_MAX_LOBES];
vec3 rho[ENVCAP_MAX_LOBES];
for (int k = 0; k < ENVCAP_MAX_LOBES; ++k) { C[k] = vec4(-1.0, -1.0, 1.0, 20.0); rho[k] = vec3(0.1); }
vec3 blocked;
vec3 bounced;
envcap_dynamic_terms(a.xyz, vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, 1.0), vec3(0.0, 1.0, 0.0), normalize(b.xyz),
                     vec3(0.5), C, rho, 2, blocked, bounced);
o = vec4(blocked + bounced, envcap_cap_overlap(a.w, b.w, c.w));""",
        (("ENVCAP_DYNAMIC_ENVIRONMENT", "unit_environment"),)),
    "envcap_sky_visibility": RuntimeUnit(("runtime/envcap_sky_visibility.glsl",),
                                         "ENVCAP_BINDING(3) uniform ENVCAP_PROBES_SAMPLER probes;\n"
                                         "ENVCAP_BINDING(5) uniform ENVCAP_PROBES_SAMPLER skyd;\n", """
float xr[ENVCAP_MAX_RUNGS];
for (int k = 0; k < ENVCAP_MAX_RUNGS; ++k) xr[k] = 16.0 - 0.25 * float(k);
vec3 ksh[ENVCAP_SKY_VIS_MAX_SH];
for (int k = 0; k < ENVCAP_SKY_VIS_MAX_SH; ++k) ksh[k] = vec3(0.1 * float(k));
o = vec4(envcap_sky_visible(probes, skyd, normalize(b.xyz), vec2(0.8, 0.6), a.w, c.z, c.w, xr, 12, 4, 1, ksh, 9, a.x, a.yzw, b.xyz, 2), 1.0);"""),
    "envcap_face_atlas": RuntimeUnit(("runtime/envcap_face_atlas.glsl",), "ENVCAP_BINDING(3) uniform sampler2DArray atlas;\n", """
o = envcap_face_atlas_lod(atlas, normalize(b.xyz), a.w, c.w);"""),
}
"""Exercising units by library file name (``shaders/runtime/NAME.glsl``)."""


def unit_source(target: str | ShaderTarget, unit: str | RuntimeUnit, *, expand: bool = True) -> str:
    """Fragment shader for ``target`` that runs ``unit`` (a :data:`RUNTIME_UNITS` name or a
    :class:`RuntimeUnit`).  ``expand``: resolve the includes (envcap's loader); else keep the
    ``#include`` lines, with ``GL_GOOGLE_include_directive`` enabled for glslang ``-I``."""
    t = TARGETS[target] if isinstance(target, str) else target
    u = RUNTIME_UNITS[unit] if isinstance(unit, str) else unit
    head, _, rest = prologue(t).partition("\n")
    ext = "" if expand else "#extension GL_GOOGLE_include_directive : require\n"
    src = (head + "\n" + ext + rest + "".join(f"#define {k} {v}\n" for k, v in u.defines)
           + "".join(f'#include "{name}"\n' for name in u.includes)
           + "ENVCAP_IN(0) in vec4 a;\nENVCAP_IN(1) in vec4 b;\nENVCAP_IN(2) in vec4 c;\n"
           + "ENVCAP_OUT(0) out vec4 o;\n" + u.declarations
           + "void main() {\n" + "\n".join("    " + ln for ln in u.body.strip("\n").splitlines()) + "\n}\n")
    return expand_includes(src) if expand else src
