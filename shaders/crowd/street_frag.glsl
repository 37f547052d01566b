#ifndef ENVCAP_CROWD_STREET_FRAG_GLSL
#define ENVCAP_CROWD_STREET_FRAG_GLSL
// envcap crowd: the street's shading, albedo * (mean sky radiance + E_sun max(n.l, 0) / pi) + emission.
uniform vec3 crowd_sky_mean;
uniform vec3 crowd_sun_dir;
uniform vec3 crowd_sun_e;
in vec3 v_normal;
in vec3 v_albedo;
in vec3 v_emission;
ENVCAP_OUT(0) out vec4 out_color;

void main()
{
    float nl = max(dot(normalize(v_normal), crowd_sun_dir), 0.0);
    out_color = vec4(v_albedo * (crowd_sky_mean + crowd_sun_e * nl / 3.14159265) + v_emission, 1.0);
}

#endif  // ENVCAP_CROWD_STREET_FRAG_GLSL
