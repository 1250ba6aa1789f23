#!/usr/bin/env node
// Draws baked files in headless Chromium with the three.js and Babylon.js
// loader snippets of docs/engines.md, for tests/it/engines.rs. The snippets
// are taken from the markdown as they stand (each fenced block after a
// `<!-- tested: NAME -->` line), so what the docs show is what runs.
//
//     node pipeline/engines.mjs OUT_DIR FILE.glb...
//
// For each file, engine (three, babylon) and variant (baked, pbr+lightmap)
// it writes OUT_DIR/<stem>.<engine>.<variant>.png: the same camera, framing
// the scene's bounds, with no lights and no environment, so only the
// lightmap and the preview's texture light it. The browser is Debian's
// `chromium` (BAKE_CHROMIUM overrides the path), driven by puppeteer-core and
// rendering WebGL in software (SwiftShader); the npm packages are pinned in
// package-lock.json and installed by pipeline/setup.sh. Files are served
// from 127.0.0.1 only.
//
// Exit code: 0 when every picture was written, 2 otherwise (one line on stderr).
import { createServer } from 'node:http';
import { readFileSync, writeFileSync, existsSync } from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
const [outDir, ...files] = process.argv.slice(2);
const WIDTH = 320;
const HEIGHT = 240;
const VARIANTS = ['pbr+lightmap', 'baked'];

function fail(message) {
  console.error(`engines.mjs: ${message}`);
  process.exit(2);
}

if (!outDir || files.length === 0) fail('usage: node pipeline/engines.mjs OUT_DIR FILE.glb...');
const chromium = process.env.BAKE_CHROMIUM || '/usr/bin/chromium';
if (!existsSync(chromium)) fail(`no browser at ${chromium}: run ./pipeline/setup.sh (it installs Debian's chromium)`);
let puppeteer;
try {
  puppeteer = (await import('puppeteer-core')).default;
} catch (error) {
  fail(`puppeteer-core is not installed (${error.code ?? error}); run ./pipeline/setup.sh`);
}

// The fenced block after each `<!-- tested: NAME -->` line of docs/engines.md.
function snippets() {
  const markdown = readFileSync(path.join(here, '..', 'docs', 'engines.md'), 'utf8');
  const found = {};
  for (const match of markdown.matchAll(/<!-- tested: (\S+) -->\n```js\n([\s\S]*?)\n```/g)) {
    found[match[1]] = match[2] + '\n';
  }
  for (const name of ['three.mjs', 'babylon.mjs']) {
    if (!(name in found)) fail(`docs/engines.md has no block marked <!-- tested: ${name} -->`);
  }
  return found;
}

const importMap = JSON.stringify({
  imports: {
    three: '/node_modules/three/build/three.module.js',
    'three/addons/': '/node_modules/three/examples/jsm/',
    '@babylonjs/core/': '/node_modules/@babylonjs/core/',
    '@babylonjs/loaders/': '/node_modules/@babylonjs/loaders/',
  },
});

// Each page defines window.draw(url, variant) → a PNG data URL of the canvas.
const pages = {
  three: `
import * as THREE from 'three';
import { loadBaked } from '/snippets/three.mjs';
const canvas = document.querySelector('canvas');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
renderer.setSize(${WIDTH}, ${HEIGHT}, false);
renderer.setClearColor(0x000000, 1);
window.draw = async (url, variant) => {
  const gltf = await loadBaked(url, variant);
  const scene = new THREE.Scene();
  scene.add(gltf.scene);
  const view = window.view(new THREE.Box3().setFromObject(gltf.scene));
  const camera = new THREE.PerspectiveCamera(view.fov, ${WIDTH} / ${HEIGHT}, view.near, view.far);
  camera.position.set(...view.eye);
  camera.lookAt(...view.target);
  renderer.render(scene, camera);
  return canvas.toDataURL('image/png');
};
window.ready = true;
`,
  babylon: `
import { Engine } from '@babylonjs/core/Engines/engine.js';
import { Scene } from '@babylonjs/core/scene.js';
import { FreeCamera } from '@babylonjs/core/Cameras/freeCamera.js';
import { Vector3 } from '@babylonjs/core/Maths/math.vector.js';
import { Color4 } from '@babylonjs/core/Maths/math.color.js';
import { loadBaked } from '/snippets/babylon.mjs';
const canvas = document.querySelector('canvas');
// As docs/engines.md says, but without antialiasing, so that edges match exactly.
const engine = new Engine(canvas, false, { preserveDrawingBuffer: true, useExactSrgbConversions: true });
window.draw = async (url, variant) => {
  const scene = new Scene(engine);
  scene.useRightHandedSystem = true;
  scene.clearColor = new Color4(0, 0, 0, 1);
  const result = await loadBaked(url, scene, variant);
  const { min, max } = result.meshes[0].getHierarchyBoundingVectors();
  const view = window.view({ min, max });
  const camera = new FreeCamera('camera', new Vector3(...view.eye), scene);
  camera.fov = view.fov * Math.PI / 180;
  camera.fovMode = FreeCamera.FOVMODE_VERTICAL_FIXED;
  camera.minZ = view.near;
  camera.maxZ = view.far;
  camera.setTarget(new Vector3(...view.target));
  await scene.whenReadyAsync();
  scene.render();
  const png = canvas.toDataURL('image/png');
  scene.dispose();
  return png;
};
window.ready = true;
`,
};

