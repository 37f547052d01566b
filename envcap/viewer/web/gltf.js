// envcap viewer: a small binary glTF 2.0 (GLB) reader for the bake's scene.glb
// (envcap/formats/scene_gltf.py): triangle primitives' POSITION, NORMAL, COLOR_0, _EMISSION and
// indices, joined into one mesh, with the first node's translation as the mesh origin (world m,
// float64).  Not a general glTF loader: no textures, skins, sparse accessors or node hierarchies.

const COMPONENTS = { SCALAR: 1, VEC2: 2, VEC3: 3, VEC4: 4 };
const ARRAYS = { 5120: Int8Array, 5121: Uint8Array, 5122: Int16Array, 5123: Uint16Array, 5125: Uint32Array, 5126: Float32Array };
const NORM = { 5120: 127, 5121: 255, 5122: 32767, 5123: 65535 };

// An accessor's elements as a Float32Array (normalized integers scaled to [0, 1]) or, for
// indices (`asIndex`), a Uint32Array; `n` components per element are kept.
function accessor(doc, bin, i, asIndex = false) {
  const a = doc.accessors[i], view = doc.bufferViews[a.bufferView];
  const Type = ARRAYS[a.componentType], comps = COMPONENTS[a.type];
  if (!Type || !comps) throw new Error(`scene.glb: accessor ${i} has an unsupported type ${a.componentType} ${a.type}`);
  const size = Type.BYTES_PER_ELEMENT, stride = view.byteStride || size * comps;
  const start = bin.byteOffset + (view.byteOffset || 0) + (a.byteOffset || 0);
  if ((view.byteOffset || 0) + (a.byteOffset || 0) + stride * (a.count - 1) + size * comps > bin.byteLength) {
    throw new Error(`scene.glb: accessor ${i} runs past the binary chunk`);
  }
  const dv = new DataView(bin.buffer), out = asIndex ? new Uint32Array(a.count * comps) : new Float32Array(a.count * comps);
  const get = {
    5120: (o) => dv.getInt8(o), 5121: (o) => dv.getUint8(o), 5122: (o) => dv.getInt16(o, true),
    5123: (o) => dv.getUint16(o, true), 5125: (o) => dv.getUint32(o, true), 5126: (o) => dv.getFloat32(o, true),
  }[a.componentType];
  const scale = !asIndex && a.normalized ? 1 / NORM[a.componentType] : 1;
  for (let e = 0; e < a.count; ++e) {
    for (let c = 0; c < comps; ++c) out[e * comps + c] = get(start + e * stride + c * size) * scale;
  }
  return { data: out, comps, count: a.count };
}

// Parse GLB bytes (ArrayBuffer) into { origin: [x, y, z] (world m), positions, normals, colors
// (RGB linear albedo, Float32Array 3 per vertex), emission (3 per vertex), indices (Uint32Array),
// triangles }.  Throws an Error naming the problem for anything else.
export function parseGlb(buffer) {
  const dv = new DataView(buffer);
  if (buffer.byteLength < 20 || dv.getUint32(0, true) !== 0x46546c67) throw new Error("scene.glb: not a binary glTF file (no 'glTF' magic)");
  if (dv.getUint32(4, true) !== 2) throw new Error(`scene.glb: glTF version ${dv.getUint32(4, true)}, expected 2`);
  let off = 12, doc = null, bin = null;
  while (off + 8 <= buffer.byteLength) {
    const len = dv.getUint32(off, true), type = dv.getUint32(off + 4, true);
    if (off + 8 + len > buffer.byteLength) throw new Error("scene.glb: a chunk runs past the end of the file");
    if (type === 0x4e4f534a) doc = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, off + 8, len)));
    else if (type === 0x004e4942) bin = new Uint8Array(buffer, off + 8, len);
    off += 8 + len;
  }
  if (!doc || !bin) throw new Error("scene.glb: JSON or BIN chunk missing");
  const node = (doc.nodes || []).find((n) => n.mesh !== undefined);
  if (!node) throw new Error("scene.glb: no node with a mesh");
  const origin = node.translation ? node.translation.slice(0, 3) : node.matrix ? node.matrix.slice(12, 15) : [0, 0, 0];
  const parts = [];
  for (const prim of doc.meshes[node.mesh].primitives) {
    if ((prim.mode ?? 4) !== 4) continue;  // triangles only
    const at = prim.attributes, pos = accessor(doc, bin, at.POSITION), n = pos.count;
    const vec3 = (name, fill) => {
      if (at[name] === undefined) return new Float32Array(3 * n).fill(fill);
      const a = accessor(doc, bin, at[name]), out = new Float32Array(3 * n);
      for (let v = 0; v < n; ++v) for (let c = 0; c < 3; ++c) out[3 * v + c] = a.data[v * a.comps + c];
      return out;
    };
    let idx;
    if (prim.indices !== undefined) idx = accessor(doc, bin, prim.indices, true).data;
    else idx = Uint32Array.from({ length: n }, (_, i) => i);
    for (const i of idx) if (i >= n) throw new Error("scene.glb: an index refers to a vertex that does not exist");
    parts.push({ positions: pos.data, normals: vec3("NORMAL", 0), colors: vec3("COLOR_0", 0.8), emission: vec3("_EMISSION", 0), indices: idx, n });
  }
  const V = parts.reduce((s, p) => s + p.n, 0), I = parts.reduce((s, p) => s + p.indices.length, 0);
  const mesh = { origin, positions: new Float32Array(3 * V), normals: new Float32Array(3 * V), colors: new Float32Array(3 * V),
                 emission: new Float32Array(3 * V), indices: new Uint32Array(I), triangles: I / 3 };
  let v0 = 0, i0 = 0;
  for (const p of parts) {
    for (const k of ["positions", "normals", "colors", "emission"]) mesh[k].set(p[k], 3 * v0);
    for (let i = 0; i < p.indices.length; ++i) mesh.indices[i0 + i] = p.indices[i] + v0;
    v0 += p.n; i0 += p.indices.length;
  }
  return mesh;
}

export async function loadGlb(url) {
  const r = await fetch(url);
  if (!r.ok) throw new Error(`${url}: HTTP ${r.status}`);
  return parseGlb(await r.arrayBuffer());
}
