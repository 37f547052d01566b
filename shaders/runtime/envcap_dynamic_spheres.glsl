#ifndef ENVCAP_DYNAMIC_SPHERES_GLSL
#define ENVCAP_DYNAMIC_SPHERES_GLSL
// envcap runtime, many dynamic spheres: the ENVCAP_SPHERE_CAP most occluding spheres of a shading
// point, their overlap rule, and the blocked / bounced light of a Lafortune material (Section IV
// of the paper on top of Eq. 3).  No #version: #include this.  Numpy twin: envcap/dynamic/spheres.py,
// envcap/dynamic/terms.py.  docs/dynamic.md, "Many spheres" and "Blocked and bounced light".
//
// Defines (before the include): ENVCAP_MAX_SPHERES (uniform array size, default 64),
// ENVCAP_SPHERE_CAP (spheres per point, default 8), ENVCAP_DYNAMIC_COMBINE (overlapping caps:
// 0 overlap, pairwise inclusion-exclusion with the caps' intersection (default); 1 independent,
// 1 - prod(1 - f); 2 sum; 3 max), ENVCAP_DYNAMIC_PAPER_FORM (Eq. 4-7 instead of
// envcap's cap form), ENVCAP_DYNAMIC_ENVIRONMENT (the name of a function vec3 NAME(vec3 dir,
// float w): the cos^w-convolved environment along the world direction dir; declared here, defined
// by the includer anywhere in the shader; needed by envcap_dynamic_terms only), ENVCAP_MAX_LOBES
// (as envcap_shade_lafortune, default 3), ENVCAP_DYNAMIC_BOUNCE_PAPER (bounce the environment
// along the paper's horizontal mirror of M instead of -M, the sphere's face towards the point).

#include "runtime/envcap_dynamic.glsl"

#ifndef ENVCAP_MAX_SPHERES
#define ENVCAP_MAX_SPHERES 64
#endif
#ifndef ENVCAP_SPHERE_CAP
#define ENVCAP_SPHERE_CAP 8
#endif
#ifndef ENVCAP_DYNAMIC_COMBINE
#define ENVCAP_DYNAMIC_COMBINE 0
#endif
#ifndef ENVCAP_MAX_LOBES
#define ENVCAP_MAX_LOBES 3
#endif

// The sphere buffer: xyz center (m, world), w radius (m; <= 0: empty); albedo rgb in [0, 1].
// Targets that take no loose uniforms (Vulkan) define ENVCAP_SPHERES_BLOCK, the block's qualifiers
// and kind (envcap.runtime.shader_targets: a std430 read-only storage buffer); same member names.
#ifdef ENVCAP_SPHERES_BLOCK
ENVCAP_SPHERES_BLOCK EnvcapSpheresBlock {
    vec4 envcap_spheres[ENVCAP_MAX_SPHERES];
    vec3 envcap_sphere_albedo[ENVCAP_MAX_SPHERES];
    int envcap_sphere_count;
};
#else
uniform vec4 envcap_spheres[ENVCAP_MAX_SPHERES];
uniform vec3 envcap_sphere_albedo[ENVCAP_MAX_SPHERES];
uniform int envcap_sphere_count;
#endif

// The selected spheres of one shading point: index (-1: empty slot), lobe vec4(D, t), and for
// the overlap rule each pair's envcap_cap_overlap (j < k at [j * CAP + k]).
struct EnvcapSphereSet {
    int index[ENVCAP_SPHERE_CAP];
    vec4 lobe[ENVCAP_SPHERE_CAP];
#if ENVCAP_DYNAMIC_COMBINE == 0
    float overlap[ENVCAP_SPHERE_CAP * ENVCAP_SPHERE_CAP];
#endif
};

// acos(num / den) as atan (GPU acos is poor); den <= 0 -> 0.
float envcap_acos_ratio(float num, float den)
{
    float x = den > 0.0 ? clamp(num / den, -1.0, 1.0) : 1.0;
    return atan(sqrt(max((1.0 - x) * (1.0 + x), 0.0)), x);
}

