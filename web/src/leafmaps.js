// Leaflet maps in occmap's two frames: the floor in metres (x east, y north, CRS.Simple with
// lat = y, lng = x) and a camera image in pixels (lat = -v, lng = u).
import L from 'leaflet';
import { gridBounds, imageBounds, url } from './api.js';

function baseMap(div) {
  return L.map(div, {
    crs: L.CRS.Simple, minZoom: -6, maxZoom: 8, zoomSnap: 0.25, zoomDelta: 0.5,
    attributionControl: false, boxZoom: false,
  });
}

// The floor map with the live tri-state map image; refresh(version) swaps the picture once the
// previous one has loaded, so a slow link shows fewer frames rather than a growing queue.
export function createFloorMap(div, grid) {
  const map = baseMap(div);
  const bounds = gridBounds(grid);
  const overlay = L.imageOverlay(url('/api/map.png', { v: 0 }), bounds, { className: 'map-image' }).addTo(map);
  L.rectangle(bounds, { color: '#555', weight: 1, fill: false, interactive: false }).addTo(map);
  addMetreAxes(map, bounds);
  L.control.scale({ imperial: false, maxWidth: 140, position: 'bottomright' }).addTo(map);
  map.fitBounds(bounds, { padding: [24, 24] });
  let loading = false;
  let wanted = null;
  let version_shown = 0;
  overlay.on('load error', (e) => {
    loading = false;
    // No map before the first frame set (404): ask again in a second.
    if (e.type === 'error' && wanted === null) setTimeout(() => refresh(version_shown), 1000);
    if (wanted !== null) { const v = wanted; wanted = null; refresh(v); }
  });
  function refresh(version) {
    if (loading) { wanted = version; return; }
    loading = true;
    version_shown = version;
    overlay.setUrl(url('/api/map.png', { v: version, t: Date.now() % 100000 }));
  }
  const resize = new ResizeObserver(() => map.invalidateSize());
  resize.observe(div);
  return { map, overlay, bounds, refresh, destroy: () => { resize.disconnect(); map.remove(); } };
}

// Tick labels in metres along the floor's lower and left edges, every 0.5, 1, 2, 5, 10, ... m so
// that at most about 10 fit along the longer side.
function addMetreAxes(map, bounds) {
  const [[y0, x0], [y1, x1]] = bounds;
  const span = Math.max(x1 - x0, y1 - y0);
  const raw = span / 10;
  const decade = 10 ** Math.floor(Math.log10(raw));
  const step = [1, 2, 5, 10].map((k) => Number((k * decade).toPrecision(6))).find((s) => s >= raw);
  // Below the lower edge, centred; left of the left edge, right-aligned (Leaflet places a marker
  // by its anchor: its own transform is Leaflet's). The axes' names past their ends, clear of
  // a tick that falls on the end (a floor of whole metres).
  const anchors = { 'axis-x': [22, -3], 'axis-y': [48, 7], 'axis-x axis-name': [-6, -3], 'axis-y axis-name': [48, 22] };
  const label = (text, latlng, cls) => L.marker(latlng, {
    interactive: false, keyboard: false,
    icon: L.divIcon({ className: `axis-label ${cls}`, html: text, iconSize: [44, 14], iconAnchor: anchors[cls] }),
  }).addTo(map);
  const digits = step < 1 ? 1 : 0;
  // Integer multiples of the step, so that no sum of steps drifts.
  for (let k = Math.ceil(x0 / step - 1e-9); k * step <= x1 + 1e-9; ++k) label((k * step).toFixed(digits), [y0, k * step], 'axis-x');
  for (let k = Math.ceil(y0 / step - 1e-9); k * step <= y1 + 1e-9; ++k) label((k * step).toFixed(digits), [k * step, x0], 'axis-y');
  label('x (m)', [y0, x1], 'axis-x axis-name');
  label('y (m)', [y1, x0], 'axis-y axis-name');
}

// A camera's picture in pixels; setUrl replaces it (the grid overlay after a calibration).
export function createImageMap(div, width, height, src) {
  const map = baseMap(div);
  const bounds = imageBounds(width, height);
  const overlay = L.imageOverlay(src, bounds).addTo(map);
  map.fitBounds(bounds);
  map.setMaxBounds(L.latLngBounds(bounds).pad(0.25));
  const resize = new ResizeObserver(() => { map.invalidateSize(); });
  resize.observe(div);
  return { map, overlay, bounds, destroy: () => { resize.disconnect(); map.remove(); } };
}

// Where a map point appears in the page (client pixels): what a user would click.
export function clientPoint(map, latlng) {
  const p = map.latLngToContainerPoint(latlng);
  const r = map.getContainer().getBoundingClientRect();
  return { x: r.left + p.x, y: r.top + p.y };
}
