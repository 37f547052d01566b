#ifndef ENVCAP_CROWD_FRAG_GLSL
#define ENVCAP_CROWD_FRAG_GLSL
// envcap crowd, fragment stage: an avatar lit by the street's probes (Eq. 3 of its Lafortune
// material through the runtime's lookup, the sky composite), minus the light its own blocker bones
// and its neighbours block, plus what they bounce (envcap_dynamic_terms), plus the analytic sun
// with its visibility.  Common subset of GLSL 4.50 / ES 3.00 after a target prologue
// (envcap.runtime.shader_targets.prologue); docs/crowd.md derives each term.
//
// Defines (before this file): CROWD_SAMPLE (the runtime lookup, vec3 NAME(probes, sky, x, d, w,
// street): the method's GLSL function, default envcap_sample_oblique), CROWD_TARGETS (desktop
// tests: also write the position, normal, self spheres and each term to float targets 1..7).
// Uniforms: envcap_street (runtime/envcap_street_uniforms.glsl), crowd_to_local (mat3: world
// directions into the street's frame, so that crowd_to_local * x is the street-local point of x
// relative to the render origin, which is the street's local origin), crowd_camera (m, relative),
// crowd_terms (0 probes only, 1 + self, 2 + self and neighbours), the material crowd_rho_d,
// crowd_C[] (xyz, w = power), crowd_rho_s[], crowd_nlobes, crowd_albedo (what the spheres bounce),
// the sun crowd_sun_dir (unit, towards the sun, world), crowd_sun_e (irradiance normal to it),
// crowd_sun_cos (cos of its angular radius), crowd_exposure.
// Textures: probes (unit 3), sky (unit 4), crowd_instances (unit 5: crowd_vert.glsl),
// crowd_neighbours (unit 6, RGBA32F, row = walker, 2K texels; envcap.crowd.sphere_buffer),
// crowd_distance (unit 7, CROWD_DISTANCE: the method depth_refine's 1/distance cube array).

#ifndef CROWD_SAMPLE
#define CROWD_SAMPLE envcap_sample_oblique
#endif
#ifndef CROWD_NEIGHBOURS
#define CROWD_NEIGHBOURS 6
#endif
#ifndef ENVCAP_MAX_SPHERES
#define ENVCAP_MAX_SPHERES 48
#endif
#ifndef CROWD_SELF_CLAMP
#define CROWD_SELF_CLAMP 0.7
#endif
#define ENVCAP_SPHERES_GLOBAL
#define ENVCAP_DYNAMIC_ENVIRONMENT crowd_environment

#include "runtime/envcap_street_uniforms.glsl"
#include "runtime/envcap_dynamic_spheres.glsl"

ENVCAP_BINDING(3) uniform ENVCAP_PROBES_SAMPLER probes;
ENVCAP_BINDING(4) uniform samplerCube sky;

#ifdef CROWD_DISTANCE
// depth_refine: the probes' inverse distance (1/m in .r, NEAREST; runtime/envcap_depth_refine.glsl)
#include "runtime/envcap_depth_refine.glsl"
ENVCAP_BINDING(7) uniform ENVCAP_DISTANCE_SAMPLER crowd_distance;
vec3 crowd_sample_depth_refine(ENVCAP_PROBES_SAMPLER probes_, ENVCAP_SKY_SAMPLER sky_, vec3 x, vec3 d, float w,
                               EnvcapStreet street)
{
    return envcap_sample_depth_refine(probes_, sky_, crowd_distance, x, d, w, street);
}
#endif
ENVCAP_BINDING(5) uniform highp sampler2D crowd_instances;
ENVCAP_BINDING(6) uniform highp sampler2D crowd_neighbours;
uniform int crowd_joint_count;
uniform mat3 crowd_to_local;
uniform vec3 crowd_camera;
uniform int crowd_terms;
uniform vec3 crowd_rho_d;
uniform vec4 crowd_C[ENVCAP_MAX_LOBES];
uniform vec3 crowd_rho_s[ENVCAP_MAX_LOBES];
uniform int crowd_nlobes;
uniform float crowd_albedo;
uniform vec3 crowd_sun_dir;
uniform vec3 crowd_sun_e;
uniform float crowd_sun_cos;
uniform float crowd_near_factor;

in vec3 v_position;
in vec3 v_normal;
flat in ivec2 v_blockers;
flat in int v_walker;

