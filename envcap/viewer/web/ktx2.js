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

// The sky (sky.ktx2, an RGBA32F cube map with the lobe ladder as mip levels) as a
// TEXTURE_CUBE_MAP, trilinear (WebGL2 cube sampling is seamless).  RGBA32F needs
// OES_texture_float_linear to filter; without it the sky goes up as RGBA16F (half floats).
// layer0: a rung-ladder set's R-layer sky array (manifest.ladder): its layer 0 only (rung j R of
// level j, the chain of the manifest's lobe table; layers are stored first, so it is each level's
// first 6 faces).
export function uploadSky(gl, ktx, layer0 = false) {
  if (ktx.faces !== 6 || (ktx.layers !== 1 && !layer0)) throw new Error(`sky.ktx2: expected one cube map, got ${ktx.layers} layers`);
  const linear32 = !!gl.getExtension("OES_texture_float_linear");
  const t = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_CUBE_MAP, t);
  gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
  gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
  ktx.levels.forEach((lv, k) => {
    const n = lv.width * lv.height * 4;
    for (let f = 0; f < 6; ++f) {
      const face = lv.data.subarray(f * n, (f + 1) * n);
      if (ktx.vkFormat === VK_RGBA32F && linear32) {
        gl.texImage2D(gl.TEXTURE_CUBE_MAP_POSITIVE_X + f, k, gl.RGBA32F, lv.width, lv.height, 0, gl.RGBA, gl.FLOAT, face);
      } else if (ktx.vkFormat === VK_RGBA32F) {
        gl.texImage2D(gl.TEXTURE_CUBE_MAP_POSITIVE_X + f, k, gl.RGBA16F, lv.width, lv.height, 0, gl.RGBA, gl.FLOAT, face);
      } else {
        gl.texImage2D(gl.TEXTURE_CUBE_MAP_POSITIVE_X + f, k, gl.RGBA16F, lv.width, lv.height, 0, gl.RGBA, gl.HALF_FLOAT, face);
      }
    }
  });
  gl.texParameteri(gl.TEXTURE_CUBE_MAP, gl.TEXTURE_MIN_FILTER, gl.LINEAR_MIPMAP_LINEAR);
  gl.texParameteri(gl.TEXTURE_CUBE_MAP, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_CUBE_MAP, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
  gl.texParameteri(gl.TEXTURE_CUBE_MAP, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
  gl.texParameteri(gl.TEXTURE_CUBE_MAP, gl.TEXTURE_MAX_LEVEL, ktx.levels.length - 1);
  return { texture: t, float32: ktx.vkFormat === VK_RGBA32F && linear32 };
}

// Load a probe set served by `envcap view`: {atlas, sky, skyFloat32, atlasKtx, skyKtx}.
// options.skyLayer0: the sky is a rung ladder's layered array, use its layer 0 (uploadSky).
export async function loadProbeSet(gl, files, options = {}) {
  const [atlasKtx, skyKtx] = await Promise.all([fetchKTX2(files.atlas), fetchKTX2(files.sky)]);
  const atlas = uploadAtlas(gl, atlasKtx);
  const sky = uploadSky(gl, skyKtx, !!options.skyLayer0);
  return { atlas, sky: sky.texture, skyFloat32: sky.float32, atlasKtx, skyKtx };
}
