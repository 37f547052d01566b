#version 430
// Sun shadow map, depth only: orthographic light-space projection of the scene mesh.
in vec3 in_position;   // meters, relative to the mesh origin
uniform mat4 light_clip;
void main() { gl_Position = light_clip * vec4(in_position, 1.0); }
