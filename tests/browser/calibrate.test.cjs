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

test('setup: four clicked floor points calibrate a camera, saved to the site file', { timeout: 240000 }, async (t) => {
  const s = await h.start(t, 'calibrate');
  const page = await s.open('/#setup');
  await s.check(async () => {
    await h.picturesLoaded(page, '[data-testid=camera-map] img.leaflet-image-layer', 30000);
    const points = h.spreadFloorPoints('cam1');
    assert.strictEqual(points.length, 4);
    await h.clickFloorPoints(page, points);
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

// One point's x and y swapped (the case): the page names it as an outlier, with the RMS
// the others give without it; Save warns and writes nothing until "Save anyway"; the server
// refuses the same save without "force".
test('setup: a mistyped floor point is named, and Save asks before using it', { timeout: 240000 }, async (t) => {
  const s = await h.start(t, 'calibrate-outlier');
  const page = await s.open('/#setup');
  await s.check(async () => {
    await h.picturesLoaded(page, '[data-testid=camera-map] img.leaflet-image-layer', 30000);
    const points = h.spreadFloorPoints('cam1', 6);
    const bad = points.findIndex((p) => Math.abs(p.x_m - p.y_m) > 1);
    assert.ok(bad >= 0, 'a point whose swap moves it');
    points[bad] = { ...points[bad], x_m: points[bad].y_m, y_m: points[bad].x_m };
    await h.clickFloorPoints(page, points);
    await page.click('[data-testid=calibrate]');
    await page.waitForSelector('[data-testid=calibration-concerns]', { timeout: 30000 });
    const flags = await page.$$eval('[data-testid=points] tr[data-outlier]', (trs) => trs.map((tr) => tr.dataset.outlier));
    assert.deepStrictEqual(flags, points.map((_, i) => String(i === bad)), 'only the swapped point is an outlier');
    const concerns = await page.textContent('[data-testid=calibration-concerns]');
    assert.match(concerns, new RegExp(`points\\[${bad}\\]: pixel .* px from where the other points put it`));
    // Over the threshold, or not finite (a swapped point the pose puts behind the camera: '–').
    const rms = (await page.textContent('[data-testid=rms-px]')).trim();
    assert.ok(rms === '–' || Number(rms) > 4, `RMS ${rms} px with the swapped point`);
    await h.screenshot(page, 'serve-calibrate-outlier.png');

    // The API refuses it without force.
    const refused = await page.evaluate(() => fetch('/api/site', {
      method: 'PUT', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify({ calibrations: { cam1: 'pending' } }),
    }).then(async (r) => [r.status, (await r.json()).error]));
    assert.strictEqual(refused[0], 400);
    assert.match(refused[1], /^calibrations\.cam1: not saved: points\[\d\]: .*save with "force": true$/);

    // Save warns; keeping the current calibration writes nothing.
    await page.click('[data-testid=save]');
    await page.waitForSelector('[data-testid=save-confirm]');
    assert.match(await page.textContent('[data-testid=save-confirm]'), /cam1: points\[\d\]: pixel/);
    await h.screenshot(page, 'serve-calibrate-confirm.png');
    await page.click('[data-testid=save-cancel]');
    assert.strictEqual(await page.locator('[data-testid=save-confirm]').count(), 0);
    assert.strictEqual(fs.readFileSync(s.site, 'utf8'), s.original, 'nothing written without the confirmation');
    // Confirmed: saved.
    await page.click('[data-testid=save]');
    await page.click('[data-testid=save-anyway]');
    // Forced past the concerns; the site's loader still checks the camera (a pose this wrong may
    // not see the floor grid: then its message, and nothing written).
    await page.waitForSelector('[data-testid=save-message]', { timeout: 60000 });
    const said = await page.textContent('[data-testid=save-message]');
    assert.doesNotMatch(said, /not saved/, said);
    if (await page.locator('[data-testid=save-message].ok').count()) assert.match(fs.readFileSync(s.site, 'utf8'), /serve_extr_cam1\.xml/);
    else assert.strictEqual(fs.readFileSync(s.site, 'utf8'), s.original, said);
  });
});
