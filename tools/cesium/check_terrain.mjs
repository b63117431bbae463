#!/usr/bin/env node
// A real CesiumJS client for a quantized-mesh terrain tileset: serves the tileset and CesiumJS
// from a local HTTP server on 127.0.0.1, opens it in headless Chromium through
// Cesium.CesiumTerrainProvider, waits until the globe's tiles are loaded, saves a screenshot and
// samples heights with Cesium.sampleTerrainMostDetailed. With --3dtiles it does the same for a
// 3D Tiles 1.1 tileset (tileset.json and glb tiles) through Cesium.Cesium3DTileset, with heights
// from Scene.sampleHeightMostDetailed. Run with --help for the arguments.
//
// Nothing but 127.0.0.1 is reached: no Cesium ion (no default imagery, no geocoder), every other
// request of the page is aborted and reported, and Chromium resolves no other host name.
// Any failure (bad arguments, server, browser, page error, console error, failed or refused
// request, timeout) exits with status 1 and a message on stderr saying what failed; the result
// JSON is still written when --out was given (with "ok": false and "failures").
import fs from 'node:fs';
import http from 'node:http';
import path from 'node:path';
import process from 'node:process';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
const started = Date.now();

const HELP = `Usage: node check_terrain.mjs --tiles DIR --out RESULT.json [options]

Loads a quantized-mesh terrain tileset (or, with --3dtiles, a 3D Tiles tileset) in CesiumJS
(headless Chromium) and reports what the client sees: whether the tiles loaded, a screenshot, and
heights at given points.

  --tiles DIR          the tileset: DIR/layer.json and DIR/z/x/y.terrain (gzip on disk, served with
                       Content-Encoding: gzip and Content-Type application/vnd.quantized-mesh)
  --3dtiles            DIR is a 3D Tiles tileset instead: DIR/tileset.json and its glb contents
                       (served as model/gltf-binary), loaded with Cesium.Cesium3DTileset.fromUrl
                       over a hidden globe; heights from Scene.sampleHeightMostDetailed, "levels"
                       the deepest level (z of the content's z/x/y.glb) served over each point
  --sse PIXELS         with --3dtiles: the tileset's maximumScreenSpaceError (default 2)
  --out FILE           result JSON: {"ok", "tiles_loaded", "heights": [m | null, ...], "levels":
                       [deepest available level at each point], "failures": [...], ...}
  --points FILE        JSON array of {"lon": deg, "lat": deg}; their heights are sampled with
                       Cesium.sampleTerrainMostDetailed (default: no points)
  --screenshot FILE    PNG of the view once the tiles are loaded (default: none)
  --view W,S,E,N       degrees: the camera frames this rectangle, looking north and obliquely down
                       (default: layer.json's bounds; with --3dtiles, the regions of the deepest
                       tiles with content)
  --pitch DEG          camera pitch, negative is down (default -35)
  --size WxH           viewport in pixels (default 1024x640)
  --imagery KIND       grid (Cesium.GridImageryProvider, drawn locally) or none (the globe's base
                       colour only) (default grid)
  --timeout SECONDS    for everything, start to end (default 120)
  --chromium PATH      the browser (default $CHROMIUM or /usr/bin/chromium)
  --help               this text

Terrain is lit by one fixed directional light (from the north-west, 40 degrees up) with the
tiles' vertex normals (requestVertexNormals), so relief shows whatever the date.
Progress goes to stderr. Exit status: 0 when everything worked, 1 on any failure, 2 on bad usage.`;

// --- arguments --------------------------------------------------------------------------------

function usage(message) {
  process.stderr.write(`check_terrain: ${message}\n(run with --help for the arguments)\n`);
  process.exit(2);
}

