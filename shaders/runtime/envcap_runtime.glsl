#ifndef ENVCAP_RUNTIME_GLSL
#define ENVCAP_RUNTIME_GLSL
// envcap runtime sampling library: three-plane parallax, mip shift, sky composite, Eq. 3.
// Include this file (resources.shader_source resolves the include lines) after "#version 430".
// A street's probes and lobe table travel in one struct, EnvcapStreet (below); declare it as a
// uniform with runtime/envcap_street_uniforms.glsl and fill it from the probe set's manifest
// (envcap.runtime.street.RuntimeStreet.uniforms(powers), the Python mirror StreetUniforms).
//
// Coordinates are street-local: every position in EnvcapStreet is in the street's frame (the world
// for a street along x or z; turned by the street's yaw about its plan origin for a street at any
// angle, envcap.core.street_frame) minus the street's origin (StreetUniforms.origin, float64 on
// the host, not uploaded: its probes' box center rounded to whole km), computed in float64 and
// rounded to float32 once.  The shading point x passed to the functions below must be in the same
// frame: StreetUniforms.to_local(x_world) (float32(world_to_frame(x) - origin), float64 maths),
// or camera-relative (in the frame) plus float32(camera_frame - origin) computed in float64.  A
// street 10^6 m from the world origin then samples like the same street at the origin (world
// float32 coordinates there have ~6 cm steps).  Directions d are WORLD directions: the
// envcap_sample_* functions turn them into the street's frame with EnvcapStreet.frame (one 2x2
// rotation) for the parallax and the probe fetches; the sky is fetched along d itself.
//
// Textures: `probes` is a cube-map array (layer = probe) of premultiplied RGBA street radiance
// (alpha 0 where the sky shows), level k convolved with the normalized cos^powers[k] lobe;
// `sky` is a cube map with the same lobe ladder.  Sampling is trilinear and seamless.
// Texture fetches per lobe: 1 probe + 1 sky (envcap_sample_*), 2 probes + 1 sky (blended); the
// sky fetch is skipped where the street's alpha is >= 1 (the result is the same: 1 - a = 0).

// ENVCAP_PROBES_SAMPLER and ENVCAP_PROBES_LOD: the probe texture of the target
#include "runtime/envcap_probe_texture.glsl"
#include "runtime/envcap_street.glsl"
#include "runtime/envcap_lobes.glsl"
// ENVCAP_SKY_SAMPLER and ENVCAP_SKY_LOD(sky, dir, lod): the sky texture and its lookup, a plain cube
// map unless a variant defines both first (runtime/envcap_rung_street.glsl: the sky's rung array).
#ifndef ENVCAP_SKY_SAMPLER
#define ENVCAP_SKY_SAMPLER samplerCube
#define ENVCAP_SKY_LOD(sky, dir, lod) textureLod(sky, dir, lod)
#endif

// One street of a probe set, as the runtime samples it.  Mirrored field for field (same names,
// same order) by envcap.runtime.street.StreetUniforms; tests/runtime/test_street_uniforms.py
// compiles this struct and checks the mirror.
struct EnvcapStreet {
    float along_s[ENVCAP_MAX_PROBES];  // along-street coordinate of probe i (m, street-local), ascending
    vec4 pos[ENVCAP_MAX_PROBES];       // probe i: xyz street-local position (m), w = its layer in `probes`
    vec4 planes[ENVCAP_MAX_PROBES];    // probe i: (facade_min, facade_max, ground0, slope) in street-local m:
                                       // ground height ground0 + slope * x[along] (slope 0: flat at ground0)
    int count;                         // number of probes, 1 .. ENVCAP_MAX_PROBES
    int along;                         // street axis: 0 = x, 2 = z (of the street's frame)
    float xk[ENVCAP_MAX_LEVELS];       // log2(1 + powers[k]): the z(w) table of the lobe ladder
    int nlevels;                       // number of levels, 1 .. ENVCAP_MAX_LEVELS
    vec2 frame;                        // (cos yaw, sin yaw) of the street's frame; (1, 0): the world
};

// Clamp a continuous mip level into the chain [0, n - 1]; NaN -> 0.
float envcap_clamp_level(float z, int n)
{
    return (z > 0.0) ? min(z, float(max(n, 1) - 1)) : 0.0;
}

