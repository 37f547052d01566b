#ifndef ENVCAP_DYNAMIC_GLSL
#define ENVCAP_DYNAMIC_GLSL
// envcap runtime, dynamic occluders (the paper's Eq. 4-7): a sphere seen from the shading point
// as a cosine lobe max(0, u.D)^t, and its product with a BRDF lobe max(0, u.C)^w.
// No #version: #include this.  Numpy twin: envcap/dynamic/ (lobe_product, sphere_lobe).
// Derivations, limits and the error against quadrature: docs/dynamic.md.

#include "runtime/envcap_lobes.glsl"

#ifndef ENVCAP_LOBE_EXPONENT
#define ENVCAP_LOBE_EXPONENT 0.7
#endif
// Lobe powers are clamped to this; a sphere of radius 0 maps to it (it blocks ~nothing).
const float ENVCAP_MAX_POWER = 1.0e30;
// Below this r / l a sphere maps to ENVCAP_MAX_POWER (t would overflow).
const float ENVCAP_MIN_SINE = 1.0e-15;
// Below this angle (rad) ln cos x is its 4-term Taylor series.
const float ENVCAP_LN_COS_SERIES_BELOW = 0.25;

// p NaN or < 0 -> 0; above ENVCAP_MAX_POWER (+inf) -> ENVCAP_MAX_POWER.
float envcap_clean_power(float p)
{
    return p > 0.0 ? min(p, ENVCAP_MAX_POWER) : 0.0;
}

// h(cos x)^p, h = max(0, .): 0 for |x| >= pi/2 (also for p = 0: a power-0 lobe is its
// hemisphere), 1 for p = 0 inside, else exp(p ln cos x) (series for ln cos at small x).
float envcap_cos_power(float x, float p)
{
    x = abs(x);
    float cx = cos(x);
    if (!(x < 0.5 * ENVCAP_PI) || !(cx > 0.0)) return 0.0;
    if (!(p > 0.0)) return 1.0;
    float x2 = x * x;
    float lc = x < ENVCAP_LN_COS_SERIES_BELOW
        ? -x2 * (0.5 + x2 * (1.0 / 12.0 + x2 * (1.0 / 45.0 + x2 * (17.0 / 2520.0))))
        : log(cx);
    return exp(p * lc);
}

// A unit vector perpendicular to unit d (Duff et al. 2017).
vec3 envcap_any_perpendicular(vec3 d)
{
    float s = d.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + d.z);
    float b = d.x * d.y * a;
    return vec3(1.0 + s * d.x * d.x * a, s * b, -s * d.x);
}

// Eq. 4-7 for the occluder lobe (D, t) and the BRDF lobe (C, w) (|Cv| = 1: multiply the
// integral by |Cv|^w).  Returns vec4(M, integral): M the unit axis of the product lobe (Eq. 4 if
// D.C >= 0: normalize(D t^k + C w^k); Eq. 5 otherwise: the great circle from D to C at the
// fraction w^k / (t^k + w^k) of their angle), integral = pi peak (D.C + 1) / (1 + w + t) (Eq. 7)
// with peak = h(M.C)^w h(M.D)^t (Eq. 6), in steradians.  D, C: any length.  Limits: t, w NaN or
// < 0 -> 0, > ENVCAP_MAX_POWER -> ENVCAP_MAX_POWER; t = w = 0 -> the bisector; C = 0 ->
// (0, 0, 1); D = 0 -> D = C (a sphere containing the point: t = 0 blocks the whole lobe);
// D = -C -> a fixed perpendicular, integral 0.
vec4 envcap_lobe_product(vec3 D, vec3 C, float t, float w)
{
    t = envcap_clean_power(t);
    w = envcap_clean_power(w);
    float lc_ = length(C);
    vec3 c = lc_ > 0.0 ? C / lc_ : vec3(0.0, 0.0, 1.0);
    float ld = length(D);
    vec3 d = ld > 0.0 ? D / ld : c;
    float cos_g = dot(d, c);
    float sin_g = length(cross(d, c));
    float gamma = atan(sin_g, cos_g);
    vec3 pr = c - cos_g * d;
    float lp = length(pr);
    vec3 p = lp > 0.0 ? pr / lp : envcap_any_perpendicular(d);
    float a = t > 0.0 ? pow(t, ENVCAP_LOBE_EXPONENT) : 0.0;
    float b = w > 0.0 ? pow(w, ENVCAP_LOBE_EXPONENT) : 0.0;
    if (a + b == 0.0) { a = 1.0; b = 1.0; }
    float alpha = cos_g >= 0.0 ? atan(b * sin_g, a + b * cos_g) : gamma * (b / (a + b));
    vec3 M = cos(alpha) * d + sin(alpha) * p;
    float peak = envcap_cos_power(gamma - alpha, w) * envcap_cos_power(alpha, t);
    float half_ = cos(0.5 * gamma);
    return vec4(M, 2.0 * ENVCAP_PI * peak * (half_ * half_) / (1.0 + w + t));
}

// A sphere (xyz center, w radius; meters) seen from x as a cosine lobe of equal solid angle:
// vec4(D, t), D the unit direction to the center, t = c (1 + c) / s^2 with s = r / l = sin theta,
// c = cos theta.  r NaN or <= 0 (no sphere) or s < ENVCAP_MIN_SINE -> t = ENVCAP_MAX_POWER;
// touching (l = r) -> t = 0; containing (l < r) -> D = 0, t = 0 (envcap_lobe_product: the whole
// lobe is blocked).
vec4 envcap_sphere_lobe(vec3 x, vec4 sphere)
{
    vec3 v = sphere.xyz - x;
    float l = length(v);
    float r = sphere.w;
    vec3 D = l > 0.0 ? v / l : vec3(0.0, 0.0, 1.0);
    if (!(r > 0.0)) return vec4(D, ENVCAP_MAX_POWER);
    if (l < r) return vec4(0.0);
    float s = r / l;
    if (!(s > ENVCAP_MIN_SINE)) return vec4(D, ENVCAP_MAX_POWER);
    float c = sqrt(max((1.0 - s) * (1.0 + s), 0.0));
    return vec4(D, min(c * (1.0 + c) / (s * s), ENVCAP_MAX_POWER));
}

#endif  // ENVCAP_DYNAMIC_GLSL
