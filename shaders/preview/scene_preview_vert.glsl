#version 430
// Quick-look scene preview (envcap/scene/scene_preview.py): not a capture shader.
uniform mat4 mvp;
in vec3 in_pos;
in vec3 in_normal;
in vec3 in_albedo;
in vec3 in_emission;
out vec3 v_normal;
out vec3 v_albedo;
out vec3 v_emission;
void main() {
    v_normal = in_normal;
    v_albedo = in_albedo;
    v_emission = in_emission;
    gl_Position = mvp * vec4(in_pos, 1.0);
}
