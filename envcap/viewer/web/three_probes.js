// envcap probe sets in three.js (WebGL2): textures with the right orientation and the runtime
// GLSL as a RawShaderMaterial chunk.  Pass your three.js namespace (`import * as THREE from
// "three"`): this module imports nothing from three.js, so it needs no bundler or import map.
//
//   const ps = await loadProbeSetThree(THREE, { atlas: "probes_atlas.ktx2", sky: "sky.ktx2" });
//   const lib = await (await fetch("/api/runtime.glsl")).text();   // or envcap's webgl2 target
//   new THREE.RawShaderMaterial({ glslVersion: THREE.GLSL3, vertexShader,
//       fragmentShader: runtimeChunk(lib) + yourMain,
//       uniforms: { envcap_probes: { value: ps.atlas }, envcap_sky: { value: ps.sky },
//                   envcap_street: { value: streetUniformValue(config.streets[0].uniforms.nominal) } } });
//
// Orientation: the files are in GL's cube convention; they go to three.js as stored (flipY
// false), and the runtime samples them with its own directions in your shader.  three.js's
// built-in environment-map path (material.envMap, scene.environment) mirrors X for cube textures
// that are not render targets (flipEnvMap = -1), so do not hand `ps.sky` to it: use the chunk.
// The probes are a face-atlas DataArrayTexture (three.js and WebGL2 have no cube-map arrays).
import { fetchKTX2, VK_RGBA16F, VK_RGBA32F } from "./ktx2.js";

export async function loadProbeSetThree(THREE, files) {
  const [a, s] = await Promise.all([fetchKTX2(files.atlas), fetchKTX2(files.sky)]);
  if (a.vkFormat !== VK_RGBA16F || a.faces !== 1 || a.levels.length !== 1) throw new Error(`${files.atlas}: expected a one-level RGBA16F 2D array`);
  const atlas = new THREE.DataArrayTexture(a.levels[0].data, a.width, a.height, a.layers);
  atlas.format = THREE.RGBAFormat;
  atlas.type = THREE.HalfFloatType;
  atlas.minFilter = atlas.magFilter = THREE.LinearFilter;
  atlas.wrapS = atlas.wrapT = THREE.ClampToEdgeWrapping;
  atlas.generateMipmaps = false;
  atlas.flipY = false;
  atlas.unpackAlignment = 1;
  atlas.needsUpdate = true;

  // files.skyLayer0: a rung-ladder set's R-layer sky array (config.ladder): its layer 0, the manifest's chain
  if (s.faces !== 6 || (s.layers !== 1 && !files.skyLayer0)) throw new Error(`${files.sky}: expected one cube map, got ${s.layers} layers`);
  const float = s.vkFormat === VK_RGBA32F;
  const faceTextures = (lv) => Array.from({ length: 6 }, (_, f) => {
    const n = lv.width * lv.height * 4;
    const t = new THREE.DataTexture(lv.data.subarray(f * n, (f + 1) * n), lv.width, lv.height, THREE.RGBAFormat,
                                    float ? THREE.FloatType : THREE.HalfFloatType);
    t.flipY = false;
    return t;
  });
  const sky = new THREE.CubeTexture(faceTextures(s.levels[0]));
  sky.mipmaps = s.levels.slice(1).map((lv) => ({ image: faceTextures(lv) }));  // levels 1.. (three.js: no base level here)
  sky.format = THREE.RGBAFormat;
  sky.type = float ? THREE.FloatType : THREE.HalfFloatType;
  sky.minFilter = THREE.LinearMipmapLinearFilter;
  sky.magFilter = THREE.LinearFilter;
  sky.generateMipmaps = false;
  sky.flipY = false;
  sky.unpackAlignment = 1;
  sky.needsUpdate = true;
  return { atlas, sky, atlasKtx: a, skyKtx: s };
}

// The runtime library for a RawShaderMaterial with glslVersion GLSL3 (three.js writes the
// #version line) plus the samplers the chunk's functions are called with.
export function runtimeChunk(library) {
  const body = library.replace(/^#version[^\n]*\n/, "");
  return body + "\nuniform ENVCAP_PROBES_SAMPLER envcap_probes;\nuniform samplerCube envcap_sky;\n";
}

// The value of the `envcap_street` struct uniform from /api/config.json's street uniforms.
// Shading points go in as the page's street_frame.js toLocal gives them (the street's frame, minus
// its origin); directions stay world (`frame`, (cos yaw, sin yaw), turns them in the GLSL).
export function streetUniformValue(u) {
  return { ...u };
}
