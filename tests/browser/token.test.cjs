// The token in a real browser: `occmap serve --listen 0.0.0.0:0` (not loopback) refuses to start
// without a token; with --token, the page without the token gets 401 and the page with
// ?token= works: the bundle, the API, the event stream and the pictures all carry it.
// (The server is reached through 127.0.0.1 only.)
'use strict';
const test = require('node:test');
const assert = require('node:assert');
const h = require('./harness.cjs');

const kToken = 'browser-test-7f3a9c';

test('a non-loopback address needs a token', { timeout: 60000 }, () => {
  const dir = h.tempDir('token-refused');
  const r = h.runOccmap(['serve', h.siteCopy(dir), '--listen', '0.0.0.0:0', '--out', `${dir}/out`]);
  assert.strictEqual(r.status, 2, `exit ${r.status}: ${r.stdout}${r.stderr}`);
  assert.match(r.stderr + r.stdout, /token/i);
});

test('with a token: refused without it, the live page works with it', { timeout: 240000 }, async (t) => {
  const s = await h.start(t, 'token', { listen: '0.0.0.0:0', args: ['--token', kToken] });
  const bare = await s.browser.newPage();
  const refused = await bare.goto(s.base + '/');
  assert.strictEqual(refused.status(), 401);
  for (const path of ['/app.js', '/api/site', '/api/map.png', '/api/coverage.png', '/events']) {
    const status = await bare.evaluate((p) => fetch(p).then((r) => r.status), path);
    assert.strictEqual(status, 401, `${path} without the token`);
  }
  const wrong = await bare.evaluate(() => fetch('/api/state', { headers: { Authorization: 'Bearer nope' } }).then((r) => r.status));
  assert.strictEqual(wrong, 401, 'a wrong Bearer token');

  const page = await s.open(`/?token=${kToken}`);
  await s.check(async () => {
    await page.waitForSelector('header .brand', { timeout: 30000 });
    await h.picturesLoaded(page, '.floor-map img.map-image');
    await page.waitForFunction(() => document.querySelector('header .dot.on') !== null, null, { timeout: 30000 });
    await h.picturesLoaded(page, '.tile img', 30000);
    const bearer = await page.evaluate((tk) => fetch('/api/state', { headers: { Authorization: `Bearer ${tk}` } }).then((r) => r.status), kToken);
    assert.strictEqual(bearer, 200, 'the Bearer header');
  });
});
