#ifndef ENVCAP_SKY_VISIBILITY_GLSL
#define ENVCAP_SKY_VISIBILITY_GLSL
// envcap runtime: the composite after filtering under a sky that changes after the bake
// (docs/lobes.md, "Composite after filtering"; numpy twin envcap.runtime.sky_visibility).
// No #version: #include this.
//
// The composite is C_w = S_w + K'_w - O_w (S_w: the street's premultiplied RGB, K'_w: the new
// sky's rung lookup, O_w ~ filter(alpha K'): the visible sky).  `vis` is the bake's visibility
// texture V_lm = filter(alpha Y_lm) (envcap.prefilter.sky_visibility.SkyVisibility.packed_levels):
// a mip-mapped cube-map array whose mip 0 is the rung level `first_level`; channel q = r*nsh + c
// (rung layer r, coefficient c) of a probe is component q % 4 of layer vbase + q / 4.  `ksh`: the
// new sky's SH coefficients (RGB, envcap.runtime.sky_visibility.sky_sh_coefficients), nsh of them
// (1, 4, 9, 16 or 25), or D = K'_lm - s K_lm with base_w = s K_w (the baked sky's lookup, scaled:
// envcap.runtime.sky_visibility.sky_delta).  At a stored rung i, a_i = V_00 / Y_00, F_i(x) =
// sum ksh lambda_l(w_i) Y_lm(x), m_i = filter(alpha u) = (V_11, V_1-1, V_10) / Y_1:
//   O_i = alpha_w base_w + sum ksh V_i
//         [mode >= 1] + a_i (K'_w - base_w - F_i(d))
//         [mode >= 2] + sum_k (m_i . t_k) d/dt_k (C'_w - F_i)(d) / lambda_1(w_i),   C' = K' - B.
// Rungs below `first_level * per_level` have no V: O_i = alpha_w K'_w there.
// Frames (docs/lobes.md, "A sky that changes"): a probe's V is in its street's frame (cube axes
// turned by the street's yaw, frame = (cos, sin) = EnvcapStreet.frame), the sky in the world's.
// d is the world direction: the sky's rungs (K'_w, base_w, skyd) are read along d and d +- h t_k,
// V along R d (envcap_frame_dir); ksh, F_i, m_i and the tangents are the frame's: ksh = the sky's
// coefficients turned by R (envcap.runtime.sky_visibility.glsl_coefficients(k, order, yaw)).
// frame = (1, 0): the world, as before.
#include "runtime/envcap_lobes.glsl"
#include "runtime/envcap_street.glsl"
#ifndef ENVCAP_SKY_VIS_MAX_SH
#define ENVCAP_SKY_VIS_MAX_SH 25
#endif

// Real SH Y_lm(d), l <= 4, z polar, order l, m = -l..l (envcap.prefilter.sky_visibility.sh_basis).
void envcap_sh_basis(vec3 d, out float y[ENVCAP_SKY_VIS_MAX_SH])
{
    float x = d.x, yy = d.y, z = d.z, z2 = z * z;
    y[0] = 0.282094791773878;
    y[1] = 0.488602511902920 * yy; y[2] = 0.488602511902920 * z; y[3] = 0.488602511902920 * x;
    y[4] = 1.092548430592079 * x * yy; y[5] = 1.092548430592079 * yy * z;
    y[6] = 0.315391565252520 * (3.0 * z2 - 1.0); y[7] = 1.092548430592079 * x * z;
    y[8] = 0.546274215296040 * (x * x - yy * yy);
    y[9] = 0.5900435899266435 * yy * (3.0 * x * x - yy * yy); y[10] = 2.890611442640554 * x * yy * z;
    y[11] = 0.4570457994644658 * yy * (5.0 * z2 - 1.0); y[12] = 0.3731763325901154 * z * (5.0 * z2 - 3.0);
    y[13] = 0.4570457994644658 * x * (5.0 * z2 - 1.0); y[14] = 1.445305721320277 * z * (x * x - yy * yy);
    y[15] = 0.5900435899266435 * x * (x * x - 3.0 * yy * yy);
    y[16] = 2.5033429417967046 * x * yy * (x * x - yy * yy);
    y[17] = 1.7701307697799304 * yy * z * (3.0 * x * x - yy * yy);
    y[18] = 0.9461746957575601 * x * yy * (7.0 * z2 - 1.0);
    y[19] = 0.6690465435572892 * yy * z * (7.0 * z2 - 3.0);
    y[20] = 0.10578554691520431 * (35.0 * z2 * z2 - 30.0 * z2 + 3.0);
    y[21] = 0.6690465435572892 * x * z * (7.0 * z2 - 3.0);
    y[22] = 0.47308734787878004 * (x * x - yy * yy) * (7.0 * z2 - 1.0);
    y[23] = 1.7701307697799304 * x * z * (x * x - 3.0 * yy * yy);
    y[24] = 0.6258357354491761 * (x * x * (x * x - 3.0 * yy * yy) - yy * yy * (3.0 * x * x - yy * yy));
}

