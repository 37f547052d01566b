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

// ---- envcap's form: the blocked fraction by a few-node integral over the lobe's rings ----------
// (numpy twin: envcap/dynamic/cap_lobe.py; derivation: docs/dynamic.md, "A better Eq. 7").
#ifndef ENVCAP_CAP_NODES
#define ENVCAP_CAP_NODES 4
#endif
// For lambda = ln z / (w + 1) above this, 1 - exp(lambda) is its 4-term series.
const float ENVCAP_EXPM1_SERIES_ABOVE = -0.03;
// Ring positions u_k in [0, 1] and weights (sum 1): Gauss-Legendre in s, u = (1 - cos s) / 2.
#if ENVCAP_CAP_NODES == 1
const float ENVCAP_CAP_U[1] = float[](0.5);
const float ENVCAP_CAP_W[1] = float[](1.0);
#elif ENVCAP_CAP_NODES == 2
const float ENVCAP_CAP_U[2] = float[](0.106201429, 0.893798571);
const float ENVCAP_CAP_W[2] = float[](0.5, 0.5);
#elif ENVCAP_CAP_NODES == 3
const float ENVCAP_CAP_U[3] = float[](0.0310140675, 0.5, 0.968985933);
const float ENVCAP_CAP_W[3] = float[](0.151176393, 0.697647215, 0.151176393);
#elif ENVCAP_CAP_NODES == 4
const float ENVCAP_CAP_U[4] = float[](0.011847713, 0.245492107, 0.754507893, 0.988152287);
const float ENVCAP_CAP_W[4] = float[](0.0591221965, 0.440877803, 0.440877803, 0.0591221965);
#elif ENVCAP_CAP_NODES == 5
const float ENVCAP_CAP_U[5] = float[](0.0054198327, 0.125740578, 0.5, 0.874259422, 0.994580167);
const float ENVCAP_CAP_W[5] = float[](0.0273241736, 0.249273694, 0.446804264, 0.249273694, 0.0273241736);
#elif ENVCAP_CAP_NODES == 6
const float ENVCAP_CAP_U[6] = float[](0.00281042655, 0.0691462504, 0.316946488, 0.683053512, 0.93085375, 0.997189573);
const float ENVCAP_CAP_W[6] = float[](0.0142467012, 0.14376898, 0.341984318, 0.341984318, 0.14376898, 0.0142467012);
#elif ENVCAP_CAP_NODES == 7
const float ENVCAP_CAP_U[7] = float[](0.0015967944, 0.0406464087, 0.202405802, 0.5, 0.797594198, 0.959353591, 0.998403206);
const float ENVCAP_CAP_W[7] = float[](0.0081211346, 0.0867603224, 0.240986355, 0.328264375, 0.240986355, 0.0867603224, 0.0081211346);
#elif ENVCAP_CAP_NODES == 8
const float ENVCAP_CAP_U[8] = float[](0.000972393075, 0.0252873079, 0.132555031, 0.357916038, 0.642083962, 0.867444969, 0.974712692, 0.999027607);
const float ENVCAP_CAP_W[8] = float[](0.00495601381, 0.0548412357, 0.167094698, 0.273108052, 0.273108052, 0.167094698, 0.0548412357, 0.00495601381);
#else
#error "ENVCAP_CAP_NODES must be 1..8"
#endif

// Half-angle (rad) of the cap whose solid angle the lobe of power t matches: cos theta = t / (1 + t).
float envcap_cap_half_angle(float t)
{
    t = envcap_clean_power(t);
    return atan(sqrt(1.0 + 2.0 * t), t);
}