// The level (the argument of ENVCAP_PROBES_LOD / ENVCAP_SKY_LOD) of a lookup of power w on the
// street's table: z(w) clamped to the chain; on a rung ladder (runtime/envcap_rung_street.glsl
// defines ENVCAP_RUNG_LADDER) the lookup position envcap_rung_lod_of_w, whose top segment
// reaches the mirror.
float envcap_lod_of_w(float w, float xk[ENVCAP_MAX_LEVELS], int n)
{
#ifdef ENVCAP_RUNG_LADDER
    return envcap_rung_lod_of_w(w, xk, n);
#else
    return envcap_clamp_level(envcap_z_of_w(w, xk, n), n);
#endif
}

// Sky composite: street radiance is premultiplied, so the visible sky adds (1 - alpha) * sky.
// Alpha is clamped to [0, 1] (filtering and half floats can step just outside).
vec3 envcap_composite(vec4 street, vec3 sky)
{
    return street.rgb + (1.0 - clamp(street.a, 0.0, 1.0)) * sky;
}

// Radiance of the environment convolved with the cos^w lobe around unit direction d (in the
// street's frame), as seen from shading point x, from one probe: `layer` of `probes`, probe
// position p, its planes.  The street is sampled along the parallax vector at the shifted level
// z(w * ratio^2); the sky along dsky (d in the world) at z(w) (the sky is at infinity: no
// parallax, no shift).
vec3 envcap_sample_probe(ENVCAP_PROBES_SAMPLER probes, ENVCAP_SKY_SAMPLER sky, vec3 x, vec3 d, vec3 dsky, float w,
                         float layer, vec3 p, vec4 planes, int along,
                         float xk[ENVCAP_MAX_LEVELS], int nlevels)
{
    vec4 par = envcap_parallax(x, d, p, planes, along);
    float zs = envcap_lod_of_w(envcap_shift_power(w, par.w), xk, nlevels);
    vec4 st = ENVCAP_PROBES_LOD(probes, par.xyz, layer, zs);
    if (!(st.a < 1.0)) return st.rgb;            // street covers the lobe: no sky fetch needed
    float zk = envcap_lod_of_w(w, xk, nlevels);
    return envcap_composite(st, ENVCAP_SKY_LOD(sky, dsky, zk).rgb);
}

// As envcap_sample_probe, with the probe of `street` nearest to x along the street; d in the world.
vec3 envcap_sample_nearest(ENVCAP_PROBES_SAMPLER probes, ENVCAP_SKY_SAMPLER sky, vec3 x, vec3 d, float w, EnvcapStreet street)
{
    int i = envcap_nearest_probe(x[street.along], street.along_s, street.count);
    return envcap_sample_probe(probes, sky, x, envcap_frame_dir(d, street.frame), d, w, street.pos[i].w,
                               street.pos[i].xyz, street.planes[i], street.along, street.xk, street.nlevels);
}

// Beyond the paper: blend the two probes that bracket x along the street, each with its own
// parallax and mip shift, weights linear in the along-street coordinate (continuous: no
// popping at the midpoint).  The sky term is shared.
vec3 envcap_sample_blended(ENVCAP_PROBES_SAMPLER probes, ENVCAP_SKY_SAMPLER sky, vec3 x, vec3 d, float w, EnvcapStreet street)
{
    vec3 pr = envcap_probe_pair(x[street.along], street.along_s, street.count);
    int i0 = int(pr.x), i1 = int(pr.y);
    vec3 df = envcap_frame_dir(d, street.frame);
    vec4 a = envcap_parallax(x, df, street.pos[i0].xyz, street.planes[i0], street.along);
    vec4 b = envcap_parallax(x, df, street.pos[i1].xyz, street.planes[i1], street.along);
    float za = envcap_lod_of_w(envcap_shift_power(w, a.w), street.xk, street.nlevels);
    float zb = envcap_lod_of_w(envcap_shift_power(w, b.w), street.xk, street.nlevels);
    vec4 st = (1.0 - pr.z) * ENVCAP_PROBES_LOD(probes, a.xyz, street.pos[i0].w, za)
            + pr.z * ENVCAP_PROBES_LOD(probes, b.xyz, street.pos[i1].w, zb);
    if (!(st.a < 1.0)) return st.rgb;            // street covers the lobe: no sky fetch needed
    float zk = envcap_lod_of_w(w, street.xk, street.nlevels);
    return envcap_composite(st, ENVCAP_SKY_LOD(sky, d, zk).rgb);
}

