// A camera's lens from a printed board (the page's side of `occmap calibrate --board-...`):
// views captured from the camera's live frame or uploaded as pictures, each inspected at once
// (used, or why not: board not found, blurred, too small, edge-on), then the intrinsics
// (cv::calibrateCamera, POST /api/board/calibrate) with their RMS. The server keeps them for
// the camera: its floor points then give the pose with them (method "camera pose").
import { h } from 'preact';
import { useEffect, useState } from 'preact/hooks';
import htm from 'htm';
import { deleteJSON, fmt, getJSON, postJSON, url } from './api.js';

const html = htm.bind(h);

// The body limit is 1 MiB: larger pictures go as JPEG (quality 0.95 keeps the corners sharp).
const MAX_UPLOAD_BYTES = 700 * 1024;

function toBase64(buffer) {
  const bytes = new Uint8Array(buffer);
  let s = '';
  for (let i = 0; i < bytes.length; i += 0x8000) s += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
  return btoa(s);
}

async function pictureBase64(file) {
  if (file.size <= MAX_UPLOAD_BYTES && /^image\/(png|jpeg)$/.test(file.type)) return toBase64(await file.arrayBuffer());
  const bitmap = await createImageBitmap(file);
  const canvas = document.createElement('canvas');
  canvas.width = bitmap.width;
  canvas.height = bitmap.height;
  canvas.getContext('2d').drawImage(bitmap, 0, 0);
  const blob = await new Promise((resolve) => canvas.toBlob(resolve, 'image/jpeg', 0.95));
  return toBase64(await blob.arrayBuffer());
}

export const defaultBoard = { kind: 'checkerboard', size: '9x6', square_m: '0.03', marker_m: '', dictionary: '4x4_50' };

function boardJson(b) {
  const m = /^\s*(\d+)\s*[x×]\s*(\d+)\s*$/.exec(b.size);
  if (!m) throw new Error(`board size: expected COLSxROWS (inner corners of a checkerboard, squares of a ChArUco), found "${b.size}"`);
  const out = { kind: b.kind, cols: Number(m[1]), rows: Number(m[2]), square_m: Number(b.square_m) };
  if (!(out.square_m > 0)) throw new Error(`square: expected a length in metres, found "${b.square_m}"`);
  if (b.kind === 'charuco') { out.marker_m = Number(b.marker_m); out.dictionary = b.dictionary; }
  return out;
}

