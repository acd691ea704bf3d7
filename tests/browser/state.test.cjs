// The header says what the pipeline does (not "live" while nothing runs): running while the
// scene's 100 frames play at their rate, then ended; and the floor map has its axes in metres
// and a scale.
'use strict';
const test = require('node:test');
const assert = require('node:assert');
const h = require('./harness.cjs');

test('the pipeline state in the header, metre axes and a scale on the map', { timeout: 240000 }, async (t) => {
  const s = await h.start(t, 'state');
  const page = await s.open('/');
  await s.check(async () => {
    const state = page.locator('[data-testid=pipeline-state]');
    await page.waitForFunction(() => document.querySelector('[data-testid=pipeline-state]')?.textContent === 'running',
      null, { timeout: 120000 });
    // The map: tick labels every whole metre (the lab's floor is 9 x 6.5 m) and a scale bar.
    const xs = await page.$$eval('.floor-map .axis-label.axis-x:not(.axis-name)', (els) => els.map((e) => e.textContent));
    const ys = await page.$$eval('.floor-map .axis-label.axis-y:not(.axis-name)', (els) => els.map((e) => e.textContent));
    assert.deepStrictEqual(xs, ['0', '1', '2', '3', '4', '5', '6', '7', '8', '9']);
    assert.deepStrictEqual(ys, ['0', '1', '2', '3', '4', '5', '6']);
    assert.strictEqual(await page.textContent('.floor-map .axis-name.axis-x'), 'x (m)');
    assert.match(await page.textContent('.floor-map .leaflet-control-scale-line'), /^\d+(\.\d+)? c?m$/);
    await h.screenshot(page, 'live.png');
    // The scene's videos end after 10 s: the header says so.
    await page.waitForFunction(() => document.querySelector('[data-testid=pipeline-state]')?.textContent === 'ended',
      null, { timeout: 120000 });
    assert.match(await state.getAttribute('title'), /the pipeline stopped: end of streams/);
  });
});
