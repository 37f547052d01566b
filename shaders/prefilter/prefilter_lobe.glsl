#version 430
// Normalized cosine-lobe filter of one cube level for P probes at once
// (envcap.prefilter.fast.prefilter_many; derivation in docs/prefilter.md).
//
// One invocation per output texel (probe p, face, row, col); its direction d is computed here
// from the GL texel center.  Over the source texels u of probe p inside the lobe's footprint:
//     out(d) = (sum_u W(u) S(u) + sum_hot W(h) S(h)) / sum_u W(u) Omega(u),  W = max(0, d.u)^w
// Source texel: S = sum of Omega * L over the level-0 texels it covers (RGBA block; the "hot"
// texels, e.g. the sun, removed), Omega its solid angle, and u its radiance-weighted centroid
// direction (so a sun inside a coarse texel sits where it really is, not at the texel center).
// Hot texels are level-0 texels listed separately and summed exactly, with no truncation.
//
// Footprint (no CPU work): per source face, rows from a conservative bound of the cap's
// projection on the face plane, then per row the exact column span of the cone
// d.x >= cos(theta) |x| (a quadratic), widened by one texel.  Texels whose weight is below
// exp(log_floor) are skipped.  log(d.u) comes from h = |u - d|^2 / 2 (no cancellation near
// the lobe axis).  Weights are scaled by exp(offset) (offset ~ w h of the nearest texel).
// From a coarse source the lobe is narrowed so that lobe + texel box has the lobe's variance.
// Mesa llvmpipe ends a shader's loops after 65535 iterations in all: the caller picks a source
// level whose footprint stays well below that (see _source_level).
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer SrcS { vec4 src_s[]; };   // [p][face][row][col]
layout(std430, binding = 1) readonly buffer SrcD { vec4 src_d[]; };   // [p][face][row][col]: centroid dir, Omega
layout(std430, binding = 2) readonly buffer HotS { vec4 hot_s[]; };   // [h]: Omega * L
layout(std430, binding = 3) readonly buffer HotD { vec4 hot_d[]; };   // [h]: direction, 0
layout(std430, binding = 4) readonly buffer HotR { ivec2 hot_r[]; };  // [p]: first hot, count
layout(std430, binding = 5) writeonly buffer Dst { vec4 dst[]; };     // [p][face][row][col]

uniform uint count;       // P * 6 * n_out^2
uniform int n_out;
uniform int n_src;
uniform float w;
uniform float log_floor;  // ln(eps): weights below eps * peak are dropped
uniform float blur_var;   // (1 - 4^-j) (2 / n_src)^2 / 12: per-axis variance a coarse texel adds, at a face center
uniform float theta;      // footprint cap half-angle (radians)
uniform float cos_theta;
uniform bool full;        // footprint covers (nearly) everything: no cap bounds

// Face frames of envcap.core.cube: direction = N + u * A + v * B (u = 2s - 1 along columns, v = 2t - 1 along rows).
const vec3 FN[6] = vec3[6](vec3(1, 0, 0), vec3(-1, 0, 0), vec3(0, 1, 0), vec3(0, -1, 0), vec3(0, 0, 1), vec3(0, 0, -1));
const vec3 FA[6] = vec3[6](vec3(0, 0, -1), vec3(0, 0, 1), vec3(1, 0, 0), vec3(1, 0, 0), vec3(1, 0, 0), vec3(-1, 0, 0));
const vec3 FB[6] = vec3[6](vec3(0, -1, 0), vec3(0, -1, 0), vec3(0, 0, 1), vec3(0, 0, -1), vec3(0, -1, 0), vec3(0, -1, 0));
const float FACE_HALF_ANGLE = 0.9553166;  // acos(1/sqrt(3)): the farthest a face point is from its normal

float log_cos(float h) {
    // log(1 - h) for 0 <= h < 1
    if (h < 0.05) {
        return -h * (1.0 + h * (0.5 + h * (1.0 / 3.0 + h * (0.25 + h * 0.2))));
    }
    return log(1.0 - h);
}