// vec3(f, vc, vp): the fraction f of the normalized lobe max(0, u.C)^w inside the cap of
// half-angle theta whose axis is gamma (rad) from C, and the blocked light's first moment along C
// (vc) and along the perpendicular towards the cap (vp).  f = int chi(alpha) dF(alpha),
// F = 1 - cos^(w+1) alpha, chi the fraction of the ring alpha inside the cap.
vec3 envcap_cap_lobe_fraction(float theta, float gamma, float w)
{
    w = envcap_clean_power(w);
    const float h = 0.5 * ENVCAP_PI;
    float a = min(abs(gamma - theta), h);
    float b = min(min(gamma + theta, 2.0 * ENVCAP_PI - gamma - theta), h);
    float p1 = w + 1.0;
    float Ga = envcap_cos_power(a, p1);
    float Gb = envcap_cos_power(b, p1);
    float f = (theta > gamma ? 1.0 - Ga : 0.0) + (gamma + theta > ENVCAP_PI ? Gb : 0.0);
    float vc = f;
    float vp = 0.0;
    float span = b > a ? Ga - Gb : 0.0;
    float sA = sin(0.5 * (theta - gamma)), cA = cos(0.5 * (theta - gamma));
    float sB = sin(0.5 * (theta + gamma)), cB = cos(0.5 * (theta + gamma));
    float sg = sin(gamma);
    for (int k = 0; k < ENVCAP_CAP_NODES; ++k) {
        float z = Ga + (Gb - Ga) * ENVCAP_CAP_U[k];
        float lam = z > 0.0 ? log(z) / p1 : -1.0e30;                  // ln cos alpha
        float m = lam > ENVCAP_EXPM1_SERIES_ABOVE                       // 1 - cos alpha
            ? -lam * (1.0 + lam * (0.5 + lam * (1.0 / 6.0 + lam * (1.0 / 24.0))))
            : 1.0 - exp(lam);
        float s2 = sqrt(max(0.5 * m, 0.0));                             // sin(alpha / 2)
        float c2 = sqrt(max(1.0 - 0.5 * m, 0.0));
        float sin_a = 2.0 * s2 * c2;
        float num = 2.0 * (sA * c2 + cA * s2) * (sB * c2 - cB * s2);
        float den = sin_a * sg;
        float q = den > 0.0 ? num / den : 2.0;
        q = q > 0.0 ? min(q, 2.0) : 0.0;                                // 1 - cos phi; NaN -> 0
        float chi = (2.0 / ENVCAP_PI) * atan(sqrt(q), sqrt(2.0 - q));  // asin(sqrt(q / 2)); asin is poor on GPUs
        float sin_phi = sqrt(q * (2.0 - q));
        float wt = span * ENVCAP_CAP_W[k];
        f += wt * chi;
        vc += wt * (chi * (1.0 - m));
        vp += wt * (sin_a * sin_phi * (1.0 / ENVCAP_PI));
    }
    return vec3(f, vc, vp);
}

// envcap's form for the occluder lobe (D, t), read as its cap (cos theta = t / (1 + t)), and the
// BRDF lobe (C, w): vec4(M, integral), integral = 2 pi f / (1 + w) (sr, |Cv| = 1; what Eq. 7
// approximates), M the blocked light's centroid (D when nothing is blocked).  Same inputs and
// limits as envcap_lobe_product (D = 0: a containing sphere, the whole lobe).
vec4 envcap_cap_lobe_product(vec3 D, vec3 C, float t, float w)
{
    w = envcap_clean_power(w);
    float lc_ = length(C);
    vec3 c = lc_ > 0.0 ? C / lc_ : vec3(0.0, 0.0, 1.0);
    float ld = length(D);
    vec3 d = ld > 0.0 ? D / ld : c;
    float cos_g = dot(d, c);
    float gamma = atan(length(cross(d, c)), cos_g);
    vec3 pr = d - cos_g * c;
    float lp = length(pr);
    vec3 P = lp > 0.0 ? pr / lp : envcap_any_perpendicular(c);
    vec3 fv = envcap_cap_lobe_fraction(envcap_cap_half_angle(t), gamma, w);
    float sc = max(abs(fv.y), abs(fv.z));                 // scaled first: |v| would underflow
    vec3 v = sc > 0.0 ? (fv.y / sc) * c + (fv.z / sc) * P : vec3(0.0);
    float lv = length(v);
    vec3 M = lv > 0.0 ? v / lv : d;
    return vec4(M, 2.0 * ENVCAP_PI * fv.x / (1.0 + w));
}

// The light the sphere lobe (D, t) blocks from the BRDF lobe (C, w): envcap's form, or the
// paper's Eq. 4-7 with #define ENVCAP_DYNAMIC_PAPER_FORM.  vec4(M, integral).
vec4 envcap_occlusion(vec3 D, vec3 C, float t, float w)
{
#ifdef ENVCAP_DYNAMIC_PAPER_FORM
    return envcap_lobe_product(D, C, t, w);
#else
    return envcap_cap_lobe_product(D, C, t, w);
#endif
}

#endif  // ENVCAP_DYNAMIC_GLSL
