// envcap viewer: a small KTX2 reader for envcap's uncompressed files and their upload to WebGL2.
// Reads what envcap writes (no supercompression; vkFormat R16G16B16A16_SFLOAT = 97 or
// R32G32B32A32_SFLOAT = 109; 2D, 2D arrays, cube maps); anything else is an error naming the file.
// Orientation: KTX2 stores rows top to bottom as GL's first row (t = 0), faces +X,-X,+Y,-Y,+Z,-Z;
// envcap cubes use the same convention (manifest cube_convention), so every image goes to WebGL2
// as stored, with UNPACK_FLIP_Y off: no flip, no mirror (three.js mirrors non-render-target cube
// maps in X; raw WebGL2 does not).

const IDENTIFIER = [0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A];
export const VK_RGBA16F = 97;
export const VK_RGBA32F = 109;

// Parse a KTX2 file: {vkFormat, width, height, layers, faces, levels: [{width, height, data}], kv}.
// data: Uint16Array (half floats) or Float32Array, layer-major, then face, then rows, RGBA.
export function parseKTX2(buffer, name = "KTX2 file") {
  const u8 = new Uint8Array(buffer);
  if (u8.length < 80 || IDENTIFIER.some((b, i) => u8[i] !== b)) throw new Error(`${name}: not a KTX2 file`);
  const dv = new DataView(buffer);
  const u32 = (o) => dv.getUint32(o, true);
  const u64 = (o) => Number(dv.getBigUint64(o, true));
  const vkFormat = u32(12), typeSize = u32(16), width = u32(20), height = u32(24), depth = u32(28);
  const layers = Math.max(1, u32(32)), faces = u32(36), levelCount = Math.max(1, u32(40)), scheme = u32(44);
  if (scheme !== 0) throw new Error(`${name}: supercompression scheme ${scheme} is not supported`);
  if (vkFormat !== VK_RGBA16F && vkFormat !== VK_RGBA32F) throw new Error(`${name}: vkFormat ${vkFormat} is not RGBA16F/RGBA32F`);
  if (depth > 1) throw new Error(`${name}: 3D textures are not supported`);
  const texel = vkFormat === VK_RGBA16F ? 8 : 16;
  if (typeSize !== texel / 4) throw new Error(`${name}: typeSize ${typeSize} does not match vkFormat ${vkFormat}`);
  const kv = {};
  const kvOff = u32(56), kvLen = u32(60);
  for (let o = kvOff; o + 4 <= kvOff + kvLen;) {
    const len = u32(o);
    const bytes = u8.subarray(o + 4, o + 4 + len);
    const nul = bytes.indexOf(0);
    const dec = new TextDecoder();
    kv[dec.decode(bytes.subarray(0, nul))] = dec.decode(bytes.subarray(nul + 1, bytes.length - (bytes[bytes.length - 1] === 0 ? 1 : 0)));
    o += 4 + len + ((4 - (len % 4)) % 4);
  }
  const levels = [];
  for (let k = 0; k < levelCount; ++k) {
    const off = u64(80 + 24 * k), len = u64(88 + 24 * k);
    const w = Math.max(1, width >> k), h = Math.max(1, (height || 1) >> k);
    const want = w * h * layers * faces * texel;
    if (len !== want || off + len > u8.length) throw new Error(`${name}: level ${k} has ${len} bytes, expected ${want}`);
    const copy = buffer.slice(off, off + len);  // aligned copy for the typed-array view
    levels.push({ width: w, height: h, data: texel === 8 ? new Uint16Array(copy) : new Float32Array(copy) });
  }
  return { vkFormat, width, height: height || 1, layers, faces, levels, kv };
}

export async function fetchKTX2(url) {
  const r = await fetch(url);
  if (!r.ok) throw new Error(`${url}: HTTP ${r.status}`);
  return parseKTX2(await r.arrayBuffer(), url);
}

