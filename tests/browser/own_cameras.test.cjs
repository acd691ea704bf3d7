// The README's "Your own cameras" followed as written, on the rendered lab: its example site file
// (read from README.md) with the lab's four videos streamed over UDP as the cameras' URLs and
// their 640x480 size, `occmap check`, `occmap serve`; in the page each camera calibrated from 8
// clicked floor points (the lens method: the example's homographies hold no intrinsics), a floor
// mask drawn on c2, a zone on the map, saved; the live view then counts people in the zone.
'use strict';
const test = require('node:test');
const assert = require('node:assert');
const fs = require('node:fs');
const path = require('node:path');
const h = require('./harness.cjs');

// The example site of README.md's "In the browser" section, made concrete: c1's entry repeated
// for c2..c4 with their stream URLs, the frames' size given.
function readmeSite(ports) {
  const readme = fs.readFileSync(path.join(h.sourceDir, 'README.md'), 'utf8');
  const section = readme.slice(readme.indexOf('### In the browser: from stream URLs to a live map'));
  const yaml = /```yaml\n([\s\S]*?)```/.exec(section)[1];
  const c1 = /( {2}- id: c1\n[\s\S]*?)(?= {2}- id: c2)/.exec(yaml)[1];
  let text = yaml.replace(/ {2}- id: c2\n {4}\.\.\.\n/, [2, 3, 4].map((n) => c1.replace('id: c1', `id: c${n}`)).join(''));
  assert.match(text, /rtsp:\/\/user:pass@192\.168\.1\.21\/stream1/, 'the README example as this test knows it');
  let n = 0;
  text = text.replace(/'rtsp:\/\/[^']*'/g, () => `'udp://127.0.0.1:${ports[n++]}?overrun_nonfatal=1&fifo_size=100000'`);
  assert.strictEqual(n, 4);
  return text.replace(/image_size: \[1280, 720\]/g, 'image_size: [640, 480]');
}

test("README's own cameras: stream URLs to a live map, set up in the page", { timeout: 400000 }, async (t) => {
  const dir = h.tempDir('own-cameras');
  const ports = await h.freeUdpPorts(4);
  const senders = h.streamCameras(ports);
  const site = path.join(dir, 'shop.yaml');
  fs.writeFileSync(site, readmeSite(ports));
  let serve = null;
  let browser = null;
  t.after(async () => {
    if (browser) await browser.close();
    if (serve) await serve.stop();
    for (const s of senders) await h.stopProcess(s);
  });
  const check = h.runOccmap(['check', site]);
  assert.strictEqual(check.status, 0, check.stdout + check.stderr);
  assert.match(check.stdout, /c4 +homography +640x480/);
  serve = await h.startServe(site, { out: path.join(dir, 'shop-out') });
  browser = await h.launchBrowser();
  const page = await h.openPage(browser, `${serve.url}/#setup`);
  try {
    for (const [i, id] of ['c1', 'c2', 'c3', 'c4'].entries()) {
      await page.click(`.cam-tabs button[data-camera=${id}]`);
      await h.picturesLoaded(page, '[data-testid=camera-map] img.leaflet-image-layer', 120000);
      await h.clickFloorPoints(page, h.spreadFloorPoints(`cam${i + 1}`, 8));
      await page.click('[data-testid=calibrate]');
      await page.waitForSelector('[data-testid=lens-fitted]', { timeout: 30000 });
      const rms = Number(await page.textContent('[data-testid=rms-px]'));
      assert.ok(rms <= 1, `${id}: RMS ${rms} px`);
    }
    await page.click('.cam-tabs button[data-camera=c2]');
    await page.check('[data-testid=mode-mask]');
    await page.click('[data-testid=camera-map] .leaflet-pm-icon-polygon');
    const corners = [[60, 180], [580, 180], [620, 470], [20, 470]];
    for (const [u, v] of [...corners, corners[0]]) {
      const at = await page.evaluate(([x, y]) => window.occmap.cameraToClient(x, y), [u, v]);
      await page.mouse.click(at.x, at.y);
    }
    await page.click('[data-testid=draw-zone]');
    const zone = [[0.5, 0.5], [7.5, 0.5], [7.5, 5.5], [0.5, 5.5]];
    for (const [x, y] of [...zone, zone[0]]) {
      const at = await page.evaluate(([px, py]) => window.occmap.setupFloorToClient(px, py), [x, y]);
      await page.mouse.click(at.x, at.y);
    }
    await page.waitForSelector('[data-testid=zone-name-0]');
    await page.fill('[data-testid=zone-name-0]', 'room');
    assert.match(await page.textContent('.savebar'), /calibration of c1, c2, c3, c4; masks of c2; zones and lines/);
    await page.click('[data-testid=save]');
    await page.waitForSelector('[data-testid=save-message].ok', { timeout: 60000 });
    h.assertSiteValid(site);
    const saved = fs.readFileSync(site, 'utf8');
    assert.strictEqual((saved.match(/format: opencv/g) || []).length, 4, saved);
    assert.match(saved, /mask: \{polygons:/);
    assert.match(saved, /name: "room"/);

    // Live: the zone's count goes above zero and tracks appear on the map.
    await page.click('a[data-tab=live]');
    await page.waitForFunction(() => {
      const row = document.querySelector('[data-testid=zone-counts] tr[data-zone=room] td.num');
      return row && Number(row.textContent) > 0;
    }, null, { timeout: 180000, polling: 500 });
    await page.waitForFunction(() => Number(document.querySelector('[data-testid=track-count]').textContent) > 0,
      null, { timeout: 60000, polling: 500 });
    assert.deepStrictEqual(page.errors, [], 'script errors on the page');
  } catch (e) {
    await page.screenshot({ path: path.join(dir, 'failure.png') }).catch(() => {});
    console.log(`serve log:\n${serve.log()}\nscreenshot: ${dir}/failure.png`);
    throw e;
  }
});