// Band of coefficient c: l = floor(sqrt(c)).
int envcap_sh_band(int c) { return int(floor(sqrt(float(c) + 0.5))); }

// Legendre coefficients lambda_l(w) of the normalized cos^w lobe, l = 0..4 (lambda_0 = 1,
// lambda_1 = (w+1)/(w+2), lambda_l = lambda_{l-2} (w - l + 2) / (w + l + 1)).
void envcap_lobe_bands(float w, out float lam[5])
{
    lam[0] = 1.0;
    lam[1] = (w + 1.0) / (w + 2.0);
    for (int l = 2; l < 5; ++l) lam[l] = lam[l - 2] * (w - float(l) + 2.0) / (w + float(l) + 1.0);
}

// sum_c ksh[c] lam[l(c)] Y_c(x): the SH sky filtered by a lobe of band factors lam.
vec3 envcap_sh_filtered(vec3 x, vec3 ksh[ENVCAP_SKY_VIS_MAX_SH], int nsh, float lam[5])
{
    float y[ENVCAP_SKY_VIS_MAX_SH];
    envcap_sh_basis(x, y);
    vec3 s = vec3(0.0);
    for (int c = 0; c < nsh; ++c) s += ksh[c] * (lam[envcap_sh_band(c)] * y[c]);
    return s;
}

// Unit tangents of unit d (numpy envcap.runtime.sky_visibility.tangent_frame).
void envcap_sky_tangents(vec3 d, out vec3 t1, out vec3 t2)
{
    t1 = normalize(cross(d, abs(d.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0)));
    t2 = cross(d, t1);
}

// The local gradient of the corrected sky part C' = K' - B (its rung texture `skyd`, layer sbase)
// along the tangents: central differences of rung lookups at d +- h t_k, h = 0.5 / sqrt(w + 2).
struct EnvcapSkyGradient { vec3 t1, t2, p1, m1, p2, m2, g1, g2; float inv2s; };

void envcap_sky_gradient(ENVCAP_PROBES_SAMPLER skyd, vec3 d, float sbase, float w, float xr[ENVCAP_MAX_RUNGS],
                         int n, int per_level, out EnvcapSkyGradient g)
{
    envcap_sky_tangents(d, g.t1, g.t2);
    float h = 0.5 / sqrt(min(w > 0.0 ? w : 0.0, 1.0e6) + 2.0);
    g.inv2s = 1.0 / (2.0 * sin(h));
    g.p1 = normalize(d + h * g.t1); g.m1 = normalize(d - h * g.t1);
    g.p2 = normalize(d + h * g.t2); g.m2 = normalize(d - h * g.t2);
    g.g1 = (envcap_rung_fetch(skyd, g.p1, sbase, w, xr, n, per_level).rgb
            - envcap_rung_fetch(skyd, g.m1, sbase, w, xr, n, per_level).rgb) * g.inv2s;
    g.g2 = (envcap_rung_fetch(skyd, g.p2, sbase, w, xr, n, per_level).rgb
            - envcap_rung_fetch(skyd, g.m2, sbase, w, xr, n, per_level).rgb) * g.inv2s;
}

// The tangents and steps of g (world) turned into the street's frame: g.g1, g.g2 (the sky's
// differences along them) are the same numbers in either frame.
void envcap_sky_gradient_to_frame(inout EnvcapSkyGradient g, vec2 frame)
{
    g.t1 = envcap_frame_dir(g.t1, frame); g.t2 = envcap_frame_dir(g.t2, frame);
    g.p1 = envcap_frame_dir(g.p1, frame); g.m1 = envcap_frame_dir(g.m1, frame);
    g.p2 = envcap_frame_dir(g.p2, frame); g.m2 = envcap_frame_dir(g.m2, frame);
}