function parseArgs(argv) {
  const known = new Set(['--tiles', '--out', '--points', '--screenshot', '--view', '--pitch', '--size',
    '--imagery', '--timeout', '--chromium', '--sse']);
  const a = {};
  let tiles3d = false;
  for (let i = 0; i < argv.length; ++i) {
    const k = argv[i];
    if (k === '--help' || k === '-h') {
      process.stdout.write(HELP + '\n');
      process.exit(0);
    }
    if (k === '--3dtiles') {
      tiles3d = true;
      continue;
    }
    if (!known.has(k)) usage(`unknown argument '${k}'`);
    if (i + 1 >= argv.length) usage(`${k} needs a value`);
    a[k.slice(2)] = argv[++i];
  }
  if (!a.tiles) usage('--tiles DIR is required');
  if (!a.out) usage('--out FILE is required');
  const number = (name, fallback) => {
    if (a[name] === undefined) return fallback;
    const v = Number(a[name]);
    if (!Number.isFinite(v)) usage(`--${name} must be a number, not '${a[name]}'`);
    return v;
  };
  const opt = {
    tiles: path.resolve(a.tiles),
    out: path.resolve(a.out),
    points: a.points ? path.resolve(a.points) : null,
    screenshot: a.screenshot ? path.resolve(a.screenshot) : null,
    view: null,
    pitch: number('pitch', -35),
    timeout: number('timeout', 120),
    tiles3d,
    sse: number('sse', 2),
    imagery: a.imagery ?? 'grid',
    chromium: a.chromium ?? process.env.CHROMIUM ?? '/usr/bin/chromium',
    width: 1024,
    height: 640,
  };
  if (a.view !== undefined) {
    const v = a.view.split(',').map(Number);
    if (v.length !== 4 || !v.every(Number.isFinite) || !(v[0] < v[2]) || !(v[1] < v[3]) || v[1] < -90 ||
        v[3] > 90)
      usage(`--view must be W,S,E,N in degrees with W < E and S < N, not '${a.view}'`);
    opt.view = v;
  }
  if (a.size !== undefined) {
    const m = /^(\d+)x(\d+)$/.exec(a.size);
    if (!m || +m[1] < 16 || +m[2] < 16 || +m[1] > 8192 || +m[2] > 8192)
      usage(`--size must be WxH (16 .. 8192 each), not '${a.size}'`);
    opt.width = +m[1];
    opt.height = +m[2];
  }
  if (!(opt.timeout > 0)) usage('--timeout must be > 0');
  if (!(opt.sse > 0)) usage('--sse must be > 0');
  if (a.sse !== undefined && !tiles3d) usage('--sse is for --3dtiles only');
  if (!(opt.pitch < 0 && opt.pitch >= -90)) usage('--pitch must be in [-90, 0)');
  if (opt.imagery !== 'grid' && opt.imagery !== 'none')
    usage(`--imagery must be grid or none, not '${opt.imagery}'`);
  return opt;
}

const opt = parseArgs(process.argv.slice(2));

function log(message) {
  process.stderr.write(`check_terrain [${((Date.now() - started) / 1000).toFixed(1)} s]: ${message}\n`);
}

// --- the result, written on every exit path ----------------------------------------------------

const result = {
  ok: false,
  tiles_loaded: false,
  heights: [],
  levels: [],
  failures: [],
  console_warnings: [],
  requests: { terrain: {}, terrain_bytes: 0, glb: {}, glb_bytes: 0, not_found: [], blocked: [] },
};
let browser = null;
let server = null;
let layerJson = null;  // the tileset's layer.json, once read
const servedGlb = new Set();  // with --3dtiles: the glb contents served, as "z/x/y.glb"
let finished = false;

function fail(message) {
  if (!result.failures.includes(message)) result.failures.push(message);
}

async function finish() {
  if (finished) return;
  finished = true;
  result.elapsed_s = (Date.now() - started) / 1000;
  result.ok = result.failures.length === 0;
  try {
    if (browser) await Promise.race([browser.close(), new Promise((r) => setTimeout(r, 5000))]);
  } catch { /* the browser may already be gone */ }
  try {
    browser?.process()?.kill('SIGKILL');
  } catch { /* already exited */ }
  server?.close();
  server?.closeAllConnections?.();
  try {
    fs.mkdirSync(path.dirname(opt.out), { recursive: true });
    fs.writeFileSync(opt.out, JSON.stringify(result, null, 2) + '\n');
  } catch (e) {
    result.ok = false;
    process.stderr.write(`check_terrain: FAILED: cannot write ${opt.out}: ${e.message}\n`);
  }
  if (result.ok) {
    log(`done: ${result.heights.length} heights, result in ${opt.out}`);
    process.exit(0);
  }
  for (const f of result.failures) process.stderr.write(`check_terrain: FAILED: ${f}\n`);
  if (result.failures.some((f) => f.includes('addAvailableTileRange')) && layerJson &&
      layerJson.metadataAvailability === undefined)
    process.stderr.write('check_terrain: the tiles carry the metadata extension but layer.json has no ' +
                         '"metadataAvailability": CesiumJS then fails on every such tile (tools/cesium/README.md)\n');
  process.exit(1);
}

