#version 430
// Example: a sphere standing in the street, lit by the probe set with Eq. 3 (two Lafortune
// materials: left half plastic, right half anisotropic metal).  PARALLAX 0 samples the nearest
// probe along the plain lobe direction (no parallax, no mip shift) for comparison.
in vec2 uv;
out vec4 color;
layout(binding = 3) uniform samplerCubeArray probes;
layout(binding = 4) uniform samplerCube sky;
#include "runtime/envcap_runtime.glsl"
#include "runtime/envcap_street_uniforms.glsl"
uniform vec3 eye;
uniform vec3 center;     // sphere center (m)
uniform float radius;    // sphere radius (m)

vec3 shade(vec3 x, vec3 T, vec3 B, vec3 N, vec3 v, bool metal) {
    vec4 C[ENVCAP_MAX_LOBES];
    vec3 rs[ENVCAP_MAX_LOBES];
    vec3 rho_d;
    int n;
    if (metal) {
        rho_d = vec3(0.02);
        C[0] = vec4(-1.05, -0.95, 1.0, 60.0); rs[0] = vec3(0.9, 0.7, 0.4) * 62.0 / 6.2832;
        n = 1;
    } else {
        rho_d = vec3(0.5, 0.1, 0.08);
        C[0] = vec4(-1.0, -1.0, 1.0, 300.0); rs[0] = vec3(0.06) * 302.0 / 6.2832;
        n = 1;
    }
#if PARALLAX
    return envcap_shade_lafortune(probes, sky, x, T, B, N, v, rho_d, C, rs, n, envcap_street);
#else
    // no parallax: every lookup from the probe itself (x = probe position), plain directions
    int i = envcap_nearest_probe(x[envcap_street.along], envcap_street.along_s, envcap_street.count);
    return envcap_shade_lafortune(probes, sky, envcap_street.pos[i].xyz, T, B, N, v, rho_d, C, rs, n, envcap_street);
#endif
}

void main() {
    // pinhole camera looking at the sphere
    vec3 fwd = normalize(center - eye);
    vec3 right = normalize(cross(fwd, vec3(0, 1, 0)));
    vec3 up = cross(right, fwd);
    vec2 p = uv * 2.0 - 1.0;
    vec3 ray = normalize(fwd + 0.45 * (p.x * right + p.y * up));
    vec3 oc = eye - center;
    float b = dot(oc, ray), c = dot(oc, oc) - radius * radius, h = b * b - c;
    if (h < 0.0) {   // background: the environment seen from the eye (sharpest level)
        color = vec4(envcap_sample_nearest(probes, sky, eye, ray, 1e9, envcap_street), 1);
        return;
    }
    float t = -b - sqrt(h);
    vec3 x = eye + t * ray;
    vec3 N = normalize(x - center);
    vec3 T = normalize(cross(vec3(0, 1, 0), N) + vec3(1e-6, 0, 0));
    vec3 B = cross(N, T);
    color = vec4(shade(x, T, B, N, -ray, dot(x - center, right) > 0.0), 1.0);
}