int lo_index(float x, int n) { return clamp(int(ceil((x + 1.0) * 0.5 * float(n) - 0.5)) - 1, 0, n); }
int hi_index(float x, int n) { return clamp(int(floor((x + 1.0) * 0.5 * float(n) - 0.5)) + 2, 0, n); }

void main() {
    uint o = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * 64u + gl_LocalInvocationID.x;
    if (o >= count) return;
    uint per = uint(6 * n_out * n_out);
    uint p = o / per;
    int t = int(o - p * per);
    int fo = t / (n_out * n_out);
    int ro = (t / n_out) % n_out;
    int co = t % n_out;
    float so = 2.0 / float(n_out);
    vec3 d = normalize(FN[fo] + ((float(co) + 0.5) * so - 1.0) * FA[fo] + ((float(ro) + 0.5) * so - 1.0) * FB[fo]);

    // A coarse source texel spreads what it holds over a box of per-axis variance ~ its solid
    // angle / 12 (relative to the level-0 texel centers); the kernel sum over coarse texels is the
    // lobe widened by that.  Shrink the lobe so the per-axis variances add up to 1 / (w + 2).
    float dmax = max(abs(d.x), max(abs(d.y), abs(d.z)));
    float var_lobe = 1.0 / (w + 2.0);
    float w_eff = (w > 0.0) ? 1.0 / max(var_lobe - blur_var * dmax * dmax * dmax, 0.25 * var_lobe) - 2.0 : 0.0;
    int n = n_src;
    float offset = min(4.0 * w_eff / float(n * n), 60.0);   // nearest centroid: h <= 4 / n^2
    uint base_p = p * uint(6 * n * n);
    float c2 = cos_theta * cos_theta;
    vec4 acc = vec4(0.0);
    float wsum = 0.0;
    for (int f = 0; f < 6; ++f) {
        float dn = dot(d, FN[f]);
        float da = dot(d, FA[f]);
        float db = dot(d, FB[f]);
        float phi = acos(clamp(dn, -1.0, 1.0));
        if (!full && phi - theta > FACE_HALF_ANGLE + 1e-3) continue;   // cap misses this face
        int j0 = 0, j1 = n;
        if (!full && phi + theta < 1.5) {
            // |b(u) - b(d)| <= theta / cos^2(phi + theta) on the face plane (b = u.B / u.N)
            float cb = cos(phi + theta);
            float r = theta / (cb * cb);
            float pv = db / dn;
            j0 = lo_index(pv - r, n);
            j1 = hi_index(pv + r, n);
        }
        for (int j = j0; j < j1; ++j) {
            float v = (float(j) + 0.5) * 2.0 / float(n) - 1.0;
            int i0 = 0, i1 = n;
            if (!full) {
                // cone d.x >= c |x| on the row line x = N + v B + u A:  a2 u^2 + 2 da e u + e^2 - c^2 (1 + v^2) >= 0
                float e = dn + v * db;
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
            uint row = base_p + uint((f * n + j) * n);
            for (int i = i0; i < i1; ++i) {
                vec4 sd = src_d[row + uint(i)];
                vec3 e3 = sd.xyz - d;
                float h = 0.5 * dot(e3, e3);
                if (h >= 1.0) continue;                 // d.u <= 0: outside the lobe
                float lw = w_eff * log_cos(h);
                if (lw < log_floor) continue;           // truncated footprint
                float wt = exp(lw + offset);
                acc += wt * src_s[row + uint(i)];
                wsum += wt * sd.w;
            }
        }
    }
    ivec2 hr = hot_r[p];
    for (int k = hr.x; k < hr.x + hr.y; ++k) {
        vec3 e3 = hot_d[k].xyz - d;
        float h = 0.5 * dot(e3, e3);
        if (h >= 1.0) continue;
        float lw = w_eff * log_cos(h);
        acc += exp(lw + offset) * hot_s[k];
    }
    // wsum = 0 only for a lobe much narrower than a source texel: the caller substitutes the
    // nearest texel (the w -> infinity limit) where this writes a non-finite value.
    dst[o] = (wsum > 0.0) ? acc / wsum : vec4(uintBitsToFloat(0x7fc00000u));
}
