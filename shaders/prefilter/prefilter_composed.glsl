#version 430
// One level of the composed cosine-lobe chain for P probes at once
// (envcap.prefilter.composed.prefilter_many_composed; derivation in docs/prefilter.md).
//
// One invocation per output texel (face, row, col) at GL texel-center direction d and group of
// PROBES probes (the weights are the same for every probe: computed once, applied to each).
// The source is a cube level of P probes holding *cold* radiance (hot texels, e.g. the sun,
// removed): either level 0 (a "direct" pass: the lobe cos^w_k itself) or an already filtered
// level j (a "composed" pass: the difference lobe, whose mean cosine times level j's gives
// level k's).  Over the source texels u inside the lobe's footprint:
//     cold(d) = sum_u W(u) Omega(u) L(u) / sum_u W(u) Omega(u),   W = max(0, d.u)^w_lobe
// nu(d) is the ratio of the exact level-0 normalizer sum_u cos^w_k Omega to its continuum value
// 2 pi / (w_k + 1), the same for every probe: measured from the weight sum in a direct pass,
// carried through a composed pass like a colour channel.  The hot texels are then added exactly
// with the level's own lobe:
//     total(d) = cold(d) + sum_hot cos^w_k(d.h) Omega_h L_h (w_k + 1) / (2 pi nu(d)).
// Weights below eps of the lobe's peak are skipped (the truncated footprint; w_lobe is lowered
// so that the truncated lobe keeps the mean cosine).
// Two ways to evaluate W Omega, chosen per dispatch:
// * exact: source texel directions are the GL texel centres, computed here; 1 - d.u comes from
//   |d x u|^2 (no cancellation near the lobe axis); Omega from the exact table.  Footprint as in
//   prefilter_lobe.glsl (per face, rows from a bound of the cap's projection, per row the exact
//   column span of the cone, widened by one texel).
// * taylor (narrow lobes on large faces): on each face plane, around the point (a, b) where d
//   meets it, log(cos^w(d.u) J(u)) (J = (1 + u^2 + v^2)^-1.5, Omega ~ J (2/n)^2) is a quartic
//   polynomial in (u - a, v - b) to within w O(theta^6) (docs/prefilter.md).  Over the cap's rows
//   (bounding box of its ellipse on the face) it is evaluated by forward differences in the exp
//   domain: four multiplies per texel, 10 per row, 6 exps and 9 short series per face.
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Src { vec4 src[]; };        // [face][row][col][p]: cold radiance
layout(std430, binding = 1) readonly buffer SrcNu { float src_nu[]; };  // [face][row][col]: nu of the source level
layout(std430, binding = 2) readonly buffer SrcOm { float src_om[]; };  // [row][col]: texel solid angles (every face alike)
layout(std430, binding = 3) readonly buffer HotS { vec4 hot_s[]; };     // [h]: Omega * L
layout(std430, binding = 4) readonly buffer HotD { vec4 hot_d[]; };     // [h]: direction, 0
layout(std430, binding = 5) readonly buffer HotR { ivec2 hot_r[]; };    // [p]: first hot, count
layout(std430, binding = 6) writeonly buffer Cold { vec4 cold[]; };     // [face][row][col][p] (probes adjacent: a group's reads share cache lines)
layout(std430, binding = 7) writeonly buffer Nu { float nu[]; };        // [face][row][col]
layout(std430, binding = 8) writeonly buffer Total { vec4 total[]; };   // [p][face][row][col]

uniform uint count;       // ceil(P / PROBES) * 6 * n_out^2 invocations
uniform int probes;       // P
uniform int n_out;
uniform int n_src;
// Compile-time variants (the caller defines them after #version; uniform branches cost ~20 %):
#ifndef DIRECT
#define DIRECT 1          // source is level 0 (nu from the weight sum) rather than a filtered level
#endif
#ifndef TAYLOR
#define TAYLOR 1          // quartic forward differences (narrow lobes) rather than exact weights
#endif
#ifndef PROBES
#define PROBES 1          // probes per invocation
#endif
const bool direct = DIRECT != 0;
const bool taylor = TAYLOR != 0;
uniform float w_lobe;     // cosine power applied to the source (truncation-compensated)
uniform float eps;        // weights below eps * peak are dropped (0: none)
uniform float theta;      // footprint cap half-angle (radians)
uniform float cos_theta;
uniform bool full;        // footprint covers (nearly) everything: no cap bounds, no truncation
uniform float offset;     // exact path: weights are scaled by exp(offset) (no underflow near the axis)
uniform float wsum_scale; // direct: nu = wsum * wsum_scale
uniform float w_level;    // cos^w_level of this level, for the hot texels
uniform float hot_norm;   // (w_level + 1) / (2 pi)

