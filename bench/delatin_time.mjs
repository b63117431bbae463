// Times delatin (github.com/mapbox/delatin, greedy insertion) on an SRTM .hgt tile, so that
// terralod-bench-pm can compare its build time with delatin's measured in the same run, on the
// same machine, instead of with a number measured elsewhere. delatin is not part of terralod:
// pass the path of its index.js (an ES module).
//
// usage: node delatin_time.mjs DELATIN_INDEX_JS TILE.hgt MAX_ERROR [CROP]
// prints one line of JSON: {"width":W,"height":H,"max_error":E,"triangles":T,"ms":M}
// (CROP > 0: the top-left CROP x CROP samples only). Exit status 1 with a message naming the
// file on any error.
import fs from 'node:fs';
import path from 'node:path';
import {pathToFileURL} from 'node:url';

function fail(message) {
    process.stderr.write(`delatin_time: ${message}\n`);
    process.exit(1);
}

const [indexJs, tile, maxErrorText, cropText] = process.argv.slice(2);
if (!indexJs || !tile || !maxErrorText) fail('usage: node delatin_time.mjs DELATIN_INDEX_JS TILE.hgt MAX_ERROR [CROP]');
const maxError = Number(maxErrorText);
if (!(maxError >= 0)) fail(`max error '${maxErrorText}' is not a number >= 0`);

let Delatin;
try {
    Delatin = (await import(pathToFileURL(path.resolve(indexJs)).href)).default;
} catch (e) {
    fail(`${indexJs}: cannot import delatin (${e.message})`);
}
if (typeof Delatin !== 'function') fail(`${indexJs}: has no default export (expected delatin's class)`);

let bytes;
try {
    bytes = fs.readFileSync(tile);
} catch (e) {
    fail(`${tile}: ${e.message}`);
}
const side = Math.round(Math.sqrt(bytes.length / 2));
if (side < 2 || side * side * 2 !== bytes.length) fail(`${tile}: ${bytes.length} bytes is not a square grid of 16-bit samples`);
const crop = cropText ? Number(cropText) : 0;
const n = crop > 0 ? Math.min(crop, side) : side;

// Big-endian signed 16-bit heights, as terralod reads them (the tile has no voids).
const data = new Float64Array(n * n);
for (let y = 0; y < n; y++)
    for (let x = 0; x < n; x++) data[y * n + x] = bytes.readInt16BE(2 * (y * side + x));

const start = process.hrtime.bigint();
const mesh = new Delatin(data, n, n);
mesh.run(maxError);
const ms = Number(process.hrtime.bigint() - start) / 1e6;
process.stdout.write(JSON.stringify({width: n, height: n, max_error: maxError, triangles: mesh.triangles.length / 3, ms}) + '\n');
