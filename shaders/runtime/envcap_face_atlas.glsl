#ifndef ENVCAP_FACE_ATLAS_GLSL
#define ENVCAP_FACE_ATLAS_GLSL
// Probes without cube-map arrays (WebGL2): a sampler2DArray of face atlases, layer = probe * 6 +
// face (GL order), sampled like textureLod(samplerCubeArray, vec4(d, probe), lod) with seamless
// trilinear filtering.  Layout (envcap/formats/face_atlas.py, docs/engines.md): for a chain of K
// levels with face sizes N_k = max(1, N >> k), an atlas of width W = (N + 2) + (max(1, N >> 1) + 2)
// holds level 0 at texel (0, 0) and level k >= 1 at (N + 2, sum_{j=1}^{k-1} (N_j + 2)); each level
// is its N_k x N_k face with a 1-texel border copied from the adjacent faces (corners: the mean of
// the three texels that meet at the cube corner).  The texture: one level, LINEAR filtering,
// CLAMP_TO_EDGE.  Two bilinear fetches per lookup (levels floor(lod) and floor(lod) + 1).
// No #version: #include this.  The WebGL2 target (envcap.runtime.shader_targets) makes it the
// runtime's probe lookup (ENVCAP_PROBES_LOD).

// Face (0..5, GL order +X -X +Y -Y +Z -Z) and (s, t) in [0, 1] of direction d: returns
// vec3(s, t, face).  GL's major-axis rule (OpenGL 4.5, table 8.19); ties go to X before Y
// before Z, as in Mesa and envcap.core.cube.  d = 0 or NaN -> face 0, (0.5, 0.5).
vec3 envcap_cube_face_st(vec3 d)
{
    vec3 a = abs(d);
    float f;
    float ma;
    float sc;
    float tc;
    if (a.x >= a.y && a.x >= a.z) { f = d.x >= 0.0 ? 0.0 : 1.0; ma = a.x; sc = d.x >= 0.0 ? -d.z : d.z; tc = -d.y; }
    else if (a.y >= a.z) { f = d.y >= 0.0 ? 2.0 : 3.0; ma = a.y; sc = d.x; tc = d.y >= 0.0 ? d.z : -d.z; }
    else { f = d.z >= 0.0 ? 4.0 : 5.0; ma = a.z; sc = d.z >= 0.0 ? d.x : -d.x; tc = -d.y; }
    if (!(ma > 0.0)) return vec3(0.5, 0.5, 0.0);
    return vec3(0.5 * (sc / ma + 1.0), 0.5 * (tc / ma + 1.0), f);
}

// Level-0 face size N of a face atlas `width` texels wide: width - 4 = N + max(1, N >> 1).
int envcap_face_atlas_size(int width)
{
    int m = width - 4;
    return m <= 2 ? 1 : (2 * m + 2) / 3;
}

// Bilinear lookup of level k (0 <= k < K) at fst = envcap_cube_face_st(d), atlas layer `layer`.
vec4 envcap_face_atlas_level(sampler2DArray atlas, vec3 fst, float layer, int k)
{
    ivec3 size = textureSize(atlas, 0);
    int n0 = envcap_face_atlas_size(size.x);
    int nk = max(1, n0 >> k);
    vec2 o = vec2(0.0);
    if (k > 0) {
        o.x = float(n0 + 2);
        for (int j = 1; j < k; ++j) o.y += float(max(1, n0 >> j) + 2);
    }
    vec2 uv = (o + 1.0 + fst.xy * float(nk)) / vec2(size.xy);
    return textureLod(atlas, vec3(uv, layer), 0.0);
}

// textureLod(samplerCubeArray, vec4(d, probe), lod) on the face-atlas array: probe rounded to
// the nearest integer (as a cube-map array layer), lod in [0, K - 1] (the runtime clamps it to
// the street's level count; NaN or < 0 -> 0), levels floor(lod) and the next mixed linearly.
vec4 envcap_face_atlas_lod(sampler2DArray atlas, vec3 d, float probe, float lod)
{
    vec3 fst = envcap_cube_face_st(d);
    float layer = floor(probe + 0.5) * 6.0 + fst.z;
    float z = lod > 0.0 ? min(lod, 30.0) : 0.0;
    int k0 = int(floor(z));
    float f = z - float(k0);
    vec4 v = envcap_face_atlas_level(atlas, fst, layer, k0);
    if (f > 0.0) v = mix(v, envcap_face_atlas_level(atlas, fst, layer, k0 + 1), f);
    return v;
}

#endif  // ENVCAP_FACE_ATLAS_GLSL