ENVCAP_OUT(0) out vec4 out_color;
#ifdef CROWD_TARGETS
ENVCAP_OUT(1) out vec4 out_position;   // xyz relative to the render origin, w = walker
ENVCAP_OUT(2) out vec4 out_normal;     // unit normal, w = 1
ENVCAP_OUT(3) out vec4 out_self0;
ENVCAP_OUT(4) out vec4 out_self1;
ENVCAP_OUT(5) out vec4 out_eq3;        // Eq. 3 from the probes
ENVCAP_OUT(6) out vec4 out_self_term;  // bounced - blocked, own bones only
ENVCAP_OUT(7) out vec4 out_all_term;   // bounced - blocked, own bones and neighbours
#endif

vec3 g_local;   // the shading point, street-local (for crowd_environment)
vec4 g_self0;   // the own blocker bones' spheres at the shading point (crowd_self_sphere)
vec4 g_self1;

// Blocker bone sphere j (< 0: none, radius 0) of the walker at the shading point x (numpy twin:
// envcap.crowd.sphere_buffer.self_spheres): slid along its bone from the joint's head h through
// the fitted centre c to 2c - h to the point nearest x, u = clamp((x - h).(b - h) / |b - h|^2);
// a slid sphere that would hold x keeps its fitted centre; its radius then at most
// CROWD_SELF_CLAMP times its centre's distance from x (a fitted sphere of the next limb holds
// points of the body's surface: unclamped it blocks half the sky there).
vec4 crowd_self_sphere(int walker, int j, vec3 x)
{
    if (j < 0) return vec4(0.0);
    vec4 s = texelFetch(crowd_instances, ivec2(4 * crowd_joint_count + j, walker), 0);
    vec3 h = texelFetch(crowd_instances, ivec2(5 * crowd_joint_count + j, walker), 0).xyz;
    vec3 e = 2.0 * (s.xyz - h);
    float ee = dot(e, e);
    float u = ee > 0.0 ? clamp(dot(x - h, e) / ee, 0.0, 1.0) : 0.5;
    vec3 p = h + u * e;
    if (length(x - p) <= s.w) p = s.xyz;
    return vec4(p, min(s.w, CROWD_SELF_CLAMP * length(p - x)));
}

// The cos^w-convolved environment along the world direction dir seen from the shading point.
vec3 crowd_environment(vec3 dir, float w)
{
    return CROWD_SAMPLE(probes, sky, g_local, dir, w, envcap_street);
}

void crowd_push(vec4 s)
{
    if (envcap_sphere_count < ENVCAP_MAX_SPHERES && s.w > 0.0) {
        envcap_spheres[envcap_sphere_count] = s;
        envcap_sphere_albedo[envcap_sphere_count] = vec3(crowd_albedo);
        envcap_sphere_count += 1;
    }
}

// Fill the runtime's sphere buffer for x (numpy twin: envcap.crowd.sphere_buffer.fragment_spheres):
// own blocker bones, then each neighbour nearest first, its bone spheres when x is within
// crowd_near_factor enclosing radii of its one sphere's centre, else that one sphere.
void crowd_gather_spheres(vec3 x, bool self_, bool neighbours)
{
    envcap_sphere_count = 0;
    if (self_) {
        crowd_push(g_self0);
        crowd_push(g_self1);
    }
    if (!neighbours) return;
    for (int m = 0; m < CROWD_NEIGHBOURS; ++m) {
        vec4 one = texelFetch(crowd_neighbours, ivec2(m, v_walker), 0);
        vec4 info = texelFetch(crowd_neighbours, ivec2(CROWD_NEIGHBOURS + m, v_walker), 0);
        if (!(one.w > 0.0)) continue;
        if (length(x - one.xyz) < crowd_near_factor * info.x) {
            int row = int(info.y);
            for (int j = 0; j < crowd_joint_count; ++j)
                crowd_push(texelFetch(crowd_instances, ivec2(4 * crowd_joint_count + j, row), 0));
        } else {
            crowd_push(one);
        }
    }
}

// Eq. 3 with the crowd's lookup (envcap_shade_lafortune with CROWD_SAMPLE for every lobe).
vec3 crowd_eq3(vec3 T, vec3 B, vec3 N, vec3 v)
{
    vec3 vl = vec3(dot(v, T), dot(v, B), dot(v, N));
    vec3 L = crowd_rho_d * crowd_environment(N, 1.0);
    for (int i = 0; i < crowd_nlobes && i < ENVCAP_MAX_LOBES; ++i) {
        vec4 lobe = envcap_lafortune_lobe(vl, crowd_C[i].xyz, crowd_C[i].w);
        if (lobe.w > 0.0)
            L += crowd_rho_s[i] * lobe.w * crowd_environment(lobe.x * T + lobe.y * B + lobe.z * N, crowd_C[i].w);
    }
    return L;
}

