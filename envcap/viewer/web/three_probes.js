// envcap probe sets in three.js (WebGL2): textures with the right orientation and the runtime
// GLSL as a RawShaderMaterial chunk.  Pass your three.js namespace (`import * as THREE from
// "three"`): this module imports nothing from three.js, so it needs no bundler or import map.
//
//   const renderer = new THREE.WebGLRenderer();
//   const ps = await loadProbeSetThree(THREE, { atlas: "probes_atlas.ktx2", sky: "sky.ktx2" }, { renderer });
//   const lib = await (await fetch("api/runtime.glsl")).text();   // or envcap's webgl2 target
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
//
// The sky's format is chosen at load (ktx2.js skyPlan): RGBA32F with LinearMipmapLinear where the
// device filters float textures (OES_texture_float_linear), else RGBA16F (HalfFloatType) when the
// sky fits half floats (no sun in the map), else RGBA32F with NEAREST filtering and a console
// warning.  Pass options.renderer (your WebGLRenderer) so that its extensions decide; without it a
// throwaway WebGL2 context is asked.  ps.skyPlan says what was chosen.
import { fetchKTX2, skyFaceData, skyFaces, skyPlan, VK_RGBA16F, VK_RGBA32F } from "./ktx2.js";

// Whether this browser filters RGBA32F textures linearly, asked of a throwaway WebGL2 context.
function floatLinearHere() {
  const gl = document.createElement("canvas").getContext("webgl2");
  const ok = !!(gl && gl.getExtension("OES_texture_float_linear"));
  const lose = gl && gl.getExtension("WEBGL_lose_context");
  if (lose) lose.loseContext();
  return ok;
}