// onShow(url) puts a view (its corners drawn) in the camera's picture; onShow(null) the live frame.
export function BoardPanel({ camera, board, update, onNewFrame, shown, onShow }) {
  const [busy, setBusy] = useState(null);
  const [error, setError] = useState(null);
  const options = board.options || defaultBoard;
  const state = board.state;  // the server's answer: {views, calibration, ...}
  const views = state ? state.views : [];
  const cal = state && state.calibration;

  // What the server holds (after a reload of the page, or another tab).
  useEffect(() => {
    if (state) return;
    getJSON(`/api/board/views?camera=${encodeURIComponent(camera.id)}`).then((s) => update({ state: s })).catch(() => {});
  }, [camera.id]);

  const setOption = (key, value) => update({ options: { ...options, [key]: value } });
  async function run(what, fn) {
    setError(null);
    setBusy(what);
    try { await fn(); } catch (e) {
      setError(e.message);
      if (e.body && e.body.views) update({ state: e.body });
    } finally { setBusy(null); }
  }
  const capture = () => run('capture', async () => {
    const s = await postJSON('/api/board/views', { camera: camera.id, board: boardJson(options), capture: true });
    update({ state: s });
    onNewFrame();
  });
  const upload = (files) => run('upload', async () => {
    for (const f of files) {
      const s = await postJSON('/api/board/views', { camera: camera.id, board: boardJson(options), name: f.name, image: await pictureBase64(f) });
      update({ state: s });
    }
  });
  const remove = (i) => run('remove', async () => {
    onShow(null);
    update({ state: await deleteJSON(`/api/board/views?camera=${encodeURIComponent(camera.id)}&index=${i}`) });
  });
  const clear = () => run('remove', async () => {
    onShow(null);
    update({ state: await deleteJSON(`/api/board/views?camera=${encodeURIComponent(camera.id)}`) });
  });
  const calibrate = () => run('calibrate', async () => {
    update({ state: await postJSON('/api/board/calibrate', { camera: camera.id, board: boardJson(options) }), lensNew: true });
  });

  const accepted = views.filter((v) => v.accepted).length;
  const intr = cal && cal.intrinsics;
  return html`<div class="board" data-testid="board">
    <div class="actions board-options">
      <label>board <select value=${options.kind} data-testid="board-kind" onChange=${(e) => setOption('kind', e.target.value)}>
        <option value="checkerboard">checkerboard</option><option value="charuco">ChArUco</option></select></label>
      <label title=${options.kind === 'charuco' ? 'squares across x down' : 'inner corners across x down (a board of 10 x 7 squares has 9 x 6)'}>
        size <input class="coord" data-testid="board-size" value=${options.size} onInput=${(e) => setOption('size', e.target.value)} /></label>
      <label>square m <input class="coord" data-testid="board-square" inputmode="decimal" value=${options.square_m}
        onInput=${(e) => setOption('square_m', e.target.value)} /></label>
      ${options.kind === 'charuco' ? html`
        <label>marker m <input class="coord" data-testid="board-marker" inputmode="decimal" value=${options.marker_m}
          onInput=${(e) => setOption('marker_m', e.target.value)} /></label>
        <label>dictionary <input class="coord" value=${options.dictionary} onInput=${(e) => setOption('dictionary', e.target.value)} /></label>` : null}
    </div>
    <div class="actions">
      <button disabled=${!!busy} onClick=${capture} data-testid="board-capture" title="Take the camera's current frame as a board view">Capture this frame</button>
      <label class="upload"><span>Upload pictures</span><input type="file" accept="image/png,image/jpeg" multiple data-testid="board-upload"
        disabled=${!!busy} onChange=${(e) => { const files = [...e.target.files]; e.target.value = ''; upload(files); }} /></label>
      ${views.length ? html`<button class="small" disabled=${!!busy} onClick=${clear}>Remove all</button>` : null}
      <span class="grow"></span>
      <button class="primary" disabled=${!!busy || accepted < 3} onClick=${calibrate} data-testid="board-calibrate"
        title="cv::calibrateCamera on the usable views (3 at least)">Calibrate the lens</button>
      ${busy ? html`<span class="hint">${busy}…</span>` : null}
    </div>
    <table class="views" data-testid="board-views">
      <tr><th>#</th><th>view</th><th></th><th>corners</th><th>blur px</th><th>tilt °</th><th>RMS px</th><th></th></tr>
      ${views.map((v, i) => html`<tr data-testid=${`board-view-${i}`} class=${v.accepted ? '' : 'rejected'}>
        <td>${i + 1}</td>
        <td><a href="#" class=${shown && shown.includes(`index=${i}&`) ? 'shown' : ''} data-testid=${`board-view-name-${i}`}
          title="Show this view with the corners found (green: accepted)"
          onClick=${(e) => { e.preventDefault(); onShow(url('/api/board/view.jpg', { camera: camera.id, index: i, n: views.length })); }}>${v.name}</a></td>
        <td class=${v.accepted ? 'good' : 'bad'} data-testid="board-view-status">${v.used ? 'used' : v.accepted ? 'usable' : v.reason}</td>
        <td class="num">${v.corners || ''}</td><td class="num">${v.corners ? fmt(v.blur_px, 1) : ''}</td>
        <td class="num">${v.corners ? fmt(v.tilt_deg, 0) : ''}</td><td class="num">${v.used ? fmt(v.rms_px, 2) : ''}</td>
        <td><button class="small" onClick=${() => remove(i)} title="Remove this view">×</button></td></tr>`)}
    </table>
    ${cal ? html`<p class="result" data-testid="board-result">
        Lens from ${cal.views_used} views: RMS <b data-testid="board-rms">${fmt(cal.rms_px, 3)}</b> px ·
        focal length <b data-testid="board-fx">${fmt(intr.fx_px, 1)}</b> × ${fmt(intr.fy_px, 1)} px ·
        centre ${fmt(intr.cx_px, 1)}, ${fmt(intr.cy_px, 1)} · k1 <b data-testid="board-k1">${fmt(intr.distortion[0], 3)}</b>,
        k2 ${fmt(intr.distortion[1], 3)} (${intr.width_px}x${intr.height_px})<br />
        <span class="hint">Kept for ${camera.id}: its floor points (Floor points, method <i>camera pose</i>) now give its pose with these intrinsics.</span></p>
      ${cal.warnings && cal.warnings.length ? html`<ul class="warnings">${cal.warnings.map((w) => html`<li>${w}</li>`)}</ul>` : null}` : null}
    <p class="hint">Print a board (<code>occmap calibrate --print-board board.png --square-m 0.03</code>), measure a
      printed square, and show it to the camera from 10-20 angles and distances (tilted by 30-45 degrees in some, near the
      picture's edges and corners in others): capture each, or upload pictures the camera took at its own size.</p>
    ${error ? html`<p class="error" data-testid="board-error">${error}</p>` : null}
  </div>`;
}
