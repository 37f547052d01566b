#ifndef ENVCAP_STREET_GLSL
#define ENVCAP_STREET_GLSL
// envcap runtime, part 1: street geometry (probe selection, three-plane parallax, mip shift).
// No #version: #include this from a shader that starts with "#version 430" (or later).
// Conventions (envcap/core/cube.py): right-handed, meters, +Y up, in the street's frame (the world
// for a street along x or z; a street at any angle: world turned by its yaw, envcap_frame_dir).
// A street runs along axis `along` (0 = x, 2 = z); its cross axis is `2 - along`.  A probe's
// planes are vec4 planes = (facade_min, facade_max, ground0, slope): absolute cross-axis
// coordinates of the two facades, and the ground, whose height at a point x is
// ground0 + slope * x[along] (normal (-slope, 1, 0) / sqrt(1 + slope^2) in (along, y, cross)).
// slope = 0 is a horizontal ground at height ground0; each function also takes vec3 planes
// (facade_min, facade_max, ground), the same as slope 0.  Derivations: docs/runtime.md.
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

// A world direction d in the frame of a street at yaw a, frame = (cos a, sin a) (EnvcapStreet.frame;
// numpy twin envcap.runtime.parallax.frame_direction).  frame = (1, 0): d itself.
vec3 envcap_frame_dir(vec3 d, vec2 frame)
{
    return vec3(frame.x * d.x + frame.y * d.z, d.y, frame.x * d.z - frame.y * d.x);
}

// Height of the ground under x, and the rate at which direction d rises above it (< 0: towards it).
float envcap_ground_height(vec3 x, vec4 planes, int along) { return planes.z + planes.w * x[along]; }
float envcap_ground_rate(vec3 d, vec4 planes, int along) { return d.y - planes.w * d[along]; }

// The point x moved into the street volume: cross coordinate clamped to the facades, height
// clamped to >= the ground under it.  The along-street coordinate is unbounded (the street is
// open at its ends).  Points outside the street or below the ground are moved onto the plane.
vec3 envcap_clamp_to_street(vec3 x, vec4 planes, int along)
{
    int cross = 2 - along;
    x[cross] = min(max(x[cross], planes.x), planes.y);
    x.y = max(x.y, envcap_ground_height(x, planes, along));
    return x;
}
vec3 envcap_clamp_to_street(vec3 x, vec3 planes, int along) { return envcap_clamp_to_street(x, vec4(planes, 0.0), along); }

// Distances along d from x to the facade d runs towards (tc) and to the ground (tg); ENVCAP_FAR
// when d is parallel to it or moves away from it (a quotient may overflow to +inf).
vec2 envcap_plane_exits(vec3 x, vec3 d, vec4 planes, int along)
{
    int cross = 2 - along;
    float dc = d[cross];
    float tc = ENVCAP_FAR;
    if (dc > 0.0) tc = (planes.y - x[cross]) / dc;
    else if (dc < 0.0) tc = (planes.x - x[cross]) / dc;
    float dg = envcap_ground_rate(d, planes, along);
    float tg = ENVCAP_FAR;
    if (dg < 0.0) tg = (envcap_ground_height(x, planes, along) - x.y) / dg;
    return vec2(tc, tg);
}

// Distance t >= 0 (m) along unit direction d from x (inside the street volume) to the first of
// the three planes, or ENVCAP_FAR when d hits none of them within ENVCAP_FAR (d up, d along
// the street, or d parallel to the plane it would hit).  A rate of +0.0 or -0.0 (d's cross
// component, or its rise above the ground) never divides: both mean "parallel".
float envcap_exit_distance(vec3 x, vec3 d, vec4 planes, int along)
{
    vec2 t = envcap_plane_exits(x, d, planes, along);
    return min(min(t.x, t.y), ENVCAP_FAR);   // a quotient that overflows to +inf becomes FAR
}
float envcap_exit_distance(vec3 x, vec3 d, vec3 planes, int along) { return envcap_exit_distance(x, d, vec4(planes, 0.0), along); }