export async function loadProbeSetThree(THREE, files, options = {}) {
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
  const faces = skyFaces(s, !!files.skyLayer0);
  const floatLinear = options.renderer ? options.renderer.extensions.has("OES_texture_float_linear") : floatLinearHere();
  const plan = skyPlan(s, floatLinear, !!files.skyLayer0);
  if (plan.warning) console.warn(plan.warning);
  const half = plan.format === "rgba16f";
  const faceTextures = (k) => faces[k].map((face) => {
    const lv = s.levels[k];
    const t = new THREE.DataTexture(skyFaceData(s, plan, face), lv.width, lv.height, THREE.RGBAFormat,
                                    half ? THREE.HalfFloatType : THREE.FloatType);
    t.flipY = false;
    return t;
  });
  const sky = new THREE.CubeTexture(faceTextures(0));
  sky.mipmaps = s.levels.slice(1).map((_, k) => ({ image: faceTextures(k + 1) }));  // levels 1.. (three.js: no base level here)
  sky.format = THREE.RGBAFormat;
  sky.type = half ? THREE.HalfFloatType : THREE.FloatType;
  sky.minFilter = plan.linear ? THREE.LinearMipmapLinearFilter : THREE.NearestMipmapNearestFilter;
  sky.magFilter = plan.linear ? THREE.LinearFilter : THREE.NearestFilter;
  sky.generateMipmaps = false;
  sky.flipY = false;
  sky.unpackAlignment = 1;
  sky.needsUpdate = true;
  return { atlas, sky, atlasKtx: a, skyKtx: s, skyPlan: plan };
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

// ---- WebGPU (three.js WebGPURenderer) --------------------------------------------------------
// WebGPU has cube-map arrays: probes.ktx2 goes up as stored, one texture_cube_array with the
// set's mips (no face atlas), the sky as a texture_cube, both on the renderer's GPUDevice.  three.js
// r187 has no cube-array texture type (its node materials bind 2D arrays and cubes only), so the
// runtime's WGSL (web/three_webgpu.wgsl, translated from the runtime GLSL by envcap) draws in its
// own render pass on that device: see three_webgpu_example.js.
//
//   const renderer = new THREE.WebGPURenderer({ canvas });   // import * as THREE from "three/webgpu"
//   const ps = await loadProbeSetWebGPU(renderer, { probes: "probes.ktx2", sky: "sky.ktx2" });
//   // bind ps.probes (22), ps.sky (24), ps.sampler (23, 25), streetBlock(uniforms) (8, storage)
const GPU_FORMATS = { [VK_RGBA16F]: "rgba16float", [VK_RGBA32F]: "rgba32float" };

// A cube (dimension "cube") or cube-map array ("cube-array") view of the KTX2 `ktx`'s first
// `layers` layers (its levels as stored: layer-major, then faces +X -X +Y -Y +Z -Z, rows).
function cubeView(device, ktx, layers, dimension, name) {
  const format = GPU_FORMATS[ktx.vkFormat];
  if (!format || ktx.faces !== 6) throw new Error(`${name}: expected an RGBA16F or RGBA32F cube map (array)`);
  if (format === "rgba32float" && !device.features.has("float32-filterable")) {
    throw new Error(`${name}: RGBA32F needs the WebGPU feature float32-filterable, which this device lacks`);
  }
  const tex = device.createTexture({ size: [ktx.width, ktx.height, 6 * layers], format, mipLevelCount: ktx.levels.length,
                                     usage: GPUTextureUsage.TEXTURE_BINDING | GPUTextureUsage.COPY_DST });
  ktx.levels.forEach((lv, k) => {
    const texelBytes = lv.data.BYTES_PER_ELEMENT * 4;
    device.queue.writeTexture({ texture: tex, mipLevel: k }, lv.data.subarray(0, lv.width * lv.height * 4 * 6 * layers),
                              { bytesPerRow: lv.width * texelBytes, rowsPerImage: lv.height }, [lv.width, lv.height, 6 * layers]);
  });
  return tex.createView({ dimension });
}

// The probe set on `renderer`'s device (three.js WebGPURenderer; initialized here).  files.probes:
// the cube-map array KTX2 (probes.ktx2), files.sky: sky.ktx2 (a rung ladder's layered sky: its
// layer 0).  Returns { device, probes, sky, sampler, probesKtx, skyKtx }.
export async function loadProbeSetWebGPU(renderer, files) {
  await renderer.init();
  const device = renderer.backend.device;
  if (!device) throw new Error("loadProbeSetWebGPU: the renderer has no GPUDevice (is it a WebGPURenderer on WebGPU?)");
  const [p, s] = await Promise.all([fetchKTX2(files.probes), fetchKTX2(files.sky)]);
  const probes = cubeView(device, p, p.layers, "cube-array", files.probes);
  const sky = cubeView(device, s, 1, "cube", files.sky);
  const sampler = device.createSampler({ magFilter: "linear", minFilter: "linear", mipmapFilter: "linear" });
  return { device, probes, sky, sampler, probesKtx: p, skyKtx: s };
}

// The street (/api/config.json's uniforms of one street) as the WGSL runtime's storage block
// (GLSL `EnvcapStreet`, std430: binding 8): float along_s[P]; vec4 pos[P]; vec4 planes[P];
// int count; int along; float xk[L]; int nlevels; vec2 frame.
export function streetBlock(u) {
  const P = u.along_s.length, L = u.xk.length, a16 = (x) => Math.ceil(x / 16) * 16;
  const oPos = a16(4 * P), oPlanes = oPos + 16 * P, oCount = oPlanes + 16 * P, oXk = oCount + 8;
  const oN = oXk + 4 * L, oFrame = Math.ceil((oN + 4) / 8) * 8;
  const buf = new ArrayBuffer(a16(oFrame + 8));
  const f = new Float32Array(buf), i = new Int32Array(buf);
  f.set(u.along_s, 0);
  f.set(u.pos, oPos / 4);
  f.set(u.planes, oPlanes / 4);
  i[oCount / 4] = u.count;
  i[oCount / 4 + 1] = u.along;
  f.set(u.xk, oXk / 4);
  i[oN / 4] = u.nlevels;
  f.set(u.frame, oFrame / 4);
  return buf;
}
