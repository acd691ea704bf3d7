// The live view: the floor map with detections, tracks and their trails, zones and lines with
// their counts and events; per-camera state and pictures (the developer's tables: system.js).
import { h } from 'preact';
import { useEffect, useRef, useState } from 'preact/hooks';
import htm from 'htm';
import L from 'leaflet';
import { colorForId, fmt, getJSON, url } from './api.js';
import { clientPoint, createFloorMap } from './leafmaps.js';

const html = htm.bind(h);
const kTrailLength = 60;          // positions kept per track (6 s at 10 events per second)
const kForgetAfterFrames = 30;    // a track absent this long loses its trail

function drawZones(layer, site, frame) {
  layer.clearLayers();
  const counts = new Map(((frame && frame.zones) || []).map((z) => [z.name, z.count]));
  for (const z of site.zones || []) {
    const n = counts.get(z.name);
    const poly = L.polygon(z.polygon_m.map(([x, y]) => [y, x]), {
      color: n ? '#d97706' : '#2563eb', weight: 2, fillOpacity: n ? 0.18 : 0.06, interactive: false,
    }).addTo(layer);
    poly.bindTooltip(`${z.name}: ${n === undefined ? '–' : n}`, { permanent: true, direction: 'center', className: 'zone-label' });
  }
  const crossings = new Map(((frame && frame.lines) || []).map((l) => [l.name, l]));
  for (const l of site.lines || []) {
    const c = crossings.get(l.name);
    L.polyline([[l.a_m[1], l.a_m[0]], [l.b_m[1], l.b_m[0]]], { color: '#7c3aed', weight: 3, interactive: false }).addTo(layer);
    // At the line's end, not its middle: a zone's label sits at its centre, often on the line's.
    L.tooltip({ permanent: true, direction: 'right', className: 'line-label', interactive: false })
      .setLatLng([l.b_m[1], l.b_m[0]]).setContent(`${l.name}: in ${c ? c.in : '–'} · out ${c ? c.out : '–'}`).addTo(layer);
  }
}

function FloorMap({ site, frame }) {
  const div = useRef(null);
  const ctx = useRef(null);
  useEffect(() => {
    const floor = createFloorMap(div.current, site.grid);
    const zones = L.layerGroup().addTo(floor.map);
    const trails = L.layerGroup().addTo(floor.map);
    const detections = L.layerGroup().addTo(floor.map);
    const tracks = L.layerGroup().addTo(floor.map);
    ctx.current = { floor, zones, trails, detections, tracks, history: new Map() };
    // For tests and scripts: where a floor point (metres) is on the screen.
    window.occmap = Object.assign(window.occmap || {}, {
      liveMap: floor.map,
      floorToClient: (x, y) => clientPoint(floor.map, [y, x]),
    });
    return () => floor.destroy();
  }, [JSON.stringify(site.grid)]);

  useEffect(() => { if (ctx.current) drawZones(ctx.current.zones, site, frame); }, [site, frame && frame.zones, frame && frame.lines]);

  useEffect(() => {
    const c = ctx.current;
    if (!c || !frame) return;
    if (frame.map_version !== undefined) c.floor.refresh(frame.map_version);
    c.detections.clearLayers();
    for (const d of frame.detections || []) {
      L.circleMarker([d.y_m, d.x_m], { radius: 5, color: '#ea580c', weight: 1.5, fillOpacity: 0.35, interactive: false })
        .addTo(c.detections);
    }
    const seen = new Set();
    for (const t of frame.tracks || []) {
      seen.add(t.id);
      let hist = c.history.get(t.id);
      if (!hist) { hist = { points: [], last: frame.frame }; c.history.set(t.id, hist); }
      hist.points.push([t.y_m, t.x_m]);
      if (hist.points.length > kTrailLength) hist.points.shift();
      hist.last = frame.frame;
    }
    for (const [id, hist] of c.history) if (frame.frame - hist.last > kForgetAfterFrames || frame.frame < hist.last) c.history.delete(id);
    c.trails.clearLayers();
    c.tracks.clearLayers();
    for (const [id, hist] of c.history) {
      const color = colorForId(id);
      L.polyline(hist.points, { color, weight: 2, opacity: seen.has(id) ? 0.8 : 0.3, interactive: false }).addTo(c.trails);
      if (!seen.has(id)) continue;
      const p = hist.points[hist.points.length - 1];
      L.circleMarker(p, { radius: 7, color: '#fff', weight: 2, fillColor: color, fillOpacity: 1, interactive: false })
        .bindTooltip(String(id), { permanent: true, direction: 'top', offset: [0, -6], className: 'track-label' })
        .addTo(c.tracks);
    }
  }, [frame]);

  return html`<div class="floor-map" ref=${div} data-testid="live-map"></div>`;
}