// Three-plane parallax for shading point x, unit direction d, probe at p with `planes`.
// Returns vec4(r, ratio): r = unit vector from the probe to the hit point (the direction to
// sample the probe with), ratio = d_probe / d_shade = |hit - p| / |hit - x| clamped to
// [1/ENVCAP_MAX_RATIO, ENVCAP_MAX_RATIO].  Fallbacks: no hit -> (d, 1); hit point within
// ENVCAP_MIN_DIST of the probe -> (d, 1/ENVCAP_MAX_RATIO); x on a plane (d_shade = 0) ->
// d_shade taken as ENVCAP_MIN_DIST (the ratio then clamps to ENVCAP_MAX_RATIO).
vec4 envcap_parallax(vec3 x, vec3 d, vec3 p, vec4 planes, int along)
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
vec4 envcap_parallax(vec3 x, vec3 d, vec3 p, vec3 planes, int along) { return envcap_parallax(x, d, p, vec4(planes, 0.0), along); }

// Mip shift in lobe-power space: the lobe of power w seen from the shading point covers the
// same patch of the hit plane as a lobe of power w * ratio^2 seen from the probe
// (docs/runtime.md).  Negative w is treated as 0.
float envcap_shift_power(float w, float ratio)
{
    return max(w, 0.0) * (ratio * ratio);
}

// ---- Oblique, anisotropic mip shift (docs/runtime.md; numpy twin envcap/runtime/footprint.py) ----

// Cosines of the hit angles below this are taken as this (grazing hits; the shift then clamps).
const float ENVCAP_MIN_COS = 1.0e-4;
// Offset of the four sigma rays of envcap_sigma_footprint, in lobe RMS tangents sqrt(2/(w+3)).
const float ENVCAP_SPREAD = 1.3;

// Unit normal of the plane a ray leaves the street through: the ground's (tilted by its slope
// planes.w along the street: (-w, 1) / sqrt(1 + w^2) in (along, y)) when `ground`, else the
// facades' (+cross axis; its sign does not matter to the |cos| that use it).
vec3 envcap_exit_normal(bool ground, vec4 planes, int along)
{
    vec3 n = vec3(0.0);
    if (ground) {
        float gl = sqrt(1.0 + planes.w * planes.w);
        n.y = 1.0 / gl;
        n[along] = -planes.w / gl;
    } else {
        n[2 - along] = 1.0;
    }
    return n;
}

// Three-plane parallax with the oblique (area-matched) mip shift.  Returns vec4(r, q): r as
// envcap_parallax, q = ratio^2 cos(alpha) / cos(beta) the power multiplier (w' = w q), alpha and
// beta the angles between the hit plane's normal and d, r.  q clamped to [1/R^2, R^2],
// R = ENVCAP_MAX_RATIO.  Fallbacks as envcap_parallax, with q = ratio^2.
vec4 envcap_parallax_oblique(vec3 x, vec3 d, vec3 p, vec4 planes, int along)
{
    vec3 xc = envcap_clamp_to_street(x, planes, along);
    vec2 te = envcap_plane_exits(xc, d, planes, along);
    float tc = te.x, tg = te.y;
    float t = min(min(tc, tg), ENVCAP_FAR);
    if (!(t < ENVCAP_FAR)) return vec4(d, 1.0);
    vec3 r = (xc - p) + t * d;
    float dp = length(r);
    if (!(dp > ENVCAP_MIN_DIST)) return vec4(d, 1.0 / (ENVCAP_MAX_RATIO * ENVCAP_MAX_RATIO));
    r = r / dp;
    float ratio = min(max(dp / max(t, ENVCAP_MIN_DIST), 1.0 / ENVCAP_MAX_RATIO), ENVCAP_MAX_RATIO);
    vec3 n = envcap_exit_normal(tg < tc, planes, along);
    float ca = max(abs(dot(n, d)), ENVCAP_MIN_COS);
    float cb = max(abs(dot(n, r)), ENVCAP_MIN_COS);
    float q = ratio * ratio * (ca / cb);
    return vec4(r, min(max(q, 1.0 / (ENVCAP_MAX_RATIO * ENVCAP_MAX_RATIO)), ENVCAP_MAX_RATIO * ENVCAP_MAX_RATIO));
}
vec4 envcap_parallax_oblique(vec3 x, vec3 d, vec3 p, vec3 planes, int along)
{
    return envcap_parallax_oblique(x, d, p, vec4(planes, 0.0), along);
}