// The probes' face atlases (probes_atlas.ktx2, one level, layer = probe * 6 + face) as a
// TEXTURE_2D_ARRAY RGBA16F, LINEAR, CLAMP_TO_EDGE, as shaders/runtime/envcap_face_atlas.glsl needs.
export function uploadAtlas(gl, ktx) {
  if (ktx.faces !== 1 || ktx.vkFormat !== VK_RGBA16F || ktx.levels.length !== 1) throw new Error("probes_atlas.ktx2: expected a one-level RGBA16F 2D array");
  const t = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D_ARRAY, t);
  gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
  gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
  gl.texImage3D(gl.TEXTURE_2D_ARRAY, 0, gl.RGBA16F, ktx.width, ktx.height, ktx.layers, 0, gl.RGBA, gl.HALF_FLOAT, ktx.levels[0].data);
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAX_LEVEL, 0);
  return t;
}

// float32 -> IEEE 754 half-float bits, round to nearest even (overflow: infinity; NaN stays NaN).
export const HALF_MAX = 65504;
const F32 = new Float32Array(1), U32 = new Uint32Array(F32.buffer);
export function toHalf(value) {
  F32[0] = value;
  const x = U32[0], sign = (x >>> 16) & 0x8000, exp = (x >>> 23) & 0xff;
  let mant = x & 0x7fffff;
  if (exp === 0xff) return sign | 0x7c00 | (mant ? 0x200 : 0);
  const e = exp - 112;                        // the half exponent (bias 15)
  if (e >= 0x1f) return sign | 0x7c00;
  if (e <= 0) {                               // subnormal half (or zero)
    if (e < -10) return sign;
    mant |= 0x800000;
    const shift = 14 - e, rem = mant & ((1 << shift) - 1), half = 1 << (shift - 1);
    let h = mant >>> shift;
    if (rem > half || (rem === half && (h & 1))) h += 1;
    return sign | h;
  }
  let h = (e << 10) | (mant >>> 13);
  const rem = mant & 0x1fff;
  if (rem > 0x1000 || (rem === 0x1000 && (h & 1))) h += 1;   // a carry into the exponent is right
  return sign | h;
}
export function toHalfArray(a) {
  const out = new Uint16Array(a.length);
  for (let i = 0; i < a.length; ++i) out[i] = toHalf(a[i]);
  return out;
}

// The sky's faces per level: [[face 0 .. 5 data]] (layer0: a rung ladder's layered sky, its layer 0).
export function skyFaces(ktx, layer0 = false) {
  if (ktx.faces !== 6 || (ktx.layers !== 1 && !layer0)) throw new Error(`sky.ktx2: expected one cube map, got ${ktx.layers} layers`);
  return ktx.levels.map((lv) => {
    const n = lv.width * lv.height * 4;
    return Array.from({ length: 6 }, (_, f) => lv.data.subarray(f * n, (f + 1) * n));
  });
}

// How the sky goes to WebGL2 (the raw page and three.js alike), chosen at load:
//   "rgba32f" linear   where float textures filter (OES_texture_float_linear): the file as stored;
//   "rgba16f" linear   without it, when every value fits half floats (<= 65504: a sky without the
//                      sun in its map); RGBA16F filters linearly everywhere in WebGL2;
//   "rgba32f" nearest  without it, when a value does not fit (--sun-in-sky): NEAREST texels and
//                      levels keep the sun's energy (blocky, no blend between levels), with a
//                      console warning (`warning`).  An RGBA32F texture sampled LINEAR without the
//                      extension is incomplete and reads 0: a black sky, no error.
// Returns {format, linear, peak, warning}.
export function skyPlan(ktx, floatLinear, layer0 = false) {
  if (ktx.vkFormat === VK_RGBA16F) return { format: "rgba16f", linear: true, peak: null, warning: null };
  if (floatLinear) return { format: "rgba32f", linear: true, peak: null, warning: null };
  let peak = 0;
  for (const level of skyFaces(ktx, layer0)) {
    for (const face of level) for (let i = 0; i < face.length; ++i) if (Math.abs(face[i]) > peak) peak = Math.abs(face[i]);
  }
  if (peak <= HALF_MAX) return { format: "rgba16f", linear: true, peak, warning: null };
  return { format: "rgba32f", linear: false, peak,
           warning: `sky.ktx2: no OES_texture_float_linear on this device and the sky peaks at ${peak.toPrecision(4)} ` +
                    `(over the half-float ${HALF_MAX}): the sky is sampled NEAREST (texels and lobe levels not blended)` };
}

