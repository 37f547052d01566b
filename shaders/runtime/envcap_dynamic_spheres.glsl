#ifndef ENVCAP_DYNAMIC_SPHERES_GLSL
#define ENVCAP_DYNAMIC_SPHERES_GLSL
// envcap runtime, many dynamic spheres: the ENVCAP_SPHERE_CAP most occluding spheres of a shading
// point, their overlap rule, and the blocked / bounced light of a Lafortune material (Section IV
// of the paper on top of Eq. 3).  No #version: #include this.  Numpy twin: envcap/dynamic/spheres.py,
// envcap/dynamic/terms.py.  docs/dynamic.md, "Many spheres" and "Blocked and bounced light".
//
// Defines (before the include): ENVCAP_MAX_SPHERES (uniform array size, default 64),
// ENVCAP_SPHERE_CAP (spheres per point, default 8), ENVCAP_DYNAMIC_COMBINE (overlapping caps:
// 4 rings, the union merged on ENVCAP_UNION_NODES rings of each lobe (default; nodes default 8);
// 0 overlap, pairwise inclusion-exclusion with the caps' solid-angle intersection; 1 independent,
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
#define ENVCAP_DYNAMIC_COMBINE 4
#endif
#ifndef ENVCAP_UNION_NODES
#define ENVCAP_UNION_NODES 8
#endif
#ifndef ENVCAP_MAX_LOBES
#define ENVCAP_MAX_LOBES 3
#endif

// The sphere buffer: xyz center (m, world), w radius (m; <= 0: empty); albedo rgb in [0, 1].
// Targets that take no loose uniforms (Vulkan) define ENVCAP_SPHERES_BLOCK, the block's qualifiers
// and kind (envcap.runtime.shader_targets: a std430 read-only storage buffer); same member names.
// ENVCAP_SPHERES_GLOBAL: plain globals the includer fills per shading point before calling
// envcap_dynamic_terms (shaders/crowd/crowd_frag.glsl gathers each fragment's own spheres).
#if defined(ENVCAP_SPHERES_GLOBAL)
vec4 envcap_spheres[ENVCAP_MAX_SPHERES];
vec3 envcap_sphere_albedo[ENVCAP_MAX_SPHERES];
int envcap_sphere_count;
#elif defined(ENVCAP_SPHERES_BLOCK)
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

#if ENVCAP_DYNAMIC_COMBINE == 4
// Ring positions and weights of the union (as ENVCAP_CAP_U / ENVCAP_CAP_W, ENVCAP_UNION_NODES of them).
#if ENVCAP_UNION_NODES == 1
const float ENVCAP_UNION_U[1] = float[](0.5);
const float ENVCAP_UNION_W[1] = float[](1.0);
#elif ENVCAP_UNION_NODES == 2
const float ENVCAP_UNION_U[2] = float[](0.106201429, 0.893798571);
const float ENVCAP_UNION_W[2] = float[](0.5, 0.5);
#elif ENVCAP_UNION_NODES == 3
const float ENVCAP_UNION_U[3] = float[](0.0310140675, 0.5, 0.968985933);
const float ENVCAP_UNION_W[3] = float[](0.151176393, 0.697647215, 0.151176393);
#elif ENVCAP_UNION_NODES == 4
const float ENVCAP_UNION_U[4] = float[](0.011847713, 0.245492107, 0.754507893, 0.988152287);
const float ENVCAP_UNION_W[4] = float[](0.0591221965, 0.440877803, 0.440877803, 0.0591221965);
#elif ENVCAP_UNION_NODES == 5
const float ENVCAP_UNION_U[5] = float[](0.0054198327, 0.125740578, 0.5, 0.874259422, 0.994580167);
const float ENVCAP_UNION_W[5] = float[](0.0273241736, 0.249273694, 0.446804264, 0.249273694, 0.0273241736);
#elif ENVCAP_UNION_NODES == 6
const float ENVCAP_UNION_U[6] = float[](0.00281042655, 0.0691462504, 0.316946488, 0.683053512, 0.93085375, 0.997189573);
const float ENVCAP_UNION_W[6] = float[](0.0142467012, 0.14376898, 0.341984318, 0.341984318, 0.14376898, 0.0142467012);
#elif ENVCAP_UNION_NODES == 7
const float ENVCAP_UNION_U[7] = float[](0.0015967944, 0.0406464087, 0.202405802, 0.5, 0.797594198, 0.959353591, 0.998403206);
const float ENVCAP_UNION_W[7] = float[](0.0081211346, 0.0867603224, 0.240986355, 0.328264375, 0.240986355, 0.0867603224, 0.0081211346);
#elif ENVCAP_UNION_NODES == 8
const float ENVCAP_UNION_U[8] = float[](0.000972393075, 0.0252873079, 0.132555031, 0.357916038, 0.642083962, 0.867444969, 0.974712692, 0.999027607);
const float ENVCAP_UNION_W[8] = float[](0.00495601381, 0.0548412357, 0.167094698, 0.273108052, 0.273108052, 0.167094698, 0.0548412357, 0.00495601381);
#else
#error "ENVCAP_UNION_NODES must be 1..8"
#endif
// A cap whose partial rings lie more than this share (in z) below L keeps its node value.
const float ENVCAP_UNION_FADE = 0.1;

