// envcap probe sets in Babylon.js (WebGL2 engine): the textures with the right orientation, the
// runtime GLSL as ShaderMaterial source, the street uniform as ShaderMaterial values.  Pass your
// BABYLON namespace (the UMD build's global, or `import * as BABYLON from "@babylonjs/core"`).
//
//   const ps = loadProbeSetBabylon(BABYLON, scene, await fetchProbeFiles(config.files));
//   const lib = await (await fetch("api/runtime.glsl")).text();   // or envcap's webgl2 target
//   const mat = new BABYLON.ShaderMaterial("m", scene,
//       { vertexSource: "#version 300 es\n...", fragmentSource: runtimeSource(lib) + yourMain },
//       { attributes: ["position", "normal"], uniforms: ["world", "viewProjection", ...streetUniformNames(u)],
//         samplers: SAMPLERS });
//   bindProbeSet(mat, ps); setStreet(mat, config.streets[0].uniforms.nominal);
//
// The shaders: Babylon passes a GLSL source that contains "#version 3" through unchanged on
// WebGL2 (no define injection, no GLSL 1 conversion) and writes the "#version 300 es" line
// itself, so the runtime's WebGL2 target goes in as it is.  The probes are a face-atlas
// RawTexture2DArray (RGBA16F, bilinear, clamped, no mipmaps: WebGL2 has no cube-map arrays); the
// sky a RawCubeTexture in GL's face order (Babylon uploads face n to TEXTURE_CUBE_MAP_POSITIVE_X + n),
// invertY false, with the file's lobe levels as its mip levels.  Orientation: the files are in
// GL's cube convention and the runtime samples them with its own directions in your shader; set
// scene.useRightHandedSystem = true so that Babylon's world axes are envcap's (Babylon is
// left-handed by default: +Z would point the other way).
//
// The sky's format follows ktx2.js skyPlan, with Babylon's caps deciding float filtering
// (getCaps().textureFloatLinearFiltering): RGBA32F trilinear, RGBA16F without float filtering
// when the sky fits half floats, else RGBA32F nearest with a console warning.  ps.skyPlan says which.
import { fetchKTX2, skyFaceData, skyFaces, skyPlan, VK_RGBA16F } from "./ktx2.js";

export const SAMPLERS = ["envcap_probes", "envcap_sky"];

// The probe files of /api/config.json's `files` ({atlas, sky, ...}) parsed (ktx2.js parseKTX2).
export async function fetchProbeFiles(files) {
  const [atlas, sky] = await Promise.all([fetchKTX2(files.atlas), fetchKTX2(files.sky)]);
  return { atlas, sky, skyLayer0: !!files.skyLayer0 };
}

function constant(BABYLON, name) {
  const v = BABYLON.Constants[name];
  if (v === undefined) throw new Error(`this Babylon.js build has no Constants.${name}`);
  return v;
}

// The sky as a Babylon RawCubeTexture with the file's levels as its mip chain.  Babylon's
// RawCubeTexture API uploads one level at the texture's size (updateRawCubeTexture uses
// InternalTexture.width), so each level k is uploaded with the size set to level k's.  WebGL2
// needs the chain down to 1 x 1; levels past the file's last are filled with its last texel and
// never read (the runtime clamps its level to the set's chain: envcap_clamp_level).
function skyTexture(BABYLON, scene, s, plan, faces) {
  const engine = scene.getEngine();
  const half = plan.format === "rgba16f";
  const format = constant(BABYLON, "TEXTUREFORMAT_RGBA");
  const type = constant(BABYLON, half ? "TEXTURETYPE_HALF_FLOAT" : "TEXTURETYPE_FLOAT");
  const sampling = constant(BABYLON, plan.linear ? "TEXTURE_TRILINEAR_SAMPLINGMODE" : "TEXTURE_NEAREST_NEAREST_MIPNEAREST");
  const data = faces.map((level) => level.map((face) => skyFaceData(s, plan, face)));
  const n = s.levels[0].width;
  const tex = new BABYLON.RawCubeTexture(scene, data[0], n, format, type, false, false, sampling);
  const it = tex.getInternalTexture();
  let size = n, k = 0;
  while (size > 1) {
    size = Math.max(1, size >> 1);
    k += 1;
    let level = data[k];
    if (!level) {   // filler below the file's chain (never read)
      const last = data[data.length - 1];
      level = last.map((face) => { const f = new face.constructor(size * size * 4); for (let i = 0; i < f.length; ++i) f[i] = face[i % 4]; return f; });
    }
    it.width = it.height = size;
    engine.updateRawCubeTexture(it, level, format, type, false, null, k);
  }
  it.width = it.height = it.baseWidth = it.baseHeight = n;
  it.useMipMaps = true;
  engine.updateTextureSamplingMode(sampling, it);
  tex.anisotropicFilteringLevel = 1;
  return tex;
}