const watchdog = setTimeout(() => {
  fail(`timeout: not finished after ${opt.timeout} s (--timeout)`);
  finish();
}, opt.timeout * 1000);

// --- inputs --------------------------------------------------------------------------------------

/// The tiles of a 3D Tiles tileset.json with content: {uri, level (z of z/x/y.glb, else the depth
/// in the tree), region (radians and metres) or null}.
function contentTiles(tileset) {
  const tiles = [];
  const walk = (tile, depth) => {
    const uri = tile.content?.uri ?? tile.content?.url;
    if (uri) {
      const m = /^(\d+)\/\d+\/\d+\.glb$/.exec(uri);
      const r = tile.boundingVolume?.region;
      tiles.push({ uri, level: m ? Number(m[1]) : depth,
                   region: Array.isArray(r) && r.length === 6 && r.every(Number.isFinite) ? r : null });
    }
    for (const c of tile.children ?? []) walk(c, depth + 1);
  };
  if (!tileset?.root) throw new Error('tileset.json has no "root"');
  walk(tileset.root, 0);
  return tiles;
}

function readTileset() {
  const tilesetPath = path.join(opt.tiles, 'tileset.json');
  let tileset;
  try {
    tileset = JSON.parse(fs.readFileSync(tilesetPath, 'utf8'));
  } catch (e) {
    throw new Error(`cannot read the tileset's ${tilesetPath}: ${e.message}`);
  }
  const tiles = contentTiles(tileset);
  if (!tiles.length) throw new Error(`${tilesetPath}: no tile has content`);
  const deepest = Math.max(...tiles.map((t) => t.level));
  // The deepest tiles' regions, in degrees, and their heights: the default view and its height.
  const d = 180 / Math.PI;
  const box = [Infinity, Infinity, -Infinity, -Infinity, Infinity, -Infinity];
  for (const t of tiles) {
    if (t.level !== deepest || !t.region) continue;
    const [w, s, e, n, lo, hi] = t.region;
    box[0] = Math.min(box[0], w * d);
    box[1] = Math.min(box[1], s * d);
    box[2] = Math.max(box[2], e * d);
    box[3] = Math.max(box[3], n * d);
    box[4] = Math.min(box[4], lo);
    box[5] = Math.max(box[5], hi);
  }
  return { tileset, tiles, deepest, bounds: box.slice(0, 4).every(Number.isFinite) ? box.slice(0, 4) : null,
           heights: box.slice(4) };
}

function readInputs() {
  let layer = null;
  let tiles3d = null;
  if (opt.tiles3d) {
    tiles3d = readTileset();
  } else {
    const layerPath = path.join(opt.tiles, 'layer.json');
    try {
      layer = JSON.parse(fs.readFileSync(layerPath, 'utf8'));
    } catch (e) {
      throw new Error(`cannot read the tileset's ${layerPath}: ${e.message}`);
    }
  }
  let points = [];
  if (opt.points) {
    try {
      points = JSON.parse(fs.readFileSync(opt.points, 'utf8'));
    } catch (e) {
      throw new Error(`cannot read --points ${opt.points}: ${e.message}`);
    }
    if (!Array.isArray(points)) throw new Error(`--points ${opt.points}: not a JSON array`);
    points.forEach((p, i) => {
      if (!p || !Number.isFinite(p.lon) || !Number.isFinite(p.lat) || Math.abs(p.lat) > 90)
        throw new Error(`--points ${opt.points}: entry ${i} is not {"lon": deg, "lat": deg}`);
    });
  }
  let view = opt.view;
  if (!view && tiles3d) {
    if (!tiles3d.bounds) throw new Error('no --view given and the deepest tiles of tileset.json have no regions');
    view = tiles3d.bounds;
  } else if (!view) {
    const b = layer.bounds;
    if (!Array.isArray(b) || b.length !== 4 || !b.every(Number.isFinite))
      throw new Error('no --view given and layer.json has no usable "bounds"');
    view = b;
  }
  return { layer, tiles3d, points, view };
}

// --- the HTTP server -----------------------------------------------------------------------------

const cesiumDir = path.join(here, 'node_modules', 'cesium', 'Build', 'Cesium');

const PAGE = `<!doctype html>
<html><head><meta charset="utf-8"><title>terralod terrain check</title>
<script>window.CESIUM_BASE_URL = '/cesium/';</script>
<script src="/cesium/Cesium.js"></script>
<link rel="stylesheet" href="/cesium/Widgets/widgets.css">
<style>
  html, body, #container { margin: 0; padding: 0; width: 100%; height: 100%; overflow: hidden; background: #000; }
</style>
</head><body><div id="container"></div><div id="credits" style="display: none"></div></body></html>
`;

