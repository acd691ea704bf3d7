// A run that fails shows why on the page, not only in the terminal: camera cam1's calibration
// says 1280x720 (a new user's slip: the README's example size) while its video and background
// are 640x480.
'use strict';
const test = require('node:test');
const assert = require('node:assert');
const h = require('./harness.cjs');

test('a failed run: its message in a banner and in the pipeline panel', { timeout: 240000 }, async (t) => {
  const s = await h.start(t, 'failure', {
    editSite: (text) => text
      .replace(/calibration: \{format: opencv, intrinsic: calib\/intr_cam1\.xml[^}]*\}/,
        'calibration: {format: homography, floor_from_image: [[0.01, 0, 0], [0, 0.01, 0], [0, 0, 1]], unit: m, image_size: [1280, 720]}')
      .replace('mask: masks/cam1.png', ''),
  });
  const page = await s.open('/');
  await s.check(async () => {
    await page.waitForSelector('[data-testid=pipeline-error]', { timeout: 120000 });
    const banner = await page.textContent('[data-testid=pipeline-error]');
    assert.match(banner, /640x480, expected the (site's )?image size 1280x720/, banner);
    assert.match(banner, /Correct the site file/);
    assert.strictEqual(await page.textContent('[data-testid=pipeline-state]'), 'failed', 'the header no longer says live');
    const st = await page.evaluate(() => fetch('/api/state').then((r) => r.json()));
    assert.strictEqual(st.running, false);
    assert.match(st.stop_reason, /^error: .*1280x720/);
  });
});
