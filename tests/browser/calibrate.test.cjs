// Calibration in a real browser: on camera cam1's frame, click four floor points at their true
// pixels (the scene's own calibration, tests/project_floor_points.py), type their positions in
// metres, Calibrate: the page shows an RMS below 1 px and the grid overlay of the new camera.
'use strict';
const test = require('node:test');
const assert = require('node:assert');
const h = require('./harness.cjs');

// Four floor points of cam1's view, spread and with no three on a line, from candidates.
function chooseFloorPoints(camera) {
  const candidates = [];
  for (let x = 0.5; x <= 8.5; x += 1) for (let y = 0.5; y <= 6.0; y += 1) candidates.push([x, y]);
  const pts = h.trueFloorPoints(camera, candidates)
    .filter((p) => p.u_px > 40 && p.u_px < 600 && p.v_px > 40 && p.v_px < 440);
  assert.ok(pts.length >= 4, `cam1 sees ${pts.length} candidate points`);
  // Spread: the two farthest apart, then each time the point farthest from those chosen.
  const d2 = (a, b) => (a.u_px - b.u_px) ** 2 + (a.v_px - b.v_px) ** 2;
  let chosen = [pts[0]];
  chosen = [pts.reduce((best, p) => (d2(p, chosen[0]) > d2(best, chosen[0]) ? p : best))];
  while (chosen.length < 4) {
    const far = (p) => Math.min(...chosen.map((c) => d2(p, c)));
    chosen.push(pts.reduce((best, p) => (far(p) > far(best) ? p : best)));
  }
  return chosen;
}

test('setup: four clicked floor points calibrate a camera', { timeout: 240000 }, async (t) => {
  const dir = h.tempDir('calibrate');
  const site = h.siteCopy(dir);
  const serve = await h.startServe(site);
  const browser = await h.launchBrowser();
  t.after(async () => { await browser.close(); await serve.stop(); });
  const page = await h.openPage(browser, serve.url + '/#setup');
  try {
    await page.waitForSelector('[data-testid=camera-map] img.leaflet-image-layer', { timeout: 30000 });
    await page.waitForFunction(() => {
      const img = document.querySelector('[data-testid=camera-map] img.leaflet-image-layer');
      return img.complete && img.naturalWidth > 0;
    }, null, { timeout: 30000 });
    const points = chooseFloorPoints('cam1');
    assert.strictEqual(points.length, 4);
    for (const [i, p] of points.entries()) {
      const at = await page.evaluate(([u, v]) => window.occmap.cameraToClient(u, v), [p.u_px, p.v_px]);
      await page.mouse.click(at.x, at.y);
      await page.fill(`[data-testid=x-${i}]`, String(p.x_m));
      await page.fill(`[data-testid=y-${i}]`, String(p.y_m));
    }
    assert.strictEqual(await page.locator('[data-testid=points] tr').count(), 5, 'a header and four points');
    await page.click('[data-testid=calibrate]');
    await page.waitForSelector('[data-testid=rms-px]', { timeout: 30000 });
    const rms = Number(await page.textContent('[data-testid=rms-px]'));
    assert.ok(rms < 1, `RMS ${rms} px, want < 1`);
    // The picture is now the floor grid of the pending calibration.
    await page.waitForFunction(() => {
      const img = document.querySelector('[data-testid=camera-map] img.leaflet-image-layer');
      return /overlay=grid/.test(img.src) && img.complete && img.naturalWidth > 0;
    }, null, { timeout: 30000 });
    await h.screenshot(page, 'serve-calibrate.png');
    assert.deepStrictEqual(page.errors, []);
  } catch (e) {
    await page.screenshot({ path: `${dir}/failure.png` });
    console.log(`serve log:\n${serve.log()}\nscreenshot: ${dir}/failure.png`);
    throw e;
  }
});