// One camera for both engines: looking down at the bounds' centre from the
// front right, far enough for the bounding sphere to fit.
const viewScript = `
window.view = ({ min, max }) => {
  const target = [(min.x + max.x) / 2, (min.y + max.y) / 2, (min.z + max.z) / 2];
  const size = Math.hypot(max.x - min.x, max.y - min.y, max.z - min.z) / 2;
  const fov = 45;
  const distance = size / Math.sin((fov / 2) * Math.PI / 180);
  const d = [0.55, 0.5, 0.67];
  const n = Math.hypot(...d);
  const eye = target.map((t, i) => t + d[i] / n * distance);
  return { eye, target, fov, near: distance / 100, far: distance * 4 };
};`;

function html(engine) {
  return `<!doctype html><html><body style="margin:0">
<canvas width="${WIDTH}" height="${HEIGHT}"></canvas>
<script type="importmap">${importMap}</script>
<script>${viewScript}</script>
<script type="module">${pages[engine]}</script>
</body></html>`;
}

const types = { '.js': 'text/javascript', '.mjs': 'text/javascript', '.glb': 'model/gltf-binary', '.html': 'text/html' };

function serve(routes) {
  const modules = path.join(here, 'node_modules');
  const server = createServer((request, response) => {
    const url = decodeURIComponent(new URL(request.url, 'http://localhost').pathname);
    let body = routes[url];
    if (body === undefined && url.startsWith('/node_modules/')) {
      const file = path.join(modules, path.normalize(url.slice('/node_modules/'.length)));
      if (file.startsWith(modules + path.sep) && existsSync(file)) body = readFileSync(file);
    }
    if (body === undefined) {
      response.writeHead(404).end();
      return;
    }
    const type = types[path.extname(url)] ?? 'application/octet-stream';
    response.writeHead(200, { 'content-type': type }).end(body);
  });
  return new Promise((resolve) => server.listen(0, '127.0.0.1', () => resolve(server)));
}

const routes = { '/three.html': html('three'), '/babylon.html': html('babylon'), '/favicon.ico': '' };
for (const [name, code] of Object.entries(snippets())) routes[`/snippets/${name}`] = code;
files.forEach((file, i) => (routes[`/files/${i}/${path.basename(file)}`] = readFileSync(file)));
const server = await serve(routes);
const origin = `http://127.0.0.1:${server.address().port}`;

const browser = await puppeteer.launch({
  executablePath: chromium,
  headless: true,
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'],
});
const problems = [];
try {
  for (const engine of ['three', 'babylon']) {
    const page = await browser.newPage();
    page.on('pageerror', (error) => problems.push(`${engine}: ${error}`));
    page.on('console', (message) => message.type() === 'error' && problems.push(`${engine}: ${message.text()}`));
    const start = Date.now();
    await page.goto(`${origin}/${engine}.html`);
    await page.waitForFunction('window.ready === true', { timeout: 60000 });
    for (const [i, file] of files.entries()) {
      for (const variant of VARIANTS) {
        const url = `/files/${i}/${path.basename(file)}`;
        const png = await page.evaluate((u, v) => window.draw(u, v), url, variant);
        const stem = path.basename(file, '.glb');
        writeFileSync(path.join(outDir, `${stem}.${engine}.${variant}.png`), Buffer.from(png.split(',')[1], 'base64'));
      }
    }
    console.log(`${engine}: ${files.length} file(s) drawn in ${((Date.now() - start) / 1000).toFixed(1)} s`);
    await page.close();
  }
} catch (error) {
  problems.push(String(error));
} finally {
  await browser.close();
  server.close();
}
if (problems.length > 0) fail(problems.join('; '));