// O_i of one stored rung i: level i / per_level - first_level of `vis`, rung layer i % per_level.
// mode 0: sum ksh V_i; 1: + the residual term; 2: + the gradient term (g).  fd, g: the street's
// frame (fd = R d; g turned by envcap_sky_gradient_to_frame); sky_w, base_w: the world's lookups.
vec3 envcap_sky_visible_rung(ENVCAP_PROBES_SAMPLER vis, vec3 fd, float vbase, int i, float xr_i, int per_level,
                             int first_level, vec3 ksh[ENVCAP_SKY_VIS_MAX_SH], int nsh, float alpha_w, vec3 sky_w,
                             vec3 base_w, int mode, EnvcapSkyGradient g)
{
    int r = i % per_level;
    float lod = float(i / per_level - first_level);
    int q0 = r * nsh;
    vec3 o = alpha_w * base_w;
    float v[4];                                   // V_00, V_1-1 (y), V_10 (z), V_11 (x)
    v[0] = 0.0; v[1] = 0.0; v[2] = 0.0; v[3] = 0.0;
    for (int layer = q0 / 4; layer <= (q0 + nsh - 1) / 4; ++layer) {
        vec4 t = ENVCAP_PROBES_LOD(vis, fd, vbase + float(layer), lod);
        for (int k = 0; k < 4; ++k) {
            int c = 4 * layer + k - q0;
            if (c < 0 || c >= nsh) continue;
            o += ksh[c] * t[k];
            if (c < 4) v[c] = t[k];
        }
    }
    if (mode >= 1) {
        float lam[5];
        envcap_lobe_bands(exp2(xr_i) - 1.0, lam);
        o += (v[0] / 0.282094791773878) * (sky_w - base_w - envcap_sh_filtered(fd, ksh, nsh, lam));
        if (mode >= 2) {
            vec3 mom = vec3(v[3], v[1], v[2]) / 0.488602511902920;      // filter(alpha u), frame
            vec3 df1 = (envcap_sh_filtered(g.p1, ksh, nsh, lam) - envcap_sh_filtered(g.m1, ksh, nsh, lam)) * g.inv2s;
            vec3 df2 = (envcap_sh_filtered(g.p2, ksh, nsh, lam) - envcap_sh_filtered(g.m2, ksh, nsh, lam)) * g.inv2s;
            o += (dot(mom, g.t1) * (g.g1 - df1) + dot(mom, g.t2) * (g.g2 - df2)) / lam[1];
        }
    }
    return o;
}

// O_w ~ filter(alpha K') along unit world d for lobe power w (rung table xr, n rungs, per_level
// rungs per level): rungs floor(u) and the next (u = envcap_rung_of_w), blended in u as
// envcap_rung_fetch.  frame: the probe's street (EnvcapStreet.frame; (1, 0): the world); ksh in
// that frame (header).  alpha_w, sky_w: the runtime's own alpha and new-sky lookups at (d, w);
// base_w: s K_w or 0.
// vbase: the probe's first layer of `vis` (probe * ceil(per_level * nsh / 4)).  mode 2 also reads
// `skyd` (the rungs of K' - B, layer sbase): 4 more rung fetches.  mode 0 / 1 never read skyd.
vec3 envcap_sky_visible(ENVCAP_PROBES_SAMPLER vis, ENVCAP_PROBES_SAMPLER skyd, vec3 d, vec2 frame, float vbase,
                        float sbase, float w, float xr[ENVCAP_MAX_RUNGS], int n, int per_level, int first_level,
                        vec3 ksh[ENVCAP_SKY_VIS_MAX_SH], int nsh, float alpha_w, vec3 sky_w, vec3 base_w, int mode)
{
    per_level = max(per_level, 1);
    n = clamp(n, 1, ENVCAP_MAX_RUNGS);
    nsh = clamp(nsh, 1, ENVCAP_SKY_VIS_MAX_SH);
    float u = envcap_rung_of_w(w, xr, n);
    int i0 = int(floor(u));
    int i1 = min(i0 + 1, n - 1);
    float t = u - float(i0);
    int first = first_level * per_level;
    vec3 plain = alpha_w * sky_w;
    if (i0 < first && !(t > 0.0 && i1 >= first)) return plain;
    EnvcapSkyGradient g = EnvcapSkyGradient(d, d, d, d, d, d, vec3(0.0), vec3(0.0), 0.0);
    if (mode >= 2) {
        envcap_sky_gradient(skyd, d, sbase, w, xr, n, per_level, g);
        envcap_sky_gradient_to_frame(g, frame);
    }
    vec3 fd = envcap_frame_dir(d, frame);
    vec3 a = i0 >= first ? envcap_sky_visible_rung(vis, fd, vbase, i0, xr[i0], per_level, first_level, ksh, nsh,
                                                   alpha_w, sky_w, base_w, mode, g) : plain;
    if (!(t > 0.0)) return a;
    vec3 b = i1 >= first ? envcap_sky_visible_rung(vis, fd, vbase, i1, xr[i1], per_level, first_level, ksh, nsh,
                                                   alpha_w, sky_w, base_w, mode, g) : plain;
    return a + t * (b - a);
}

#endif  // ENVCAP_SKY_VISIBILITY_GLSL