// A basis (e1, e2) across unit v: e1 = normalize(cross(v, X)), X = +x (+y when |v.x| >= 0.9).
void envcap_basis(vec3 v, out vec3 e1, out vec3 e2)
{
    vec3 X = abs(v.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
    e1 = normalize(cross(v, X));
    e2 = cross(v, e1);
}

// The footprint of the cos^w lobe around d from x, seen from the probe at p, traced with four
// sigma rays normalize(d +- a e_j), a = ENVCAP_SPREAD sqrt(2 / (w + 3)), through the three
// planes.  Returns vec2(var_minor, var_major): per-axis variances of the sine of the angle to r
// seen from the probe (a cos^W lobe has 1 / (W + 3)); r (as envcap_parallax) and the unit long
// axis `major` (across r) are written to the out parameters.  w < 0 and NaN count as 0; w = +inf
// gives a point footprint (0, 0).  img[j]: the four sigma rays' hits seen from the probe (unit;
// a ray that hits no plane: its own direction), rays d + a e1, d - a e1, d + a e2, d - a e2.
vec2 envcap_sigma_footprint_rays(vec3 x, vec3 d, float w, vec3 p, vec4 planes, int along, out vec3 r, out vec3 major,
                                 out vec3 img[4])
{
    w = w > 0.0 ? w : 0.0;
    vec3 xc = envcap_clamp_to_street(x, planes, along);
    float t = envcap_exit_distance(xc, d, planes, along);
    vec3 rv = (xc - p) + t * d;
    float dp = length(rv);
    r = (t < ENVCAP_FAR && dp > ENVCAP_MIN_DIST) ? rv / dp : d;
    vec3 e1, e2, f1, f2;
    envcap_basis(d, e1, e2);
    envcap_basis(r, f1, f2);
    float a = ENVCAP_SPREAD * sqrt(2.0 / (w + 3.0));
    vec2 c[4];
    for (int j = 0; j < 4; ++j) {
        vec3 u = d + ((j == 0 || j == 2) ? a : -a) * (j < 2 ? e1 : e2);
        u = u / length(u);
        float tu = envcap_exit_distance(xc, u, planes, along);
        vec3 v = (xc - p) + tu * u;
        float vl = length(v);
        v = (tu < ENVCAP_FAR && vl > ENVCAP_MIN_DIST) ? v / vl : u;
        img[j] = v;
        c[j] = vec2(dot(v, f1), dot(v, f2));
    }
    float k = 0.25 * (1.0 + a * a) / (ENVCAP_SPREAD * ENVCAP_SPREAD);
    float s11 = 0.0, s22 = 0.0, s12 = 0.0, det = 0.0;
    for (int j = 0; j < 4; ++j) {
        s11 += c[j].x * c[j].x;
        s22 += c[j].y * c[j].y;
        s12 += c[j].x * c[j].y;
        for (int l = j + 1; l < 4; ++l) {   // det by Cauchy-Binet: a sum of squares, no cancellation
            float cb = c[j].x * c[l].y - c[j].y * c[l].x;
            det += cb * cb;
        }
    }
    s11 *= k;
    s22 *= k;
    s12 *= k;
    det *= k * k;
    float half_ = 0.5 * (s11 + s22);
    float vmaj = half_ + sqrt(0.25 * (s11 - s22) * (s11 - s22) + s12 * s12);
    float vmin = vmaj > 0.0 ? min(det / vmaj, vmaj) : 0.0;
    bool first = s11 >= s22;
    vec2 u = first ? vec2(vmaj - s22, s12) : vec2(s12, vmaj - s11);
    float big = max(abs(u.x), abs(u.y));   // scaled first: the components may underflow when squared
    u = big > 0.0 ? u / big : vec2(1.0, 0.0);
    vec3 m = u.x * f1 + u.y * f2;
    major = m / length(m);
    return vec2(vmin, vmaj);
}

// As envcap_sigma_footprint_rays, without the rays' hits: returns vec2(var_minor, var_major).
vec2 envcap_sigma_footprint(vec3 x, vec3 d, float w, vec3 p, vec4 planes, int along, out vec3 r, out vec3 major)
{
    vec3 img[4];
    return envcap_sigma_footprint_rays(x, d, w, p, planes, along, r, major, img);
}
vec2 envcap_sigma_footprint(vec3 x, vec3 d, float w, vec3 p, vec3 planes, int along, out vec3 r, out vec3 major)
{
    return envcap_sigma_footprint(x, d, w, p, vec4(planes, 0.0), along, r, major);
}

// Lobe power of a footprint variance v (per axis, of the sine): 1/v - 3, >= 0; v = 0 -> a power
// above any chain's level 0 (the mirror).
float envcap_footprint_power(float v)
{
    return v > 0.0 ? max(1.0 / v - 3.0, 0.0) : ENVCAP_FAR * ENVCAP_FAR;
}

#endif  // ENVCAP_STREET_GLSL
