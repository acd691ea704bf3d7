// The live view of `occmap fuse --listen` in a real browser: the rendered lab's four cameras
// streamed in real time over UDP, two `occmap edge` processes (two cameras each) and the fuse
// joined by a mosquitto of the test's own (127.0.0.1, a free port). The page shows the fused map,
// tracks that move, the frame number advancing, every camera up with the changes its edge sent as
// its picture; the setup's edits are refused (the site file is the edges' too). The fuse runs
// with --token: the page signs in on the login page and runs on its cookie.
'use strict';
const test = require('node:test');
const assert = require('node:assert');
const { spawn } = require('node:child_process');
const fs = require('node:fs');
const net = require('node:net');
const path = require('node:path');
const h = require('./harness.cjs');

const occmap = process.env.OCCMAP;
const kToken = 'fuse-test-token-5d1e';

function freeTcpPort() {
  return new Promise((resolve, reject) => {
    const srv = net.createServer();
    srv.once('error', reject);
    srv.listen(0, '127.0.0.1', () => {
      const { port } = srv.address();
      srv.close(() => resolve(port));
    });
  });
}

// Resolves once `proc` printed a line matching `re` (its match), rejects after `ms` or its exit.
function waitForOutput(proc, re, ms, what) {
  let log = '';
  return new Promise((resolve, reject) => {
    const timer = setTimeout(() => reject(new Error(`${what}: no ${re} in ${ms} ms:\n${log}`)), ms);
    const onData = (d) => {
      log += d.toString();
      const m = log.match(re);
      if (m) {
        clearTimeout(timer);
        resolve(m);
      }
    };
    proc.stdout.on('data', onData);
    proc.stderr.on('data', onData);
    proc.on('exit', (code) => { clearTimeout(timer); reject(new Error(`${what} exited (${code}):\n${log}`)); });
  });
}

function brokerUp(port, ms = 5000) {
  const until = Date.now() + ms;
  return new Promise((resolve, reject) => {
    const attempt = () => {
      const s = net.connect(port, '127.0.0.1');
      s.once('connect', () => { s.destroy(); resolve(); });
      s.once('error', () => {
        s.destroy();
        if (Date.now() > until) reject(new Error(`mosquitto on 127.0.0.1:${port} did not start`));
        else setTimeout(attempt, 50);
      });
    };
    attempt();
  });
}

