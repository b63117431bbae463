#!/usr/bin/env node
// Checks a 3D Tiles 1.1 tileset written by `terralod export --format 3dtiles`, independently of
// the exporter: every tile's glb content through the Khronos glTF-Validator (no errors, no
// warnings), the tree (refine REPLACE, geometricError shrinking strictly from parent to child,
// each child's region inside its parent's, content files present and every glb listed once).
// The validator cannot look inside EXT_meshopt_compression, so a compressed glb is also decoded
// here (meshoptimizer's own decoder) into the uncompressed glb it stands for, which is validated
// in full (accessor bounds, index ranges).
//
// Usage: node check_3dtiles.mjs DIR [--same-as DIR2]     (DIR/tileset.json)
//   --same-as DIR2: every glb's content as decoded must equal DIR2's glb of the same name: vertex
//   data byte for byte, and the same triangles in the same order with the same winding (the meshopt
//   index codec may start a triangle at another of its corners). A compressed export against an
//   uncompressed one: the compression is lossless.
// Prints one JSON line {"tiles":N,"glb":N,"meshopt":N,"max_depth":D,"problems":[...]} and exits 1
// when there is any problem, 2 on bad usage.
import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';
import { MeshoptDecoder } from 'meshoptimizer';

const require = createRequire(import.meta.url);
const validator = require('gltf-validator');

const args = process.argv.slice(2);
const usage = 'usage: node check_3dtiles.mjs DIR [--same-as DIR2]   (checks DIR/tileset.json and every glb it lists)';
if (args[0] === '--help' || args[0] === '-h') {
  console.log(usage);
  process.exit(0);
}
if (!(args.length === 1 || (args.length === 3 && args[1] === '--same-as'))) {
  console.error(usage);
  process.exit(2);
}
const dir = args[0];
const sameAs = args.length === 3 ? args[2] : null;
await MeshoptDecoder.ready;

// GLB: {json, bin} of a binary glTF (bin null when there is no BIN chunk).
function readGlb(bytes) {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  if (bytes.byteLength < 20 || view.getUint32(0, true) !== 0x46546c67) throw new Error('not a glb');
  const jsonLength = view.getUint32(12, true);
  const json = JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + jsonLength)));
  const at = 20 + jsonLength;
  const bin = at + 8 <= bytes.byteLength ? bytes.subarray(at + 8, at + 8 + view.getUint32(at, true)) : null;
  return { json, bin };
}
function writeGlb(json, bin) {
  let text = Buffer.from(JSON.stringify(json));
  text = Buffer.concat([text, Buffer.alloc((4 - (text.length % 4)) % 4, 0x20)]);
  const data = Buffer.concat([Buffer.from(bin), Buffer.alloc((4 - (bin.length % 4)) % 4)]);
  const head = Buffer.alloc(20);
  head.writeUInt32LE(0x46546c67, 0), head.writeUInt32LE(2, 4);
  head.writeUInt32LE(12 + 8 + text.length + 8 + data.length, 8);
  head.writeUInt32LE(text.length, 12), head.writeUInt32LE(0x4e4f534a, 16);
  const binHead = Buffer.alloc(8);
  binHead.writeUInt32LE(data.length, 0), binHead.writeUInt32LE(0x004e4942, 4);
  return new Uint8Array(Buffer.concat([head, text, binHead, data]));
}
// The uncompressed glb an EXT_meshopt_compression glb stands for: each compressed view decoded
// into its fallback buffer, which becomes the only buffer. {bytes, bin}; throws on a malformed file.
function decodeMeshopt(bytes) {
  const { json, bin } = readGlb(bytes);
  const E = 'EXT_meshopt_compression';
  if (json.buffers.length !== 2 || !json.buffers[1].extensions?.[E]?.fallback)
    throw new Error('EXT_meshopt_compression without the fallback buffer 1');
  const out = new Uint8Array(json.buffers[1].byteLength);
  for (const v of json.bufferViews) {
    const m = v.extensions?.[E];
    if (!m || m.buffer !== 0 || v.buffer !== 1) throw new Error('a buffer view is not meshopt-compressed');
    const source = bin.subarray(m.byteOffset, m.byteOffset + m.byteLength);
    const target = new Uint8Array(m.count * m.byteStride);
    MeshoptDecoder.decodeGltfBuffer(target, m.count, m.byteStride, source, m.mode, m.filter);
    if (target.length !== v.byteLength) throw new Error(`a view decodes to ${target.length} bytes, not ${v.byteLength}`);
    out.set(target, v.byteOffset ?? 0);
    delete v.extensions;
    v.buffer = 0;
  }
  json.buffers = [{ byteLength: out.length }];
  json.extensionsUsed = json.extensionsUsed.filter((e) => e !== E);
  json.extensionsRequired = json.extensionsRequired.filter((e) => e !== E);
  return { bytes: writeGlb(json, out), json, bin: out };
}
const sameBytes = (a, b) => a.length === b.length && Buffer.compare(Buffer.from(a), Buffer.from(b)) === 0;
// Why two uncompressed glTF {json, bin} differ ('' when they draw the same): accessor by accessor.
function contentDifference(a, b) {
  if (a.json.accessors.length !== b.json.accessors.length) return 'a different number of accessors';
  for (let k = 0; k < a.json.accessors.length; ++k) {
    const [x, y] = [a.json.accessors[k], b.json.accessors[k]];
    if (x.count !== y.count || x.componentType !== y.componentType || x.type !== y.type)
      return `accessor ${k} differs in count or type`;
    const slice = (g, acc) => {
      const v = g.json.bufferViews[acc.bufferView];
      return g.bin.subarray((v.byteOffset ?? 0) + (acc.byteOffset ?? 0), (v.byteOffset ?? 0) + v.byteLength);
    };
    const [p, q] = [slice(a, x), slice(b, y)];
    if (x.type !== 'SCALAR') {
      if (!sameBytes(p, q)) return `accessor ${k} (${x.type}) differs`;
      continue;
    }
    const wide = x.componentType === 5125;
    const read = (bytes, i) => (wide ? Buffer.from(bytes).readUInt32LE(4 * i) : Buffer.from(bytes).readUInt16LE(2 * i));
    for (let t = 0; t + 2 < x.count; t += 3) {
      const s = [read(p, t), read(p, t + 1), read(p, t + 2)];
      const o = [read(q, t), read(q, t + 1), read(q, t + 2)];
      const same = [0, 1, 2].some((r) => s[0] === o[r] && s[1] === o[(r + 1) % 3] && s[2] === o[(r + 2) % 3]);
      if (!same) return `triangle ${t / 3} is ${s} here, ${o} there`;
    }
  }
  return '';
}
const problems = [];
let tileset;
try {
  tileset = JSON.parse(fs.readFileSync(path.join(dir, 'tileset.json'), 'utf8'));
} catch (e) {
  console.log(JSON.stringify({ problems: [`${dir}/tileset.json: ${e.message}`] }));
  process.exit(1);
}
if (tileset.asset?.version !== '1.1') problems.push(`asset.version is ${tileset.asset?.version}, not 1.1`);