// bounced - blocked of the gathered spheres.
vec3 crowd_dynamic(vec3 x, vec3 T, vec3 B, vec3 N, vec3 v)
{
    vec3 blocked;
    vec3 bounced;
    envcap_dynamic_terms(x, T, B, N, v, crowd_rho_d, crowd_C, crowd_rho_s, crowd_nlobes, blocked, bounced);
    return bounced - blocked;
}

// The sun's visible fraction at x: the street (the nearest probe's alpha along the sun, with its
// parallax, at level 0: the street geometry that hides the sun from x as the probe saw it) times
// each gathered sphere's cover of the sun's disk (a linear ramp over the disk's diameter).
float crowd_sun_visibility(vec3 x)
{
    vec3 xl = g_local;
    int i = envcap_nearest_probe(xl[envcap_street.along], envcap_street.along_s, envcap_street.count);
    vec4 par = envcap_parallax(xl, envcap_frame_dir(crowd_sun_dir, envcap_street.frame), envcap_street.pos[i].xyz,
                               envcap_street.planes[i], envcap_street.along);
    float vis = 1.0 - clamp(ENVCAP_PROBES_LOD(probes, par.xyz, envcap_street.pos[i].w, 0.0).a, 0.0, 1.0);
    float sun_r = acos(clamp(crowd_sun_cos, -1.0, 1.0));
    for (int k = 0; k < ENVCAP_MAX_SPHERES; ++k) {
        if (k >= envcap_sphere_count) break;
        vec3 D = envcap_spheres[k].xyz - x;
        float l = length(D);
        if (!(l > envcap_spheres[k].w)) continue;
        float theta = asin(envcap_spheres[k].w / l);
        float gamma = acos(clamp(dot(D / l, crowd_sun_dir), -1.0, 1.0));
        vis *= clamp((gamma - theta) / max(2.0 * sun_r, 1.0e-4) + 0.5, 0.0, 1.0);
    }
    return vis;
}

// The Lafortune BRDF (1/sr) for light from l to the viewer v, both world, frame T, B, N.
vec3 crowd_brdf(vec3 T, vec3 B, vec3 N, vec3 l, vec3 v)
{
    vec3 ul = vec3(dot(l, T), dot(l, B), dot(l, N));
    vec3 vl = vec3(dot(v, T), dot(v, B), dot(v, N));
    vec3 f = crowd_rho_d / ENVCAP_PI;
    for (int i = 0; i < crowd_nlobes && i < ENVCAP_MAX_LOBES; ++i)
        f += crowd_rho_s[i] * pow(max(dot(ul, crowd_C[i].xyz * vl), 0.0), crowd_C[i].w);
    return f;
}

void main()
{
    if (crowd_terms < 0) {                             // the unlit crowd (the bench's reference)
        out_color = vec4(0.5, 0.5, 0.5, 1.0);
        return;
    }
    vec3 x = v_position;
    vec3 N = normalize(v_normal);
    vec3 v = normalize(crowd_camera - x);
    if (dot(N, v) < 0.0) N = -N;                       // a back face seen through a gap
    vec3 T = normalize(cross(abs(N.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0), N));
    vec3 B = cross(N, T);
    g_local = crowd_to_local * x;
    g_self0 = crowd_self_sphere(v_walker, v_blockers.x, x);
    g_self1 = crowd_self_sphere(v_walker, v_blockers.y, x);
    vec3 L = crowd_eq3(T, B, N, v);
#ifdef CROWD_TARGETS
    out_position = vec4(x, float(v_walker));
    out_normal = vec4(N, 1.0);
    out_self0 = g_self0;
    out_self1 = g_self1;
    out_eq3 = vec4(L, 1.0);
    crowd_gather_spheres(x, true, false);
    out_self_term = vec4(crowd_dynamic(x, T, B, N, v), 1.0);
    crowd_gather_spheres(x, true, true);
    out_all_term = vec4(crowd_dynamic(x, T, B, N, v), 1.0);
#endif
    crowd_gather_spheres(x, crowd_terms >= 1, crowd_terms >= 2);
    if (crowd_terms >= 1) L += crowd_dynamic(x, T, B, N, v);
    float nl = dot(N, crowd_sun_dir);
    if (nl > 0.0 && dot(crowd_sun_e, crowd_sun_e) > 0.0)
        L += crowd_sun_e * crowd_brdf(T, B, N, crowd_sun_dir, v) * nl * crowd_sun_visibility(x);
    out_color = vec4(max(L, vec3(0.0)), 1.0);
}

#endif  // ENVCAP_CROWD_FRAG_GLSL
