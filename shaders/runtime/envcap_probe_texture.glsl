#ifndef ENVCAP_PROBE_TEXTURE_GLSL
#define ENVCAP_PROBE_TEXTURE_GLSL
// The probe texture type and its lookup, for every runtime function that samples probes.
// Desktop GL, GLSL ES 3.20 and Vulkan: a cube-map array, as below.  A target without cube-map
// arrays (WebGL2) defines both before the include (envcap.runtime.shader_targets: a 2D array of
// face atlases, runtime/envcap_face_atlas.glsl).  ENVCAP_PROBES_LOD(probes, dir, layer, lod) means
// textureLod(samplerCubeArray, vec4(dir, layer), lod).  No #version: #include this.
#ifndef ENVCAP_PROBES_SAMPLER
#define ENVCAP_PROBES_SAMPLER samplerCubeArray
#define ENVCAP_PROBES_LOD(probes, dir, layer, lod) textureLod(probes, vec4(dir, layer), lod)
#endif
// ENVCAP_PROBES_FACE_SIZE(probes): texels per face edge of level 0 (the top of a rung ladder,
// envcap_rung_top, reads level 0 on its own texel grid).  A target that defines its own probe
// texture defines this too (WebGL2: envcap_face_atlas_size of the atlas width).
#ifndef ENVCAP_PROBES_FACE_SIZE
#define ENVCAP_PROBES_FACE_SIZE(probes) textureSize(probes, 0).x
#endif

#endif  // ENVCAP_PROBE_TEXTURE_GLSL
