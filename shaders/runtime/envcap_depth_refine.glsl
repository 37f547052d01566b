#ifndef ENVCAP_DEPTH_REFINE_GLSL
#define ENVCAP_DEPTH_REFINE_GLSL
// envcap runtime: the depth-refined lookup (method depth_refine; numpy twin
// envcap/runtime/methods/depth_refine.py, which documents the steps).  No #version: #include this.
//
// `dist`: a cube-map array, one layer per probe (the same layers as `probes`), one level, filtered
// NEAREST (GL_NEAREST: a linear read mixes a roof's distance with the sky's 0), holding the
// inverse radial distance 1/m from the probe in .r, 0 where the probe sees the sky
// (envcap.runtime.methods.depth_refine.inverse_distance; R16F or R32F).  The street's planes are
// the fitted set (RuntimeStreet with planes = "fitted").
// Fetches: 1 probe + 1 sky (skipped where alpha >= 1) + 1 distance, + ENVCAP_DEPTH_STEPS - 1
// distance fetches where the planes disagree with the distance (a branch).
// ENVCAP_DISTANCE_SAMPLER / ENVCAP_DISTANCE_FETCH(dist, dir, layer): the distance texture and its
// level-0 read; by default the probes' layout (ENVCAP_PROBES_SAMPLER, ENVCAP_PROBES_LOD): a
// cube-map array on desktop GL, GL ES 3.2 and Vulkan; on WebGL2 a face atlas
// (runtime/envcap_face_atlas.glsl), whose read is filtered, not the nearest texel.

#include "runtime/envcap_runtime.glsl"

#ifndef ENVCAP_DISTANCE_SAMPLER
#define ENVCAP_DISTANCE_SAMPLER ENVCAP_PROBES_SAMPLER
#define ENVCAP_DISTANCE_FETCH(dist, dir, layer) ENVCAP_PROBES_LOD(dist, dir, layer, 0.0).r
#endif

#ifndef ENVCAP_DEPTH_STEPS
#define ENVCAP_DEPTH_STEPS 2
#endif
// relative mismatch of the plane hit's distance and the probe's above which the hit is refined
#ifndef ENVCAP_DEPTH_TOL
#define ENVCAP_DEPTH_TOL 0.1
#endif
// inverse distances (1/m) at or below this are sky
const float ENVCAP_MIN_INV_DISTANCE = 1.0e-5;

// Unit direction from the probe towards o + t d (o = x_c - p); d where that point is at the probe.
vec3 envcap_depth_towards(vec3 o, vec3 d, float t, out float hl)
{
    vec3 h = o + t * d;
    hl = length(h);
    return hl > ENVCAP_MIN_DIST ? h / hl : d;
}

// The depth-refined hit: vec4(r, q), r the unit direction from the probe at p to the hit, q the
// power multiplier of the oblique shift (w' = w q).  planes: the probe's vec4 (facade_min,
// facade_max, ground0, slope).  Total: finite for finite inputs.
vec4 envcap_depth_refine(ENVCAP_DISTANCE_SAMPLER dist, float layer, vec3 x, vec3 d, vec3 p, vec4 planes, int along)
{
    vec3 xc = envcap_clamp_to_street(x, planes, along);
    vec2 te = envcap_plane_exits(xc, d, planes, along);
    float t = min(min(te.x, te.y), ENVCAP_FAR);
    bool ground = te.y < te.x;
    vec3 o = xc - p;
    float hl;
    vec3 u = envcap_depth_towards(o, d, t, hl);
    float s = ENVCAP_DISTANCE_FETCH(dist, u, layer);
    if (s > ENVCAP_MIN_INV_DISTANCE && abs(hl * s - 1.0) > ENVCAP_DEPTH_TOL) {
        float b = dot(o, d), oo = dot(o, o);
        for (int k = 0; k < ENVCAP_DEPTH_STEPS; ++k) {
            if (s > ENVCAP_MIN_INV_DISTANCE) {
                float rad = 1.0 / s;
                float disc = b * b - (oo - rad * rad);
                float tn = -b + sqrt(max(disc, 0.0));
                if (disc >= 0.0 && tn > 0.0) t = tn;
            }
            if (k + 1 < ENVCAP_DEPTH_STEPS) {
                u = envcap_depth_towards(o, d, t, hl);
                s = ENVCAP_DISTANCE_FETCH(dist, u, layer);
            }
        }
    }
    const float lo = 1.0 / (ENVCAP_MAX_RATIO * ENVCAP_MAX_RATIO);
    if (!(t < ENVCAP_FAR)) return vec4(d, 1.0);
    float dp;
    vec3 r = envcap_depth_towards(o, d, t, dp);
    if (!(dp > ENVCAP_MIN_DIST)) return vec4(d, lo);
    float ratio = min(max(dp / max(t, ENVCAP_MIN_DIST), 1.0 / ENVCAP_MAX_RATIO), ENVCAP_MAX_RATIO);
    vec3 n = envcap_exit_normal(ground, planes, along);   // the plane the ray left through
    float ca = max(abs(dot(n, d)), ENVCAP_MIN_COS);
    float cb = max(abs(dot(n, r)), ENVCAP_MIN_COS);
    return vec4(r, min(max(ratio * ratio * (ca / cb), lo), ENVCAP_MAX_RATIO * ENVCAP_MAX_RATIO));
}

// The full lookup of method depth_refine: nearest probe, depth-refined hit, oblique level, sky.
vec3 envcap_sample_depth_refine(ENVCAP_PROBES_SAMPLER probes, ENVCAP_SKY_SAMPLER sky, ENVCAP_DISTANCE_SAMPLER dist,
                                vec3 x, vec3 d, float w, EnvcapStreet street)
{
    int i = envcap_nearest_probe(x[street.along], street.along_s, street.count);
    // parallax and probe fetches in the street's frame; the sky along the world direction d
    vec4 rq = envcap_depth_refine(dist, street.pos[i].w, x, envcap_frame_dir(d, street.frame), street.pos[i].xyz,
                                  street.planes[i], street.along);
    float zs = envcap_lod_of_w(max(w, 0.0) * rq.w, street.xk, street.nlevels);
    return envcap_over_sky(ENVCAP_PROBES_LOD(probes, rq.xyz, street.pos[i].w, zs), sky, d, w, street);
}

#endif  // ENVCAP_DEPTH_REFINE_GLSL
