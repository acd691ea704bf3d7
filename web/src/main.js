// occmap serve's page: the live view (map, tracks, zones, cameras, events), the setup
// (calibration from floor points, floor masks, zones and lines, saved to the site file) and, at
// /system, the developer's figures (stage times, latency, the cameras' counters, MQTT).
import 'leaflet/dist/leaflet.css';
import '@geoman-io/leaflet-geoman-free/dist/leaflet-geoman.css';
import './style.css';
import { h, render } from 'preact';
import { useEffect, useState } from 'preact/hooks';
import htm from 'htm';
import { getJSON, postJSON, subscribe } from './api.js';
import { LiveView } from './live.js';
import { SetupView } from './setup.js';
import { SystemView } from './system.js';

const html = htm.bind(h);

function initialTab() {
  if (location.pathname === '/system') return 'system';
  return location.hash === '#setup' ? 'setup' : 'live';
}

// Signing out: the server clears the session cookie; the page goes to the login page.
async function signOut() {
  await postJSON('/api/logout', {}).catch(() => {});
  location.assign('/login');
}

function App() {
  const [site, setSite] = useState(null);
  const [state, setState] = useState(null);
  const [frame, setFrame] = useState(null);
  const [connected, setConnected] = useState(false);
  const [error, setError] = useState(null);
  const [tab, setTab] = useState(initialTab());
  const [session, setSession] = useState(null);

  useEffect(() => {
    getJSON('/api/site').then(setSite).catch((e) => setError(e.message));
    getJSON('/api/state').then(setState).catch(() => {});
    getJSON('/api/session').then(setSession).catch(() => {});
    return subscribe({ frame: setFrame, state: setState, site: setSite }, setConnected);
  }, []);
  useEffect(() => {
    const onHash = () => setTab(initialTab());
    window.addEventListener('hashchange', onHash);
    return () => window.removeEventListener('hashchange', onHash);
  }, []);

  if (error) return html`<div class="fatal"><h1>occmap</h1><p>${error}</p></div>`;
  if (!site) return html`<p class="loading">occmap: loading the site…</p>`;
  const fps = frame ? frame.fps : state && state.fps;
  // A run that failed (a camera that cannot be opened, frames of another size than the site
  // says): its message, which otherwise only the terminal shows.
  const failed = state && state.running === false && !state.starting && /^error: /.test(state.stop_reason || '')
    ? state.stop_reason.slice(7) : null;
  const pipeline = pipelineState(state, connected);
  return html`
    <header>
      <span class="brand">occmap</span>
      <span class="site-name" title=${site.path}>${site.name}</span>
      <nav>
        <a href="/#live" class=${tab === 'live' ? 'active' : ''} data-tab="live">Live</a>
        <a href="/#setup" class=${tab === 'setup' ? 'active' : ''} data-tab="setup">Setup</a>
        <a href="/system" class=${tab === 'system' ? 'active' : ''} data-tab="system">System</a>
      </nav>
      <span class="grow"></span>
      <span class="status">
        frame <b data-testid="frame">${frame ? frame.frame : state && state.frame >= 0 ? state.frame : "–"}</b>${' · '}${fps !== undefined && fps !== null ? Number(fps).toFixed(1) : '–'} fps
        · <span class=${'dot ' + (connected && pipeline.on ? 'on' : 'off')}></span><span data-testid="pipeline-state"
          title=${pipeline.title}>${pipeline.label}</span>
        ${state && state.starting ? html`<span class="badge warn" data-testid="starting"
          title="opening the cameras, taking their backgrounds, loading or building the tables">starting…</span>` : null}
        ${state && state.mqtt ? html`<span class=${'badge ' + (state.mqtt.connected ? 'up' : 'down')} data-testid="mqtt"
          title=${state.mqtt.connected ? `publishing to ${state.mqtt.broker}`
            : `cannot publish to ${state.mqtt.broker}: ${state.mqtt.error}; ${state.mqtt.dropped} messages dropped`}>${
          state.mqtt.connected ? 'MQTT' : 'MQTT down'}</span>` : null}
      </span>
      ${session && session.token_required ? html`<button class="logout" data-testid="logout" onClick=${signOut}
        title="forget the token in this browser">Sign out</button>` : null}
    </header>
    ${failed ? html`<div class="banner" data-testid="pipeline-error"><b>The pipeline stopped:</b> ${failed}
      <span class="hint">Correct the site file (${site.path}) and start <code>occmap serve</code> again.</span></div>` : null}
    <main>
      ${tab === 'live' ? html`<${LiveView} site=${site} state=${state} frame=${frame} />`
        : tab === 'system' ? html`<${SystemView} state=${state} frame=${frame} />`
        : html`<${SetupView} site=${site} frame=${frame} onSaved=${setSite} />`}
    </main>`;
}

// What the header says of the pipeline: the page's link to the server first, then the run's
// life from /api/state (running, starting, ended as inputs ran out or a stop, failed).
function pipelineState(state, connected) {
  if (!connected) return { label: 'reconnecting', on: false, title: 'the page lost its link to occmap serve' };
  if (!state) return { label: 'connecting', on: false, title: '' };
  if (state.starting) return { label: 'starting', on: false, title: 'opening the cameras, backgrounds, tables' };
  if (state.running) return { label: 'running', on: true, title: 'the pipeline runs' };
  const reason = state.stop_reason || 'inputs ended';
  const ended = ['end of streams', 'frame limit', 'stop requested', 'stopped', 'inputs ended'].includes(reason);
  return { label: ended ? 'ended' : 'failed', on: false, title: `the pipeline stopped: ${reason}` };
}

render(html`<${App} />`, document.getElementById('app'));