const MIME = {
  '.js': 'text/javascript', '.mjs': 'text/javascript', '.css': 'text/css', '.json': 'application/json',
  '.html': 'text/html', '.png': 'image/png', '.jpg': 'image/jpeg', '.jpeg': 'image/jpeg', '.gif': 'image/gif',
  '.svg': 'image/svg+xml', '.wasm': 'application/wasm', '.ktx2': 'image/ktx2', '.glb': 'model/gltf-binary',
  '.xml': 'application/xml', '.woff': 'font/woff', '.woff2': 'font/woff2', '.ttf': 'font/ttf',
};

/// `rel` (URL path below a prefix) as a file below `root`, or null when it would leave it.
function fileBelow(root, rel) {
  let decoded;
  try {
    decoded = decodeURIComponent(rel);
  } catch {
    return null;
  }
  const p = path.resolve(root, '.' + path.posix.normalize('/' + decoded));
  return p === root || p.startsWith(root + path.sep) ? p : null;
}

function startServer() {
  return new Promise((resolve, reject) => {
    const s = http.createServer((req, res) => {
      const url = new URL(req.url, 'http://127.0.0.1');
      const p = url.pathname;
      const send = (status, headers, body) => {
        res.writeHead(status, headers);
        res.end(body);
      };
      const notFound = (what) => {
        result.requests.not_found.push(p);
        fail(`HTTP 404 for ${p}${what ? ` (${what})` : ''}`);
        send(404, { 'Content-Type': 'text/plain' }, 'not found\n');
      };
      if (req.method !== 'GET' && req.method !== 'HEAD') return send(405, {}, '');
      if (p === '/' || p === '/index.html') return send(200, { 'Content-Type': 'text/html' }, PAGE);
      if (p === '/favicon.ico') return send(204, {}, '');
      let file = null;
      let headers = {};
      const terrain = opt.tiles3d ? null : /^\/tiles\/(\d+)\/(\d+)\/(\d+)\.terrain$/.exec(p);
      const glb = opt.tiles3d ? /^\/tiles\/((\d+)\/\d+\/\d+\.glb)$/.exec(p) : null;
      if (terrain) {
        file = fileBelow(opt.tiles, p.slice('/tiles'.length));
        headers = { 'Content-Type': 'application/vnd.quantized-mesh', 'Content-Encoding': 'gzip' };
      } else if (p.startsWith('/tiles/')) {
        file = fileBelow(opt.tiles, p.slice('/tiles'.length));
      } else if (p.startsWith('/cesium/')) {
        file = fileBelow(cesiumDir, p.slice('/cesium'.length));
      }
      if (!file) return notFound();
      fs.readFile(file, (err, data) => {
        if (err) {
          return notFound(terrain ? 'a tile that layer.json says is available'
                                  : glb ? 'a tile content that tileset.json lists' : '');
        }
        if (terrain) {
          const z = terrain[1];
          result.requests.terrain[z] = (result.requests.terrain[z] ?? 0) + 1;
          result.requests.terrain_bytes += data.length;
          if (data.length < 2 || data[0] !== 0x1f || data[1] !== 0x8b) {
            fail(`${p}: not gzip on disk (the tileset must hold gzipped .terrain files)`);
            headers = { 'Content-Type': 'application/vnd.quantized-mesh' };
          }
        } else {
          headers['Content-Type'] = MIME[path.extname(file).toLowerCase()] ?? 'application/octet-stream';
          if (glb) {
            result.requests.glb[glb[2]] = (result.requests.glb[glb[2]] ?? 0) + 1;
            result.requests.glb_bytes += data.length;
            servedGlb.add(glb[1]);
          }
        }
        headers['Cache-Control'] = 'no-store';
        send(200, headers, req.method === 'HEAD' ? undefined : data);
      });
    });
    s.on('error', reject);
    s.listen(0, '127.0.0.1', () => resolve(s));
  });
}

// --- the page's work (runs in the browser; `cfg` is plain data) ----------------------------------