// Solid angle of the intersection of two caps (half-angles t1, t2, axes beta apart; rad) over the
// smaller cap's: 0 disjoint, 1 nested, else 2 (pi - a - b cos t1 - c cos t2) / Omega_min.
float envcap_cap_overlap(float t1, float t2, float beta)
{
    if (beta >= t1 + t2) return 0.0;
    if (beta <= abs(t1 - t2)) return 1.0;
    float c1 = cos(t1), c2 = cos(t2), cb = cos(beta);
    float s1 = sin(t1), s2 = sin(t2), sb = sin(beta);
    float a = envcap_acos_ratio(cb - c1 * c2, s1 * s2);
    float b = envcap_acos_ratio(c2 - cb * c1, sb * s1);
    float c = envcap_acos_ratio(c1 - cb * c2, sb * s2);
    float lens = 2.0 * (ENVCAP_PI - a - b * c1 - c * c2);
    float small_ = 2.0 * ENVCAP_PI * (1.0 - max(c1, c2));
    return small_ > 0.0 ? clamp(lens, 0.0, small_) / small_ : 0.0;
}

// The ENVCAP_SPHERE_CAP spheres of largest solid angle (smallest t) seen from x, by insertion
// (ties: lower index first, as numpy's stable sort), leaving out the spheres wholly below the
// horizon of the unit normal (D . normal <= -sin(theta)); normal = vec3(0): none left out.
EnvcapSphereSet envcap_select_spheres(vec3 x, vec3 normal)
{
    EnvcapSphereSet s;
    for (int k = 0; k < ENVCAP_SPHERE_CAP; ++k) {
        s.index[k] = -1;
        s.lobe[k] = vec4(0.0, 0.0, 1.0, ENVCAP_MAX_POWER);
    }
    int n = min(envcap_sphere_count, ENVCAP_MAX_SPHERES);
    for (int j = 0; j < n; ++j) {
        if (!(envcap_spheres[j].w > 0.0)) continue;
        vec4 lobe = envcap_sphere_lobe(x, envcap_spheres[j]);
        if (dot(lobe.xyz, normal) <= -sin(envcap_cap_half_angle(lobe.w))) continue;
        int slot = ENVCAP_SPHERE_CAP;
        for (int k = ENVCAP_SPHERE_CAP - 1; k >= 0; --k)
            if (s.index[k] < 0 || lobe.w < s.lobe[k].w) slot = k;
        for (int k = ENVCAP_SPHERE_CAP - 1; k > slot; --k) {
            s.index[k] = s.index[k - 1];
            s.lobe[k] = s.lobe[k - 1];
        }
        if (slot < ENVCAP_SPHERE_CAP) {
            s.index[slot] = j;
            s.lobe[slot] = lobe;
        }
    }
#if ENVCAP_DYNAMIC_COMBINE == 0
    for (int j = 0; j < ENVCAP_SPHERE_CAP; ++j) {
        float tj = envcap_cap_half_angle(s.lobe[j].w);
        for (int k = j + 1; k < ENVCAP_SPHERE_CAP; ++k) {
            vec3 dj = s.lobe[j].xyz, dk = s.lobe[k].xyz;
            float beta = atan(length(cross(dj, dk)), dot(dj, dk));
            s.overlap[j * ENVCAP_SPHERE_CAP + k] = s.index[j] >= 0 && s.index[k] >= 0
                ? envcap_cap_overlap(tj, envcap_cap_half_angle(s.lobe[k].w), beta) : 0.0;
        }
    }
#endif
    return s;
}

