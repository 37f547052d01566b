#ifndef ENVCAP_SHADOW_LOOKUP_GLSL
#define ENVCAP_SHADOW_LOOKUP_GLSL
// Sun visibility from an orthographic light-space depth map (envcap/capture/effects/sun_shadows.py).
// The receiver is pushed off its surface along the normal by shadow_normal_offset (m) and its
// depth is lowered by a slope-scaled bias; 3x3 PCF of hardware 2x2-filtered comparisons.
// With SUN_SHADOW_CASCADES defined (a texel size was asked) and shadow_cascades = K >= 2,
// shadow_map is an atlas of K cascades (finest first, the last one the whole map of light_clip)
// and the finest cascade whose PCF footprint holds the point is read (docs/capture.md, "Shadow
// cascades"); K = 0 is the single map.
uniform sampler2DShadow shadow_map;
uniform mat4 light_clip;            // mesh-origin-relative -> light clip (orthographic, depth in [-1, 1])
uniform float shadow_normal_offset; // meters
uniform float shadow_bias_const;    // depth units [0, 1]
uniform float shadow_bias_slope;    // depth units per unit tan(angle of incidence)
uniform float shadow_texel;         // 1 / resolution

// 3x3 PCF of bilinear 2x2 comparisons at offsets of one texel around x (map texels, texel
// centers at +0.5; texel: 1 / map size), evaluated as its 4x4 texel footprint: per axis the
// texels b-1, b, b+1, b+2 (b = floor(x), f = fract(x)) carry weights 1-f, 1, 1, f (sum 3), so 4
// gathers of compare results replace 9 filtered taps (docs/capture.md).
float shadow_pcf(vec2 x, float ref, vec2 texel) {
    vec2 b = floor(x);
    vec2 f = x - b;
    vec4 g00 = textureGather(shadow_map, (b + vec2(0.0, 0.0)) * texel, ref);  // texels b-1, b
    vec4 g10 = textureGather(shadow_map, (b + vec2(2.0, 0.0)) * texel, ref);  // x: b+1, b+2
    vec4 g01 = textureGather(shadow_map, (b + vec2(0.0, 2.0)) * texel, ref);  // y: b+1, b+2
    vec4 g11 = textureGather(shadow_map, (b + vec2(2.0, 2.0)) * texel, ref);
    // gather order: (x0, y1), (x1, y1), (x1, y0), (x0, y0); weights per column / row:
    vec4 wx = vec4(1.0 - f.x, 1.0, 1.0, f.x);
    vec4 wy = vec4(1.0 - f.y, 1.0, 1.0, f.y);
    float v = wy.x * (wx.x * g00.w + wx.y * g00.z + wx.z * g10.w + wx.w * g10.z)
            + wy.y * (wx.x * g00.x + wx.y * g00.y + wx.z * g10.x + wx.w * g10.y)
            + wy.z * (wx.x * g01.w + wx.y * g01.z + wx.z * g11.w + wx.w * g11.z)
            + wy.w * (wx.x * g01.x + wx.y * g01.y + wx.z * g11.x + wx.w * g11.y);
    return v / 9.0;
}

#ifdef SUN_SHADOW_CASCADES
uniform int shadow_cascades;             // 0: single map; K >= 2: cascades in an atlas
uniform vec4 shadow_cascade_uv[8];       // cascade uv = p.xy * xy + zw (p.xy: light_clip's [0, 1] window)
uniform vec4 shadow_cascade_cell[8];     // xy: the cell's first atlas texel, z: its side in texels
uniform vec4 shadow_cascade_bias[8];     // x: normal offset (m), y: depth bias, z: slope bias (depth units)
uniform vec2 shadow_atlas_texel;         // 1 / atlas size in texels

// Cascades: the finest one whose 4x4 PCF footprint lies inside its cell (cell texels 1.5 ..
// side - 1.5); the last (whole-map) cascade is read like the single map (outside: lit).
float sun_visibility_cascaded(vec3 local, vec3 n, float cos_l) {
    float tan_l = sqrt(max(1.0 - cos_l * cos_l, 0.0)) / max(cos_l, 1e-3);
    for (int k = 0; k < shadow_cascades; ++k) {
        vec4 bias = shadow_cascade_bias[k];
        vec3 p = (light_clip * vec4(local + n * bias.x, 1.0)).xyz * 0.5 + 0.5;
        vec4 cell = shadow_cascade_cell[k];
        vec2 x = (p.xy * shadow_cascade_uv[k].xy + shadow_cascade_uv[k].zw) * cell.z;   // cell texels
        if (k == shadow_cascades - 1) {
            if (any(lessThan(x, vec2(0.0))) || any(greaterThan(x, vec2(cell.z)))) return 1.0;
        } else if (any(lessThan(x, vec2(1.5))) || any(greaterThanEqual(x, vec2(cell.z - 1.5)))) {
            continue;
        }
        if (p.z > 1.0) return 1.0;
        float ref = p.z - bias.y - bias.z * min(tan_l, 10.0);
        return shadow_pcf(cell.xy + x - 0.5, ref, shadow_atlas_texel);   // atlas texels
    }
    return 1.0;
}
#endif  // SUN_SHADOW_CASCADES

float sun_visibility(vec3 local, vec3 n, float cos_l) {
#ifdef SUN_SHADOW_CASCADES
    if (shadow_cascades > 0) return sun_visibility_cascaded(local, n, cos_l);
#endif
    vec4 c = light_clip * vec4(local + n * shadow_normal_offset, 1.0);
    vec3 p = c.xyz * 0.5 + 0.5;
    if (any(lessThan(p.xy, vec2(0.0))) || any(greaterThan(p.xy, vec2(1.0))) || p.z > 1.0) return 1.0;
    float tan_l = sqrt(max(1.0 - cos_l * cos_l, 0.0)) / max(cos_l, 1e-3);
    float ref = p.z - shadow_bias_const - shadow_bias_slope * min(tan_l, 10.0);
    return shadow_pcf(p.xy / shadow_texel - 0.5, ref, vec2(shadow_texel));
}

#endif  // ENVCAP_SHADOW_LOOKUP_GLSL