// Quantized-mesh terrain (cfg.tiles3d false): a CesiumTerrainProvider on the globe. 3D Tiles
// (cfg.tiles3d true): a Cesium3DTileset and no globe at all, so that every height picked comes from
// the tileset.
async function setUpAndWait(cfg) {
  const C = window.Cesium;
  const say = (m) => window.checkProgress(m);
  const failures = (window.checkFailures = []);  // read again after sampling
  let provider = null;
  let tileset = null;
  if (!cfg.tiles3d) {
    provider = await C.CesiumTerrainProvider.fromUrl('/tiles/', {
      requestVertexNormals: true,
      requestMetadata: true,
    });
    provider.errorEvent.addEventListener((e) => failures.push(`terrain provider: ${e.message}`));
    say(`CesiumJS ${C.VERSION}: terrain provider ready (normals: ${provider.hasVertexNormals}, ` +
        `metadata: ${provider.hasMetadata})`);
  }

  const baseLayer = cfg.imagery === 'grid' && !cfg.tiles3d
    ? new C.ImageryLayer(new C.GridImageryProvider({
      cells: 4,
      color: C.Color.fromCssColorString('#f4f1e8').withAlpha(0.55),
      glowColor: C.Color.TRANSPARENT,
      glowWidth: 0,
      backgroundColor: C.Color.fromCssColorString('#9c9478'),
    }))
    : false;
  const widget = new C.CesiumWidget('container', {
    ...(cfg.tiles3d ? { globe: false } : { terrainProvider: provider }),
    baseLayer,
    skyBox: false,
    skyAtmosphere: false,
    creditContainer: 'credits',
    showRenderLoopErrors: false,
    requestRenderMode: false,
    msaaSamples: 1,
    contextOptions: { webgl: { preserveDrawingBuffer: true, alpha: false } },
  });
  window.checkWidget = widget;
  window.checkProvider = provider;
  const scene = widget.scene;
  const globe = scene.globe;  // undefined with 3D Tiles
  scene.renderError.addEventListener((_s, e) => failures.push(`render error: ${e?.message ?? e}`));
  if (globe) {
    globe.baseColor = C.Color.fromCssColorString('#9c9478');
    globe.showGroundAtmosphere = false;
    globe.enableLighting = true;
    globe.dynamicAtmosphereLighting = false;
    // Software WebGL draws a few frames a second, and CesiumJS spends at most 5 ms of each frame on
    // tile loading (QuadtreePrimitive._loadQueueTimeSlice, private): give it more, so that loading
    // is not paced by the frame rate. Unknown to other versions: then it is left as it is.
    if (typeof globe._surface?._loadQueueTimeSlice === 'number')
      globe._surface._loadQueueTimeSlice = cfg.loadSliceMs;
  }
  if (cfg.tiles3d) {
    // Made after the widget: a tileset's models size their environment map from the WebGL
    // context's limits, which are unknown (0) before the first context exists.
    tileset = await C.Cesium3DTileset.fromUrl('/tiles/tileset.json', {
      maximumScreenSpaceError: cfg.sse,
      // No shortcut in the refinement: what is drawn and picked is what the tree says.
      skipLevelOfDetail: false,
      foveatedScreenSpaceError: false,
      dynamicScreenSpaceError: false,
      // No sky to reflect, and costly in software WebGL.
      environmentMapOptions: { enabled: false },
    });
    tileset.tileFailed.addEventListener((e) => failures.push(`tile failed: ${e.url}: ${e.message}`));
    // The tiles have no material: shade them like the terrain, the ground colour lit by the one
    // directional light through the tiles' normals (the default PBR material is flat grey here).
    tileset.customShader = new C.CustomShader({
      lightingModel: C.LightingModel.UNLIT,
      fragmentShaderText: `
        void fragmentMain(FragmentInput fsInput, inout czm_modelMaterial material) {
          float lit = max(dot(normalize(fsInput.attributes.normalEC), czm_lightDirectionEC), 0.0);
          material.diffuse = vec3(0.45, 0.42, 0.33) * (0.15 + 0.85 * lit);
        }`,
    });
    window.checkTileset = tileset;
    scene.primitives.add(tileset);
    say(`CesiumJS ${C.VERSION}: 3D tileset ready (asset ${tileset.asset?.version}, ` +
        `maximumScreenSpaceError ${tileset.maximumScreenSpaceError})`);
  }
  scene.fog.enabled = false;
  scene.backgroundColor = C.Color.fromCssColorString('#1d2633');
  widget.clock.shouldAnimate = false;
  widget.clock.currentTime = C.JulianDate.fromIso8601('2024-06-21T16:00:00Z');

  // The camera: looking north at the view's centre (at its terrain height), pitched down, at a
  // range that fits the rectangle; the light from the north-west, 40 degrees above the horizon.
  const [w, s, e, n] = cfg.view;
  const centre = C.Cartographic.fromDegrees((w + e) / 2, (s + n) / 2);
  let centreHeight = cfg.centreHeight ?? 0;
  if (provider) {
    const [sampled] = await C.sampleTerrainMostDetailed(provider, [centre.clone()], true);
    centreHeight = Number.isFinite(sampled.height) ? sampled.height : 0;
  }
  const target = C.Cartesian3.fromRadians(centre.longitude, centre.latitude, centreHeight);
  const R = 6378137;
  const ew = C.Math.toRadians(e - w) * R * Math.cos(centre.latitude);
  const ns = C.Math.toRadians(n - s) * R;
  const camera = scene.camera;
  const aspect = cfg.width / cfg.height;
  const fov = camera.frustum.fov;  // the wider dimension's angle
  const fovx = aspect >= 1 ? fov : 2 * Math.atan(Math.tan(fov / 2) * aspect);
  const fovy = aspect >= 1 ? 2 * Math.atan(Math.tan(fov / 2) / aspect) : fov;
  const pitch = C.Math.toRadians(cfg.pitch);
  const range = cfg.rangeFactor *
      Math.max(ew / (2 * Math.tan(fovx / 2)), ns * Math.sin(-pitch) / (2 * Math.tan(fovy / 2)));
  camera.lookAt(target, new C.HeadingPitchRange(0, pitch, range));
  camera.lookAtTransform(C.Matrix4.IDENTITY);
  const enu = C.Transforms.eastNorthUpToFixedFrame(target);
  const elevation = C.Math.toRadians(40);
  const fromLight = new C.Cartesian3(-Math.cos(elevation) / Math.SQRT2, Math.cos(elevation) / Math.SQRT2,
                                     Math.sin(elevation));  // towards the light, east-north-up
  const toLight = C.Matrix4.multiplyByPointAsVector(enu, fromLight, new C.Cartesian3());
  const direction = C.Cartesian3.normalize(C.Cartesian3.negate(toLight, toLight), toLight);
  scene.light = new C.DirectionalLight({ direction, intensity: 2.2 });
  say(`camera at range ${(range / 1000).toFixed(1)} km, pitch ${cfg.pitch} deg, looking at ` +
      `${C.Math.toDegrees(centre.longitude).toFixed(4)}, ${C.Math.toDegrees(centre.latitude).toFixed(4)}`);

  // tilesLoaded (the globe's, or the tileset's) once loading has been seen, for 10 rendered frames
  // in a row.
  let sawLoading = false;
  let lastQueue = 0;
  let lastSaid = 0;
  if (tileset) {
    tileset.loadProgress.addEventListener((pending, processing) => {
      if (pending + processing > 0) sawLoading = true;
      lastQueue = pending + processing;
    });
  } else {
    globe.tileLoadProgressEvent.addEventListener((queued) => {
      if (queued > 0) sawLoading = true;
      lastQueue = queued;
    });
  }
  const tilesLoaded = () => (tileset ? tileset.tilesLoaded : globe.tilesLoaded);
  let frames = 0;
  const loaded = await new Promise((resolve) => {
    let stable = 0;
    const timer = setTimeout(() => {
      remove();
      resolve(false);
    }, cfg.waitMs);
    const remove = scene.postRender.addEventListener(() => {
      ++frames;
      if (failures.length) {
        clearTimeout(timer);
        remove();
        resolve(false);
        return;
      }
      stable = tilesLoaded() && sawLoading ? stable + 1 : 0;
      const now = performance.now();
      if (now - lastSaid > 2000) {
        lastSaid = now;
        say(`frame ${frames}: ${lastQueue} tiles queued for loading`);
      }
      if (stable >= 10) {
        clearTimeout(timer);
        remove();
        resolve(true);
      }
    });
  });
  return { loaded, frames, failures, cesium_version: C.VERSION, camera_range_m: range };
}