test('fuse view: map, cameras and moving tracks from edges', { timeout: 240000 }, async (t) => {
  const dir = h.tempDir('fuse');
  const ports = await h.freeUdpPorts(4);
  const senders = h.streamCameras(ports);
  const site = h.siteCopy(dir, ports);
  const procs = [];
  let browser = null;
  t.after(async () => {
    if (browser) await browser.close();
    for (const p of procs.reverse()) await h.stopProcess(p);
    for (const s of senders) await h.stopProcess(s);
  });

  const brokerPort = await freeTcpPort();
  fs.writeFileSync(path.join(dir, 'mosquitto.conf'),
    `listener ${brokerPort} 127.0.0.1\nallow_anonymous true\npersistence false\n`);
  procs.push(spawn('/usr/sbin/mosquitto', ['-c', path.join(dir, 'mosquitto.conf')], { stdio: 'ignore' }));
  await brokerUp(brokerPort);
  const broker = `mqtt://127.0.0.1:${brokerPort}`;

  const fuse = spawn(occmap, ['fuse', site, '--broker', broker, '--out', path.join(dir, 'fuse'), '--no-video',
    '--no-cache', '--listen', '127.0.0.1:0', '--token', kToken, '--latency-budget-s', '0.5', '--dead-after-s', '2'],
  { stdio: ['ignore', 'pipe', 'pipe'] });
  procs.push(fuse);
  let fuseLog = '';
  fuse.stdout.on('data', (d) => { fuseLog += d.toString(); });
  fuse.stderr.on('data', (d) => { fuseLog += d.toString(); });
  const [, url] = await waitForOutput(fuse, /occmap fuse: listening on (http:\/\/\S+?)\/?\s/, 60000, 'occmap fuse');
  await waitForOutput(fuse, /subscribed to/, 60000, 'occmap fuse');
  for (const cams of ['cam1,cam2', 'cam3,cam4']) {
    procs.push(spawn(occmap, ['edge', site, '--cameras', cams, '--broker', broker, '--no-cache'], { stdio: 'ignore' }));
  }

  browser = await h.launchBrowser();
  const page = await h.openPage(browser, url + '/');
  try {
    // Signing in: the login page, then the live page on the cookie.
    assert.strictEqual(new URL(page.url()).pathname, '/login');
    await page.fill('[data-testid=login-token]', kToken);
    await page.click('[data-testid=login-submit]');
    await page.waitForURL((u) => u.pathname === '/', { timeout: 10000 });
    assert.strictEqual((await page.context().cookies())[0].httpOnly, true);
    // The fused map's picture arrives, one pixel per cell.
    const grid = await page.evaluate(() => fetch('/api/site').then((r) => r.json()).then((s) => s.grid));
    await page.waitForFunction((g) => {
      const img = document.querySelector('.floor-map img.map-image');
      return img && img.complete && img.naturalWidth === g.cols && img.naturalHeight === g.rows && !/[?&]v=0\b/.test(img.src);
    }, grid, { timeout: 90000 });
    // Tracks appear and one moves between two moments 1 s apart.
    await page.waitForFunction(() => document.querySelectorAll('.floor-map .track-label').length > 0, null, { timeout: 60000 });
    const labels = () => page.$$eval('.floor-map .leaflet-tooltip.track-label', (els) =>
      els.map((e) => ({ id: e.textContent, at: `${e.getBoundingClientRect().left},${e.getBoundingClientRect().top}` })));
    let moved = [];
    for (let i = 0; i < 30 && moved.length === 0; i += 1) {
      const before = await labels();
      await page.waitForTimeout(1000);
      moved = (await labels()).filter((a) => before.some((b) => b.id === a.id && b.at !== a.at));
    }
    assert.ok(moved.length > 0, 'no track moved on the fuse\'s page');
    const frame1 = Number(await page.textContent('[data-testid=frame]'));
    await page.waitForTimeout(1500);
    const frame2 = Number(await page.textContent('[data-testid=frame]'));
    assert.ok(frame2 > frame1, `the frame number advances (${frame1}, then ${frame2})`);
    // Every camera's edge is heard: four tiles, each up, each showing the changes its edge sent
    // (the fuse has no frames): light pixels on dark, at the camera's size.
    assert.strictEqual(await page.locator('.tile').count(), 4);
    await page.waitForFunction(() => document.querySelectorAll('.tile .badge.up').length === 4, null, { timeout: 30000 });
    await h.picturesLoaded(page, '.tile img', 30000);
    const shares = await page.evaluate(async () => {
      const out = [];
      for (const id of ['cam1', 'cam2', 'cam3', 'cam4']) {
        const blob = await fetch(`/api/cameras/${id}/frame.jpg`).then((r) => r.blob());
        const bmp = await createImageBitmap(blob);
        const c = new OffscreenCanvas(bmp.width, bmp.height);
        const g = c.getContext('2d');
        g.drawImage(bmp, 0, 0);
        const px = g.getImageData(0, 0, bmp.width, bmp.height).data;
        let light = 0;
        for (let i = 0; i < px.length; i += 4) light += px[i + 1] > 128;
        out.push({ id, width: bmp.width, light: light / (px.length / 4) });
      }
      return out;
    });
    for (const s of shares) {
      assert.strictEqual(s.width, 640, JSON.stringify(s));
      assert.ok(s.light > 0 && s.light < 0.5, `${s.id}: its changes, some pixels and not most: ${JSON.stringify(s)}`);
    }
    const state = await page.evaluate(() => fetch('/api/state').then((r) => r.json()));
    assert.ok(state.frame > 0 && state.cameras.length === 4, JSON.stringify(state).slice(0, 300));
    // The site is shown, not edited: a save is refused and says where to edit it.
    const put = await page.evaluate(() => fetch('/api/site', { method: 'PUT', headers: { 'Content-Type': 'application/json' },
      body: JSON.stringify({ zones: [] }) }).then(async (r) => ({ status: r.status, body: await r.json() })));
    assert.strictEqual(put.status, 400, JSON.stringify(put));
    assert.match(put.body.error, /view only: edit the site file/);
    await h.screenshot(page, 'fuse-live.png');
    assert.deepStrictEqual(page.errors, [], 'script errors on the page');
  } catch (e) {
    await page.screenshot({ path: path.join(dir, 'failure.png') }).catch(() => {});
    console.log(`fuse log:\n${fuseLog}\nscreenshot: ${dir}/failure.png`);
    throw e;
  }
});
