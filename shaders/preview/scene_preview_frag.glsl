#version 430
// Quick-look scene preview: Lambert with one fixed light + ambient, emission, Reinhard, sRGB-ish.
uniform vec3 light_dir;
in vec3 v_normal;
in vec3 v_albedo;
in vec3 v_emission;
out vec4 frag;
void main() {
    float ndl = max(dot(normalize(v_normal), light_dir), 0.0);
    vec3 c = v_albedo * (0.35 + 0.9 * ndl) + v_emission / 100.0;
    c = c / (1.0 + c);
    frag = vec4(pow(c, vec3(1.0 / 2.2)), 1.0);
}