// Face frames of envcap.core.cube: direction = N + u * A + v * B (u = 2s - 1 along columns, v = 2t - 1 along rows).
const vec3 FN[6] = vec3[6](vec3(1, 0, 0), vec3(-1, 0, 0), vec3(0, 1, 0), vec3(0, -1, 0), vec3(0, 0, 1), vec3(0, 0, -1));
const vec3 FA[6] = vec3[6](vec3(0, 0, -1), vec3(0, 0, 1), vec3(1, 0, 0), vec3(1, 0, 0), vec3(1, 0, 0), vec3(-1, 0, 0));
const vec3 FB[6] = vec3[6](vec3(0, -1, 0), vec3(0, -1, 0), vec3(0, 0, 1), vec3(0, 0, -1), vec3(0, -1, 0), vec3(0, -1, 0));
const float FACE_HALF_ANGLE = 0.9553166;  // acos(1/sqrt(3)): the farthest a face point is from its normal

vec4 acc[PROBES];         // per probe of the group
uint pq[PROBES];          // the probes of the group (past P: a repeat of the last, not written)
float wsum = 0.0;
float nusum = 0.0;

float log_cos(float h) {
    // log(1 - h) for 0 <= h < 1
    if (h < 0.05) {
        return -h * (1.0 + h * (0.5 + h * (1.0 / 3.0 + h * (0.25 + h * 0.2))));
    }
    return log(1.0 - h);
}

int lo_index(float x, int n) { return clamp(int(ceil((x + 1.0) * 0.5 * float(n) - 0.5)) - 1, 0, n); }
int hi_index(float x, int n) { return clamp(int(floor((x + 1.0) * 0.5 * float(n) - 0.5)) + 2, 0, n); }

void accumulate_exact(vec3 d, int f, float log_floor) {
    int n = n_src;
    float sn = 2.0 / float(n);
    float c2 = cos_theta * cos_theta;
    float dn = dot(d, FN[f]);
    float da = dot(d, FA[f]);
    float db = dot(d, FB[f]);
    float phi = acos(clamp(dn, -1.0, 1.0));
    if (!full && phi - theta > FACE_HALF_ANGLE + 1e-3) return;   // cap misses this face
    int j0 = 0, j1 = n;
    if (!full && phi + theta < 1.5) {
        // |b(u) - b(d)| <= theta / cos^2(phi + theta) on the face plane (b = u.B / u.N)
        float cb = cos(phi + theta);
        float r = theta / (cb * cb);
        float pv = db / dn;
        j0 = lo_index(pv - r, n);
        j1 = hi_index(pv + r, n);
    }
    // d x (N + u A + v B) = cN + u cA + v cB
    vec3 cN = cross(d, FN[f]);
    vec3 cA = cross(d, FA[f]);
    vec3 cB = cross(d, FB[f]);
    for (int j = j0; j < j1; ++j) {
        float v = (float(j) + 0.5) * sn - 1.0;
        int i0 = 0, i1 = n;
        float e = dn + v * db;
        if (!full) {
            // cone d.x >= c |x| on the row line x = N + v B + u A:  a2 u^2 + 2 da e u + e^2 - c^2 (1 + v^2) >= 0
            float a2 = da * da - c2;
            if (a2 < -1e-6) {
                float q = e * e + a2 * (1.0 + v * v);
                if (q < 0.0) continue;
                float umid = -da * e / a2;
                if (e + umid * da < 0.0) continue;   // the other nappe
                float s = cos_theta * sqrt(q) / a2;
                float ua = umid - s, ub = umid + s;
                i0 = lo_index(min(ua, ub), n);
                i1 = hi_index(max(ua, ub), n);
            }
        }
        vec3 cR = cN + v * cB;
        float qR = 1.0 + v * v;
        uint row = uint((f * n + j) * n);
        uint orow = uint(j * n);
        for (int i = i0; i < i1; ++i) {
            float u = (float(i) + 0.5) * sn - 1.0;
            float s = e + u * da;                     // d.x, x = N + u A + v B
            if (s <= 0.0) continue;                   // behind the lobe
            vec3 cx = cR + u * cA;
            float rq = sqrt(qR + u * u);              // |x|
            float h = dot(cx, cx) / (rq * (rq + s));  // 1 - d.x / |x|
            float lw = w_lobe * log_cos(min(h, 0.999999));
            if (lw < log_floor) continue;             // truncated footprint
            float wt = exp(lw + offset) * src_om[orow + uint(i)];
            uint ti = (row + uint(i)) * uint(probes);
            for (int q = 0; q < PROBES; ++q) acc[q] += wt * src[ti + pq[q]];
            wsum += wt;
            if (!direct) nusum += wt * src_nu[row + uint(i)];
        }
    }
}

