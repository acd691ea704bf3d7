// The page's side of the serve contract (docs/formats.md, "Web API"). With a token the browser
// holds it in the session cookie /login sets (HttpOnly: no script here sees it), which every
// request of this origin carries, fetch(), EventSource and <img> alike: no URL holds the token.
export function url(path, params = {}) {
  const u = new URL(path, location.href);
  for (const [k, v] of Object.entries(params)) if (v !== undefined && v !== null) u.searchParams.set(k, v);
  return u.pathname + u.search;
}

// The cookie expired or the server was started with another token: sign in again.
export function signIn() {
  location.assign(`/login?next=${encodeURIComponent(location.pathname)}`);
}

async function request(method, path, body) {
  const headers = {};
  if (body !== undefined) headers['Content-Type'] = 'application/json';
  const res = await fetch(url(path), { method, headers, body: body === undefined ? undefined : JSON.stringify(body) });
  let data = null;
  const text = await res.text();
  try { data = text ? JSON.parse(text) : null; } catch { data = { error: text }; }
  if (res.status === 401 && path !== '/api/login') signIn();
  if (!res.ok) {
    const message = (data && data.error) || `${method} ${path}: HTTP ${res.status}`;
    const err = new Error(message);
    err.status = res.status;
    err.body = data;
    throw err;
  }
  return data;
}

export const getJSON = (path) => request('GET', path);
export const postJSON = (path, body) => request('POST', path, body);
export const putJSON = (path, body) => request('PUT', path, body);
export const deleteJSON = (path) => request('DELETE', path);

export function subscribe(handlers, onStatus) {
  const es = new EventSource(url('/events'));
  for (const [name, fn] of Object.entries(handlers)) {
    es.addEventListener(name, (e) => {
      let data;
      try { data = JSON.parse(e.data); } catch { return; }
      fn(data);
    });
  }
  es.onopen = () => onStatus && onStatus(true);
  es.onerror = () => onStatus && onStatus(false);
  return () => es.close();
}

// The site's grid as Leaflet bounds in metres (CRS.Simple: lat = y, lng = x).
export function gridBounds(grid) {
  const x1 = grid.x_min_m + grid.cols * grid.cell_size_m;
  const y1 = grid.y_min_m + grid.rows * grid.cell_size_m;
  return [[grid.y_min_m, grid.x_min_m], [y1, x1]];
}

// A camera image in Leaflet: lat = -v, lng = u, with occmap's pixel convention (pixel (c, r)
// has its centre at (c, r), the image's top-left corner at (-0.5, -0.5)).
export function imageBounds(width, height) {
  return [[-(height - 0.5), -0.5], [0.5, width - 0.5]];
}
export const pixelToLatLng = (u, v) => [-v, u];
export const latLngToPixel = (ll) => [ll.lng, -ll.lat];

export function colorForId(id) {
  const hue = (Number(id) * 137.508) % 360;
  return `hsl(${hue.toFixed(0)}, 85%, 42%)`;
}

export const fmt = (v, digits = 1) => (v === undefined || v === null || Number.isNaN(v) ? '–' : Number(v).toFixed(digits));
