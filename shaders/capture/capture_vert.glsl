#version 430
// Cube-face capture, vertex stage.  One draw per cube face; face_clip maps (position - probe, 1)
// to clip space so that x_clip = s-coordinate numerator sc, y_clip = tc, w_clip = major axis
// (envcap/capture/projection.py, face_clip_matrix_reversed): NDC (x, y) = (u, v) = (2s - 1, 2t - 1).
in vec3 in_position;   // meters, relative to the mesh origin (SceneMesh.origin)
in vec3 in_normal;     // unit, world
in vec3 in_albedo;     // diffuse reflectance [0, 1]
in vec3 in_emission;   // emitted radiance
#ifdef ENVCAP_TEXTURED
in vec3 in_uv_layer;   // texture coordinates (u, v) and layer of surface_textures (-1: none)
out vec2 v_uv;
flat out float v_layer;
#endif

uniform vec3 probe;       // probe center minus the mesh origin (float64 on the CPU, rounded once)
uniform mat4 face_clip;   // (position - probe, 1) -> clip

out vec3 v_rel;       // position relative to the probe (interpolated perspective-correctly)
out vec3 v_local;     // position relative to the mesh origin (world positions never reach the GPU)
out vec3 v_normal;
out vec3 v_albedo;
out vec3 v_emission;

void main() {
    vec3 rel = in_position - probe;
    v_rel = rel;
    v_local = in_position;
    v_normal = in_normal;
    v_albedo = in_albedo;
    v_emission = in_emission;
#ifdef ENVCAP_TEXTURED
    v_uv = in_uv_layer.xy;
    v_layer = in_uv_layer.z;
#endif
    gl_Position = face_clip * vec4(rel, 1.0);
}
