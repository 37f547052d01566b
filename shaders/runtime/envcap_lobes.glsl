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

// Lookup position of power w (numpy twin envcap.runtime.rungs.rung_lod_of_w): the rung position
// envcap_rung_of_w up to rung 0's power w_0 (xr[0] = log2(1 + w_0)); above it the top segment
// -(1 - (1 + w_0) / (1 + w)) in (-1, 0), -1 at w = +inf (the mirror).  w < 0, NaN -> 0.
float envcap_rung_lod_of_w(float w, float xr[ENVCAP_MAX_RUNGS], int n)
{
    float x = log2(1.0 + (w > 0.0 ? w : 0.0));
    if (!(x < xr[0])) return -(1.0 - exp2(xr[0] - x));
    return envcap_rung_of_w(w, xr, n);
}

// The top of the ladder (docs/lobes.md, "The top of the ladder"; numpy twin envcap.runtime.rung_top):
// where one seamless bilinear read of an n-texel level along d gives the cos^w quadrature weights
// (d.u)^w Omega_u of its 2x2 footprint, as a separable kernel with their marginals (exact for the
// mirror, one texel, up to the cube's corner cells).  Face plane: the two minor components of d
// over the major one (ties X, Y, Z as GL); w up to 1e30.
vec3 envcap_rung_top_dir(vec3 d, float n, float w)
{
    vec3 a = abs(d);
    int k = (a.x >= a.y && a.x >= a.z) ? 0 : (a.y >= a.z ? 1 : 2);
    float ma = k == 0 ? a.x : (k == 1 ? a.y : a.z);
    if (!(ma > 0.0)) return d;
    vec2 f = (k == 0 ? d.yz : (k == 1 ? d.xz : d.xy)) / ma;
    vec2 i0 = floor((f + 1.0) * 0.5 * n - 0.5);
    vec2 ca = 2.0 * (i0 + 0.5) / n - 1.0;                 // the footprint's centres
    vec2 cb = ca + 2.0 / n;
    // a footprint across one face edge: its texels there are the adjacent face's edge row (GL's
    // seamless read), centres at 1 / (1 - 1/n) on this face's plane, solid angle on their own face
    bvec2 lo = lessThan(i0, vec2(0.0));
    bvec2 hi = greaterThan(i0 + 1.0, vec2(n - 1.0));
    bool sx = (lo.x || hi.x) && !(lo.y || hi.y);
    bool sy = (lo.y || hi.y) && !(lo.x || hi.x);
    bvec4 ax = bvec4(sx && lo.x, sx && !lo.x, sx && lo.x, sx && !lo.x);       // entries across x
    bvec4 ay = bvec4(sy && lo.y, sy && lo.y, sy && !lo.y, sy && !lo.y);
    float g = n / max(n - 1.0, 0.5);
    vec4 xs = vec4(ca.x, cb.x, ca.x, cb.x);
    vec4 ys = vec4(ca.y, ca.y, cb.y, cb.y);
    vec4 lq = mix(mix(log(1.0 + xs * xs + ys * ys), log(1.0 + 1.0 / (g * g) + xs * xs), ay),
                  log(1.0 + 1.0 / (g * g) + ys * ys), ax);
    vec4 xg = mix(mix(xs, xs * g, ay), sign(xs) * g, ax);
    ys = mix(mix(ys, ys * g, ax), sign(ys) * g, ay);
    xs = xg;
    vec4 q = 1.0 + xs * xs + ys * ys;
    // -log cos of the angle to each centre, from the small differences (Lagrange's identity for
    // sin^2, then atanh(z), z = sin^2 / (2 - sin^2), by its series): no 1 - cos cancellation
    vec4 dx = xs - f.x;
    vec4 dy = ys - f.y;
    vec4 cr = f.x * dy - f.y * dx;
    vec4 s2 = (dx * dx + dy * dy + cr * cr) / ((1.0 + dot(f, f)) * q);
    vec4 z = s2 / (2.0 - s2);
    vec4 z2 = z * z;
    vec4 nlc = z * (1.0 + z2 * (1.0 / 3.0 + z2 * (1.0 / 5.0 + z2 * (1.0 / 7.0 + z2 * (1.0 / 9.0)))));
    vec4 e = -w * nlc - 1.5 * lq;
    vec4 wt = exp(e - max(max(e.x, e.y), max(e.z, e.w)));
    vec2 t = vec2(wt.y + wt.w, wt.z + wt.w) / (wt.x + wt.y + wt.z + wt.w);
    vec2 f2 = ca + t * (2.0 / n);
    // past the edge: the point on the adjacent face as far from the edge, at the same place along it
    float major = 1.0;
    if (sx && abs(f2.x) > 1.0) { major = 2.0 - abs(f2.x); f2.x = sign(f2.x); }
    else if (sy && abs(f2.y) > 1.0) { major = 2.0 - abs(f2.y); f2.y = sign(f2.y); }
    float s = (d[k] >= 0.0 ? 1.0 : -1.0) * major;
    return k == 0 ? vec3(s, f2) : (k == 1 ? vec3(f2.x, s, f2.y) : vec3(f2, s));
}

