#version 430
// Quick-look scene preview: Lambert with one fixed light + ambient, emission, Reinhard, sRGB-ish.
// A back face seen by the camera (a surface wound inward: the capture sees its unlit side) is
// drawn in magenta stripes, so that the preview shows what the capture will get wrong.
uniform vec3 light_dir;
in vec3 v_normal;
in vec3 v_albedo;
in vec3 v_emission;
out vec4 frag;
void main() {
    float ndl = max(dot(normalize(v_normal), light_dir), 0.0);
    vec3 c = v_albedo * (0.35 + 0.9 * ndl) + v_emission / 100.0;
    c = c / (1.0 + c);
    if (!gl_FrontFacing) {
        float stripe = step(0.5, fract((gl_FragCoord.x + gl_FragCoord.y) / 8.0));
        c = mix(vec3(0.85, 0.05, 0.75), vec3(0.35, 0.0, 0.3), stripe);
    }
    frag = vec4(pow(c, vec3(1.0 / 2.2)), 1.0);
}
