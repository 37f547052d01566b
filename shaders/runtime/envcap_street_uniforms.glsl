#ifndef ENVCAP_STREET_UNIFORMS_GLSL
#define ENVCAP_STREET_UNIFORMS_GLSL
// The uniforms of one street for the envcap runtime library: one EnvcapStreet struct (declared
// and documented in runtime/envcap_runtime.glsl, which this file includes).  Fill it from a probe
// set's manifest with envcap.runtime.street.RuntimeStreet.from_manifest(street).uniforms(powers)
// .values() (names "envcap_street.<member>"), and pass `envcap_street` to the library's
// envcap_sample_nearest / envcap_sample_blended / envcap_shade_lafortune, with shading points in
// the street-local frame of the uniforms (StreetUniforms.to_local; see envcap_runtime.glsl).
#include "runtime/envcap_runtime.glsl"

uniform EnvcapStreet envcap_street;

#endif  // ENVCAP_STREET_UNIFORMS_GLSL
