// Shared by the browser tests: the rendered lab scene (rendered once per build tree by the
// occmap_browser_scene fixture), its cameras streamed on loopback by ffmpeg in real time,
// `occmap serve` on 127.0.0.1:0 started and stopped by PID, and Debian's headless Chromium driven
// by playwright-core (never a downloaded browser).
// Environment (set by CTest): OCCMAP (the binary), OCCMAP_SCENE (the rendered scene folder),
// OCCMAP_SOURCE_DIR, NODE_PATH (npm ci's node_modules of the build tree).
'use strict';
const assert = require('node:assert');
const { spawn, spawnSync } = require('node:child_process');
const dgram = require('node:dgram');
const fs = require('node:fs');
const os = require('node:os');
const path = require('node:path');
const { chromium } = require('playwright-core');

const occmap = process.env.OCCMAP;
const sceneDir = process.env.OCCMAP_SCENE;
const sourceDir = process.env.OCCMAP_SOURCE_DIR;
if (!occmap || !sceneDir) throw new Error('harness: OCCMAP and OCCMAP_SCENE must be set (run through ctest)');

const browserPaths = ['/usr/bin/chromium-headless-shell', '/usr/bin/chromium'];
function browserPath() {
  const p = process.env.OCCMAP_CHROMIUM || browserPaths.find((f) => fs.existsSync(f));
  if (!p) throw new Error(`no Chromium at ${browserPaths.join(' or ')}: scripts/install-deps.sh installs chromium-headless-shell`);
  return p;
}

function tempDir(name) {
  return fs.mkdtempSync(path.join(os.tmpdir(), `occmap-browser-${name}-`));
}

// A copy of the rendered scene's site file in `dir`, its paths still pointing at the scene, its
// video sources optionally replaced by UDP streams (`ports`: one per camera).
function siteCopy(dir, ports) {
  let text = fs.readFileSync(path.join(sceneDir, 'site.yaml'), 'utf8');
  if (!/^data_root:/m.test(text)) text = `data_root: ${sceneDir}\n${text}`;
  else text = text.replace(/^data_root:.*$/m, `data_root: ${sceneDir}`);
  if (ports) {
    ports.forEach((port, i) => {
      text = text.replace(`{video: frames/cam${i + 1}.mp4}`,
        `{stream: 'udp://127.0.0.1:${port}?overrun_nonfatal=1&fifo_size=100000'}`);
    });
    if (!text.includes('stream:')) throw new Error('harness: no video source to replace by a stream in site.yaml');
  }
  const file = path.join(dir, 'site.yaml');
  fs.writeFileSync(file, text);
  return file;
}

async function freeUdpPorts(n) {
  const socks = await Promise.all(Array.from({ length: n }, () => new Promise((resolve) => {
    const s = dgram.createSocket('udp4');
    s.bind(0, '127.0.0.1', () => resolve(s));
  })));
  const ports = socks.map((s) => s.address().port);
  socks.forEach((s) => s.close());
  return ports;
}

// Each camera's video (or videos[i] in its place), looped, in real time, as MPEG-TS over UDP to
// its port: a live camera.
function streamCameras(ports, videos = []) {
  return ports.map((port, i) => spawn('ffmpeg', ['-loglevel', 'error', '-re', '-stream_loop', '-1',
    '-i', videos[i] || path.join(sceneDir, 'frames', `cam${i + 1}.mp4`), '-c', 'copy', '-f', 'mpegts',
    `udp://127.0.0.1:${port}?pkt_size=1316`], { stdio: 'ignore' }));
}

function stopProcess(proc, timeoutMs = 10000) {
  return new Promise((resolve) => {
    if (proc.exitCode !== null || proc.signalCode !== null) { resolve(proc.exitCode); return; }
    const timer = setTimeout(() => proc.kill('SIGKILL'), timeoutMs);
    proc.once('exit', (code) => { clearTimeout(timer); resolve(code); });
    proc.kill('SIGTERM');
  });
}

