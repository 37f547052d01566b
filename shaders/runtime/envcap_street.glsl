#ifndef ENVCAP_STREET_GLSL
#define ENVCAP_STREET_GLSL
// envcap runtime, part 1: street geometry (probe selection, three-plane parallax, mip shift).
// No #version: #include this from a shader that starts with "#version 430" (or later).
// Conventions (envcap/core/cube.py): world right-handed, meters, +Y up.  A street runs along world
// axis `along` (0 = x, 2 = z); its cross axis is `2 - along`.  A probe's three planes are
// vec3 planes = (facade_min, facade_max, ground): absolute cross-axis coordinates of the two
// facades and the ground height, in meters.  Derivations: docs/runtime.md.
// Every function is total: no input listed in docs/runtime.md "Fallbacks" yields NaN or Inf.

#ifndef ENVCAP_MAX_PROBES
#define ENVCAP_MAX_PROBES 64
#endif

// Hits farther than this (m) count as "no hit": the plane is at infinity, no parallax.
const float ENVCAP_FAR = 1.0e6;
// Distances (m) below this are treated as this (zero-length probe vector, point on a plane).
const float ENVCAP_MIN_DIST = 1.0e-4;
// Bound of the distance ratio d_probe / d_shade: at most log2(256) = 8 doublings of the lobe
// angle (w scaled by at most 65536 either way).
const float ENVCAP_MAX_RATIO = 256.0;

// Index of the probe nearest to along-street coordinate s (m).  `along[k]` are the probes'
// along-street coordinates, sorted ascending, `count` >= 1 of them are used.  Ties go to the
// lower index.  Always returns a valid index in [0, count - 1] (count < 1 is treated as 1).
int envcap_nearest_probe(float s, float along[ENVCAP_MAX_PROBES], int count)
{
    int best = 0;
    float bd = abs(s - along[0]);
    for (int k = 1; k < count && k < ENVCAP_MAX_PROBES; ++k) {
        float dk = abs(s - along[k]);
        if (dk < bd) { bd = dk; best = k; }
    }
    return best;
}

// The two probes bracketing s and the blend weight of the second: the result blends probe i0
// with weight (1 - t) and probe i1 with weight t.  t is linear in s between the two probes,
// so the blend is continuous in s.  Outside [along[0], along[count-1]]: i0 = i1 = end probe,
// t = 0.  Returns vec3(i0, i1, t) (indices as floats).
vec3 envcap_probe_pair(float s, float along[ENVCAP_MAX_PROBES], int count)
{
    int n = clamp(count, 1, ENVCAP_MAX_PROBES);
    if (!(s > along[0])) return vec3(0.0, 0.0, 0.0);
    if (!(s < along[n - 1])) return vec3(float(n - 1), float(n - 1), 0.0);
    int i = 0;
    for (int k = 1; k < n - 1; ++k) {
        if (s >= along[k]) i = k;
    }
    float span = along[i + 1] - along[i];
    float t = span > 0.0 ? clamp((s - along[i]) / span, 0.0, 1.0) : 0.0;
    return vec3(float(i), float(i + 1), t);
}

// The point x moved into the street volume: cross coordinate clamped to the facades, height
// clamped to >= ground.  The along-street coordinate is unbounded (the street is open at its
// ends).  Points outside the street or below the ground are projected onto the nearest plane.
vec3 envcap_clamp_to_street(vec3 x, vec3 planes, int along)
{
    int cross = 2 - along;
    x[cross] = min(max(x[cross], planes.x), planes.y);
    x.y = max(x.y, planes.z);
    return x;
}

// Distance t >= 0 (m) along unit direction d from x (inside the street volume) to the first of
// the three planes, or ENVCAP_FAR when d hits none of them within ENVCAP_FAR (d up, d along
// the street, or d parallel to the plane it would hit).  Components of d equal to +0.0 or -0.0
// never divide: the explicit sign tests make both mean "parallel".
float envcap_exit_distance(vec3 x, vec3 d, vec3 planes, int along)
{
    int cross = 2 - along;
    float dc = d[cross];
    float tc = ENVCAP_FAR;
    if (dc > 0.0) tc = (planes.y - x[cross]) / dc;
    else if (dc < 0.0) tc = (planes.x - x[cross]) / dc;
    float tg = ENVCAP_FAR;
    if (d.y < 0.0) tg = (planes.z - x.y) / d.y;
    return min(min(tc, tg), ENVCAP_FAR);   // a quotient that overflows to +inf becomes FAR
}

// Three-plane parallax for shading point x, unit direction d, probe at p with `planes`.
// Returns vec4(r, ratio): r = unit vector from the probe to the hit point (the direction to
// sample the probe with), ratio = d_probe / d_shade = |hit - p| / |hit - x| clamped to
// [1/ENVCAP_MAX_RATIO, ENVCAP_MAX_RATIO].  Fallbacks: no hit -> (d, 1); hit point within
// ENVCAP_MIN_DIST of the probe -> (d, 1/ENVCAP_MAX_RATIO); x on a plane (d_shade = 0) ->
// d_shade taken as ENVCAP_MIN_DIST (the ratio then clamps to ENVCAP_MAX_RATIO).
vec4 envcap_parallax(vec3 x, vec3 d, vec3 p, vec3 planes, int along)
{
    vec3 xc = envcap_clamp_to_street(x, planes, along);
    float t = envcap_exit_distance(xc, d, planes, along);
    if (!(t < ENVCAP_FAR)) return vec4(d, 1.0);
    vec3 r = (xc - p) + t * d;
    float dp = length(r);
    if (!(dp > ENVCAP_MIN_DIST)) return vec4(d, 1.0 / ENVCAP_MAX_RATIO);
    float ratio = dp / max(t, ENVCAP_MIN_DIST);
    ratio = min(max(ratio, 1.0 / ENVCAP_MAX_RATIO), ENVCAP_MAX_RATIO);
    return vec4(r / dp, ratio);
}

// Mip shift in lobe-power space: the lobe of power w seen from the shading point covers the
// same patch of the hit plane as a lobe of power w * ratio^2 seen from the probe
// (docs/runtime.md).  Negative w is treated as 0.
float envcap_shift_power(float w, float ratio)
{
    return max(w, 0.0) * (ratio * ratio);
}

#endif  // ENVCAP_STREET_GLSL
