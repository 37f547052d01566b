#ifndef ENVCAP_CROWD_SKY_VERT_GLSL
#define ENVCAP_CROWD_SKY_VERT_GLSL
// envcap crowd: the sky behind the street (a full-screen triangle; crowd_sky_frag.glsl).
out vec2 v_ndc;

void main()
{
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2)) * 2.0 - 1.0;
    v_ndc = p;
    gl_Position = vec4(p, 1.0, 1.0);
}

#endif  // ENVCAP_CROWD_SKY_VERT_GLSL