// The log-weight log(cos^w(d.u) J(u)) at face point (u, v) = (a + x, b + y), J = (1 + u^2 + v^2)^-1.5,
// to fourth order in (x, y).  With S = 1 + a^2 + b^2, p = (a x + b y) / S, q = (x^2 + y^2) / S and
// N = ((x^2 + y^2) + (a y - b x)^2) / S^2 (exact: sin^2 = N / (1 + 2p + q)):
//   w log cos = (w/2) log(1 - sin^2) = -(w/2) (N (1 - 2p - q + 4p^2) + N^2 / 2) + O(6)
//   log J = -1.5 log S - 1.5 (2p + q - 2p^2 - 2pq - q^2/2 + 8p^3/3 + 4p^2 q - 4p^4) + O(5)
// Grouped by degree (p: degree 1; q, N: degree 2):
//   0: -1.5 log S    1: -3p    2: -(w/2) N - 1.5 q + 3 p^2    3: w N p + 3 p q - 4 p^3
//   4: -(w/2) (4 N p^2 - N q + N^2 / 2) + 0.75 q^2 - 6 p^2 q + 6 p^4
// Coefficients c<k><l> of x^k y^l (k + l <= 4); the setup below is straight-line code (Mesa
// llvmpipe keeps dynamically indexed local arrays in memory, which made a loop version as slow
// as the exact weights), written out from the products above (tests/prefilter/test_composed.py
// compares these weights with exact ones); the Taylor shift is Horner's rule per variable;
// M[s][k] = s! S(k, s) (Stirling numbers of the second kind) turns monomial coefficients into
// forward differences (D^s i^k at 0).
// exp(x) for the third- and fourth-order differences, |x| << 1 (texel below the lobe's width):
// error x^5 / 120 (< 1e-7 for |x| < 0.1).
float exp_small(float x) { return 1.0 + x * (1.0 + 0.5 * x * (1.0 + x * (1.0 / 3.0) * (1.0 + 0.25 * x))); }

