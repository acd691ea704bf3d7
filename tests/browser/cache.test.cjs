// The live view shows each live camera's cached background (issue 17): the lab's four cameras
// streamed over UDP, their backgrounds learned by the adaptive model and written back every
// second (backgrounds.refresh_cache_s), into a cache folder where a regular file stands in
// place of backgrounds/ (the tests may run as root, whom no mode stops): every write fails. The
// Cameras panel shows per camera that no write worked yet, the failures counting up, and the
// last error naming the entry; the server goes on.
'use strict';
const test = require('node:test');
const assert = require('node:assert');
const fs = require('node:fs');
const path = require('node:path');
const h = require('./harness.cjs');

test('live view: the cached backgrounds\' state per camera', { timeout: 240000 }, async (t) => {
  let cache = null;
  const s = await h.start(t, 'cache', {
    streams: true,
    cache: (dir) => {
      cache = path.join(dir, 'cache');
      fs.mkdirSync(cache);
      fs.writeFileSync(path.join(cache, 'backgrounds'), 'not a folder');
      return cache;
    },
    editSite: (text) => text.replace(/^ *background: .*\n/gm, '').replace(/^backgrounds:.*\n( .*\n)*/m, '') +
      'backgrounds: {adaptive: true, learn_s: 2, learn_samples: 10, refresh_cache_s: 1}\n',
  });
  const page = await s.open('/system');  // the cameras' table is a developer's
  await s.check(async () => {
    // Two failed writes per camera at least: the count goes up while the run goes on.
    await page.waitForFunction(() => {
      const cells = [...document.querySelectorAll('.cams [data-testid=cache-failures]')];
      return cells.length === 4 && cells.every((c) => parseInt(c.textContent, 10) >= 2);
    }, null, { timeout: 120000 });
    const rows = await page.$$eval('.cams tr[data-camera]', (trs) => trs.map((tr) => ({
      id: tr.dataset.camera,
      age: tr.querySelector('[data-testid=cache-age]').textContent,
      failures: tr.querySelector('[data-testid=cache-failures]').textContent,
    })));
    assert.deepStrictEqual(rows.map((r) => r.id), ['cam1', 'cam2', 'cam3', 'cam4']);
    for (const r of rows) {
      assert.strictEqual(r.age, 'not yet', JSON.stringify(r));
      assert.match(r.failures, /^\d+ failed$/, JSON.stringify(r));
    }
    const errors = await page.$$eval('.cams [data-testid=cache-error]', (tds) => tds.map((td) => td.textContent));
    assert.strictEqual(errors.length, 4, JSON.stringify(errors));
    for (const [k, e] of errors.entries()) {
      assert.ok(e.startsWith(`cache: camera cam${k + 1}: refreshing its cached background: `), e);
      assert.ok(e.includes(path.join(cache, 'backgrounds')), e);
    }
    // As /api/state says.
    const st = await page.evaluate(() => fetch('/api/state').then((r) => r.json()));
    assert.ok(st.cameras.every((c) => c.background_cache && c.background_cache.refreshes === 0 &&
      c.background_cache.failures >= 2), JSON.stringify(st.cameras));
    assert.ok(st.running, 'the run goes on');
    await h.screenshot(page, 'live-cache.png');
    // The server said so once per camera on stderr (and once more at start-up for the learned entry).
    const said = s.serve.log().split('\n').filter((l) => l.includes('refreshing its cached background'));
    assert.strictEqual(said.length, 4, said.join('\n'));
  });
});
