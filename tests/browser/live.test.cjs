// The live view in a real browser: the rendered lab's four cameras streamed in real time over
// UDP, `occmap serve` on them; the page shows the map picture, the camera pictures refreshed
// with their state (up, background age), and tracks whose positions on the page change between
// two moments; the events of a zone and a line listed with their times; the stage timings are on
// the system page its link opens, not on the live page.
'use strict';
const test = require('node:test');
const assert = require('node:assert');
const h = require('./harness.cjs');

async function trackLabels(page) {
  return page.$$eval('.floor-map .leaflet-tooltip.track-label', (els) =>
    els.map((e) => ({ id: e.textContent, at: e.getBoundingClientRect().left + ',' + e.getBoundingClientRect().top })));
}

test('live view: map, cameras and moving tracks', { timeout: 240000 }, async (t) => {
  // A zone over the room and a line across it: their events are listed with their times.
  const s = await h.start(t, 'live', {
    streams: true,
    editSite: (text) => `${text.replace(/\n*$/, '\n')}tracking:\n  zones:\n    - {name: room, polygon: [[0.5, 0.5], [8.5, 0.5], [8.5, 6.0], [0.5, 6.0]]}\n`
      + '  lines:\n    - {name: middle, from: [4.5, 0.2], to: [4.5, 6.3]}\n',
  });
  const page = await s.open('/');
  await s.check(async () => {
    // The map picture arrives and is refreshed: its URL carries the frame of the map.
    await page.waitForFunction(() => {
      const img = document.querySelector('.floor-map img.map-image');
      return img && img.complete && img.naturalWidth > 0 && !/[?&]v=0\b/.test(img.src);
    }, null, { timeout: 60000 });
    const grid = await page.evaluate(() => fetch('/api/site').then((r) => r.json()).then((site) => site.grid));
    // One pixel per cell (read while no newer picture is loading).
    await page.waitForFunction((g) => {
      const img = document.querySelector('.floor-map img.map-image');
      return img.complete && img.naturalWidth === g.cols && img.naturalHeight === g.rows;
    }, grid, { timeout: 10000 });

    // Tracks appear; some track's label moves between two moments 1 s apart (tried for up to
    // 30 s: a new scene starts with tracks being confirmed and lost).
    await page.waitForFunction(() => document.querySelectorAll('.floor-map .track-label').length > 0, null, { timeout: 60000 });
    let moved = [];
    const samples = [];
    for (let i = 0; i < 30 && moved.length === 0; i += 1) {
      const before = await trackLabels(page);
      await page.waitForTimeout(1000);
      const after = await trackLabels(page);
      moved = after.filter((a) => before.some((b) => b.id === a.id && b.at !== a.at));
      samples.push([before, after]);
    }
    assert.ok(moved.length > 0, `no track moved on the page: ${JSON.stringify(samples.slice(-3))}`);

    // Every camera tile shows a picture and its camera is up; the pictures are refreshed.
    await h.picturesLoaded(page, '.tile img', 30000);
    assert.strictEqual(await page.locator('.tile').count(), 4);
    await page.waitForFunction(() => document.querySelectorAll('.tile .badge.up').length === 4, null, { timeout: 30000 });
    const tileFrame = () => page.$eval('.tile[data-camera=cam1]', (e) => Number(e.dataset.frame));
    const shown1 = await tileFrame();
    const frame1 = Number(await page.textContent('[data-testid=frame]'));
    await page.waitForTimeout(1500);
    const frame2 = Number(await page.textContent('[data-testid=frame]'));
    assert.ok(frame2 > frame1, `the frame number advances (${frame1}, then ${frame2})`);
    const shown2 = await tileFrame();
    assert.ok(shown2 > shown1, `cam1's picture is refreshed (frame ${shown1}, then ${shown2})`);

    // Stage timings, from /api/state: measured, and shown on the system page (its link on the
    // live page), which the live page leaves out.
    assert.strictEqual(await page.locator('[data-testid=stages], .cams').count(), 0, 'no developer tables on the live page');
    assert.strictEqual(await page.getAttribute('[data-testid=system-link]', 'href'), '/system');
    const sys = await s.open('/system');
    await sys.waitForFunction(() => {
      const row = document.querySelector('[data-testid=stages] tr[data-stage=decode] td.num');
      return row && parseFloat(row.textContent) > 0;
    }, null, { timeout: 30000 });
    const stages = await sys.$$eval('[data-testid=stages] tr', (rows) => rows.map((r) => r.dataset.stage));
    for (const k of ['tables', 'decode', 'detect', 'fuse', 'blobs', 'track', 'output']) assert.ok(stages.includes(k), `stage ${k} in ${stages}`);
    await sys.waitForFunction(() => document.querySelectorAll('.cams tr[data-camera]').length === 4, null, { timeout: 10000 });
    assert.strictEqual(await sys.getAttribute('header a[data-tab=system]', 'class'), 'active');
    await sys.waitForFunction(() => /"frames"/.test(document.querySelector('[data-testid=summary]').textContent), null, { timeout: 30000 });
    await h.screenshot(sys, 'serve-system.png');
    await sys.close();
    // The lab's backgrounds are given and fixed: they age with the run.
    const ages = await page.$$eval('.tile [data-testid=tile-bg-age]', (els) => els.map((e) => e.textContent));
    assert.ok(ages.every((a) => /^bg \d+ s$/.test(a)), `background ages on the tiles: ${ages}`);
    const state = await page.evaluate(() => fetch('/api/state').then((r) => r.json()));
    assert.ok(state.cameras.every((c) => c.background_age_s > 0), `background_age_s: ${JSON.stringify(state.cameras)}`);
    assert.ok(state.stages_s.decode > 0 && state.stages_s.output > 0, `stages_s: ${JSON.stringify(state.stages_s)}`);
    // The events list: zone entries (and crossings) with their times, newest first.
    await page.waitForFunction(() => document.querySelectorAll('[data-testid=events] tr[data-event]').length > 0, null, { timeout: 90000 });
    const rows = await page.$$eval('[data-testid=events] tr[data-event]', (trs) => trs.map((tr) => tr.textContent.replace(/\s+/g, ' ').trim()));
    assert.ok(rows.some((r) => /^\d\d:\d\d:\d\d ?track \d+ (entered|left) room \(\d+ inside\)$/.test(r)), `events: ${JSON.stringify(rows)}`);
    assert.strictEqual(await page.locator('[data-testid=events] tr[data-event=count]').count(), 0, 'count events repeat the entries');
    const api = await page.evaluate(() => fetch('/api/events').then((r) => r.json()));
    assert.ok(api.events_total >= rows.length && api.events.length > 0, JSON.stringify(api).slice(0, 300));
    await h.screenshot(page, 'serve-live.png');

    // cam4's stream stops: its tile says so while the others stay up.
    await h.stopProcess(s.senders[3]);
    await page.waitForFunction(() => {
      const badge = document.querySelector('.tile[data-camera=cam4] [data-testid=camera-condition]');
      return badge && /reconnecting|lost/.test(badge.textContent);
    }, null, { timeout: 60000 });
    assert.strictEqual(await page.locator('.tile .badge.up').count(), 3);
  });
});
