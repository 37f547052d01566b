#ifndef ENVCAP_CROWD_SKY_FRAG_GLSL
#define ENVCAP_CROWD_SKY_FRAG_GLSL
// envcap crowd: the sky map (level 0) along each pixel's view ray, drawn first behind everything.
ENVCAP_BINDING(4) uniform samplerCube sky;
uniform mat4 crowd_inverse_view_proj;   // render frame from clip
in vec2 v_ndc;
ENVCAP_OUT(0) out vec4 out_color;

void main()
{
    vec4 a = crowd_inverse_view_proj * vec4(v_ndc, -1.0, 1.0);
    vec4 b = crowd_inverse_view_proj * vec4(v_ndc, 1.0, 1.0);
    vec3 d = normalize(b.xyz / b.w - a.xyz / a.w);
    out_color = vec4(textureLod(sky, d, 0.0).rgb, 1.0);
}

#endif  // ENVCAP_CROWD_SKY_FRAG_GLSL
