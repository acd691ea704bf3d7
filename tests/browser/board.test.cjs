// The lens from a board in a real browser: pictures of a checkerboard seen through camera cam1's
// true intrinsics (k1 -0.16: rendered here, board_views.cjs) are uploaded in Setup's "Lens
// (board)", each listed as usable or with its reason (a blurred one, one without a board, the
// live frame captured from the camera); "Calibrate the lens" gives the RMS and the focal length
// and distortion, which the floor points then use for the pose; Save writes them. The API's
// refusals are checked first (Node's fetch). Then the live route: cam1 streams a video of the
// board turning in front of it (H.264 over UDP) and the page captures its frames.
'use strict';
const test = require('node:test');
const assert = require('node:assert');
const fs = require('node:fs');
const path = require('node:path');
const { spawnSync } = require('node:child_process');
const h = require('./harness.cjs');
const b = require('./board_views.cjs');

const board = { cols: 9, rows: 6, square: 0.04 };
const boardJson = { kind: 'checkerboard', cols: 9, rows: 6, square_m: 0.04 };

function renderViews(dir, cam) {
  const files = b.poses.map((pose, i) => {
    const file = path.join(dir, `board${String(i + 1).padStart(2, '0')}.png`);
    fs.writeFileSync(file, b.png(b.renderBoard(cam, board, pose, i + 1)));
    return file;
  });
  const blurred = path.join(dir, 'blurred.png');
  fs.writeFileSync(blurred, b.png(b.blur(b.renderBoard(cam, board, { rx: 20, ry: 15, rz: 0, distance: 0.6, ox: 0, oy: 0 }, 99), 4)));
  const empty = path.join(dir, 'wall.png');
  fs.writeFileSync(empty, b.png({ width: cam.width, height: cam.height, gray: new Uint8Array(cam.width * cam.height).fill(128) }));
  return { good: files, blurred, empty };
}

async function call(base, method, p, body) {
  const r = await fetch(base + p, {
    method, headers: body === undefined ? {} : { 'Content-Type': 'application/json' },
    body: body === undefined ? undefined : JSON.stringify(body),
  });
  const text = await r.text();
  return { status: r.status, body: text.startsWith('{') ? JSON.parse(text) : text, type: r.headers.get('content-type') };
}

