// The token in a real browser: `occmap serve --listen 0.0.0.0:0` (not loopback) refuses to start
// without a token; with --token, a browser without it is sent to the login page and the API
// answers 401; signing in there keeps the token in an HttpOnly, SameSite=Strict cookie, after which
// the live page, its pictures, its event stream and the system page work with no token in any
// URL; scripts still use the Bearer header or ?token=; an old ?token= link sets the cookie and
// leaves the address bar clean; signing out forgets it. (The server is reached through
// 127.0.0.1 only.)
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

test('with a token: the login page, the cookie, the system page, sign out', { timeout: 240000 }, async (t) => {
  const s = await h.start(t, 'token', { listen: '0.0.0.0:0', args: ['--token', kToken] });
  const page = await s.open('/system');
  const urls = [];
  page.on('request', (r) => urls.push(r.url()));
  await s.check(async () => {
    // Without the token: the login page, which remembers where the visitor was going.
    assert.strictEqual(new URL(page.url()).pathname, '/login');
    assert.strictEqual(new URL(page.url()).searchParams.get('next'), '/system');
    for (const path of ['/app.js', '/api/site', '/api/state', '/api/map.png', '/api/coverage.png', '/events', '/metrics']) {
      const status = await page.evaluate((p) => fetch(p).then((r) => r.status), path);
      assert.strictEqual(status, 401, `${path} without the token`);
    }
    // A wrong token: said, and no cookie.
    await page.fill('[data-testid=login-token]', 'not-the-token');
    await page.click('[data-testid=login-submit]');
    await page.waitForFunction(() => document.querySelector('[data-testid=login-error]').textContent !== '', null, { timeout: 10000 });
    assert.strictEqual(await page.textContent('[data-testid=login-error]'), 'wrong token');
    assert.deepStrictEqual(await page.context().cookies(), []);
    await h.screenshot(page, 'serve-login.png');

    // The right one: the cookie, HttpOnly and SameSite=Strict, and on to the system page.
    await page.fill('[data-testid=login-token]', kToken);
    await page.click('[data-testid=login-submit]');
    await page.waitForURL((u) => u.pathname === '/system', { timeout: 10000 });
    const cookies = await page.context().cookies();
    assert.strictEqual(cookies.length, 1, JSON.stringify(cookies));
    assert.strictEqual(cookies[0].name, 'occmap_token');
    assert.strictEqual(cookies[0].value, Buffer.from(kToken).toString('hex'));
    assert.strictEqual(cookies[0].httpOnly, true);
    assert.strictEqual(cookies[0].sameSite, 'Strict');
    assert.strictEqual(await page.evaluate(() => document.cookie), '', 'no script sees the cookie');
    await page.waitForFunction(() => {
      const row = document.querySelector('[data-testid=stages] tr[data-stage=decode] td.num');
      return row && parseFloat(row.textContent) > 0;
    }, null, { timeout: 60000 });

    // The live page through the header's link: map, pictures and the event stream, on the cookie.
    await page.click('header a[data-tab=live]');
    await page.waitForURL((u) => u.pathname === '/', { timeout: 10000 });
    await h.picturesLoaded(page, '.floor-map img.map-image');
    await page.waitForFunction(() => document.querySelector('header [data-testid=pipeline-state]')?.textContent === 'running'
      || document.querySelector('header [data-testid=pipeline-state]')?.textContent === 'ended', null, { timeout: 30000 });
    await h.picturesLoaded(page, '.tile img', 30000);
    await page.waitForFunction(() => Number(document.querySelector('[data-testid=frame]').textContent) > 0, null, { timeout: 30000 });
    const leaked = urls.filter((u) => u.includes(kToken));
    assert.deepStrictEqual(leaked, [], 'no URL carries the token');
    assert.ok(urls.some((u) => /\/api\/cameras\/cam1\/frame\.jpg/.test(u)) && urls.some((u) => /\/events$/.test(u)), urls.join('\n'));

    // Scripts: the Bearer header and ?token= still work, alone.
    const bare = await s.browser.newPage();
    await bare.goto(`${s.base}/login`);
    const bearer = await bare.evaluate((tk) => fetch('/api/state', { headers: { Authorization: `Bearer ${tk}` } }).then((r) => r.status), kToken);
    assert.strictEqual(bearer, 200, 'the Bearer header');
    const query = await bare.evaluate((tk) => fetch(`/api/state?token=${tk}`).then((r) => r.status), kToken);
    assert.strictEqual(query, 200, '?token=');
    const wrong = await bare.evaluate(() => fetch('/api/state', { headers: { Authorization: 'Bearer nope' } }).then((r) => r.status));
    assert.strictEqual(wrong, 401, 'a wrong Bearer token');
    await bare.close();

    // An old link with ?token=: the cookie is set and the address bar keeps no token.
    const context = await s.browser.newContext();
    const linked = await context.newPage();
    await linked.goto(`${s.base}/system?token=${kToken}`);
    assert.strictEqual(linked.url(), `${s.base}/system`);
    await linked.waitForSelector('[data-testid=stages]', { timeout: 30000 });
    assert.strictEqual((await context.cookies())[0].httpOnly, true);
    await context.close();

    // Signing out: the cookie is gone, the page is the login page, the API refuses again.
    await h.screenshot(page, 'serve-live-token.png');
    await page.click('[data-testid=logout]');
    await page.waitForURL((u) => u.pathname === '/login', { timeout: 10000 });
    assert.deepStrictEqual(await page.context().cookies(), []);
    assert.strictEqual(await page.evaluate(() => fetch('/api/state').then((r) => r.status)), 401);
    await page.goto(`${s.base}/`);
    assert.strictEqual(new URL(page.url()).pathname, '/login');
  });
});
