#ifndef ENVCAP_CROSSING_GLSL
#define ENVCAP_CROSSING_GLSL
// The lookup inside a crossing (docs/crossings.md, "In your shader"): the street a position in
// crossing k is looked up on, with the crossing's shared probe among its probes (the default
// lookup mode `shared` of the evaluator).  Numpy twin: envcap/runtime/crossing_lookup.py.
//
// An engine finds k with envcap_street_map_crossing (runtime/envcap_street_map.glsl) and reads
// crossings[k] of the manifest: the probe's layer and its street (the owner, the first street).
// Then, with the uniforms of the street the position walks on:
//   * a street along the owner's frame (the owner itself, or one with the owner's yaw):
//     envcap_crossing_street(street, vec4(centre in this street's local frame (m), layer));
//   * a street turned differently from the owner: envcap_probe_street(owner, layer), the crossing
//     probe alone in the owner's frame (the shading point then in the owner's local frame).
// Any envcap_sample_* (envcap_sample_depth_refine: the best inside a crossing) then runs on the result.
// Mode `direction` (the default): build that street for each meeting street and look each direction
// up on the one whose facades the ray leaves last (envcap_facade_exit; ties: the first street).
#include "runtime/envcap_runtime.glsl"

// Street `street` with the probe `probe` (xyz: its position in the street's local frame, m;
// w: its layer) among its probes, in along order (after probes at the same along coordinate).
// Its planes: those of the street's probe nearest to it along the street (ties: the lower index),
// the ground plane extended along its slope.  A street that already holds a probe of that layer
// is returned unchanged; a full street (ENVCAP_MAX_PROBES) drops its end probe farther from the
// crossing probe along the street (ties: the last).
EnvcapStreet envcap_crossing_street(EnvcapStreet street, vec4 probe)
{
    int n = clamp(street.count, 1, ENVCAP_MAX_PROBES);
    for (int k = 0; k < n; ++k) {
        if (street.pos[k].w == probe.w) return street;
    }
    float s = probe.xyz[street.along];
    vec4 planes = street.planes[envcap_nearest_probe(s, street.along_s, n)];
    EnvcapStreet out_street = street;
    int first = 0;
    if (n == ENVCAP_MAX_PROBES) {
        if (abs(s - street.along_s[0]) > abs(s - street.along_s[n - 1])) first = 1;
        n -= 1;
    }
    int j = 0;   // where the probe goes: after every kept probe at or before s
    for (int k = 0; k < n; ++k) {
        if (street.along_s[first + k] <= s) j = k + 1;
    }
    for (int k = 0; k < ENVCAP_MAX_PROBES; ++k) {
        if (k < j) {
            out_street.along_s[k] = street.along_s[first + k];
            out_street.pos[k] = street.pos[first + k];
            out_street.planes[k] = street.planes[first + k];
        } else if (k == j) {
            out_street.along_s[k] = s;
            out_street.pos[k] = probe;
            out_street.planes[k] = planes;
        } else if (k <= n) {
            out_street.along_s[k] = street.along_s[first + k - 1];
            out_street.pos[k] = street.pos[first + k - 1];
            out_street.planes[k] = street.planes[first + k - 1];
        }
    }
    out_street.count = n + 1;
    return out_street;
}

// Street `street` cut to its probe of layer `layer` alone (the crossing probe, looked up in its
// owner's frame); a street without that layer is returned unchanged.
EnvcapStreet envcap_probe_street(EnvcapStreet street, float layer)
{
    int n = clamp(street.count, 1, ENVCAP_MAX_PROBES);
    EnvcapStreet out_street = street;
    for (int k = 0; k < n; ++k) {
        if (street.pos[k].w == layer) {
            out_street.along_s[0] = street.along_s[k];
            out_street.pos[0] = street.pos[k];
            out_street.planes[0] = street.planes[k];
            out_street.count = 1;
        }
    }
    return out_street;
}

const float ENVCAP_NO_EXIT = 1e30;   // envcap_facade_exit of a ray parallel to the facades

// The distance (m, along d) at which the ray from x (street-local, m) along the WORLD direction d
// leaves `street` through one of its facades (the planes of its probe nearest to x along it);
// ENVCAP_NO_EXIT for a ray parallel to them (or NaN), 0 for a point already outside them.
// Numpy twin: envcap.runtime.crossing_lookup.facade_exit.
float envcap_facade_exit(EnvcapStreet street, vec3 x, vec3 d)
{
    int i = envcap_nearest_probe(x[street.along], street.along_s, street.count);
    int c = 2 - street.along;
    float dc = envcap_frame_dir(d, street.frame)[c];
    float t = ENVCAP_NO_EXIT;
    if (dc > 0.0) t = (street.planes[i].y - x[c]) / dc;
    if (dc < 0.0) t = (street.planes[i].x - x[c]) / dc;
    return (t > 0.0) ? min(t, ENVCAP_NO_EXIT) : ((t <= 0.0) ? 0.0 : ENVCAP_NO_EXIT);
}

#endif  // ENVCAP_CROSSING_GLSL