/// Heights of the 3D tileset at the points: Scene.sampleHeightMostDetailed loads the tileset's
/// leaves along a vertical ray at each point (whatever the camera sees) and picks the first
/// surface from 9 km above the ellipsoid down; there is no globe to hit.
async function sampleTilesetHeights(points) {
  const C = window.Cesium;
  const scene = window.checkWidget.scene;
  if (!scene.sampleHeightSupported) {
    window.checkFailures.push('scene.sampleHeightSupported is false (no depth texture in this WebGL)');
    return { heights: points.map(() => null), failures: window.checkFailures };
  }
  const cartographics = points.map((p) => C.Cartographic.fromDegrees(p.lon, p.lat));
  // A leaf that fails to load never lets the pick complete: stop at the first failure instead.
  let poll;
  const failed = new Promise((resolve) => {
    poll = setInterval(() => window.checkFailures.length && resolve(null), 100);
  });
  const sampled = await Promise.race([scene.sampleHeightMostDetailed(cartographics), failed]);
  clearInterval(poll);
  if (!sampled) return { heights: points.map(() => null), failures: window.checkFailures };
  const heights = sampled.map((c) => (c && Number.isFinite(c.height) ? c.height : null));
  return { heights, failures: window.checkFailures };
}

async function sampleHeights(points) {
  const C = window.Cesium;
  const provider = window.checkProvider;
  const cartographics = points.map((p) => C.Cartographic.fromDegrees(p.lon, p.lat));
  const sampled = await C.sampleTerrainMostDetailed(provider, cartographics, true);
  // After sampling: with "metadataAvailability" the deeper levels are only known by then.
  const levels = cartographics.map((c) => provider.availability.computeMaximumLevelAtPosition(c));
  const heights = sampled.map((c) => (Number.isFinite(c.height) ? c.height : null));
  return { heights, levels, failures: window.checkFailures };
}