// Rung 0 (level 0, layer `layer`) along d at top position u in [-1, 0]: the lobe power
// c / (1 + u) - 1, c = 3 N^2 - 1 (rung 0's own power 3 N^2 - 2 at u = 0; at most 1e30), read with
// its 2x2 footprint kernel: one bilinear fetch.
vec4 envcap_rung_top(ENVCAP_PROBES_SAMPLER tex, vec3 d, float layer, float u)
{
    float n = float(max(ENVCAP_PROBES_FACE_SIZE(tex), 1));
    float c = 3.0 * n * n - 1.0;
    float w = c / max(1.0 + min(u, 0.0), c * 1e-30) - 1.0;
    return ENVCAP_PROBES_LOD(tex, envcap_rung_top_dir(d, n, w), layer, 0.0);
}

// The texel along d at lookup position u (>= -1, at most the last rung; NaN -> 0) of the probe
// whose rungs start at layer `base`: rungs floor(u) and the next, each one bilinear fetch at its
// integer level (ENVCAP_PROBES_LOD as the file is included), blended linearly in u; rung 0 is
// envcap_rung_top at min(u, 0).  The street rung variant (runtime/envcap_rung_street.glsl)
// routes every probe and sky lookup through this.
vec4 envcap_rung_lod(ENVCAP_PROBES_SAMPLER tex, vec3 d, float base, float u, int per_level)
{
    per_level = max(per_level, 1);
    u = u > -1.0 ? u : (u <= -1.0 ? -1.0 : 0.0);
    float up = max(u, 0.0);
    int i0 = int(floor(up));
    float t = up - float(i0);
    vec4 a = i0 == 0 ? envcap_rung_top(tex, d, base, u)
                     : ENVCAP_PROBES_LOD(tex, d, base + float(i0 % per_level), float(i0 / per_level));
    if (!(t > 0.0)) return a;
    int i1 = i0 + 1;
    vec4 b = ENVCAP_PROBES_LOD(tex, d, base + float(i1 % per_level), float(i1 / per_level));
    return a + t * (b - a);
}

// The cos^w-convolved texel along d of the probe whose rungs start at layer `base`: envcap_rung_lod
// at u = envcap_rung_lod_of_w(w) (two bilinear fetches: the texel reads of one trilinear fetch;
// one where u is a whole rung or above rung 0).
vec4 envcap_rung_fetch(ENVCAP_PROBES_SAMPLER tex, vec3 d, float base, float w, float xr[ENVCAP_MAX_RUNGS],
                       int n, int per_level)
{
    return envcap_rung_lod(tex, d, base, envcap_rung_lod_of_w(w, xr, n), per_level);
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
