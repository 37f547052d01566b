#ifndef ENVCAP_RUNG_STREET_GLSL
#define ENVCAP_RUNG_STREET_GLSL
// The street runtime (runtime/envcap_runtime.glsl: parallax, mip shift, sky composite, Eq. 3) on a
// probe set baked with a rung ladder (manifest "ladder", docs/lobes.md "Ladder modes"; envcap
// capture --ladder).  Include this INSTEAD of runtime/envcap_runtime.glsl (or before it and
// before any other runtime file); no #version: #include this.  Numpy twin: envcap.runtime.chains
// (ProbeChains with a ladder) and envcap.runtime.sampling.sample_sky (a SkyChain with a ladder).
//
// * `probes`: probes.ktx2 as stored, ENVCAP_RUNGS_PER_LEVEL (R) layers per probe: layer p R + r of
//   level j = rung j R + r of probe p.  EnvcapStreet.pos[i].w stays the probe index p.
// * `sky`: sky.ktx2, an R-layer cube-map array (the same texture type as the probes').
// * EnvcapStreet.xk: the rung table (envcap.runtime.rungs.rung_table(ladder.powers), up to
//   ENVCAP_MAX_LEVELS = 48 entries here), nlevels: the number of rungs
//   (envcap.runtime.rungs.rung_street_uniforms fills both).
// Every ENVCAP_PROBES_LOD(probes, dir, p, z) of the runtime becomes envcap_rung_lod at lookup
// position z = envcap_rung_lod_of_w(w) (envcap_lod_of_w: the rung position of w, and above rung 0
// the top segment up to the mirror): two bilinear fetches, the texel reads of the trilinear fetch
// it replaces; every sky lookup likewise.
#ifdef ENVCAP_RUNTIME_GLSL
#error "include runtime/envcap_rung_street.glsl before runtime/envcap_runtime.glsl"
#endif
#ifndef ENVCAP_RUNGS_PER_LEVEL
#define ENVCAP_RUNGS_PER_LEVEL 4
#endif
#ifndef ENVCAP_MAX_LEVELS
#define ENVCAP_MAX_LEVELS 48
#endif
// envcap_rung_lod, bound to the target's own texel fetch (ENVCAP_PROBES_LOD as defined now)
#include "runtime/envcap_lobes.glsl"
#undef ENVCAP_PROBES_LOD
#define ENVCAP_PROBES_LOD(probes, dir, layer, lod) envcap_rung_lod(probes, dir, (layer) * float(ENVCAP_RUNGS_PER_LEVEL), lod, ENVCAP_RUNGS_PER_LEVEL)
#define ENVCAP_SKY_SAMPLER ENVCAP_PROBES_SAMPLER
#define ENVCAP_SKY_LOD(sky, dir, lod) envcap_rung_lod(sky, dir, 0.0, lod, ENVCAP_RUNGS_PER_LEVEL)
#define ENVCAP_RUNG_LADDER
#include "runtime/envcap_runtime.glsl"

#endif  // ENVCAP_RUNG_STREET_GLSL
