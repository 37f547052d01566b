#ifndef ENVCAP_CROWD_STREET_VERT_GLSL
#define ENVCAP_CROWD_STREET_VERT_GLSL
// envcap crowd: the street mesh, the backdrop of the crowd (simple shading; docs/crowd.md).
uniform mat4 crowd_view_proj;
ENVCAP_IN(0) in vec3 in_position;   // m, relative to the render origin
ENVCAP_IN(1) in vec3 in_normal;
ENVCAP_IN(2) in vec3 in_albedo;
ENVCAP_IN(3) in vec3 in_emission;
out vec3 v_normal;
out vec3 v_albedo;
out vec3 v_emission;

void main()
{
    v_normal = in_normal;
    v_albedo = in_albedo;
    v_emission = in_emission;
    gl_Position = crowd_view_proj * vec4(in_position, 1.0);
}

#endif  // ENVCAP_CROWD_STREET_VERT_GLSL
