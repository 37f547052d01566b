#ifndef ENVCAP_LOBES_GLSL
#define ENVCAP_LOBES_GLSL
// envcap runtime, part 2: cosine lobes.  z(w) from the manifest's lobe table and the lobes of
// Eq. 3 for a Lafortune BRDF.  No #version: #include this.  Derivations: docs/runtime.md.

#ifndef ENVCAP_MAX_LEVELS
#define ENVCAP_MAX_LEVELS 16
#endif

const float ENVCAP_PI = 3.14159265358979;
// Upper bound of log2 of a Lafortune lobe weight |Cv|^w (2^64 ~ 1.8e19): keeps the weight
// finite in float32 for absurd materials (|Cv| > 1 with large w).
const float ENVCAP_MAX_LOG2_WEIGHT = 64.0;

// Continuous mip level of cosine power w.  `xk[k]` = log2(1 + powers[k]) for the manifest's
// strictly decreasing lobe powers (k = 0 .. n-1, filled by envcap.runtime.mip.lobe_table), so
// xk is strictly decreasing.  Piecewise linear in x = log2(1 + w); clamped to [0, n - 1]:
// w >= powers[0] (also +inf) -> 0, w <= powers[n-1] -> n - 1.  w < 0 and NaN are treated as 0.
float envcap_z_of_w(float w, float xk[ENVCAP_MAX_LEVELS], int n)
{
    n = clamp(n, 1, ENVCAP_MAX_LEVELS);
    float x = log2(1.0 + (w > 0.0 ? w : 0.0));
    if (!(x < xk[0])) return 0.0;
    for (int k = 1; k < n; ++k) {
        if (x >= xk[k]) return float(k - 1) + (xk[k - 1] - x) / (xk[k - 1] - xk[k]);
    }
    return float(n - 1);
}

// Rung ladders (docs/lobes.md, "Ladder modes"; numpy twin envcap.runtime.rungs): a mip-mapped
// cube-map array holding `per_level` rungs per level, layer base + r at level j = rung j*per_level + r.
// ENVCAP_PROBES_SAMPLER and ENVCAP_PROBES_LOD: the probe texture of the target
#include "runtime/envcap_probe_texture.glsl"
#ifndef ENVCAP_MAX_RUNGS
#define ENVCAP_MAX_RUNGS 48
#endif

// Continuous rung position of power w: the z(w) rule over the flat rung table `xr` (xr[i] =
// log2(1 + powers[i]), strictly decreasing, n entries); clamped to [0, n - 1]; w < 0, NaN -> 0.
float envcap_rung_of_w(float w, float xr[ENVCAP_MAX_RUNGS], int n)
{
    n = clamp(n, 1, ENVCAP_MAX_RUNGS);
    float x = log2(1.0 + (w > 0.0 ? w : 0.0));
    if (!(x < xr[0])) return 0.0;
    for (int k = 1; k < n; ++k) {
        if (x >= xr[k]) return float(k - 1) + (xr[k - 1] - x) / (xr[k - 1] - xr[k]);
    }
    return float(n - 1);
}

// The texel along d at continuous rung position u (>= 0, at most the last rung; NaN -> 0) of the
// probe whose rungs start at layer `base`: rungs floor(u) and the next, each one bilinear fetch at
// its integer level (ENVCAP_PROBES_LOD as the file is included), blended linearly in u.  The street
// rung variant (runtime/envcap_rung_street.glsl) routes every probe and sky lookup through this.
vec4 envcap_rung_lod(ENVCAP_PROBES_SAMPLER tex, vec3 d, float base, float u, int per_level)
{
    per_level = max(per_level, 1);
    u = u > 0.0 ? u : 0.0;
    int i0 = int(floor(u));
    float t = u - float(i0);
    vec4 a = ENVCAP_PROBES_LOD(tex, d, base + float(i0 % per_level), float(i0 / per_level));
    if (!(t > 0.0)) return a;
    int i1 = i0 + 1;
    vec4 b = ENVCAP_PROBES_LOD(tex, d, base + float(i1 % per_level), float(i1 / per_level));
    return a + t * (b - a);
}

// The cos^w-convolved texel along d of the probe whose rungs start at layer `base`: rungs
// floor(u) and the next at u = envcap_rung_of_w(w), blended linearly in u (envcap_rung_lod; two
// bilinear fetches: the texel reads of one trilinear fetch; one where u is a whole rung).
vec4 envcap_rung_fetch(ENVCAP_PROBES_SAMPLER tex, vec3 d, float base, float w, float xr[ENVCAP_MAX_RUNGS],
                       int n, int per_level)
{
    return envcap_rung_lod(tex, d, base, envcap_rung_of_w(w, xr, n), per_level);
}

// One specular lobe of a Lafortune BRDF, term rho_s * max(u . Cv, 0)^w with
// Cv = (C.x v.x, C.y v.y, C.z v.z), for view direction v (unit, toward the viewer) in the local
// shading frame (z = normal).  Returns vec4(c, weight): c = Cv / |Cv| (unit lobe axis, local
// frame) and weight = |Cv|^w * 2 pi / (1 + w) * max(c.z, 0), so that the lobe's reflected
// radiance is rho_s * weight * E_w(c), E_w = environment convolved with the normalized
// cos^w lobe (the mip chain at level z(w)).  Fallbacks: |Cv| = 0 -> (0, 0, 1, 0) (no light);
// log2 of |Cv|^w clamped to ENVCAP_MAX_LOG2_WEIGHT; w < 0 treated as 0.
// Form of Eq. 3 (docs/runtime.md, "Two forms of Eq. 3"): by default envcap's, whose lobes are the
// BRDF's own and carry the foreshortening max(c.z, 0) above.  #define ENVCAP_EQ3_PAPER_FORM
// before the include for the paper's, whose lobes were fitted to BRDF x cos: weight =
// |Cv|^w * 2 pi / (1 + w), no cosine factor (a lobe axis below the horizon still contributes).
vec4 envcap_lafortune_lobe(vec3 v, vec3 C, float w)
{
    w = max(w, 0.0);
    vec3 cv = C * v;
    float len = length(cv);
    if (!(len > 0.0)) return vec4(0.0, 0.0, 1.0, 0.0);
    vec3 c = cv / len;
    float e = min(w * log2(len), ENVCAP_MAX_LOG2_WEIGHT);
    float mag = e < -126.0 ? 0.0 : exp2(e);
#ifdef ENVCAP_EQ3_PAPER_FORM
    return vec4(c, mag * (2.0 * ENVCAP_PI / (1.0 + w)));
#else
    return vec4(c, mag * (2.0 * ENVCAP_PI / (1.0 + w)) * max(c.z, 0.0));
#endif
}

#endif  // ENVCAP_LOBES_GLSL
