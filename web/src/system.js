// The system page (/system): the developer's figures the live page leaves out: the pipeline's
// frame, latency and uptime, the MQTT link, each stage's time, the cameras' counters and their
// cached backgrounds, and the run's summary.json.
import { h } from 'preact';
import { useEffect, useState } from 'preact/hooks';
import htm from 'htm';
import { fmt, getJSON } from './api.js';
import { cameraCondition } from './live.js';

const html = htm.bind(h);

// A live camera's cached background (its `background_cache` in /api/state: written back from its
// model every refresh_cache_s): when it was last written, as the run's seconds at its rate
// (`state.fps`), and its failed writes. Null for a camera whose entry is not refreshed.
export function cacheCondition(cam, state) {
  const c = cam.background_cache;
  if (!c) return null;
  let age = 'not yet';
  if (c.last_refresh_frame !== null && c.last_refresh_frame !== undefined && state && state.frame >= 0) {
    const frames = Math.max(0, state.frame - c.last_refresh_frame);
    age = state.fps > 0 ? `${fmt(frames / state.fps, 0)} s ago` : `${frames} frames ago`;
  }
  return { age, failures: c.failures || 0, error: c.last_error || '' };
}

const kStageOrder = ['tables', 'decode', 'detect', 'fuse', 'people', 'background', 'blobs', 'track', 'output'];
const kOptionalStages = new Set(['people', 'background']);

function Pipeline({ state, frame }) {
  const lat = (state && state.latency_ms) || {};
  // A frame set's way through the run; the stages a site does not use (0 s) are left out.
  const stages = kStageOrder.map((k) => [k, Number(((state && state.stages_s) || {})[k])])
    .filter(([k, v]) => v > 0 || !kOptionalStages.has(k)).filter(([, v]) => Number.isFinite(v));
  const total = stages.reduce((a, [k, v]) => a + (k === 'tables' ? 0 : v), 0);
  const frames = (state && state.frames) || 0;
  return html`
    <section class="panel">
      <h2>Pipeline</h2>
      <dl class="kv">
        <dt>frame</dt><dd>${frame ? frame.frame : state ? state.frame : '–'}</dd>
        <dt>time</dt><dd>${frame ? fmt(frame.time_s, 1) + ' s' : '–'}</dd>
        <dt>fps</dt><dd>${fmt(state && state.fps)} (${frames} frame sets in ${state ? fmt(state.elapsed_s, 1) : '–'} s)</dd>
        <dt>tracks</dt><dd title="tracks started so far">${state ? state.tracks_total : '–'} started · ${frame ? (frame.tracks || []).length : '–'} now</dd>
        <dt>latency</dt><dd>p50 ${fmt(lat.p50, 0)} · p95 ${fmt(lat.p95, 0)} · p99 ${fmt(lat.p99, 0)} ms</dd>
        ${state && state.mqtt ? html`<dt>MQTT</dt><dd data-testid="mqtt-state" class=${state.mqtt.connected ? '' : 'bad'}>${
          state.mqtt.connected ? 'connected to ' + state.mqtt.broker : `not connected to ${state.mqtt.broker}: ${state.mqtt.error}`}
          · ${state.mqtt.published} sent · ${state.mqtt.dropped} dropped</dd>` : null}
        <dt>up</dt><dd>${state ? fmt(state.uptime_s, 0) + ' s' : '–'}${state && state.starting ? ' (starting: backgrounds, tables)' : state && state.running === false ? ` (stopped: ${state.stop_reason || 'inputs ended'})` : ''}</dd>
      </dl>
      <h3>Stage time <span class="hint">(the stages overlap)</span></h3>
      ${stages.length === 0 ? html`<p class="hint">not measured yet</p>` : null}
      <table class="stages" data-testid="stages">
        ${stages.length ? html`<tr><th>stage</th><th class="num">total</th><th class="num">per frame</th><th></th></tr>` : null}
        ${stages.map(([k, v]) => html`
          <tr data-stage=${k}><td>${k}</td><td class="num">${fmt(v, 2)} s</td>
              <td class="num">${k !== 'tables' && frames > 0 ? fmt((1000 * v) / frames, 1) + ' ms' : ''}</td>
              <td class="bar"><span style=${`width:${total > 0 && k !== 'tables' ? (100 * v) / total : 0}%`}></span></td></tr>`)}
      </table>
    </section>`;
}

function Cameras({ state }) {
  const cams = (state && state.cameras) || [];
  return html`
    <section class="panel">
      <h2>Cameras</h2>
      <table class="cams">
        <tr><th>id</th><th>state</th><th>fps</th><th title="frames read">frames</th><th title="frames dropped">drop</th><th title="reconnections">reconn</th><th title="age of the background model">bg age</th><th title="the cached background, written back from the model (live cameras): its last write, failed writes">bg cache</th></tr>
        ${cams.map((c) => {
          const cache = cacheCondition(c, state);
          return html`
          <tr data-camera=${c.id}><td>${c.id}</td><td>${cameraCondition(c, state).label}</td>
              <td class="num">${fmt(c.fps)}</td><td class="num">${c.frames ?? '–'}</td><td class="num">${c.dropped ?? '–'}</td>
              <td class="num">${c.reconnects ?? '–'}</td><td class="num bg-age">${fmt(c.background_age_s, 0)} s</td>
              <td class="bg-cache" data-testid="camera-cache" title=${cache && cache.error ? 'last error: ' + cache.error : ''}>${cache === null ? '–' : html`
                <span data-testid="cache-age">${cache.age}</span>${cache.failures > 0
                  ? html` <span class="bad" data-testid="cache-failures">${cache.failures} failed</span>` : null}`}</td></tr>
          ${cache && cache.error ? html`
          <tr class="cache-error" data-camera-error=${c.id}><td colspan="8" data-testid="cache-error">cache: ${cache.error}</td></tr>` : null}`;
        })}
      </table>
    </section>`;
}

// summary.json as the run last wrote it (GET /api/stats), fetched again every 5 s.
function Summary() {
  const [stats, setStats] = useState(null);
  useEffect(() => {
    const get = () => getJSON('/api/stats').then(setStats).catch(() => {});
    get();
    const timer = setInterval(get, 5000);
    return () => clearInterval(timer);
  }, []);
  return html`
    <section class="panel wide">
      <h2>summary.json</h2>
      <pre class="summary" data-testid="summary">${stats === null ? '–' : JSON.stringify(stats, null, 2)}</pre>
    </section>`;
}

export function SystemView({ state, frame }) {
  return html`
    <div class="system" data-testid="system">
      <div class="system-col"><${Pipeline} state=${state} frame=${frame} /></div>
      <div class="system-col"><${Cameras} state=${state} />
        <p class="hint">Scripts: <a href="/api/state">/api/state</a> · <a href="/metrics">/metrics</a> (Prometheus)
          · <a href="/api/stats">/api/stats</a></p></div>
      <${Summary} />
    </div>`;
}
