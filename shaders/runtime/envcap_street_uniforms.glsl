#ifndef ENVCAP_STREET_UNIFORMS_GLSL
#define ENVCAP_STREET_UNIFORMS_GLSL
// The uniforms of one street for the envcap runtime library: one EnvcapStreet struct (declared
// and documented in runtime/envcap_runtime.glsl, which this file includes).  Fill it from a probe
// set's manifest with envcap.runtime.street.RuntimeStreet.from_manifest(street).uniforms(powers)
// .values() (names "envcap_street.<member>"), and pass `envcap_street` to the library's
// envcap_sample_nearest / envcap_sample_blended / envcap_shade_lafortune, with shading points in
// the street-local frame of the uniforms (StreetUniforms.to_local: turned into the street's frame
// and moved to its origin; see envcap_runtime.glsl) and world directions.
#include "runtime/envcap_runtime.glsl"

#ifdef ENVCAP_STREET_BLOCK
// Targets that take no loose uniforms (Vulkan): the street in one block; ENVCAP_STREET_BLOCK is
// its qualifiers and kind (envcap.runtime.shader_targets: a std430 read-only storage buffer,
// which spirv-cross also translates to HLSL).  The member keeps the name envcap_street.
ENVCAP_STREET_BLOCK EnvcapStreetBlock { EnvcapStreet envcap_street; };
#else
uniform EnvcapStreet envcap_street;
#endif

#endif  // ENVCAP_STREET_UNIFORMS_GLSL
