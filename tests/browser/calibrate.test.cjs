// Calibration in a real browser: on camera cam1's frame, click four floor points at their true
// pixels (the scene's own calibration, tests/project_floor_points.py), type their positions in
// metres, Calibrate: the page shows an RMS below 1 px, the floor error and the grid overlay of
// the new camera; Save writes it into the site file (calib/serve_*.xml beside it), which
// `occmap check` loads.
'use strict';
const test = require('node:test');
const assert = require('node:assert');
const fs = require('node:fs');
const path = require('node:path');
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

test('setup: four clicked floor points calibrate a camera, saved to the site file', { timeout: 240000 }, async (t) => {
  const s = await h.start(t, 'calibrate');
  const page = await s.open('/#setup');
  await s.check(async () => {
    await h.picturesLoaded(page, '[data-testid=camera-map] img.leaflet-image-layer', 30000);
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
    const floorCm = Number(await page.textContent('[data-testid=floor-cm]'));
    assert.ok(floorCm >= 0 && floorCm < 5, `floor error ${floorCm} cm, want < 5`);
    // Each point's own error is listed.
    const perPoint = await page.$$eval('[data-testid=points] td.error-px', (tds) => tds.map((td) => Number(td.textContent)));
    assert.strictEqual(perPoint.length, 4);
    assert.ok(perPoint.every((e) => e >= 0 && e < 2), `per-point errors ${perPoint}`);
    // The picture is now the floor grid of the pending calibration.
    await page.waitForFunction(() => {
      const img = document.querySelector('[data-testid=camera-map] img.leaflet-image-layer');
      return /overlay=grid/.test(img.src) && img.complete && img.naturalWidth > 0;
    }, null, { timeout: 30000 });
    await h.screenshot(page, 'serve-calibrate.png');

    // Saved: the camera's calibration entry names the new files, and the site loads.
    await page.click('[data-testid=save]');
    await page.waitForSelector('[data-testid=save-message].ok', { timeout: 60000 });
    h.assertSiteValid(s.site);
    const saved = fs.readFileSync(s.site, 'utf8');
    assert.match(saved, /serve_intr_cam1\.xml/, 'cam1 names its new intrinsics');
    assert.match(saved, /serve_extr_cam1\.xml/, 'cam1 names its new extrinsics');
    for (const f of ['serve_intr_cam1.xml', 'serve_extr_cam1.xml']) {
      assert.ok(fs.existsSync(path.join(s.dir, 'calib', f)), `${f} beside the site file`);
    }
    assert.strictEqual(fs.readFileSync(s.site + '.bak', 'utf8'), s.original, 'the previous file kept as .bak');
    // Nothing is pending any more, and the pipeline runs on the saved site.
    await page.waitForSelector('[data-testid=save]:disabled');
    await page.waitForFunction(() => fetch('/api/state').then((r) => r.json()).then((st) => st.frame >= 0), null,
      { timeout: 60000, polling: 1000 });
  });
});