// The face data of one sky face for a plan: Float32Array for "rgba32f", Uint16Array half floats for "rgba16f".
export function skyFaceData(ktx, plan, face) {
  if (plan.format === "rgba32f" || ktx.vkFormat === VK_RGBA16F) return face;
  return toHalfArray(face);
}

// The sky (sky.ktx2, an RGBA32F cube map with the lobe ladder as mip levels) as a
// TEXTURE_CUBE_MAP, trilinear (WebGL2 cube sampling is seamless), in the format skyPlan chooses.
// layer0: a rung-ladder set's R-layer sky array (manifest.ladder): its layer 0 only (rung j R of
// level j, the chain of the manifest's lobe table; layers are stored first, so it is each level's
// first 6 faces).  Returns {texture, float32, plan}.
export function uploadSky(gl, ktx, layer0 = false) {
  const faces = skyFaces(ktx, layer0);
  const plan = skyPlan(ktx, !!gl.getExtension("OES_texture_float_linear"), layer0);
  if (plan.warning) console.warn(plan.warning);
  const t = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_CUBE_MAP, t);
  gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
  gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
  ktx.levels.forEach((lv, k) => {
    for (let f = 0; f < 6; ++f) {
      const data = skyFaceData(ktx, plan, faces[k][f]);
      if (plan.format === "rgba32f") {
        gl.texImage2D(gl.TEXTURE_CUBE_MAP_POSITIVE_X + f, k, gl.RGBA32F, lv.width, lv.height, 0, gl.RGBA, gl.FLOAT, data);
      } else {
        gl.texImage2D(gl.TEXTURE_CUBE_MAP_POSITIVE_X + f, k, gl.RGBA16F, lv.width, lv.height, 0, gl.RGBA, gl.HALF_FLOAT, data);
      }
    }
  });
  gl.texParameteri(gl.TEXTURE_CUBE_MAP, gl.TEXTURE_MIN_FILTER, plan.linear ? gl.LINEAR_MIPMAP_LINEAR : gl.NEAREST_MIPMAP_NEAREST);
  gl.texParameteri(gl.TEXTURE_CUBE_MAP, gl.TEXTURE_MAG_FILTER, plan.linear ? gl.LINEAR : gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_CUBE_MAP, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
  gl.texParameteri(gl.TEXTURE_CUBE_MAP, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
  gl.texParameteri(gl.TEXTURE_CUBE_MAP, gl.TEXTURE_MAX_LEVEL, ktx.levels.length - 1);
  return { texture: t, float32: plan.format === "rgba32f", plan };
}

// A short name of a sky plan for status lines: "RGBA32F", "RGBA16F", "RGBA32F nearest".
export function skyPlanName(plan) {
  return plan.format.toUpperCase() + (plan.linear ? "" : " nearest");
}

// Load a probe set served by `envcap view`: {atlas, sky, skyFloat32, skyPlan, atlasKtx, skyKtx}.
// options.skyLayer0: the sky is a rung ladder's layered array, use its layer 0 (uploadSky).
export async function loadProbeSet(gl, files, options = {}) {
  const [atlasKtx, skyKtx] = await Promise.all([fetchKTX2(files.atlas), fetchKTX2(files.sky)]);
  const atlas = uploadAtlas(gl, atlasKtx);
  const sky = uploadSky(gl, skyKtx, !!options.skyLayer0);
  return { atlas, sky: sky.texture, skyFloat32: sky.float32, skyPlan: sky.plan, atlasKtx, skyKtx };
}
