// The MQTT link's failures are not silent: `occmap serve --mqtt` to a port where no broker
// listens shows it on the page (header badge; the system page's pipeline panel), in /api/state and /metrics and
// once on the terminal; a mosquitto started later on that port (by this test, stopped by its
// PID) is reached, and the page, the API and the terminal say so.
'use strict';
const test = require('node:test');
const assert = require('node:assert');
const { spawn } = require('node:child_process');
const fs = require('node:fs');
const net = require('node:net');
const path = require('node:path');
const h = require('./harness.cjs');

function freeTcpPort() {
  return new Promise((resolve) => {
    const srv = net.createServer();
    srv.listen(0, '127.0.0.1', () => { const { port } = srv.address(); srv.close(() => resolve(port)); });
  });
}

test('MQTT down, then up: the page, the API, the metrics and the terminal', { timeout: 300000 }, async (t) => {
  const port = await freeTcpPort();
  const s = await h.start(t, 'mqtt', { streams: true, args: ['--mqtt', `mqtt://127.0.0.1:${port}`] });
  let broker = null;
  t.after(async () => { if (broker) await new Promise((r) => { broker.once('exit', r); broker.kill('SIGTERM'); }); });
  const page = await s.open('/');
  const sys = await s.open('/system');  // the MQTT line with its figures is a developer's
  await s.check(async () => {
    const badge = page.locator('[data-testid=mqtt]');
    await page.waitForFunction(() => document.querySelector('[data-testid=mqtt]')?.textContent === 'MQTT down',
      null, { timeout: 120000 });
    assert.match(await badge.getAttribute('title'), new RegExp(`cannot publish to mqtt://127.0.0.1:${port}: Connection refused`));
    await sys.waitForFunction(() => /^not connected to .*: Connection refused/.test(document.querySelector('[data-testid=mqtt-state]')?.textContent),
      null, { timeout: 10000 });
    let st = await page.evaluate(() => fetch('/api/state').then((r) => r.json()));
    assert.strictEqual(st.mqtt.connected, false);
    assert.strictEqual(st.mqtt.error, 'Connection refused');
    let metrics = await page.evaluate(() => fetch('/metrics').then((r) => r.text()));
    assert.match(metrics, new RegExp(`occmap_mqtt_connected\\{broker="mqtt://127.0.0.1:${port}"\\} 0\\n`));
    assert.match(metrics, /occmap_mqtt_messages_dropped_total [1-9]\d*\n/);
    const downLines = s.serve.log().split('\n').filter((l) => /occmap serve: mqtt: cannot publish/.test(l));
    assert.strictEqual(downLines.length, 1, s.serve.log());

    const conf = path.join(s.dir, 'mosquitto.conf');
    fs.writeFileSync(conf, `listener ${port} 127.0.0.1\nallow_anonymous true\npersistence false\nlog_dest stderr\n`);
    broker = spawn('/usr/sbin/mosquitto', ['-c', conf], { stdio: 'ignore' });
    // The client retries with back-off (1 s doubling to 30 s).
    await page.waitForFunction(() => document.querySelector('[data-testid=mqtt]')?.textContent === 'MQTT',
      null, { timeout: 90000 });
    await sys.waitForFunction((p) => document.querySelector('[data-testid=mqtt-state]')?.textContent.startsWith(`connected to mqtt://127.0.0.1:${p}`),
      port, { timeout: 10000 });
    st = await page.evaluate(() => fetch('/api/state').then((r) => r.json()));
    assert.strictEqual(st.mqtt.connected, true);
    assert.strictEqual(st.mqtt.error, null);
    metrics = await page.evaluate(() => fetch('/metrics').then((r) => r.text()));
    assert.match(metrics, /occmap_mqtt_connected\{[^}]*\} 1\n/);
    await h.screenshot(page, 'mqtt.png');
    assert.match(s.serve.log(), /occmap serve: mqtt: connected to mqtt:\/\/127\.0\.0\.1:\d+ again after \d+ s; \d+ messages dropped meanwhile/);
  });
});