// x in (-2 pi, 2 pi) wrapped to (-pi, pi].
float envcap_wrap_pi(float x)
{
    return x > ENVCAP_PI ? x - 2.0 * ENVCAP_PI : (x <= -ENVCAP_PI ? x + 2.0 * ENVCAP_PI : x);
}

// Covered fraction of a circle by the arcs of half-widths phi[k] (rad; 0: none) centered at
// azimuths psi[k]: the uncovered length is the sum, over arc ends strictly inside no other arc, of
// the gap to the next arc start; one difference per pair decides both ends (ties: the lower index
// keeps its end), so near-identical arcs never hide each other's gap.  Numpy twin:
// envcap.dynamic.union.arc_union.
float envcap_arc_union(float phi[ENVCAP_SPHERE_CAP], float psi[ENVCAP_SPHERE_CAP])
{
    const float two_pi = 2.0 * ENVCAP_PI;
    bool covered[ENVCAP_SPHERE_CAP];
    float gap[ENVCAP_SPHERE_CAP];
    bool any_ = false, full = false;
    for (int k = 0; k < ENVCAP_SPHERE_CAP; ++k) {
        covered[k] = false;
        gap[k] = two_pi - 2.0 * phi[k];
        any_ = any_ || phi[k] > 0.0;
        full = full || phi[k] >= ENVCAP_PI;
    }
    if (!any_) return 0.0;
    if (full) return 1.0;
    for (int i = 0; i < ENVCAP_SPHERE_CAP; ++i) {
        if (!(phi[i] > 0.0)) continue;
        for (int j = i + 1; j < ENVCAP_SPHERE_CAP; ++j) {
            if (!(phi[j] > 0.0)) continue;
            float delta = envcap_wrap_pi(psi[i] - psi[j]) + (phi[i] - phi[j]);   // end_i - end_j
            float dn = delta > 0.0 ? delta - two_pi : delta;                     // i's end behind j's
            float v = -dn - 2.0 * phi[j];                                        // j's start ahead of i's end
            if (v < 0.0 && dn < 0.0) covered[i] = true;
            else gap[i] = min(gap[i], v < 0.0 ? v + two_pi : v);
            float dm = -delta > 0.0 ? -delta - two_pi : -delta;                 // j's end behind i's
            float vm = -dm - 2.0 * phi[i];
            if ((vm < 0.0 && dm < 0.0) || dm == 0.0) covered[j] = true;
            else gap[j] = min(gap[j], vm < 0.0 ? vm + two_pi : vm);
        }
    }
    float uncovered = 0.0;
    for (int k = 0; k < ENVCAP_SPHERE_CAP; ++k)
        if (phi[k] > 0.0 && !covered[k]) uncovered += gap[k];
    return clamp(1.0 - uncovered / two_pi, 0.0, 1.0);
}

