// Another site's page in a real browser: it may send writes to `occmap serve` on loopback without
// asking (a text/plain fetch, a form), and with DNS rebinding read its answers under its own
// name. Chromium's --host-resolver-rules stands in for the rebinding DNS (attacker.test ->
// 127.0.0.1). The evidence is the server's state: a calibration planted by a write shows as the
// camera's pending calibration (its grid picture), which only the server's own page may make.
'use strict';
const test = require('node:test');
const assert = require('node:assert');
const http = require('node:http');
const { chromium } = require('playwright-core');
const h = require('./harness.cjs');

function listen(server) {
  return new Promise((resolve) => server.listen(0, '127.0.0.1', () => resolve(server.address().port)));
}

test('cross-origin writes are refused, a rebinding name is refused, the own page works', { timeout: 240000 }, async (t) => {
  const s = await h.start(t, 'cross-origin');
  const port = Number(new URL(s.base).port);
  // The attacker's pages: another origin of the same site (127.0.0.1, another port) and another
  // site (localhost).
  const evil = http.createServer((req, res) => {
    res.setHeader('Content-Type', 'text/html');
    res.end('<!doctype html><title>a page elsewhere</title><p>hello</p>');
  });
  const evilPort = await listen(evil);
  t.after(() => evil.close());
  const browser = await chromium.launch({
    executablePath: ['/usr/bin/chromium-headless-shell', '/usr/bin/chromium'].find((f) => require('node:fs').existsSync(f)),
    args: ['--no-sandbox', '--host-resolver-rules=MAP attacker.test 127.0.0.1'],
    headless: true,
  });
  t.after(() => browser.close());

  const points = h.spreadFloorPoints('cam1', 4);
  const body = JSON.stringify({ camera: 'cam1', points, method: 'homography' });
  const pendingStatus = () => fetch(`${s.base}/api/cameras/cam1/frame.jpg?overlay=grid&calibration=pending`).then((r) => r.status);
  await s.check(async () => {
    // cam1's first frame: the pending picture's 404 then means "no pending calibration".
    for (let i = 0; i < 120 && (await fetch(`${s.base}/api/cameras/cam1/frame.jpg`)).status !== 200; ++i) {
      await new Promise((r) => setTimeout(r, 500));
    }
    assert.strictEqual(await pendingStatus(), 404, 'no pending calibration at the start');

    for (const origin of [`http://127.0.0.1:${evilPort}`, `http://localhost:${evilPort}`]) {
      const page = await browser.newPage();
      await page.goto(`${origin}/`);
      // A "simple" request: no preflight, the browser sends it and hides the answer.
      await page.evaluate(([url, b]) => fetch(url, { method: 'POST', mode: 'no-cors', headers: { 'Content-Type': 'text/plain' }, body: b })
        .catch(() => null), [`${s.base}/api/calibrate`, body]);
      // The same body as JSON: the browser asks first (CORS preflight), is never granted.
      const json = await page.evaluate(([url, b]) => fetch(url, { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: b })
        .then((r) => `HTTP ${r.status}`, (e) => e.name), [`${s.base}/api/calibrate`, body]);
      assert.strictEqual(json, 'TypeError', `${origin}: a JSON POST is blocked by the browser`);
      // A form whose text/plain body is the JSON: {"camera": ..., "x": "="}.
      await Promise.all([page.waitForNavigation({ waitUntil: 'load' }), page.evaluate(([url, b]) => {
        const form = document.createElement('form');
        form.method = 'POST';
        form.action = url;
        form.enctype = 'text/plain';
        const input = document.createElement('input');
        input.name = `${b.slice(0, -1)}, "x": "`;
        input.value = '"}';
        form.appendChild(input);
        document.body.appendChild(form);
        form.submit();
      }, [`${s.base}/api/calibrate`, body])]);
      const formAnswer = await page.textContent('body');
      assert.match(formAnswer, /another (site|origin)/, `${origin}: the form's answer: ${formAnswer}`);
      await page.close();
      assert.strictEqual(await pendingStatus(), 404, `${origin}: no calibration planted`);
    }

    // Rebinding: attacker.test resolves to the server; the browser takes it for attacker.test's
    // own origin, the Host header still says so.
    const rebound = await browser.newPage();
    const site = await rebound.goto(`http://attacker.test:${port}/api/site`);
    assert.strictEqual(site.status(), 403, 'GET /api/site under a foreign name');
    const put = await rebound.evaluate(() => fetch('/api/site', { method: 'PUT', headers: { 'Content-Type': 'application/json' },
      body: JSON.stringify({ zones: [] }) }).then((r) => r.status));
    assert.strictEqual(put, 403, 'PUT /api/site under a foreign name');
    const picture = await rebound.evaluate(() => fetch('/api/cameras/cam1/frame.jpg').then((r) => r.status));
    assert.strictEqual(picture, 403, 'a camera picture under a foreign name');
    await rebound.close();
    assert.strictEqual(require('node:fs').readFileSync(s.site, 'utf8'), s.original, 'the site file is unchanged');

    // The server's own page, by address and by localhost: the same body is taken.
    for (const base of [s.base, `http://localhost:${port}`]) {
      const own = await browser.newPage();
      await own.goto(`${base}/`);
      const status = await own.evaluate((b) => fetch('/api/calibrate', { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: b })
        .then((r) => r.status), body);
      assert.strictEqual(status, 200, `${base}: the own page calibrates`);
      await own.close();
    }
    assert.strictEqual(await pendingStatus(), 200, 'the own page planted its calibration');
  });
});