// `occmap serve SITE --listen ... --out DIR [args]`: resolves once it printed its address.
// cache: a cache folder (--cache-dir) instead of --no-cache.
function startServe(site, { listen = '127.0.0.1:0', args = [], out, cache } = {}) {
  const outDir = out || path.join(path.dirname(site), 'out');
  const cacheArgs = cache ? ['--cache-dir', cache] : ['--no-cache'];
  const proc = spawn(occmap, ['serve', site, '--listen', listen, '--out', outDir, ...cacheArgs, ...args],
    { stdio: ['ignore', 'pipe', 'pipe'] });
  let log = '';
  return new Promise((resolve, reject) => {
    const timer = setTimeout(() => { proc.kill('SIGKILL'); reject(new Error(`occmap serve printed no address in 60 s:\n${log}`)); }, 60000);
    const onData = (d) => {
      log += d.toString();
      const m = log.match(/occmap serve: listening on (http:\/\/\S+?)\/?\s/);
      if (m) {
        clearTimeout(timer);
        resolve({ url: m[1], proc, outDir, log: () => log, stop: () => stopProcess(proc) });
      }
    };
    proc.stdout.on('data', onData);
    proc.stderr.on('data', (d) => { log += d.toString(); });
    proc.on('exit', (code) => { clearTimeout(timer); reject(new Error(`occmap serve exited (${code}) before listening:\n${log}`)); });
  });
}

async function launchBrowser() {
  return chromium.launch({ executablePath: browserPath(), args: ['--no-sandbox'], headless: true });
}

// A page that fails the test on any uncaught error of its script.
async function openPage(browser, url, viewport = { width: 1400, height: 900 }) {
  const page = await browser.newPage({ viewport });
  page.errors = [];
  page.on('pageerror', (e) => page.errors.push(e.message));
  // A picture asked before the first frame set is a 404 by contract: not a page error.
  page.on('console', (m) => {
    if (m.type() === 'error' && !/Failed to load resource/.test(m.text())) page.errors.push(`console: ${m.text()}`);
  });
  await page.goto(url);
  return page;
}

// Screenshots for docs/images when OCCMAP_SCREENSHOTS names a folder.
async function screenshot(page, name) {
  const dir = process.env.OCCMAP_SCREENSHOTS;
  if (!dir) return;
  fs.mkdirSync(dir, { recursive: true });
  await page.screenshot({ path: path.join(dir, name), fullPage: true });
}

function runOccmap(args) {
  return spawnSync(occmap, args, { encoding: 'utf8' });
}

// The true floor points of a camera, projected through the scene's calibration
// (tests/project_floor_points.py), optionally perturbed by Gaussian noise of `noisePx` with a
// fixed seed: [{u_px, v_px, x_m, y_m}].
function trueFloorPoints(camera, points, { noisePx = 0, seed = 1 } = {}) {
  const calib = path.join(sceneDir, 'calib');
  const r = spawnSync(process.env.PYTHON || 'python3', [path.join(sourceDir, 'tests/project_floor_points.py'),
    path.join(calib, `intr_${camera}.xml`), path.join(calib, `extr_${camera}.xml`),
    ...points.map(([x, y]) => `${x},${y}`), '--noise-px', String(noisePx), '--seed', String(seed)], { encoding: 'utf8' });
  if (r.status !== 0) throw new Error(`project_floor_points.py: ${r.stderr}`);
  return r.stdout.trim().split('\n').slice(1).map((line) => {
    const [u, v, x, y] = line.split(',').map(Number);
    return { u_px: u, v_px: v, x_m: x, y_m: y };
  });
}