void accumulate_taylor(vec3 d, int f) {
    int n = n_src;
    float dn = dot(d, FN[f]);
    float sin_theta = sqrt(max(1.0 - cos_theta * cos_theta, 0.0));
    if (dn <= sin_theta + 1e-4) return;   // the cap misses this face's front (taylor runs with small caps only)
    float da = dot(d, FA[f]), db = dot(d, FB[f]);
    // the cap meets the face's pyramid x.N >= |x.A|, |x.B| only if d is within theta of each bounding plane
    float reach = 1.41422 * sin_theta;
    if (abs(da) - dn > reach || abs(db) - dn > reach) return;
    // bounding box of the cap's ellipse on the face plane (as envcap.prefilter.footprint.footprint_rects)
    float cc = cos_theta * cos_theta;
    float A = da * da - cc, B = 2.0 * da * db, C = db * db - cc;
    float D = 2.0 * da * dn, E = 2.0 * db * dn, F = dn * dn - cc;
    float k4 = 4.0 * A * C - B * B;
    float qa_b = 4.0 * C * D - 2.0 * B * E, qa_c = 4.0 * C * F - E * E;
    float qb_b = 4.0 * A * E - 2.0 * B * D, qb_c = 4.0 * A * F - D * D;
    float ra = sqrt(max(qa_b * qa_b - 4.0 * k4 * qa_c, 0.0)) / abs(2.0 * k4);
    float rb = sqrt(max(qb_b * qb_b - 4.0 * k4 * qb_c, 0.0)) / abs(2.0 * k4);
    float a = da / dn, b = db / dn;
    float ua = -qa_b / (2.0 * k4), va = -qb_b / (2.0 * k4);   // ellipse centre
    // texel centres (i + 0.5) 2/n - 1 inside [centre - r, centre + r], widened by 0.05 texel
    float hn = 0.5 * float(n);
    int i0 = clamp(int(ceil((min(ua - ra, a) + 1.0) * hn - 0.55)), 0, n);
    int i1 = clamp(int(floor((max(ua + ra, a) + 1.0) * hn - 0.45)) + 1, 0, n);
    int j0 = clamp(int(ceil((min(va - rb, b) + 1.0) * hn - 0.55)), 0, n);
    int j1 = clamp(int(floor((max(va + rb, b) + 1.0) * hn - 0.45)) + 1, 0, n);
    if (i0 >= i1 || j0 >= j1) return;
    float s = 1.0 + a * a + b * b;
    float w2 = 0.5 * w_lobe;
    float p10 = a / s, p01 = b / s;                                      // p
    float q2 = 1.0 / s;                                                  // q
    float n20 = (1.0 + b * b) / (s * s), n11 = -2.0 * a * b / (s * s), n02 = (1.0 + a * a) / (s * s);   // N
    float pp20 = p10 * p10, pp11 = 2.0 * p10 * p01, pp02 = p01 * p01;   // p^2
    float h = 2.0 / float(n), h2 = h * h, h3 = h2 * h, h4 = h2 * h2;
    float x0 = (float(i0) + 0.5) * h - 1.0 - a;
    float y0 = (float(j0) + 0.5) * h - 1.0 - b;
    float c00 = -1.5 * log(s);
    float c10 = -3.0 * p10;
    float c01 = -3.0 * p01;
    float c20 = -w2 * n20 + -1.5 * q2 + 3.0 * pp20;
    float c11 = -w2 * n11 + 3.0 * pp11;
    float c02 = -w2 * n02 + -1.5 * q2 + 3.0 * pp02;
    float c30 = w_lobe * n20 * p10 + 3.0 * p10 * q2 + -4.0 * pp20 * p10;
    float c21 = w_lobe * n20 * p01 + w_lobe * n11 * p10 + 3.0 * p01 * q2 + -4.0 * pp20 * p01 + -4.0 * pp11 * p10;
    float c12 = w_lobe * n11 * p01 + w_lobe * n02 * p10 + 3.0 * p10 * q2 + -4.0 * pp11 * p01 + -4.0 * pp02 * p10;
    float c03 = w_lobe * n02 * p01 + 3.0 * p01 * q2 + -4.0 * pp02 * p01;
    float c40 = (-4.0 * w2) * n20 * pp20 + w2 * n20 * q2 + (-0.5 * w2) * n20 * n20 + 0.75 * q2 * q2 + -6.0 * pp20 * q2 + 6.0 * pp20 * pp20;
    float c31 = (-4.0 * w2) * n20 * pp11 + (-4.0 * w2) * n11 * pp20 + w2 * n11 * q2 + (-0.5 * w2) * n20 * n11 + (-0.5 * w2) * n11 * n20 + -6.0 * pp11 * q2 + 6.0 * pp20 * pp11 + 6.0 * pp11 * pp20;
    float c22 = (-4.0 * w2) * n20 * pp02 + (-4.0 * w2) * n11 * pp11 + (-4.0 * w2) * n02 * pp20 + w2 * n20 * q2 + w2 * n02 * q2 + (-0.5 * w2) * n20 * n02 + (-0.5 * w2) * n11 * n11 + (-0.5 * w2) * n02 * n20 + 0.75 * q2 * q2 + 0.75 * q2 * q2 + -6.0 * pp20 * q2 + -6.0 * pp02 * q2 + 6.0 * pp20 * pp02 + 6.0 * pp11 * pp11 + 6.0 * pp02 * pp20;
    float c13 = (-4.0 * w2) * n11 * pp02 + (-4.0 * w2) * n02 * pp11 + w2 * n11 * q2 + (-0.5 * w2) * n11 * n02 + (-0.5 * w2) * n02 * n11 + -6.0 * pp11 * q2 + 6.0 * pp11 * pp02 + 6.0 * pp02 * pp11;
    float c04 = (-4.0 * w2) * n02 * pp02 + w2 * n02 * q2 + (-0.5 * w2) * n02 * n02 + 0.75 * q2 * q2 + -6.0 * pp02 * q2 + 6.0 * pp02 * pp02;
    // Taylor shift to the box origin (x0, y0), then scale to texel steps
    c30 += x0 * c40;
    c20 += x0 * c30;
    c10 += x0 * c20;
    c00 += x0 * c10;
    c30 += x0 * c40;
    c20 += x0 * c30;
    c10 += x0 * c20;
    c30 += x0 * c40;
    c20 += x0 * c30;
    c30 += x0 * c40;
    c21 += x0 * c31;
    c11 += x0 * c21;
    c01 += x0 * c11;
    c21 += x0 * c31;
    c11 += x0 * c21;
    c21 += x0 * c31;
    c12 += x0 * c22;
    c02 += x0 * c12;
    c12 += x0 * c22;
    c03 += x0 * c13;
    c03 += y0 * c04;
    c02 += y0 * c03;
    c01 += y0 * c02;
    c00 += y0 * c01;
    c03 += y0 * c04;
    c02 += y0 * c03;
    c01 += y0 * c02;
    c03 += y0 * c04;
    c02 += y0 * c03;
    c03 += y0 * c04;
    c12 += y0 * c13;
    c11 += y0 * c12;
    c10 += y0 * c11;
    c12 += y0 * c13;
    c11 += y0 * c12;
    c12 += y0 * c13;
    c21 += y0 * c22;
    c20 += y0 * c21;
    c21 += y0 * c22;
    c30 += y0 * c31;
    c10 *= h;
    c01 *= h;
    c20 *= h2;
    c11 *= h * h;
    c02 *= h2;
    c30 *= h3;
    c21 *= h2 * h;
    c12 *= h * h2;
    c03 *= h3;
    c40 *= h4;
    c31 *= h3 * h;
    c22 *= h2 * h2;
    c13 *= h * h3;
    c04 *= h4;
    // forward differences at the box origin, T[s][t] = sum_kl M[s][k] M[t][l] c[k][l] (M[s][k] = s! S(k, s)), in the exp domain
    float g00 = exp(c00);
    float g01 = exp(c01 + c02 + c03 + c04);
    float g02 = exp(2.0 * c02 + 6.0 * c03 + 14.0 * c04);
    float g03 = exp_small(6.0 * c03 + 36.0 * c04);
    float g04 = exp_small(24.0 * c04);
    float g10 = exp(c10 + c20 + c30 + c40);
    float g11 = exp(c11 + c12 + c13 + c21 + c22 + c31);
    float g12 = exp_small(2.0 * c12 + 6.0 * c13 + 2.0 * c22);
    float g13 = exp_small(6.0 * c13);
    float g20 = exp(2.0 * c20 + 6.0 * c30 + 14.0 * c40);
    float g21 = exp_small(2.0 * c21 + 2.0 * c22 + 6.0 * c31);
    float g22 = exp_small(4.0 * c22);
    float g30 = exp_small(6.0 * c30 + 36.0 * c40);
    float g31 = exp_small(6.0 * c31);
    float g40 = exp_small(24.0 * c40);
    float thr = eps * pow(s, -1.5);   // eps x J at the cap centre
    float a2 = da * da - cc;
    for (int j = j0; j < j1; ++j) {
        // the row's texels inside the cone d.x >= cos(theta) |x| (as in accumulate_exact, 0.05 texel wider)
        float v = (float(j) + 0.5) * h - 1.0;
        float e = dn + v * db;
        float q = max(e * e + a2 * (1.0 + v * v), 0.0);
        float umid = -da * e / a2;
        float sq = cos_theta * sqrt(q) / abs(a2);
        int ia = clamp(int(ceil((umid - sq + 1.0) * hn - 0.55)), i0, i1);
        int ib = clamp(int(floor((umid + sq + 1.0) * hn - 0.45)) + 1, ia, i1);
        float W = g00, e1 = g10, e2 = g20, e3 = g30;
        for (int i = i0; i < ia; ++i) {   // advance to the span
            W *= e1;
            e1 *= e2;
            e2 *= e3;
            e3 *= g40;
        }
        uint row = uint((f * n + j) * n);
        for (int i = ia; i < ib; ++i) {
            if (W >= thr) {
                uint ti = (row + uint(i)) * uint(probes);
                for (int q = 0; q < PROBES; ++q) acc[q] += W * src[ti + pq[q]];
                wsum += W;
                if (!direct) nusum += W * src_nu[row + uint(i)];
            }
            W *= e1;
            e1 *= e2;
            e2 *= e3;
            e3 *= g40;
        }
        // next row: every D_i^s D_j^t moves one step in j
        g00 *= g01; g01 *= g02; g02 *= g03; g03 *= g04;
        g10 *= g11; g11 *= g12; g12 *= g13;
        g20 *= g21; g21 *= g22;
        g30 *= g31;
    }
}