const uris = [];
let tiles = 0;
let maxDepth = 0;
const inside = (c, p) =>
  c[0] >= p[0] - 1e-12 && c[2] <= p[2] + 1e-12 && c[1] >= p[1] - 1e-12 && c[3] <= p[3] + 1e-12;
function walk(tile, parent, depth, where) {
  ++tiles;
  maxDepth = Math.max(maxDepth, depth);
  const region = tile.boundingVolume?.region;
  if (!Array.isArray(region) || region.length !== 6) problems.push(`${where}: no region`);
  else if (!(region[4] <= region[5])) problems.push(`${where}: region heights ${region[4]} > ${region[5]}`);
  if (!(tile.geometricError >= 0)) problems.push(`${where}: geometricError ${tile.geometricError}`);
  if (parent) {
    if (!(tile.geometricError < parent.geometricError))
      problems.push(`${where}: geometricError ${tile.geometricError} not below its parent's ${parent.geometricError}`);
    if (region && parent.boundingVolume?.region && !inside(region, parent.boundingVolume.region))
      problems.push(`${where}: region outside its parent's`);
  }
  if (tile.refine !== undefined && tile.refine !== 'REPLACE') problems.push(`${where}: refine ${tile.refine}`);
  if (tile.content?.uri) uris.push(tile.content.uri);
  (tile.children ?? []).forEach((c, i) => walk(c, tile, depth + 1, `${where}.children[${i}]`));
}
walk(tileset.root, null, 0, 'root');
if (!(tileset.geometricError > tileset.root.geometricError))
  problems.push(`tileset geometricError ${tileset.geometricError} not above the root's`);

// Every glb under DIR is listed exactly once.
const onDisk = [];
(function list(d, rel) {
  for (const e of fs.readdirSync(d, { withFileTypes: true })) {
    if (e.isDirectory()) list(path.join(d, e.name), rel ? `${rel}/${e.name}` : e.name);
    else if (e.name.endsWith('.glb')) onDisk.push(rel ? `${rel}/${e.name}` : e.name);
  }
})(dir, '');
const listed = new Set(uris);
if (listed.size !== uris.length) problems.push('a content uri is listed twice');
for (const f of onDisk) if (!listed.has(f)) problems.push(`${f} is on disk but not in tileset.json`);

let glb = 0;
let meshopt = 0;
for (const uri of uris) {
  let bytes;
  try {
    bytes = fs.readFileSync(path.join(dir, uri));
  } catch (e) {
    problems.push(`${uri}: ${e.message}`);
    continue;
  }
  const validate = async (b, what) => {
    const report = await validator.validateBytes(b, { maxIssues: 20 });
    const { numErrors, numWarnings, messages } = report.issues;
    if (numErrors > 0 || numWarnings > 0)
      problems.push(`${uri}${what}: ${numErrors} errors, ${numWarnings} warnings: ` +
        messages.slice(0, 3).map((m) => `${m.code} ${m.message} ${m.pointer ?? ''}`).join('; '));
  };
  await validate(new Uint8Array(bytes), '');
  let content = null;  // {json, bin} as a client draws it
  try {
    content = readGlb(bytes);
    if ((content.json.extensionsUsed ?? []).includes('EXT_meshopt_compression')) {
      const decoded = decodeMeshopt(bytes);
      await validate(decoded.bytes, ' (decoded from EXT_meshopt_compression)');
      content = decoded;
      ++meshopt;
    }
  } catch (e) {
    problems.push(`${uri}: ${e.message}`);
  }
  if (sameAs && content) {
    try {
      const why = contentDifference(content, readGlb(fs.readFileSync(path.join(sameAs, uri))));
      if (why) problems.push(`${uri}: differs from ${path.join(sameAs, uri)}: ${why}`);
    } catch (e) {
      problems.push(`${uri}: ${e.message}`);
    }
  }
  ++glb;
  if (glb % 100 === 0) process.stderr.write(`check_3dtiles: ${glb}/${uris.length} glb validated\n`);
}
// The first 20 problems (a broken export would otherwise print one line per tile).
console.log(JSON.stringify({ tiles, glb, meshopt, max_depth: maxDepth, problem_count: problems.length,
                             problems: problems.slice(0, 20) }));
process.exit(problems.length ? 1 : 0);
