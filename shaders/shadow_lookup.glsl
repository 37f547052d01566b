// Sun visibility from an orthographic light-space depth map (envcap/capture.py, ShadowMap).
// The receiver is pushed off its surface along the normal by shadow_normal_offset (m) and its
// depth is lowered by a slope-scaled bias; 3x3 PCF of hardware 2x2-filtered comparisons.
uniform sampler2DShadow shadow_map;
uniform mat4 light_clip;            // world -> light clip (orthographic, depth in [-1, 1])
uniform float shadow_normal_offset; // meters
uniform float shadow_bias_const;    // depth units [0, 1]
uniform float shadow_bias_slope;    // depth units per unit tan(angle of incidence)
uniform float shadow_texel;         // 1 / resolution

float sun_visibility(vec3 world, vec3 n, float cos_l) {
    vec4 c = light_clip * vec4(world + n * shadow_normal_offset, 1.0);
    vec3 p = c.xyz * 0.5 + 0.5;
    if (any(lessThan(p.xy, vec2(0.0))) || any(greaterThan(p.xy, vec2(1.0))) || p.z > 1.0) return 1.0;
    float tan_l = sqrt(max(1.0 - cos_l * cos_l, 0.0)) / max(cos_l, 1e-3);
    float ref = p.z - shadow_bias_const - shadow_bias_slope * min(tan_l, 10.0);
    float v = 0.0;
    for (int j = -1; j <= 1; ++j)
        for (int i = -1; i <= 1; ++i)
            v += texture(shadow_map, vec3(p.xy + vec2(i, j) * shadow_texel, ref));
    return v / 9.0;
}
