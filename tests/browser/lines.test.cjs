// Counting lines' rules through the page: a line written by hand with its own hysteresis band
// and counting every crossing keeps both when the page saves the zones and lines (they were
// dropped before); a band typed in the list, slowly while the page re-renders, is saved.
'use strict';
const test = require('node:test');
const assert = require('node:assert');
const fs = require('node:fs');
const h = require('./harness.cjs');

async function clickFloor(page, x, y) {
  const at = await page.evaluate(([px, py]) => window.occmap.setupFloorToClient(px, py), [x, y]);
  await page.mouse.click(at.x, at.y);
}

test('setup: a counting line keeps its hysteresis band and once-per-track rule when saved', { timeout: 240000 }, async (t) => {
  const s = await h.start(t, 'lines', {
    editSite: (text) => `${text.replace(/\n*$/, "\n")}tracking:\n  lines:\n    - {name: door, from: [2, 1], to: [2, 5], hysteresis_m: 0.5, once_per_track: false}\n`,
  });
  const page = await s.open('/#setup');
  await s.check(async () => {
    const site = await page.evaluate(() => fetch('/api/site').then((r) => r.json()));
    assert.deepStrictEqual(site.lines.map((l) => [l.name, l.hysteresis_m, l.once_per_track]), [['door', 0.5, false]]);
    await page.waitForSelector('[data-testid=line-band-0]');
    assert.strictEqual(await page.inputValue('[data-testid=line-band-0]'), '0.5');
    assert.strictEqual(await page.isChecked('[data-testid=line-once-0]'), false);

    // A zone drawn beside it: zones and lines are saved together.
    await page.click('[data-testid=draw-zone]');
    const corners = [[4, 1], [7, 1], [7, 4], [4, 4]];
    for (const [x, y] of corners) await clickFloor(page, x, y);
    await clickFloor(page, ...corners[0]);
    await page.waitForSelector('[data-testid=zone-name-0]');
    await page.click('[data-testid=save]');
    await page.waitForSelector('[data-testid=save-message].ok', { timeout: 60000 });
    h.assertSiteValid(s.site);
    let saved = fs.readFileSync(s.site, 'utf8');
    assert.match(saved, /name: "door", from: \[2, 1\], to: \[2, 5\], hysteresis_m: 0\.5, once_per_track: false/, saved);

    // The band changed in the list, typed as a person types (the page re-renders with every
    // frame event meanwhile: the typed text must survive them), the rule switched on.
    await page.click('[data-testid=line-band-0]', { clickCount: 3 });
    await page.keyboard.type('0.3', { delay: 200 });
    assert.strictEqual(await page.inputValue('[data-testid=line-band-0]'), '0.3', 'the text typed stays');
    await page.keyboard.press('Enter');
    await page.check('[data-testid=line-once-0]');
    await page.click('[data-testid=save]');
    await page.waitForFunction(() => document.querySelector('[data-testid=save]').disabled, null, { timeout: 60000 });
    await page.waitForSelector('[data-testid=save-message].ok', { timeout: 60000 });
    saved = fs.readFileSync(s.site, 'utf8');
    assert.match(saved, /name: "door", from: \[2, 1\], to: \[2, 5\], hysteresis_m: 0\.3, once_per_track: true/, saved);
    const after = await page.evaluate(() => fetch('/api/site').then((r) => r.json()));
    assert.deepStrictEqual(after.lines.map((l) => [l.hysteresis_m, l.once_per_track]), [[0.3, true]]);
  });
});
