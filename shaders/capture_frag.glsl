#version 430
// Cube-face capture, fragment stage.  Shading terms are compiled in only for the effects a scene
// calls for (defines SUN_LIGHT, SUN_SHADOWS, SKY_LIGHT, EMISSIVE_WINDOWS); see docs/capture.md.
// Output: rgb = outgoing radiance toward the probe, a = signed radial distance in meters
// (positive on front faces, negative on back faces).  The clear value 0 means "no geometry".
in vec3 v_rel;
in vec3 v_world;
in vec3 v_normal;
in vec3 v_albedo;
in vec3 v_emission;

layout(location = 0) out vec4 out_color;

const float PI = 3.14159265358979323846;

#ifdef SUN_LIGHT
uniform vec3 sun_dir;        // unit, toward the sun
uniform vec3 sun_E;          // sun illuminance at normal incidence (RGB)
#endif

#ifdef SUN_SHADOWS
#include "shadow_lookup.glsl"
#endif

#ifdef SKY_LIGHT
uniform vec3 sky_sh[9];      // irradiance SH coefficients E_lm = A_l * L_lm (basis in sh_eval)
vec3 sky_irradiance(vec3 n) {
    float x = n.x, y = n.y, z = n.z;
    vec3 e = sky_sh[0] * 0.282094791773878
           + sky_sh[1] * (0.488602511902920 * y)
           + sky_sh[2] * (0.488602511902920 * z)
           + sky_sh[3] * (0.488602511902920 * x)
           + sky_sh[4] * (1.092548430592079 * x * y)
           + sky_sh[5] * (1.092548430592079 * y * z)
           + sky_sh[6] * (0.315391565252520 * (3.0 * z * z - 1.0))
           + sky_sh[7] * (1.092548430592079 * x * z)
           + sky_sh[8] * (0.546274215296040 * (x * x - y * y));
    return max(e, vec3(0.0));   // SH9 ringing can dip below 0 facing away from the sky
}
#endif

void main() {
    float dist = length(v_rel);
    float ln = length(v_normal);
    vec3 n = ln > 0.0 ? v_normal / ln : -v_rel / max(dist, 1e-30);
    bool back = dot(n, v_rel) > 0.0;   // the camera sees the unlit side
    vec3 L = vec3(0.0);
    if (!back) {
        vec3 E = vec3(0.0);
#ifdef SUN_LIGHT
        float c = max(dot(n, sun_dir), 0.0);
        float vis = 1.0;
#ifdef SUN_SHADOWS
        if (c > 0.0) vis = sun_visibility(v_world, n, c);
#endif
        E += sun_E * (c * vis);
#endif
#ifdef SKY_LIGHT
        E += sky_irradiance(n);
#endif
        L = v_albedo * (1.0 / PI) * E;
#ifdef EMISSIVE_WINDOWS
        L += v_emission;
#endif
    }
    out_color = vec4(L, back ? -dist : dist);
}