// The street part of a lookup composited over the sky at d (world), level z(w) (skipped where alpha >= 1).
vec3 envcap_over_sky(vec4 st, ENVCAP_SKY_SAMPLER sky, vec3 d, float w, EnvcapStreet street)
{
    if (!(st.a < 1.0)) return st.rgb;
    float zk = envcap_lod_of_w(w, street.xk, street.nlevels);
    return envcap_composite(st, ENVCAP_SKY_LOD(sky, d, zk).rgb);
}

// Beyond the paper: the nearest probe with the oblique mip shift w' = w ratio^2 cos(alpha)/cos(beta)
// (envcap_parallax_oblique; method planes_mip_oblique).  Fetches: 1 probe + 1 sky, as envcap_sample_nearest.
vec3 envcap_sample_oblique(ENVCAP_PROBES_SAMPLER probes, ENVCAP_SKY_SAMPLER sky, vec3 x, vec3 d, float w, EnvcapStreet street)
{
    int i = envcap_nearest_probe(x[street.along], street.along_s, street.count);
    vec4 par = envcap_parallax_oblique(x, envcap_frame_dir(d, street.frame), street.pos[i].xyz, street.planes[i], street.along);
    float zs = envcap_lod_of_w(max(w, 0.0) * par.w, street.xk, street.nlevels);
    return envcap_over_sky(ENVCAP_PROBES_LOD(probes, par.xyz, street.pos[i].w, zs), sky, d, w, street);
}

// Beyond the paper: the nearest probe at the level of the lobe's traced footprint (four sigma rays,
// envcap_sigma_footprint; method planes_mip_footprint).  Fetches: 1 probe + 1 sky.
vec3 envcap_sample_footprint(ENVCAP_PROBES_SAMPLER probes, ENVCAP_SKY_SAMPLER sky, vec3 x, vec3 d, float w, EnvcapStreet street)
{
    int i = envcap_nearest_probe(x[street.along], street.along_s, street.count);
    vec3 r, m;
    vec2 v = envcap_sigma_footprint(x, envcap_frame_dir(d, street.frame), w, street.pos[i].xyz, street.planes[i],
                                    street.along, r, m);
    float wp = envcap_footprint_power(sqrt(v.x * v.y));
    float zs = envcap_lod_of_w(wp, street.xk, street.nlevels);
    return envcap_over_sky(ENVCAP_PROBES_LOD(probes, r, street.pos[i].w, zs), sky, d, w, street);
}

// Beyond the paper: the traced footprint with its anisotropy, ENVCAP_ANISO_TAPS lookups along its
// long axis (method planes_mip_aniso, docs/runtime.md).  Each tap has the variance
// max(V_minor, V_major / (1 + (n^2 - 1) / 3)); the taps are equally spaced, mean square offset
// V_major - V_tap.  Fetches: ENVCAP_ANISO_TAPS probes + 1 sky.
#ifndef ENVCAP_ANISO_TAPS
#define ENVCAP_ANISO_TAPS 2
#endif
vec3 envcap_sample_aniso(ENVCAP_PROBES_SAMPLER probes, ENVCAP_SKY_SAMPLER sky, vec3 x, vec3 d, float w, EnvcapStreet street)
{
    int i = envcap_nearest_probe(x[street.along], street.along_s, street.count);
    vec3 r, m;
    vec2 v = envcap_sigma_footprint(x, envcap_frame_dir(d, street.frame), w, street.pos[i].xyz, street.planes[i],
                                    street.along, r, m);
    float n = float(ENVCAP_ANISO_TAPS);
    float vt = max(v.x, v.y / (1.0 + (n * n - 1.0) / 3.0));
    float zs = envcap_lod_of_w(envcap_footprint_power(vt), street.xk, street.nlevels);
    float spread = sqrt(max(v.y - vt, 0.0));
    float step_ = n > 1.0 ? sqrt(12.0 / (n * n - 1.0)) : 0.0;
    vec4 st = vec4(0.0);
    for (int k = 0; k < ENVCAP_ANISO_TAPS; ++k) {
        vec3 u = r + ((float(k) - 0.5 * (n - 1.0)) * step_ * spread) * m;
        st += ENVCAP_PROBES_LOD(probes, u / length(u), street.pos[i].w, zs);
    }
    return envcap_over_sky(st / n, sky, d, w, street);
}