// The fraction of the BRDF lobe (axis c, power w) blocked by the union of the selected caps, on
// the lobe's rings (docs/dynamic.md, "The union on the lobe's rings"; numpy twin
// envcap.dynamic.union.ring_union): rings below A (inside a cap) whole, the others from L to B on
// ENVCAP_UNION_NODES rings with the arcs merged exactly, rescaled by the caps' exact light over
// their node values.  occ[k].w: each sphere's blocked fraction f (0: left out).
float envcap_ring_union(EnvcapSphereSet s, vec3 c, float w, vec4 occ[ENVCAP_SPHERE_CAP])
{
    const float h = 0.5 * ENVCAP_PI;
    w = envcap_clean_power(w);
    float lc_ = length(c);
    c = lc_ > 0.0 ? c / lc_ : vec3(0.0, 0.0, 1.0);
    vec3 e1 = envcap_any_perpendicular(c);
    vec3 e2 = cross(c, e1);
    float theta[ENVCAP_SPHERE_CAP], gamma[ENVCAP_SPHERE_CAP], psi[ENVCAP_SPHERE_CAP], f[ENVCAP_SPHERE_CAP];
    vec4 half_[ENVCAP_SPHERE_CAP];     // sin, cos of (theta - gamma) / 2 and of (theta + gamma) / 2
    float sg[ENVCAP_SPHERE_CAP];
    float A = 0.0, L = h, B = 0.0, fmax = 0.0, fsum = 0.0;
    for (int k = 0; k < ENVCAP_SPHERE_CAP; ++k) {
        f[k] = clamp(occ[k].w, 0.0, 1.0);
        vec3 D = s.lobe[k].xyz;
        float ld = length(D);
        vec3 d = ld > 0.0 ? D / ld : c;
        gamma[k] = atan(length(cross(d, c)), dot(d, c));
        theta[k] = envcap_cap_half_angle(s.lobe[k].w);
        float px = dot(d, e1), py = dot(d, e2);
        psi[k] = px != 0.0 || py != 0.0 ? atan(py, px) : 0.0;
        float hm = 0.5 * (theta[k] - gamma[k]), hp = 0.5 * (theta[k] + gamma[k]);
        half_[k] = vec4(sin(hm), cos(hm), sin(hp), cos(hp));
        sg[k] = sin(gamma[k]);
        fmax = max(fmax, f[k]);
        fsum += f[k];
        if (!(f[k] > 0.0)) continue;
        A = max(A, min(max(theta[k] - gamma[k], 0.0), h));
        L = min(L, min(max(gamma[k] - theta[k], 0.0), h));
        B = max(B, min(gamma[k] + theta[k], h));
    }
    L = max(A, L);
    float p1 = w + 1.0;
    float GA = envcap_cos_power(A, p1), GL = envcap_cos_power(L, p1), GB = envcap_cos_power(B, p1);
    float span = B > L ? GL - GB : 0.0;
    float Un = 0.0;
    float Fn[ENVCAP_SPHERE_CAP];
    for (int k = 0; k < ENVCAP_SPHERE_CAP; ++k) Fn[k] = 0.0;
    for (int n = 0; n < ENVCAP_UNION_NODES; ++n) {
        float z = GL + (GB - GL) * ENVCAP_UNION_U[n];
        float lam = z > 0.0 ? log(z) / p1 : -1.0e30;                  // ln cos alpha
        float m = lam > ENVCAP_EXPM1_SERIES_ABOVE                       // 1 - cos alpha
            ? -lam * (1.0 + lam * (0.5 + lam * (1.0 / 6.0 + lam * (1.0 / 24.0))))
            : 1.0 - exp(lam);
        float s2 = sqrt(max(0.5 * m, 0.0));                             // sin(alpha / 2)
        float c2 = sqrt(max(1.0 - 0.5 * m, 0.0));
        float phi[ENVCAP_SPHERE_CAP];
        for (int k = 0; k < ENVCAP_SPHERE_CAP; ++k) {
            vec4 hk = half_[k];
            float num = 2.0 * (hk.x * c2 + hk.y * s2) * (hk.z * c2 - hk.w * s2);
            float den = 2.0 * s2 * c2 * sg[k];
            float q = den > 0.0 ? num / den : (num > 0.0 ? 2.0 : 0.0);
            q = q > 0.0 ? min(q, 2.0) : 0.0;                                // 1 - cos phi; NaN -> 0
            phi[k] = f[k] > 0.0 ? 2.0 * atan(sqrt(q), sqrt(2.0 - q)) : 0.0;
            Fn[k] += span * ENVCAP_UNION_W[n] * phi[k] * (1.0 / ENVCAP_PI);
        }
        Un += span * ENVCAP_UNION_W[n] * envcap_arc_union(phi, psi);
    }
    float S = 0.0, Fsum = 0.0;
    for (int k = 0; k < ENVCAP_SPHERE_CAP; ++k) {
        if (!(f[k] > 0.0)) continue;
        float tk = theta[k], gk = gamma[k];
        float a = min(abs(tk - gk), h);
        float b = min(min(gk + tk, 2.0 * ENVCAP_PI - gk - tk), h);
        float Ga = envcap_cos_power(a, p1), Gb = envcap_cos_power(b, p1);
        float rho = Ga > Gb ? clamp((Ga - GL) / (Ga - Gb), 0.0, 1.0) : (a < L ? 1.0 : 0.0);
        float omega = clamp(1.0 - rho / ENVCAP_UNION_FADE, 0.0, 1.0);
        float F = f[k] - (tk > gk ? 1.0 - GL : 0.0);                    // the cap's light on rings past L
        S += Fn[k] + omega * (F - Fn[k]);
        Fsum += Fn[k];
    }
    float part = Fsum > 0.0 ? Un * (S / Fsum) : S;
    return clamp(1.0 - GA + max(part, 0.0), fmax, min(fsum, 1.0));
}
#endif

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
#elif ENVCAP_DYNAMIC_COMBINE == 3
    float U = most;
#else
    float U = envcap_ring_union(s, c, w, occ);
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