void main() {
    uint o = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * 64u + gl_LocalInvocationID.x;
    if (o >= count) return;
    uint per = uint(6 * n_out * n_out);
    uint g = o / per;                     // probe group
    int t = int(o - g * per);             // output texel
    int fo = t / (n_out * n_out);
    int ro = (t / n_out) % n_out;
    int co = t % n_out;
    float so = 2.0 / float(n_out);
    vec3 d = normalize(FN[fo] + ((float(co) + 0.5) * so - 1.0) * FA[fo] + ((float(ro) + 0.5) * so - 1.0) * FB[fo]);
    for (int q = 0; q < PROBES; ++q) {
        acc[q] = vec4(0.0);
        pq[q] = uint(min(int(g) * PROBES + q, probes - 1));
    }
    float log_floor = (full || eps <= 0.0) ? -1e30 : log(eps);
    for (int f = 0; f < 6; ++f) {
        if (taylor) {
            accumulate_taylor(d, f);
        } else {
            accumulate_exact(d, f, log_floor);
        }
    }
    float nu_d = direct ? wsum * wsum_scale : nusum / wsum;
    if (g == 0u) nu[t] = nu_d;
    float h_cut = 50.0 / max(w_level, 1e-30);   // cos^w < e^-50: no contribution
    for (int q = 0; q < PROBES; ++q) {
        int p = int(g) * PROBES + q;
        if (p >= probes) break;
        // wsum = 0 only for a lobe much narrower than a source texel (a direct pass): the caller
        // substitutes the nearest texel (the w -> infinity limit) where this writes a non-finite value.
        vec4 c = (wsum > 0.0) ? acc[q] / wsum : vec4(uintBitsToFloat(0x7fc00000u));
        vec4 hot = vec4(0.0);
        ivec2 hr = hot_r[p];
        for (int k = hr.x; k < hr.x + hr.y; ++k) {
            vec3 e3 = hot_d[k].xyz - d;
            float h = 0.5 * dot(e3, e3);
            if (h >= 1.0 || h > h_cut) continue;
            hot += exp(w_level * log_cos(h)) * hot_s[k];
        }
        cold[uint(t) * uint(probes) + uint(p)] = c;
        total[uint(p) * per + uint(t)] = c + hot * (hot_norm / nu_d);
    }
}
