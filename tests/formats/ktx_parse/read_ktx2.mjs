// Read KTX2 files with ktx-parse and print, per file, one JSON line: the header fields, the
// DFD, the key/value data, each level's byte length and SHA-256, and whether ktx-parse's own
// writer re-serializes the parsed container to the same bytes.  Usage: node read_ktx2.mjs FILE...
import { readFileSync } from "node:fs";
import { createHash } from "node:crypto";
import { read, write } from "./vendor/ktx-parse.mjs";   // ktx-parse 2.0.0 (MIT), vendored: no npm at test time

const sha = (bytes) => createHash("sha256").update(bytes).digest("hex");
for (const path of process.argv.slice(2)) {
  const bytes = new Uint8Array(readFileSync(path));
  const c = read(bytes);
  const kv = {};
  for (const [k, v] of Object.entries(c.keyValue)) kv[k] = typeof v === "string" ? v : Array.from(v);
  const again = write(c, { keepWriter: true });
  console.log(JSON.stringify({
    path, vkFormat: c.vkFormat, typeSize: c.typeSize, pixelWidth: c.pixelWidth, pixelHeight: c.pixelHeight,
    pixelDepth: c.pixelDepth, layerCount: c.layerCount, faceCount: c.faceCount, levelCount: c.levels.length,
    supercompressionScheme: c.supercompressionScheme, dfd: c.dataFormatDescriptor, keyValue: kv,
    levels: c.levels.map((l) => ({ byteLength: l.levelData.byteLength, uncompressed: l.uncompressedByteLength, sha256: sha(l.levelData) })),
    rewriteIdentical: again.length === bytes.length && again.every((b, i) => b === bytes[i]),
    rewriteLength: again.length, length: bytes.length,
  }));
}