// Beyond the paper: four lookups where the lobe's four sigma rays land, seen from the probe (method
// planes_mip_sigma, docs/runtime.md): taps towards r + (sqrt(F) / ENVCAP_SPREAD)(img_j - r), each at the
// power of the variance (1 - F) V_minor, F = ENVCAP_TAP_SHARE.  They follow a footprint that a plane
// switch splits in two.  Fetches: 4 probes + 1 sky.
const float ENVCAP_TAP_SHARE = 0.75;
vec3 envcap_sample_sigma(ENVCAP_PROBES_SAMPLER probes, ENVCAP_SKY_SAMPLER sky, vec3 x, vec3 d, float w, EnvcapStreet street)
{
    int i = envcap_nearest_probe(x[street.along], street.along_s, street.count);
    vec3 r, m, img[4];
    vec2 v = envcap_sigma_footprint_rays(x, envcap_frame_dir(d, street.frame), w, street.pos[i].xyz, street.planes[i],
                                         street.along, r, m, img);
    float zs = envcap_lod_of_w(envcap_footprint_power((1.0 - ENVCAP_TAP_SHARE) * v.x), street.xk, street.nlevels);
    float beta = sqrt(ENVCAP_TAP_SHARE) / ENVCAP_SPREAD;
    vec4 st = vec4(0.0);
    for (int k = 0; k < 4; ++k) {
        vec3 u = r + beta * (img[k] - r);
        st += ENVCAP_PROBES_LOD(probes, u / length(u), street.pos[i].w, zs);
    }
    return envcap_over_sky(0.25 * st, sky, d, w, street);
}

// Eq. 3 for a Lafortune BRDF  f(u, v) = rho_d / pi + sum_i rho_s[i] max(u . Cv_i, 0)^w[i]:
//   L_o(v) ~ rho_d E_1(n) + sum_i rho_s[i] |Cv_i|^w_i (2 pi / (1 + w_i)) max(c_i . n, 0) E_wi(c_i)
// (envcap's form, the default).  With ENVCAP_EQ3_PAPER_FORM defined the factor max(c_i . n, 0)
// is left out: the paper's form, for lobes fitted to BRDF x cos (envcap_lafortune_lobe; a fit
// without a diffuse term passes rho_d = 0).  docs/runtime.md, "Two forms of Eq. 3".
// with E_w the cos^w-convolved environment seen from x (parallax + mip shift + sky, nearest
// probe).  Frame: tangent T, bitangent B, normal N (world, orthonormal); v world, toward the
// viewer.  Up to ENVCAP_MAX_LOBES specular lobes (C[i].xyz, w = C[i].w), rho_s[i].rgb.
#ifndef ENVCAP_MAX_LOBES
#define ENVCAP_MAX_LOBES 3
#endif
vec3 envcap_shade_lafortune(ENVCAP_PROBES_SAMPLER probes, ENVCAP_SKY_SAMPLER sky, vec3 x, vec3 T, vec3 B, vec3 N,
                            vec3 v, vec3 rho_d, vec4 C[ENVCAP_MAX_LOBES], vec3 rho_s[ENVCAP_MAX_LOBES],
                            int nlobes, EnvcapStreet street)
{
    vec3 vl = vec3(dot(v, T), dot(v, B), dot(v, N));
    vec3 L = rho_d * envcap_sample_nearest(probes, sky, x, N, 1.0, street);
    for (int i = 0; i < nlobes && i < ENVCAP_MAX_LOBES; ++i) {
        vec4 lobe = envcap_lafortune_lobe(vl, C[i].xyz, C[i].w);
        if (lobe.w > 0.0) {
            vec3 cw = lobe.x * T + lobe.y * B + lobe.z * N;
            L += rho_s[i] * lobe.w * envcap_sample_nearest(probes, sky, x, cw, C[i].w, street);
        }
    }
    return L;
}

#endif  // ENVCAP_RUNTIME_GLSL
