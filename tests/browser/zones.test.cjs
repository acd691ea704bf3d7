// Zones in a real browser, on the live lab streams: the cameras' coverage shown on the setup
// map; a zone drawn on it and saved is written to the site file (valid for `occmap check`, the
// old file kept as .bak), and its count appears in the live view once the pipeline runs on the
// new site. A name the loader refuses shows the loader's message and writes nothing.
'use strict';
const test = require('node:test');
const assert = require('node:assert');
const fs = require('node:fs');
const h = require('./harness.cjs');

async function clickFloor(page, x, y) {
  const at = await page.evaluate(([px, py]) => window.occmap.setupFloorToClient(px, py), [x, y]);
  await page.mouse.click(at.x, at.y);
}

test('setup: coverage shown; a zone drawn and saved gets its count in the live view', { timeout: 300000 }, async (t) => {
  const s = await h.start(t, 'zones', { streams: true });
  const page = await s.open('/#setup');
  await s.check(async () => {
    // The first frame set's map and camera picture, before drawing.
    await h.picturesLoaded(page, '.leaflet-image-layer');

    // The coverage: a picture of a pixel per cell in place of the live map, and its legend
    // (unseen, then 1..4 cameras).
    await page.check('[data-testid=show-coverage]');
    const grid = await page.evaluate(() => fetch('/api/site').then((r) => r.json()).then((site) => site.grid));
    await page.waitForFunction((g) => {
      const img = document.querySelector('[data-testid=zone-map] img.coverage-image');
      return img && img.complete && img.naturalWidth === g.cols && img.naturalHeight === g.rows;
    }, grid, { timeout: 60000 });
    assert.strictEqual(await page.locator('[data-testid=coverage-legend] [data-count]').count(), 5);
    const coverage = await page.evaluate(() => fetch('/api/coverage').then((r) => r.json()));
    assert.strictEqual(coverage.cells, grid.cols * grid.rows);
    assert.ok(coverage.cells_seen_by[4] > coverage.cells / 2, `the lab's floor is mostly seen by all 4: ${coverage.cells_seen_by}`);
    await h.screenshot(page, 'serve-coverage.png');

    // Most of the room, so that the lab's walkers are in it.
    await page.click('[data-testid=draw-zone]');
    const corners = [[0.5, 0.5], [8.5, 0.5], [8.5, 6.0], [0.5, 6.0]];
    for (const [x, y] of corners) await clickFloor(page, x, y);
    await clickFloor(page, ...corners[0]);
    await page.waitForSelector('[data-testid=zone-name-0]');
    assert.strictEqual(await page.inputValue('[data-testid=zone-name-0]'), 'zone1');
    await page.uncheck('[data-testid=show-coverage]');
    await h.screenshot(page, 'serve-zones.png');

    // A name the loader refuses: its message is shown, the file is untouched.
    await page.fill('[data-testid=zone-name-0]', '');
    await page.click('[data-testid=save]');
    await page.waitForSelector('[data-testid=save-message].error', { timeout: 30000 });
    const refusal = await page.textContent('[data-testid=save-message]');
    assert.match(refusal, /zone|name/i, `the loader's message: ${refusal}`);
    assert.strictEqual(fs.readFileSync(s.site, 'utf8'), s.original, 'nothing written on a refused save');

    await page.fill('[data-testid=zone-name-0]', 'room');
    await page.click('[data-testid=save]');
    await page.waitForSelector('[data-testid=save-message].ok', { timeout: 60000 });
    h.assertSiteValid(s.site);
    assert.match(fs.readFileSync(s.site, 'utf8'), /room/, 'the zone is in the saved site file');
    assert.strictEqual(fs.readFileSync(s.site + '.bak', 'utf8'), s.original, 'the previous file kept as .bak');

    // The live view lists the zone and its count arrives with the frames.
    await page.click('a[data-tab=live]');
    await page.waitForFunction(() => {
      const row = document.querySelector('[data-testid=zone-counts] tr[data-zone=room] td.num');
      return row && /^\d+$/.test(row.textContent.trim());
    }, null, { timeout: 90000 });
    await page.waitForFunction(() => document.querySelector('.floor-map .zone-label') !== null);
  });
});