// A camera's condition from /api/state: its stream ended or failed (lost), a live stream
// reopening (reconnecting), the run over (stopped), else up.
export function cameraCondition(cam, state) {
  if (state && state.starting) return { label: 'starting', cls: 'warn' };
  if (state && state.running === false) return { label: 'stopped', cls: 'idle' };
  if (cam.active === false) return { label: 'lost', cls: 'down' };
  if (cam.connected === false) return { label: 'reconnecting', cls: 'warn' };
  return { label: 'up', cls: 'up' };
}

const kTileIntervalMs = 250;  // camera pictures: 4 a second each, whatever the frame rate

// A camera's latest frame with its changed pixels tinted red, fetched at a steady rate while
// frames come (at most one request in flight; a frame already shown is not fetched again).
function CameraTile({ camera, latestFrame, camState, state }) {
  const img = useRef(null);
  const busy = useRef(false);
  const shown = useRef(null);
  const [loaded, setLoaded] = useState(null);
  useEffect(() => {
    const tick = () => {
      const f = latestFrame.current;
      if (busy.current || f === null || f === shown.current || !img.current) return;
      busy.current = true;
      shown.current = f;
      img.current.src = url(`/api/cameras/${encodeURIComponent(camera.id)}/frame.jpg`, { overlay: 'change', f });
    };
    tick();
    const timer = setInterval(tick, kTileIntervalMs);
    return () => clearInterval(timer);
  }, [camera.id]);
  const done = (ok) => () => {
    busy.current = false;
    if (ok) setLoaded(shown.current);
    else shown.current = null;  // 404 before its first frame: ask again at the next tick
  };
  const s = camState || {};
  const cond = cameraCondition(s, state);
  return html`
    <figure class="tile" data-camera=${camera.id} data-frame=${loaded ?? ''}>
      <img ref=${img} onLoad=${done(true)} onError=${done(false)} alt=${'camera ' + camera.id}
           style=${`aspect-ratio: ${camera.width_px} / ${camera.height_px}`} />
      <figcaption>
        <b>${camera.id}</b>
        <span class=${'badge ' + cond.cls} data-testid="camera-condition">${cond.label}</span>
        <span title="frames per second this camera gives the run">${fmt(s.fps)} fps</span>
        ${s.dropped ? html`<span title="frames a live stream dropped to stay on the newest">${s.dropped} drop</span>` : null}
        ${s.reconnects ? html`<span title="times the stream was opened again">${s.reconnects} reconn</span>` : null}
        <span title="mean age of the background's pixels" data-testid="tile-bg-age">bg ${fmt(s.background_age_s, 0)} s</span>
      </figcaption>
    </figure>`;
}

// What a user watches beside the map: the frame, its people and objects, the counts. The
// developer's figures (latency, stage times, the cameras' details, MQTT) are on /system.
function Now({ state, frame, site }) {
  return html`
    <section class="panel">
      <h2>Now</h2>
      <dl class="kv">
        <dt>time</dt><dd>${frame ? (frame.t_unix ? new Date(frame.t_unix * 1000).toLocaleTimeString([], { hour12: false })
          : fmt(frame.time_s, 1) + ' s') : '–'}</dd>
        <dt>tracks</dt><dd data-testid="track-count">${frame ? (frame.tracks || []).length : '–'}</dd>
        <dt>detections</dt><dd>${frame ? (frame.detections || []).length : '–'}</dd>
      </dl>
      <p class="hint"><a href="/system" data-testid="system-link">System</a>: stage times, latency, the cameras' figures, MQTT.</p>
    </section>
    <section class="panel">
      <h2>Zones and lines</h2>
      ${(site.zones || []).length + (site.lines || []).length === 0
        ? html`<p class="hint">No zones yet: draw them in Setup.</p>` : null}
      <table class="counts" data-testid="zone-counts">
        ${(site.zones || []).map((z) => {
          const c = ((frame && frame.zones) || []).find((q) => q.name === z.name);
          return html`<tr data-zone=${z.name}><td>${z.name}</td><td class="num">${c ? c.count : '–'}</td></tr>`;
        })}
        ${(site.lines || []).map((l) => {
          const c = ((frame && frame.lines) || []).find((q) => q.name === l.name);
          return html`<tr data-line=${l.name}><td>${l.name}</td><td class="num">in ${c ? c.in : '–'} · out ${c ? c.out : '–'}</td></tr>`;
        })}
      </table>
    </section>`;
}