// --- main ----------------------------------------------------------------------------------------

async function main() {
  const { layer, tiles3d, points, view } = readInputs();
  layerJson = layer;
  if (!fs.existsSync(path.join(cesiumDir, 'Cesium.js')))
    throw new Error(`CesiumJS is missing (${cesiumDir}): run scripts/install-deps.sh`);
  let puppeteer;
  try {
    puppeteer = (await import('puppeteer-core')).default;
  } catch (e) {
    throw new Error(`puppeteer-core is missing (${e.message}): run scripts/install-deps.sh`);
  }
  if (!fs.existsSync(opt.chromium))
    throw new Error(`Chromium not found at ${opt.chromium} (apt install chromium, or --chromium PATH)`);
  result.view = view;
  if (layer) result.layer = { format: layer.format, maxzoom: layer.maxzoom, extensions: layer.extensions };
  if (tiles3d) {
    result.tileset = { version: tiles3d.tileset.asset?.version, contents: tiles3d.tiles.length,
                       deepest_level: tiles3d.deepest };
  }

  server = await startServer();
  const origin = `http://127.0.0.1:${server.address().port}`;
  log(`serving ${opt.tiles} and CesiumJS at ${origin}`);

  const args = [
    '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist', '--enable-webgl',
    '--disable-dev-shm-usage', '--no-first-run', '--no-default-browser-check', '--disable-component-update',
    '--disable-background-networking', '--disable-domain-reliability', '--disable-sync', '--disable-breakpad',
    '--mute-audio', '--host-resolver-rules=MAP * ~NOTFOUND , EXCLUDE 127.0.0.1',
    `--window-size=${opt.width},${opt.height}`,
  ];
  if (process.getuid?.() === 0) args.push('--no-sandbox');
  log(`launching ${opt.chromium} (headless)`);
  try {
    browser = await puppeteer.launch({
      executablePath: opt.chromium,
      headless: true,
      args,
      defaultViewport: { width: opt.width, height: opt.height },
      timeout: opt.timeout * 1000,
      protocolTimeout: opt.timeout * 1000,
    });
  } catch (e) {
    throw new Error(`cannot start Chromium (${opt.chromium}): ${e.message}`);
  }
  result.chromium_version = await browser.version();
  log(`browser ${result.chromium_version}`);
  browser.on('disconnected', () => {
    if (!finished) {
      fail('the browser went away (crashed or was killed)');
      finish();
    }
  });

  const page = await browser.newPage();
  page.on('pageerror', (e) => fail(`page error: ${e.message}`));
  page.on('error', (e) => fail(`page crashed: ${e.message}`));
  page.on('console', (m) => {
    const text = m.text();
    if (m.type() === 'error') fail(`console error: ${text}`);
    else if (m.type() === 'warn' || m.type() === 'warning') result.console_warnings.push(text);
  });
  page.on('requestfailed', (r) => {
    // net::ERR_ABORTED: CesiumJS cancelled the request (a tile no longer needed); refused
    // requests to other hosts are reported where they are refused.
    const why = r.failure()?.errorText ?? '';
    if (why !== 'net::ERR_ABORTED' && !why.startsWith('net::ERR_BLOCKED_BY_CLIENT'))
      fail(`request failed: ${r.url()} (${why})`);
  });
  await page.setRequestInterception(true);
  page.on('request', (r) => {
    const u = r.url();
    if (u.startsWith(origin + '/') || u.startsWith('data:') || u.startsWith('blob:')) return r.continue();
    result.requests.blocked.push(u);
    fail(`network request outside 127.0.0.1 refused: ${u}`);
    return r.abort('blockedbyclient');
  });
  await page.exposeFunction('checkProgress', (m) => log(m));

  await page.goto(`${origin}/index.html`, { waitUntil: 'load', timeout: opt.timeout * 1000 });
  const hasWebGL = await page.evaluate(() => {
    const c = document.createElement('canvas');
    return !!(c.getContext('webgl2') || c.getContext('webgl'));
  });
  if (!hasWebGL) throw new Error('no WebGL in headless Chromium (SwiftShader missing?)');
  const hasCesium = await page.evaluate(() => typeof window.Cesium === 'object');
  if (!hasCesium) throw new Error('Cesium.js did not load in the page');

  const remainingMs = () => opt.timeout * 1000 - (Date.now() - started);
  const what = tiles3d ? "the 3D tileset's tiles" : "the globe's tiles";
  log(`page loaded; waiting for ${what}`);
  const loaded = await page.evaluate(setUpAndWait, {
    view, pitch: opt.pitch, imagery: opt.imagery, width: opt.width, height: opt.height,
    loadSliceMs: 50, rangeFactor: 1.8,
    waitMs: Math.max(1000, remainingMs() - 5000),
    tiles3d: !!tiles3d, sse: opt.sse,
    centreHeight: tiles3d ? (tiles3d.heights[0] + tiles3d.heights[1]) / 2 : null,
  });
  for (const f of loaded.failures) fail(f);
  result.cesium_version = loaded.cesium_version;
  result.frames = loaded.frames;
  result.tiles_loaded = loaded.loaded;
  result.camera_range_m = loaded.camera_range_m;
  if (!loaded.loaded) {
    fail(loaded.failures.length ? `${what} did not finish loading (see the failures before)`
                                : `timeout: ${what} were not loaded after ${loaded.frames} frames`);
    return;
  }
  log(`tiles loaded after ${loaded.frames} frames; ${tiles3d ? 'glb' : 'terrain'} tiles served per level: ` +
      JSON.stringify(tiles3d ? result.requests.glb : result.requests.terrain));

  if (opt.screenshot) {
    fs.mkdirSync(path.dirname(opt.screenshot), { recursive: true });
    await page.screenshot({ path: opt.screenshot, type: 'png' });
    result.screenshot = opt.screenshot;
    log(`screenshot ${opt.screenshot}`);
  }
  if (points.length && tiles3d) {
    log(`sampling ${points.length} heights (scene.sampleHeightMostDetailed)`);
    const s = await page.evaluate(sampleTilesetHeights, points);
    for (const f of s.failures) fail(f);
    result.heights = s.heights;
    // The deepest level whose content over each point (by its region) was served: picking the
    // leaves needs them loaded.
    result.levels = points.map((p) => {
      const lon = (p.lon * Math.PI) / 180, lat = (p.lat * Math.PI) / 180;
      let level = null;
      for (const t of tiles3d.tiles) {
        const r = t.region;
        if (r && servedGlb.has(t.uri) && lon >= r[0] && lon <= r[2] && lat >= r[1] && lat <= r[3])
          level = Math.max(level ?? -1, t.level);
      }
      return level;
    });
    log(`glb tiles served per level after sampling: ${JSON.stringify(result.requests.glb)}`);
    const missing = s.heights.filter((h) => h === null).length;
    if (missing) fail(`sampleHeightMostDetailed gave no height at ${missing} of ${points.length} points`);
  } else if (points.length) {
    log(`sampling ${points.length} heights (sampleTerrainMostDetailed)`);
    const s = await page.evaluate(sampleHeights, points);
    for (const f of s.failures) fail(f);
    result.heights = s.heights;
    result.levels = s.levels;
    const missing = s.heights.filter((h) => h === null).length;
    if (missing) fail(`sampleTerrainMostDetailed gave no height at ${missing} of ${points.length} points`);
  }
}

main()
  .catch((e) => fail(e?.message ?? String(e)))
  .finally(() => {
    clearTimeout(watchdog);
    finish();
  });