// One test's world, torn down by node:test's t.after whatever happens: a folder, a copy of the
// scene's site (its cameras streamed over UDP when `streams`, `videos(dir)[i]` in place of camera
// i's video), `occmap serve` on it (with the cache folder `cache(dir)` gives, else none) and a
// browser (`editSite(text)` changes the site file's text first). open(path) gives a page of it;
// check(body) runs the test's steps, then asserts that
// no page had a script error, and on a failure keeps a screenshot and the server's log.
//   const s = await h.start(t, 'zones', { streams: true });
//   const page = await s.open('/#setup');
//   await s.check(async () => { ... });
async function start(t, name, { streams = false, videos, listen, args, editSite, cache } = {}) {
  const dir = tempDir(name);
  const cameras = fs.readdirSync(path.join(sceneDir, 'frames')).filter((f) => /^cam\d+\.mp4$/.test(f)).length;
  const ports = streams ? await freeUdpPorts(cameras) : null;
  const senders = ports ? streamCameras(ports, typeof videos === 'function' ? videos(dir) : videos) : [];
  const world = { dir, site: siteCopy(dir, ports), senders, serve: null, browser: null, pages: [] };
  if (editSite) fs.writeFileSync(world.site, editSite(fs.readFileSync(world.site, 'utf8')));
  world.original = fs.readFileSync(world.site, 'utf8');
  t.after(async () => {
    if (world.browser) await world.browser.close();
    if (world.serve) await world.serve.stop();
    for (const s of senders) await stopProcess(s);
  });
  world.serve = await startServe(world.site, { listen, args, cache: cache ? cache(dir) : undefined });
  world.browser = await launchBrowser();
  // A server on every address is reached through loopback.
  world.base = world.serve.url.replace('://0.0.0.0:', '://127.0.0.1:');
  world.open = async (p = '/') => {
    const page = await openPage(world.browser, world.base + p);
    world.pages.push(page);
    return page;
  };
  world.check = async (body) => {
    try {
      await body();
      for (const page of world.pages) assert.deepStrictEqual(page.errors, [], 'script errors on the page');
    } catch (e) {
      const page = world.pages[world.pages.length - 1];
      if (page && !page.isClosed()) await page.screenshot({ path: path.join(dir, 'failure.png') }).catch(() => {});
      console.log(`serve log:\n${world.serve.log()}\nscreenshot: ${dir}/failure.png`);
      throw e;
    }
  };
  return world;
}

// `count` floor points of a camera's view (true pixels, 40 px inside its 640x480 picture), spread
// and with no three on a line: the two farthest apart, then each time the point farthest from
// those chosen.
function spreadFloorPoints(camera, count = 4) {
  const candidates = [];
  for (let x = 0.5; x <= 8.5; x += 1) for (let y = 0.5; y <= 6.0; y += 1) candidates.push([x, y]);
  const pts = trueFloorPoints(camera, candidates)
    .filter((p) => p.u_px > 40 && p.u_px < 600 && p.v_px > 40 && p.v_px < 440);
  assert.ok(pts.length >= count, `${camera} sees ${pts.length} candidate points`);
  const d2 = (a, b) => (a.u_px - b.u_px) ** 2 + (a.v_px - b.v_px) ** 2;
  const chosen = [pts.reduce((best, p) => (d2(p, pts[0]) > d2(best, pts[0]) ? p : best))];
  while (chosen.length < count) {
    const far = (p) => Math.min(...chosen.map((c) => d2(p, c)));
    chosen.push(pts.reduce((best, p) => (far(p) > far(best) ? p : best)));
  }
  return chosen;
}

// Clicks the points on the setup's camera picture and types their floor positions.
async function clickFloorPoints(page, points) {
  for (const [i, p] of points.entries()) {
    const at = await page.evaluate(([u, v]) => window.occmap.cameraToClient(u, v), [p.u_px, p.v_px]);
    await page.mouse.click(at.x, at.y);
    await page.fill(`[data-testid=x-${i}]`, String(p.x_m));
    await page.fill(`[data-testid=y-${i}]`, String(p.y_m));
  }
}

// Waits until every picture matching `selector` has loaded.
function picturesLoaded(page, selector, timeout = 60000) {
  return page.waitForFunction((sel) => {
    const imgs = [...document.querySelectorAll(sel)];
    return imgs.length > 0 && imgs.every((img) => img.complete && img.naturalWidth > 0);
  }, selector, { timeout });
}

// `occmap check SITE` passes.
function assertSiteValid(site) {
  const r = runOccmap(['check', site]);
  assert.strictEqual(r.status, 0, `occmap check ${site}: ${r.stdout}${r.stderr}`);
}

module.exports = {
  sceneDir, sourceDir, tempDir, siteCopy, freeUdpPorts, streamCameras, stopProcess, startServe,
  launchBrowser, openPage, screenshot, runOccmap, trueFloorPoints, spreadFloorPoints, clickFloorPoints, start,
  picturesLoaded, assertSiteValid,
};
