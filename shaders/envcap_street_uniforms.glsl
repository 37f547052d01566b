// The uniforms of one street for the envcap runtime library (include after envcap_runtime.glsl).
// envcap.runtime.parallax.RuntimeStreet.from_manifest(entry).uniforms(powers) gives their values from a
// probe set's manifest:
//   along_s[i]  along-street coordinate of probe i (m), sorted
//   pos[i]      probe i: xyz world position (m), w = its layer in the probe cube-map array
//   planes[i]   probe i: (facade_min, facade_max, ground) in world meters, w unused
//   count       number of probes (<= ENVCAP_MAX_PROBES)
//   along       street axis: 0 = x, 2 = z
//   xk[k]       log2(1 + lobe power of level k), the z(w) table (manifest "levels")
//   nlevels     number of levels (<= ENVCAP_MAX_LEVELS)
uniform float along_s[ENVCAP_MAX_PROBES];
uniform vec4 pos[ENVCAP_MAX_PROBES];
uniform vec4 planes[ENVCAP_MAX_PROBES];
uniform int count;
uniform int along;
uniform float xk[ENVCAP_MAX_LEVELS];
uniform int nlevels;
