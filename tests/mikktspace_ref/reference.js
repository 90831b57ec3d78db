// Reference MikkTSpace tangents for tests/tangents_test.cpp.
//
// The npm package `mikktspace` is a WebAssembly build of the reference
// algorithm (gltf-rs/mikktspace, a port of Mikkelsen's mikktspace.c, run with
// the default 180 degree angular threshold). Its generateTangents() takes
// unindexed triangles: position and normal Float32Arrays with 3 floats per
// corner, texcoord with 2, and returns 4 floats per corner (xyz, sign).
//
// Usage: node reference.js IN OUT
//   IN  (little endian): records of  uint32 corner_count,
//       float32 position[3 * n], float32 normal[3 * n], float32 texcoord[2 * n]
//   OUT (little endian): records of  uint32 corner_count, float32 tangent[4 * n]
'use strict';

const fs = require('fs');
const { generateTangents } = require('mikktspace');

function fail(message) {
  process.stderr.write(`reference.js: ${message}\n`);
  process.exit(1);
}

if (process.argv.length !== 4) fail('usage: node reference.js IN OUT');
const input = fs.readFileSync(process.argv[2]);
const view = new DataView(input.buffer, input.byteOffset, input.byteLength);

function read_floats(offset, count) {
  const out = new Float32Array(count);
  for (let i = 0; i < count; ++i) out[i] = view.getFloat32(offset + 4 * i, true);
  return out;
}

const chunks = [];
let offset = 0;
while (offset < input.byteLength) {
  if (offset + 4 > input.byteLength) fail(`truncated record header at byte ${offset}`);
  const corner_count = view.getUint32(offset, true);
  offset += 4;
  if (corner_count % 3 !== 0) fail(`corner count ${corner_count} is not a multiple of 3`);
  const bytes = corner_count * (3 + 3 + 2) * 4;
  if (offset + bytes > input.byteLength) fail(`truncated record at byte ${offset}`);
  const position = read_floats(offset, 3 * corner_count);
  offset += 12 * corner_count;
  const normal = read_floats(offset, 3 * corner_count);
  offset += 12 * corner_count;
  const texcoord = read_floats(offset, 2 * corner_count);
  offset += 8 * corner_count;

  const tangent = corner_count > 0 ? generateTangents(position, normal, texcoord) : new Float32Array(0);
  // An empty result is how the package reports that the reference failed.
  if (tangent.length !== 4 * corner_count)
    fail(`reference returned ${tangent.length} floats for ${corner_count} corners`);

  const out = Buffer.alloc(4 + 16 * corner_count);
  out.writeUInt32LE(corner_count, 0);
  for (let i = 0; i < tangent.length; ++i) out.writeFloatLE(tangent[i], 4 + 4 * i);
  chunks.push(out);
}
fs.writeFileSync(process.argv[3], Buffer.concat(chunks));
