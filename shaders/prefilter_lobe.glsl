#version 430
// Normalized cosine-lobe filter of one cube level (envcap.prefilter.prefilter_chain).
//
// One invocation per output texel.  For an output direction d and every source texel u inside
// the footprint rectangles (computed on the CPU, float64, per output texel and source face):
//     out(d) = sum_u W(u) Omega(u) L(u) / sum_u W(u) Omega(u),   W(u) = max(0, d.u)^w
// Source texels hold Omega * L (RGBA, Omega = exact texel solid angle) and Omega separately.
// log(d.u) is computed from h = 1 - d.u = |u - d|^2 / 2 (no cancellation near the lobe axis)
// with a series for small h.  Weights below exp(log_floor) of the peak are skipped (footprint
// truncation); weights are scaled by exp(offset) so the nearest texel never underflows.
//
// Mesa llvmpipe stops any loop after 65535 iterations (a guard against infinite loops), so one
// dispatch only visits source rows [row_begin, row_end) of the 6 * n_src face rows, and writes
// partial sums that the caller adds up in float64: (acc, (wsum, best_lw, 0, 0), best_val).
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Src { vec4 src[]; };     // [face][row][col], Omega * L
layout(std430, binding = 1) readonly buffer Omega { float omega[]; }; // [row][col]
layout(std430, binding = 2) readonly buffer Dirs { vec4 dirs[]; };    // unit output directions
layout(std430, binding = 3) readonly buffer Rects { ivec4 rects[]; }; // [out][face]: col0, col1, row0, row1 (exclusive ends)
layout(std430, binding = 4) writeonly buffer Dst { vec4 dst[]; };     // [out][3]

uniform uint count;
uniform int n_src;
uniform float w;
uniform float log_floor;
uniform float offset;
uniform int row_begin;
uniform int row_end;

// Face frames of envcap.cube: direction = N + u * A + v * B (u = 2s - 1 along columns, v = 2t - 1 along rows).
const vec3 FN[6] = vec3[6](vec3(1, 0, 0), vec3(-1, 0, 0), vec3(0, 1, 0), vec3(0, -1, 0), vec3(0, 0, 1), vec3(0, 0, -1));
const vec3 FA[6] = vec3[6](vec3(0, 0, -1), vec3(0, 0, 1), vec3(1, 0, 0), vec3(1, 0, 0), vec3(1, 0, 0), vec3(-1, 0, 0));
const vec3 FB[6] = vec3[6](vec3(0, -1, 0), vec3(0, -1, 0), vec3(0, 0, 1), vec3(0, 0, -1), vec3(0, -1, 0), vec3(0, -1, 0));

float log_cos(float h) {
    // log(1 - h) for 0 <= h < 1
    if (h < 0.05) {
        return -h * (1.0 + h * (0.5 + h * (1.0 / 3.0 + h * (0.25 + h * 0.2))));
    }
    return log(1.0 - h);
}

void main() {
    uint o = gl_GlobalInvocationID.x;
    if (o >= count) return;
    vec3 d = dirs[o].xyz;
    float scale = 2.0 / float(n_src);
    vec4 acc = vec4(0.0);
    float wsum = 0.0;
    float best = -1e30;
    vec4 best_val = vec4(0.0);
    for (int f = 0; f < 6; ++f) {
        ivec4 r = rects[o * 6u + uint(f)];
        int j0 = max(r.z, row_begin - f * n_src);
        int j1 = min(r.w, row_end - f * n_src);
        if (r.x >= r.y) continue;
        for (int j = j0; j < j1; ++j) {
            float v = (float(j) + 0.5) * scale - 1.0;
            vec3 base = FN[f] + v * FB[f];
            vec4 racc = vec4(0.0);
            float rsum = 0.0;
            int row = (f * n_src + j) * n_src;
            for (int i = r.x; i < r.y; ++i) {
                float u = (float(i) + 0.5) * scale - 1.0;
                vec3 dir = normalize(base + u * FA[f]);
                vec3 e = dir - d;
                float h = 0.5 * dot(e, e);
                if (h >= 1.0) continue;             // d.u <= 0: outside the lobe
                float lw = (w > 0.0) ? w * log_cos(h) : 0.0;
                if (lw > best) { best = lw; best_val = src[row + i] / omega[j * n_src + i]; }
                if (lw < log_floor) continue;        // truncated footprint
                float wt = exp(lw + offset);
                racc += wt * src[row + i];
                rsum += wt * omega[j * n_src + i];
            }
            acc += racc;
            wsum += rsum;
        }
    }
    dst[3u * o] = acc;
    dst[3u * o + 1u] = vec4(wsum, best, 0.0, 0.0);
    dst[3u * o + 2u] = best_val;
}