const kEventsShown = 50;

// The run's events (zone entries and exits, line crossings): GET /api/events once, then those
// each frame event carries (its last 20, and events_total); a gap (frames skipped by the
// server's pacing, a restart) asks /api/events again.
function useEvents(frame) {
  const [events, setEvents] = useState([]);
  const seen = useRef(null);
  const refetch = () => getJSON('/api/events').then((r) => {
    seen.current = r.events_total;
    setEvents(r.events.slice(-kEventsShown));
  }).catch(() => {});
  useEffect(() => { refetch(); }, []);
  useEffect(() => {
    if (!frame || frame.events_total === undefined || seen.current === null) return;
    const fresh = frame.events_total - seen.current;
    if (fresh === 0) return;
    const got = frame.events || [];
    if (fresh < 0 || fresh > got.length) { refetch(); return; }
    seen.current = frame.events_total;
    setEvents((old) => [...old, ...got.slice(got.length - fresh)].slice(-kEventsShown));
  }, [frame]);
  return events;
}

function eventTime(e) {
  if (e.t_unix) return new Date(e.t_unix * 1000).toLocaleTimeString([], { hour12: false });
  return `${fmt(e.time_s, 1)} s`;
}

function eventText(e) {
  const who = e.track_id !== null && e.track_id !== undefined ? `track ${e.track_id}` : '';
  if (e.line !== undefined) return html`${who} crossed <b>${e.line}</b> ${e.direction === 'in' ? 'in' : 'out'} (in ${e.in} · out ${e.out})`;
  const verb = { enter: 'entered', leave: 'left', dwell: 'stays in', count: 'count of' }[e.event] || e.event;
  return html`${who} ${verb} <b>${e.zone}</b>${e.event === 'count' || e.count !== undefined ? ` (${e.count} inside)` : ''}`;
}

// A zone's count events repeat what its entries and exits say ("(N inside)"): left out here
// (they stay in events.jsonl, MQTT and /api/events).
function Events({ events }) {
  const shown = events.filter((e) => e.event !== 'count');
  return html`<section class="panel">
    <h2>Events</h2>
    ${shown.length === 0 ? html`<p class="hint">No zone entries or line crossings yet.</p>` : null}
    <table class="events" data-testid="events">
      ${[...shown].reverse().map((e) => html`<tr data-event=${e.event} data-frame=${e.frame}>
        <td class="num">${eventTime(e)}</td><td>${eventText(e)}</td></tr>`)}
    </table>
  </section>`;
}

export function LiveView({ site, state, frame }) {
  const events = useEvents(frame);
  const camStates = new Map(((state && state.cameras) || []).map((c) => [c.id, c]));
  // The newest frame set, for the tiles' own timers (no re-render per frame event needed).
  const latestFrame = useRef(null);
  const newest = frame ? frame.frame : state && state.frame >= 0 ? state.frame : null;
  if (newest !== null) latestFrame.current = newest;
  return html`
    <div class="live">
      <div class="map-col">
        <${FloorMap} site=${site} frame=${frame} />
        <div class="legend">
          <span><i class="sw free"></i>free</span><span><i class="sw occ"></i>occupied</span>
          <span><i class="sw unseen"></i>unseen</span><span><i class="sw det"></i>detection</span>
          <span><i class="sw trk"></i>track, trail</span>
        </div>
        <div class="tiles">
          ${site.cameras.map((c) => html`<${CameraTile} key=${c.id} camera=${c} latestFrame=${latestFrame}
            camState=${camStates.get(c.id)} state=${state} />`)}
        </div>
      </div>
      <aside class="side"><${Now} state=${state} frame=${frame} site=${site} /><${Events} events=${events} /></aside>
    </div>`;
}