// For one BRDF lobe (unit axis c, power w): per selected sphere vec4(M, share), the share of the
// lobe's light it blocks after the overlap rule (shares add up to the union's fraction U).
// Returns U.
float envcap_sphere_shares(EnvcapSphereSet s, vec3 c, float w, out vec4 occ[ENVCAP_SPHERE_CAP])
{
    float wc = envcap_clean_power(w);
    float total = 0.0, keep = 1.0, most = 0.0;
    for (int k = 0; k < ENVCAP_SPHERE_CAP; ++k) {
        vec4 o = envcap_occlusion(s.lobe[k].xyz, c, s.lobe[k].w, w);
        float f = s.index[k] >= 0 ? clamp(o.w * (1.0 + wc) / (2.0 * ENVCAP_PI), 0.0, 1.0) : 0.0;
        occ[k] = vec4(o.xyz, f);
        total += f;
        keep *= 1.0 - f;
        most = max(most, f);
    }
#if ENVCAP_DYNAMIC_COMBINE == 0
    float pairs = 0.0;
    for (int j = 0; j < ENVCAP_SPHERE_CAP; ++j)
        for (int k = j + 1; k < ENVCAP_SPHERE_CAP; ++k)
            pairs += min(occ[j].w, occ[k].w) * s.overlap[j * ENVCAP_SPHERE_CAP + k];
    float U = clamp(total - pairs, most, 1.0);
#elif ENVCAP_DYNAMIC_COMBINE == 1
    float U = 1.0 - keep;
#elif ENVCAP_DYNAMIC_COMBINE == 2
    float U = min(total, 1.0);
#else
    float U = most;
#endif
    float scale = total > 0.0 ? U / total : 0.0;
    for (int k = 0; k < ENVCAP_SPHERE_CAP; ++k) occ[k].w *= scale;
    return U;
}

// d with its horizontal components negated (+Y up): the paper's "x and y negated".
vec3 envcap_mirror_horizontal(vec3 d)
{
    return vec3(-d.x, d.y, -d.z);
}

#ifdef ENVCAP_DYNAMIC_ENVIRONMENT
vec3 ENVCAP_DYNAMIC_ENVIRONMENT(vec3 dir, float w);

// Blocked and bounced light at x for the Lafortune material of envcap_shade_lafortune (frame
// T, B, N; world view direction v; rho_d; C[i] = (C, w); rho_s[i]): per lobe of weight W and
// power w, blocked += W sum_k share_k env(M_k, w + t_k), bounced += W sum_k share_k albedo_k
// env(-M_k, 1) (env(mirror(M_k), 1) with ENVCAP_DYNAMIC_BOUNCE_PAPER).  Static + dynamic = Eq. 3 - blocked + bounced.
void envcap_dynamic_terms(vec3 x, vec3 T, vec3 B, vec3 N, vec3 v, vec3 rho_d, vec4 C[ENVCAP_MAX_LOBES],
                          vec3 rho_s[ENVCAP_MAX_LOBES], int nlobes, out vec3 blocked, out vec3 bounced)
{
    blocked = vec3(0.0);
    bounced = vec3(0.0);
    EnvcapSphereSet s = envcap_select_spheres(x, N);
    if (s.index[0] < 0) return;
    vec3 vl = vec3(dot(v, T), dot(v, B), dot(v, N));
    vec4 occ[ENVCAP_SPHERE_CAP];
    for (int i = -1; i < nlobes && i < ENVCAP_MAX_LOBES; ++i) {
        vec3 axis = N;
        float w = 1.0;
        vec3 W = rho_d;
        if (i >= 0) {
            vec4 lobe = envcap_lafortune_lobe(vl, C[i].xyz, C[i].w);
            axis = lobe.x * T + lobe.y * B + lobe.z * N;
            w = max(C[i].w, 0.0);
            W = rho_s[i] * lobe.w;
        }
        envcap_sphere_shares(s, axis, w, occ);
        for (int k = 0; k < ENVCAP_SPHERE_CAP; ++k) {
            if (!(occ[k].w > 0.0)) continue;
            float p = min(w + s.lobe[k].w, ENVCAP_MAX_POWER);
            blocked += W * occ[k].w * ENVCAP_DYNAMIC_ENVIRONMENT(occ[k].xyz, p);
#ifdef ENVCAP_DYNAMIC_BOUNCE_PAPER
            vec3 rd = envcap_mirror_horizontal(occ[k].xyz);
#else
            vec3 rd = -occ[k].xyz;
#endif
            bounced += W * occ[k].w * envcap_sphere_albedo[s.index[k]] * ENVCAP_DYNAMIC_ENVIRONMENT(rd, 1.0);
        }
    }
}
#endif

#endif  // ENVCAP_DYNAMIC_SPHERES_GLSL