// The probe set in Babylon: {atlas (RawTexture2DArray), sky (RawCubeTexture), skyPlan}.
export function loadProbeSetBabylon(BABYLON, scene, files) {
  const a = files.atlas, s = files.sky;
  if (a.vkFormat !== VK_RGBA16F || a.faces !== 1 || a.levels.length !== 1) throw new Error("probes_atlas.ktx2: expected a one-level RGBA16F 2D array");
  const atlas = new BABYLON.RawTexture2DArray(a.levels[0].data, a.width, a.height, a.layers,
    constant(BABYLON, "TEXTUREFORMAT_RGBA"), scene, false, false,
    constant(BABYLON, "TEXTURE_BILINEAR_SAMPLINGMODE"), constant(BABYLON, "TEXTURETYPE_HALF_FLOAT"));
  atlas.wrapU = atlas.wrapV = constant(BABYLON, "TEXTURE_CLAMP_ADDRESSMODE");
  atlas.anisotropicFilteringLevel = 1;

  const floatLinear = !!scene.getEngine().getCaps().textureFloatLinearFiltering;
  const plan = skyPlan(s, floatLinear, files.skyLayer0);
  if (plan.warning) console.warn(plan.warning);
  const sky = skyTexture(BABYLON, scene, s, plan, skyFaces(s, files.skyLayer0));
  return { atlas, sky, atlasKtx: a, skyKtx: s, skyPlan: plan };
}

// The runtime library as a Babylon ShaderMaterial fragment source: its "#version 300 es" line
// kept (Babylon's sign to pass the source through) and the samplers the chunk's functions take.
export function runtimeSource(library) {
  if (!/^#version 300 es/m.test(library)) throw new Error("runtime.glsl: expected the WebGL2 target (#version 300 es)");
  return library + "\nuniform ENVCAP_PROBES_SAMPLER envcap_probes;\nuniform samplerCube envcap_sky;\n";
}

// The struct's members, as /api/config.json's street uniforms name them, by uniform type.
const VEC4 = new Set(["pos", "planes"]);
const INT = new Set(["count", "along", "nlevels"]);

// The uniform names of the `envcap_street` struct for ShaderMaterial's `uniforms` option.
export function streetUniformNames(u) {
  return Object.keys(u).map((name) => `envcap_street.${name}`);
}

export function bindProbeSet(material, ps) {
  material.setTexture("envcap_probes", ps.atlas);
  material.setTexture("envcap_sky", ps.sky);
}

// One street's uniforms (config.streets[i].uniforms.nominal or .fitted) on the material.
// Shading points go in as the page's street_frame.js toLocal gives them; directions stay world.
export function setStreet(BABYLON, material, u) {
  for (const [name, v] of Object.entries(u)) {
    const key = `envcap_street.${name}`;
    if (INT.has(name)) material.setInt(key, v);
    else if (VEC4.has(name)) material.setArray4(key, Array.from(v));
    else if (name === "frame") material.setVector2(key, new BABYLON.Vector2(v[0], v[1]));
    else material.setFloats(key, Array.isArray(v) ? v : [v]);
  }
}
