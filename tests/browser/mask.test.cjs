// A floor mask in a real browser: camera cam2's mask picture is shown over its frame; replacing
// it chosen, draw a polygon with the mask tool,
// (a click where geoman's Finish / Cancel pop-up would be reaches the picture), save: the site
// file has it as the camera's mask polygon (`occmap check` loads it); reloaded,
// the page shows the polygon again and /api/site lists it.
'use strict';
const test = require('node:test');
const assert = require('node:assert');
const fs = require('node:fs');
const h = require('./harness.cjs');

async function clickPixel(page, u, v) {
  const at = await page.evaluate(([x, y]) => window.occmap.cameraToClient(x, y), [u, v]);
  await page.mouse.click(at.x, at.y);
}

test('setup: a floor mask polygon drawn, saved and reloaded', { timeout: 240000 }, async (t) => {
  const s = await h.start(t, 'mask');
  const page = await s.open('/#setup');
  const corners = [[60, 180], [580, 180], [620, 470], [20, 470]];
  await s.check(async () => {
    await page.click('.cam-tabs button[data-camera=cam2]');
    await h.picturesLoaded(page, '[data-testid=camera-map] img.leaflet-image-layer', 30000);
    await page.check('[data-testid=mode-mask]');

    // The site's mask picture (masks/cam2.png) is shown over the frame, and the drawing tools
    // wait until replacing it is chosen.
    assert.match(await page.textContent('[data-testid=mask-file]'), /mask is the picture masks\/cam2\.png/);
    await page.waitForFunction(() => {
      const img = document.querySelector('[data-testid=camera-map] img.mask-file-image');
      return img && img.complete && img.naturalWidth === 640 && img.naturalHeight === 480;
    }, null, { timeout: 30000 });
    assert.strictEqual(await page.locator('[data-testid=camera-map] .leaflet-pm-icon-polygon').count(), 0, 'no drawing over the picture yet');
    await h.screenshot(page, 'serve-mask-file.png');
    await page.click('[data-testid=mask-replace]');
    assert.match(await page.textContent('[data-testid=mask-file]'), /Replacing masks\/cam2\.png/);
    await page.click('[data-testid=camera-map] .leaflet-pm-icon-polygon');

    // Geoman's Finish / Cancel pop-up would open beside the tool, over the picture: it is hidden
    // and a click where it would be reaches the map (a corner); the buttons above the map do its
    // work ("Remove last corner" takes that corner back).
    const popup = await page.evaluate(() => {
      const el = [...document.querySelectorAll('[data-testid=camera-map] .leaflet-pm-actions-container')]
        .find((e) => e.parentElement.querySelector('.leaflet-pm-icon-polygon'));
      const shown = getComputedStyle(el).display;
      el.style.setProperty('display', 'flex', 'important');
      const r = el.getBoundingClientRect();
      el.style.removeProperty('display');
      return { shown, x: r.left + r.width / 2, y: r.top + r.height / 2, w: r.width };
    });
    assert.strictEqual(popup.shown, 'none', 'the pop-up is not shown');
    assert.ok(popup.w > 20, `where the pop-up would be: ${JSON.stringify(popup)}`);
    const vertices = () => page.evaluate(() => window.occmap.cameraMap.pm.Draw.Polygon._layer.getLatLngs().length);
    assert.strictEqual(await vertices(), 0);
    await page.waitForSelector('[data-testid=draw-actions] [data-testid=draw-finish]');
    await page.mouse.click(popup.x, popup.y);
    assert.strictEqual(await vertices(), 1, 'a click where the pop-up was adds a corner');
    await clickPixel(page, 320, 300);
    assert.strictEqual(await vertices(), 2);
    await page.click('[data-testid=draw-undo]');
    assert.strictEqual(await vertices(), 1, 'Remove last corner takes one back');
    await page.click('[data-testid=draw-cancel]');
    await page.waitForSelector('[data-testid=draw-actions]', { state: 'detached' });
    assert.strictEqual(await page.locator('[data-testid=camera-map] path.leaflet-interactive').count(), 0, 'cancelled: no polygon');
    await page.click('[data-testid=camera-map] .leaflet-pm-icon-polygon');

    for (const [u, v] of corners) await clickPixel(page, u, v);
    await h.screenshot(page, 'serve-mask.png');  // the drawing's buttons above the picture
    await clickPixel(page, ...corners[0]);
    await page.waitForFunction(() => document.querySelectorAll('[data-testid=camera-map] path.leaflet-interactive').length === 1);
    assert.strictEqual(await page.locator('[data-testid=draw-actions]').count(), 0, 'the drawing buttons go with the drawing');
    assert.match(await page.textContent('.savebar'), /masks of cam2 \(replacing masks\/cam2\.png\)/);

    await page.click('[data-testid=save]');
    await page.waitForSelector('[data-testid=save-message].ok', { timeout: 60000 });
    h.assertSiteValid(s.site);
    const saved = fs.readFileSync(s.site, 'utf8');
    assert.match(saved, /mask: \{polygons: \[\[\[/, 'cam2 has a mask polygon in the site file');

    // Reloaded: the polygon is read back from the file.
    await page.reload();
    await page.click('.cam-tabs button[data-camera=cam2]');
    await page.check('[data-testid=mode-mask]');
    await page.waitForFunction(() => document.querySelectorAll('[data-testid=camera-map] path.leaflet-interactive').length === 1,
      null, { timeout: 30000 });
    const site = await page.evaluate(() => fetch('/api/site').then((r) => r.json()));
    const cam2 = site.cameras.find((c) => c.id === 'cam2');
    assert.strictEqual(cam2.mask_polygons_px.length, 1, JSON.stringify(cam2));
    const poly = cam2.mask_polygons_px[0];
    assert.strictEqual(poly.length, 4);
    // Where the clicks landed: a screen pixel spans about 1.6 of the image's at the page's zoom.
    poly.forEach(([u, v], i) => {
      assert.ok(Math.abs(u - corners[i][0]) <= 3 && Math.abs(v - corners[i][1]) <= 3, `corner ${i}: (${u}, ${v}) for ${corners[i]}`);
    });
    assert.ok(cam2.has_mask);
    assert.strictEqual(cam2.mask_file, null, 'the picture replaced by the polygon');
    assert.strictEqual(await page.locator('[data-testid=mask-file]').count(), 0);
  });
});
