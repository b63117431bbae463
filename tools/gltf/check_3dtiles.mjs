#!/usr/bin/env node
// Checks a 3D Tiles 1.1 tileset written by `terralod export --format 3dtiles`, independently of
// the exporter: every tile's glb content through the Khronos glTF-Validator (no errors, no
// warnings), the tree (refine REPLACE, geometricError shrinking strictly from parent to child,
// each child's region inside its parent's, content files present and every glb listed once).
//
// Usage: node check_3dtiles.mjs DIR     (DIR/tileset.json)
// Prints one JSON line {"tiles":N,"glb":N,"max_depth":D,"problems":[...]} and exits 1 when there
// is any problem, 2 on bad usage.
import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';

const require = createRequire(import.meta.url);
const validator = require('gltf-validator');

const args = process.argv.slice(2);
if (args.length !== 1 || args[0] === '--help' || args[0] === '-h') {
  console.log('usage: node check_3dtiles.mjs DIR   (checks DIR/tileset.json and every glb it lists)');
  process.exit(args.length === 1 ? 0 : 2);
}
const dir = args[0];
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
for (const uri of uris) {
  let bytes;
  try {
    bytes = fs.readFileSync(path.join(dir, uri));
  } catch (e) {
    problems.push(`${uri}: ${e.message}`);
    continue;
  }
  const report = await validator.validateBytes(new Uint8Array(bytes), { maxIssues: 20 });
  const { numErrors, numWarnings, messages } = report.issues;
  if (numErrors > 0 || numWarnings > 0)
    problems.push(`${uri}: ${numErrors} errors, ${numWarnings} warnings: ` +
      messages.slice(0, 3).map((m) => `${m.code} ${m.message} ${m.pointer ?? ''}`).join('; '));
  ++glb;
  if (glb % 100 === 0) process.stderr.write(`check_3dtiles: ${glb}/${uris.length} glb validated\n`);
}
console.log(JSON.stringify({ tiles, glb, max_depth: maxDepth, problems }));
process.exit(problems.length ? 1 : 0);
