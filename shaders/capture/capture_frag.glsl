#version 430
// Cube-face capture, fragment stage.  The shading terms are the capture effects a scene calls
// for (envcap/capture/effects/, one module per effect): the capture inserts each applied
// effect's GLSL at the three "// @effects:" lines below, in registry order, and defines its name
// in capitals (SUN_LIGHT, ...).  Without effects this file compiles as it is (geometry only,
// radiance 0).  Shading model: docs/capture.md.
// Output: rgb = outgoing radiance toward the probe, a = signed radial distance in meters
// (positive on front faces, negative on back faces).  The clear value 0 means "no geometry".
in vec3 v_rel;
in vec3 v_local;
in vec3 v_normal;
in vec3 v_albedo;
in vec3 v_emission;
#ifdef ENVCAP_TEXTURED
// Surface textures (SceneMesh.textures): linear RGB, mipmapped, repeating; albedo x texel.
in vec2 v_uv;
flat in float v_layer;
uniform sampler2DArray surface_textures;
#endif

layout(location = 0) out vec4 out_color;

const float PI = 3.14159265358979323846;

// @effects:declarations

void main() {
    float dist = length(v_rel);
    float ln = length(v_normal);
    vec3 n = ln > 0.0 ? v_normal / ln : -v_rel / max(dist, 1e-30);
    bool back = dot(n, v_rel) > 0.0;   // the camera sees the unlit side
    vec3 L = vec3(0.0);
    if (!back) {
        vec3 E = vec3(0.0);   // irradiance on the surface
        // @effects:irradiance
        vec3 albedo = v_albedo;
#ifdef ENVCAP_TEXTURED
        if (v_layer >= 0.0) albedo *= texture(surface_textures, vec3(v_uv, v_layer)).rgb;
#endif
        L = albedo * (1.0 / PI) * E;
        // @effects:radiance
    }
    out_color = vec4(L, back ? -dist : dist);
}