test('setup: the lens from board pictures, then the pose from floor points', { timeout: 300000 }, async (t) => {
  const s = await h.start(t, 'board');
  const truth = b.readIntrinsics(path.join(h.sceneDir, 'calib', 'intr_cam1.xml'));
  const views = renderViews(s.dir, truth);
  const page = await s.open('/#setup');
  await s.check(async () => {
    // The API: bad requests are refused with the field named; cam2's views stay apart from cam1's.
    const image = fs.readFileSync(views.good[0]).toString('base64');
    let r = await call(s.base, 'POST', '/api/board/views', { camera: 'cam2', board: { ...boardJson, square_m: -1 }, image });
    assert.strictEqual(r.status, 400);
    assert.match(r.body.error, /board square/);
    r = await call(s.base, 'POST', '/api/board/views', { camera: 'nope', board: boardJson, capture: true });
    assert.strictEqual(r.status, 400);
    assert.match(r.body.error, /no camera 'nope'/);
    r = await call(s.base, 'POST', '/api/board/views', { camera: 'cam2', board: boardJson, image: 'not*base64' });
    assert.strictEqual(r.status, 400);
    assert.match(r.body.error, /image: expected base64/);
    r = await call(s.base, 'POST', '/api/board/views', { camera: 'cam2', board: boardJson, image: Buffer.from('no picture').toString('base64') });
    assert.strictEqual(r.status, 400);
    assert.match(r.body.error, /not a picture/);
    r = await call(s.base, 'POST', '/api/board/views', { camera: 'cam2', board: boardJson, image: `data:image/png;base64,${image}`, name: 'one.png' });
    assert.strictEqual(r.status, 200, JSON.stringify(r.body));
    assert.deepStrictEqual([r.body.view.name, r.body.view.accepted, r.body.view.corners], ['one.png', true, 54]);
    r = await call(s.base, 'POST', '/api/board/calibrate', { camera: 'cam2', board: boardJson });
    assert.strictEqual(r.status, 400, 'one view is not enough');
    assert.match(r.body.error, /1 of 1 usable, at least 3 needed/);
    assert.strictEqual(r.body.views.length, 1, 'the views come back with the error');
    // Another board: the views already there are inspected again with it.
    r = await call(s.base, 'POST', '/api/board/views', { camera: 'cam2', board: { ...boardJson, cols: 8 }, image, name: 'two.png' });
    assert.strictEqual(r.status, 200, JSON.stringify(r.body));
    assert.deepStrictEqual(r.body.views.map((v) => [v.name, v.accepted]), [['one.png', false], ['two.png', false]]);
    assert.match(r.body.views[0].reason, /no 8x6 checkerboard found/);
    r = await call(s.base, 'GET', '/api/board/view.jpg?camera=cam2&index=0');
    assert.strictEqual(r.type, 'image/jpeg');
    r = await call(s.base, 'DELETE', '/api/board/views?camera=cam2&index=3');
    assert.strictEqual(r.status, 400);
    r = await call(s.base, 'DELETE', '/api/board/views?camera=cam2');
    assert.deepStrictEqual([r.status, r.body.views.length], [200, 0]);

    // Sizes: a view of another shape (1280x720 for the 640x480 camera) is refused and keeps
    // nothing, so the correct views after it are taken; one of the same shape but twice the size
    // is scaled to the camera's.
    const gray = b.renderBoard(truth, board, b.poses[0], 1);
    const twice = { width: 1280, height: 960, gray: new Uint8Array(1280 * 960) };
    for (let y = 0; y < 960; y += 1) for (let x = 0; x < 1280; x += 1) twice.gray[y * 1280 + x] = gray.gray[(y >> 1) * 640 + (x >> 1)];
    const wide = { width: 1280, height: 720, gray: twice.gray.slice(120 * 1280, 840 * 1280) };
    r = await call(s.base, 'POST', '/api/board/views', { camera: 'cam2', board: boardJson, image: b.png(wide).toString('base64'), name: 'wide.png' });
    assert.strictEqual(r.status, 400, JSON.stringify(r.body));
    assert.match(r.body.error, /^wide\.png: 1280x720, camera 'cam2' gives 640x480 pictures \(another aspect ratio\)/);
    r = await call(s.base, 'GET', '/api/board/views?camera=cam2');
    assert.strictEqual(r.body.views.length, 0, 'the refused view is not kept');
    r = await call(s.base, 'POST', '/api/board/views', { camera: 'cam2', board: boardJson, image, name: 'right.png' });
    assert.strictEqual(r.status, 200, `a correct view after the refused one: ${JSON.stringify(r.body)}`);
    r = await call(s.base, 'POST', '/api/board/views', { camera: 'cam2', board: boardJson, image: b.png(twice).toString('base64'), name: 'big.png' });
    assert.strictEqual(r.status, 200, JSON.stringify(r.body));
    assert.deepStrictEqual([r.body.view.width_px, r.body.view.height_px, r.body.view.scaled_from_px, r.body.view.accepted],
      [640, 480, [1280, 960], true]);
    r = await call(s.base, 'DELETE', '/api/board/views?camera=cam2');
    assert.deepStrictEqual([r.status, r.body.views.length], [200, 0]);

    // The page: the pictures uploaded, the live frame captured.
    await h.picturesLoaded(page, '[data-testid=camera-map] img.leaflet-image-layer', 60000);
    await page.click('[data-testid=mode-lens]');
    await page.fill('[data-testid=board-size]', '9x6');
    await page.fill('[data-testid=board-square]', '0.04');
    await page.setInputFiles('[data-testid=board-upload]', [...views.good, views.blurred, views.empty]);
    const n = views.good.length + 2;
    await page.waitForSelector(`[data-testid=board-view-${n - 1}]`, { timeout: 120000 });
    await page.click('[data-testid=board-capture]');
    await page.waitForSelector(`[data-testid=board-view-${n}]`, { timeout: 30000 });
    const status = await page.$$eval('[data-testid=board-view-status]', (tds) => tds.map((td) => td.textContent));
    assert.deepStrictEqual(status.slice(0, views.good.length), views.good.map(() => 'usable'), `views: ${status}`);
    assert.match(status[n - 2], /blurred/);
    assert.match(status[n - 1], /no 9x6 checkerboard found/);
    assert.match(status[n], /no 9x6 checkerboard found/, 'the lab camera shows no board');

    await page.click('[data-testid=board-calibrate]');
    await page.waitForSelector('[data-testid=board-result]', { timeout: 120000 });
    const rms = Number(await page.textContent('[data-testid=board-rms]'));
    const fx = Number(await page.textContent('[data-testid=board-fx]'));
    const k1 = Number(await page.textContent('[data-testid=board-k1]'));
    console.log(`board: RMS ${rms} px, fx ${fx} px (true ${truth.fx}), k1 ${k1} (true ${truth.d[0]})`);
    assert.ok(rms < 0.3, `RMS ${rms} px`);
    assert.ok(Math.abs(fx / truth.fx - 1) < 0.01, `fx ${fx} px, true ${truth.fx}`);
    assert.ok(Math.abs(k1 - truth.d[0]) < 0.02, `k1 ${k1}, true ${truth.d[0]}`);
    const used = await page.$$eval('[data-testid=board-view-status]', (tds) => tds.filter((td) => td.textContent === 'used').length);
    assert.strictEqual(used, views.good.length);
    assert.match(await page.textContent('[data-testid=lens-waiting]'), /lens of cam1 is saved\s+with the camera's pose/);
    // A view shown in the camera's picture, its corners drawn.
    await page.click('[data-testid=board-view-name-5]');
    await page.waitForFunction(() => {
      const img = document.querySelector('[data-testid=camera-map] img.leaflet-image-layer');
      return /board\/view\.jpg/.test(img.src) && /index=5/.test(img.src) && img.complete && img.naturalWidth === 640;
    }, null, { timeout: 30000 });
    await h.screenshot(page, 'serve-board.png');

    // The floor points give the pose with these intrinsics.
    await page.click('[data-testid=mode-points]');
    await h.clickFloorPoints(page, h.spreadFloorPoints('cam1'));
    await page.click('[data-testid=calibrate]');
    await page.waitForSelector('[data-testid=intrinsics-from-board]', { timeout: 30000 });
    const prms = Number(await page.textContent('[data-testid=rms-px]'));
    const floorCm = Number(await page.textContent('[data-testid=floor-cm]'));
    assert.ok(prms < 1, `pose RMS ${prms} px`);
    assert.ok(floorCm < 3, `floor ${floorCm} cm`);

    await page.click('[data-testid=save]');
    await page.waitForSelector('[data-testid=save-message].ok', { timeout: 60000 });
    h.assertSiteValid(s.site);
    assert.strictEqual(await page.locator('[data-testid=lens-waiting]').count(), 0, 'the lens saved with the pose');
    const saved = b.readIntrinsics(path.join(s.dir, 'calib', 'serve_intr_cam1.xml'));
    assert.ok(Math.abs(saved.fx / truth.fx - 1) < 0.01, `saved fx ${saved.fx}, true ${truth.fx}`);
    assert.ok(Math.abs(saved.d[0] - truth.d[0]) < 0.02, `saved k1 ${saved.d[0]}, true ${truth.d[0]}`);
  });
});

// The rendered poses, a second each, as cam1's video (H.264, 10 fps, as the scene's).
function boardVideo(dir, cam) {
  const frames = path.join(dir, 'board-frames');
  fs.mkdirSync(frames);
  b.poses.forEach((pose, i) => {
    fs.writeFileSync(path.join(frames, `${String(i).padStart(2, '0')}.png`), b.png(b.renderBoard(cam, board, pose, i + 1)));
  });
  const video = path.join(dir, 'board.mp4');
  const r = spawnSync('ffmpeg', ['-loglevel', 'error', '-y', '-framerate', '1', '-i', path.join(frames, '%02d.png'),
    '-r', '10', '-c:v', 'libx264', '-pix_fmt', 'yuv420p', '-crf', '12', '-g', '10', video], { encoding: 'utf8' });
  if (r.status !== 0) throw new Error(`ffmpeg: ${r.stderr}`);
  return video;
}

test('setup: the lens from board views captured from a live camera', { timeout: 300000 }, async (t) => {
  const truth = b.readIntrinsics(path.join(h.sceneDir, 'calib', 'intr_cam1.xml'));
  const s = await h.start(t, 'board-live', { streams: true, videos: (dir) => [boardVideo(dir, truth)] });
  const page = await s.open('/#setup');
  await s.check(async () => {
    await h.picturesLoaded(page, '[data-testid=camera-map] img.leaflet-image-layer', 90000);
    await page.click('[data-testid=mode-lens]');
    await page.fill('[data-testid=board-square]', '0.04');
    // A capture a second or so, as a person turning the board would: until 5 views are usable.
    const usable = () => page.$$eval('[data-testid=board-view-status]', (tds) => tds.filter((td) => td.textContent === 'usable').length);
    for (let i = 0; i < 25 && (await usable()) < 5; i += 1) {
      const rows = await page.locator('[data-testid=board-views] tr').count();
      await page.click('[data-testid=board-capture]');
      await page.waitForFunction((n) => document.querySelectorAll('[data-testid=board-views] tr').length > n, rows, { timeout: 30000 });
      await new Promise((resolve) => setTimeout(resolve, 900));
    }
    const names = await page.$$eval('[data-testid=board-views] tr td:nth-child(2)', (tds) => tds.map((td) => td.textContent));
    assert.ok(await usable() >= 5, `usable captures: ${await usable()} of ${names.length}`);
    assert.ok(names.every((n) => /^frame \d+$/.test(n)), `captured frames are named by their frame: ${names}`);
    await page.click('[data-testid=board-calibrate]');
    await page.waitForSelector('[data-testid=board-result]', { timeout: 120000 });
    const rms = Number(await page.textContent('[data-testid=board-rms]'));
    const fx = Number(await page.textContent('[data-testid=board-fx]'));
    const k1 = Number(await page.textContent('[data-testid=board-k1]'));
    console.log(`live board: ${names.length} captures, RMS ${rms} px, fx ${fx} px (true ${truth.fx}), k1 ${k1} (true ${truth.d[0]})`);
    assert.ok(rms < 0.5, `RMS ${rms} px`);
    assert.ok(Math.abs(fx / truth.fx - 1) < 0.02, `fx ${fx} px, true ${truth.fx}`);
    assert.ok(Math.abs(k1 - truth.d[0]) < 0.03, `k1 ${k1}, true ${truth.d[0]}`);
  });
});
