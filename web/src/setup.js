// The setup: per camera, its lens from board views (board.js), floor points clicked on its
// current frame and typed in metres ->
// POST /api/calibrate (errors and the floor grid shown), floor-mask polygons drawn on the image;
// zones and counting lines drawn on the floor map; Save -> PUT /api/site.
import { h } from 'preact';
import { useEffect, useRef, useState } from 'preact/hooks';
import htm from 'htm';
import L from 'leaflet';
import '@geoman-io/leaflet-geoman-free';
import { fmt, getJSON, latLngToPixel, pixelToLatLng, postJSON, putJSON, url } from './api.js';
import { clientPoint, createFloorMap, createImageMap } from './leafmaps.js';
import { BoardPanel } from './board.js';

const html = htm.bind(h);

const round = (v, d = 2) => Math.round(v * 10 ** d) / 10 ** d;

function geomanControls(map, shapes) {
  map.pm.addControls({
    position: 'topleft', drawMarker: false, drawCircleMarker: false, drawCircle: false,
    drawRectangle: false, drawText: false, cutPolygon: false, rotateMode: false,
    drawPolygon: shapes.includes('Polygon'), drawPolyline: shapes.includes('Line'),
    editMode: true, dragMode: true, removalMode: true,
  });
  map.pm.setGlobalOptions({ snappable: false, allowSelfIntersection: false });
}

// Geoman's Finish / Cancel pop-up opens over the map beside its button and takes the clicks
// meant for corners beneath it; it is hidden (style.css) and these buttons, above the map, do
// its work for whatever mode is on.
function DrawActions({ map }) {
  const [mode, setMode] = useState(null);
  useEffect(() => {
    if (!map) return undefined;
    const sync = () => {
      const pm = map.pm;
      if (pm.globalDrawModeEnabled()) setMode({ kind: 'draw', shape: pm.Draw.getActiveShape() });
      else if (pm.globalEditModeEnabled()) setMode({ kind: 'edit' });
      else if (pm.globalDragModeEnabled()) setMode({ kind: 'drag' });
      else if (pm.globalRemovalModeEnabled()) setMode({ kind: 'remove' });
      else setMode(null);
    };
    const events = 'pm:drawstart pm:drawend pm:globaldrawmodetoggled pm:globaleditmodetoggled '
      + 'pm:globaldragmodetoggled pm:globalremovalmodetoggled';
    map.on(events, sync);
    sync();
    return () => map.off(events, sync);
  }, [map]);
  if (!mode) return null;
  const pm = map.pm;
  if (mode.kind === 'draw') {
    const tool = pm.Draw[mode.shape];
    return html`<span class="draw-actions" data-testid="draw-actions">
      <span class="hint">drawing a ${mode.shape === 'Line' ? 'line' : 'polygon'}:</span>
      ${mode.shape === 'Polygon' ? html`<button data-testid="draw-finish" onClick=${() => tool._finishShape()}>Finish</button>` : null}
      <button data-testid="draw-undo" onClick=${() => tool._removeLastVertex()}>Remove last corner</button>
      <button data-testid="draw-cancel" onClick=${() => pm.disableDraw()}>Cancel</button></span>`;
  }
  const done = { edit: () => pm.disableGlobalEditMode(), drag: () => pm.disableGlobalDragMode(), remove: () => pm.disableGlobalRemovalMode() };
  const what = { edit: 'moving corners', drag: 'moving shapes', remove: 'click a shape to remove it' };
  return html`<span class="draw-actions" data-testid="draw-actions"><span class="hint">${what[mode.kind]}</span>
    <button data-testid="draw-done" onClick=${done[mode.kind]}>Done</button></span>`;
}

// A counting line is two points: finish the drawing at the second click.
function twoPointLines(map) {
  map.on('pm:drawstart', ({ shape, workingLayer }) => {
    if (shape !== 'Line') return;
    workingLayer.on('pm:vertexadded', () => {
      if (workingLayer.getLatLngs().length >= 2) map.pm.Draw.Line._finishShape();
    });
  });
}

const ringOf = (layer) => {
  const lls = layer.getLatLngs();
  return Array.isArray(lls[0]) ? lls[0] : lls;
};

function pointIcon(n, state) {
  return L.divIcon({ className: `fp-icon ${state || ''}`, html: `<span>${n}</span>`, iconSize: [22, 22], iconAnchor: [11, 11] });
}

// ---------------------------------------------------------------------------------------------
function CameraSetup({ camera, draft, update }) {
  const div = useRef(null);
  const ctx = useRef(null);
  const [mode, setMode] = useState('points');
  const [busy, setBusy] = useState(false);
  const [error, setError] = useState(null);
  const [showGrid, setShowGrid] = useState(true);
  const [snapshot, setSnapshot] = useState(Date.now());
  const [leafletMap, setLeafletMap] = useState(null);
  const [boardView, setBoardView] = useState(null);  // the URL of the board view shown
  const points = draft.points || [];
  const result = draft.result;
  // A mask from a picture file is shown, and drawing polygons (which replace it) waits for a click.
  const maskFile = camera.mask_file || null;
  const maskLocked = !!maskFile && !draft.replaceMaskFile;
  const boardLens = draft.board && draft.board.state && draft.board.state.calibration;

  // The map and its layers, once per camera.
  useEffect(() => {
    const src = url(`/api/cameras/${encodeURIComponent(camera.id)}/frame.jpg`, { overlay: 'none', t: snapshot });
    const im = createImageMap(div.current, camera.width_px, camera.height_px, src);
    const masks = L.featureGroup().addTo(im.map);
    const pointsLayer = L.layerGroup().addTo(im.map);
    geomanControls(im.map, ['Polygon']);
    im.map.pm.setGlobalOptions({ layerGroup: masks, snappable: false, allowSelfIntersection: false });
    for (const poly of draft.masks || []) {
      L.polygon(poly.map(([u, v]) => pixelToLatLng(u, v)), { color: '#16a34a', weight: 2, fillOpacity: 0.12 }).addTo(masks);
    }
    const readMasks = () => {
      const out = [];
      masks.eachLayer((layer) => {
        out.push(ringOf(layer).map((ll) => latLngToPixel(ll).map((p) => round(p, 1))));
      });
      update({ masks: out, masksDirty: true });
    };
    im.map.on('pm:create', ({ layer }) => {
      layer.setStyle({ color: '#16a34a', weight: 2, fillOpacity: 0.12 });
      layer.on('pm:edit pm:dragend', readMasks);
      readMasks();
    });
    masks.eachLayer((layer) => layer.on('pm:edit pm:dragend', readMasks));
    im.map.on('pm:remove', readMasks);
    // No picture before the camera's first frame (404): take another in a second.
    im.overlay.on('error', () => setTimeout(() => ctx.current && setSnapshot(Date.now()), 1000));
    ctx.current = { im, masks, pointsLayer };
    setLeafletMap(im.map);
    window.occmap = Object.assign(window.occmap || {}, {
      cameraMap: im.map,
      cameraToClient: (u, v) => clientPoint(im.map, pixelToLatLng(u, v)),
    });
    return () => { im.destroy(); ctx.current = null; };
  }, [camera.id]);

  // Clicks add floor points in points mode; geoman owns the clicks in mask mode.
  useEffect(() => {
    const c = ctx.current;
    if (!c) return;
    const map = c.im.map;
    if (mode !== 'mask' || maskLocked) {
      map.pm.disableDraw();
      map.pm.disableGlobalEditMode();
      map.pm.disableGlobalDragMode();
      map.pm.disableGlobalRemovalMode();
      map.pm.removeControls();
    } else {
      geomanControls(map, ['Polygon']);
    }
    const onClick = (e) => {
      if (mode !== 'points') return;
      const [u, v] = latLngToPixel(e.latlng);
      if (u < -0.5 || v < -0.5 || u > camera.width_px - 0.5 || v > camera.height_px - 0.5) return;
      update((d) => ({ points: [...(d.points || []), { u_px: round(u, 1), v_px: round(v, 1), x_m: '', y_m: '' }], result: null }));
    };
    map.on('click', onClick);
    return () => map.off('click', onClick);
  }, [mode, camera.id, maskLocked]);

  // The site's mask picture over the frame in mask mode: what is not floor, shaded.
  useEffect(() => {
    const c = ctx.current;
    if (!c || !maskFile || mode !== 'mask') return undefined;
    const overlay = L.imageOverlay(url(`/api/cameras/${encodeURIComponent(camera.id)}/mask.png`, { f: maskFile }), c.im.bounds, {
      className: 'mask-file-image', interactive: false, pmIgnore: true, opacity: draft.replaceMaskFile ? 0.5 : 1,
    }).addTo(c.im.map);
    return () => overlay.remove();
  }, [mode, camera.id, maskFile, draft.replaceMaskFile]);

  // The points' markers follow the list; dragging one moves its pixel.
  useEffect(() => {
    const c = ctx.current;
    if (!c) return;
    c.pointsLayer.clearLayers();
    points.forEach((p, i) => {
      const err = result && result.points && result.points[i];
      const m = L.marker(pixelToLatLng(p.u_px, p.v_px), {
        icon: pointIcon(i + 1, err ? (err.error_px <= 1 ? 'good' : 'bad') : ''), draggable: mode === 'points', pmIgnore: true,
      }).addTo(c.pointsLayer);
      m.on('dragend', () => {
        const [u, v] = latLngToPixel(m.getLatLng());
        update((d) => ({ points: d.points.map((q, j) => (j === i ? { ...q, u_px: round(u, 1), v_px: round(v, 1) } : q)), result: null }));
      });
    });
  }, [points, result, mode]);

  // The picture: a board view with its corners (Lens), the grid overlay of the pending
  // calibration, or the plain frame.
  useEffect(() => {
    const c = ctx.current;
    if (!c) return;
    const src = mode === 'lens' && boardView
      ? boardView
      : result && showGrid && result.overlay_url
        ? url(result.overlay_url, { t: snapshot })
        : url(`/api/cameras/${encodeURIComponent(camera.id)}/frame.jpg`, { overlay: 'none', t: snapshot });
    c.im.overlay.setUrl(src);
  }, [result, showGrid, snapshot, camera.id, mode, boardView]);

  const setField = (i, key, value) => update((d) => ({
    points: d.points.map((q, j) => (j === i ? { ...q, [key]: value } : q)), result: null,
  }));
  const remove = (i) => update((d) => ({ points: d.points.filter((_, j) => j !== i), result: null }));

  async function calibrate() {
    setError(null);
    const bad = points.findIndex((p) => p.x_m === '' || p.y_m === '' || !Number.isFinite(Number(p.x_m)) || !Number.isFinite(Number(p.y_m)));
    if (points.length < 4) { setError(`Click at least 4 floor points (${points.length} so far).`); return; }
    if (bad >= 0) { setError(`Point ${bad + 1}: type its floor position x, y in metres.`); return; }
    setBusy(true);
    try {
      const body = {
        camera: camera.id,
        points: points.map((p) => ({ u_px: p.u_px, v_px: p.v_px, x_m: Number(p.x_m), y_m: Number(p.y_m) })),
      };
      if (draft.method) body.method = draft.method;
      const res = await postJSON('/api/calibrate', body);
      update({ result: res, calibrationPending: true });
      setShowGrid(true);
    } catch (e) {
      setError(e.message);
    } finally {
      setBusy(false);
    }
  }

  return html`
    <div class="camera-setup">
      <div class="toolbar">
        <label class=${mode === 'points' ? 'on' : ''}><input type="radio" name="mode" checked=${mode === 'points'}
          onChange=${() => setMode('points')} data-testid="mode-points" />Floor points</label>
        <label class=${mode === 'mask' ? 'on' : ''}><input type="radio" name="mode" checked=${mode === 'mask'}
          onChange=${() => setMode('mask')} data-testid="mode-mask" />Floor mask</label>
        <label class=${mode === 'lens' ? 'on' : ''} title="The camera's intrinsics from a printed checkerboard or ChArUco board">
          <input type="radio" name="mode" checked=${mode === 'lens'} onChange=${() => setMode('lens')} data-testid="mode-lens" />Lens (board)</label>
        ${mode === 'mask' && !maskLocked ? html`<${DrawActions} map=${leafletMap} />` : null}
        <span class="grow"></span>
        ${result ? html`<label><input type="checkbox" checked=${showGrid} onChange=${(e) => setShowGrid(e.target.checked)} />grid</label>` : null}
        <button onClick=${() => { setBoardView(null); setSnapshot(Date.now()); }} title="Take the camera's current frame">New frame</button>
      </div>
      <div class="camera-map" ref=${div} data-testid="camera-map"></div>
      ${mode === 'lens' ? html`<${BoardPanel} camera=${camera} board=${draft.board || {}}
        update=${(patch) => update((d) => ({ board: { ...(d.board || {}), ...patch }, result: null }))}
        onNewFrame=${() => { setBoardView(null); setSnapshot(Date.now()); }} shown=${boardView} onShow=${setBoardView} />` : null}
      ${mode === 'mask' && maskFile ? html`<div class=${'mask-file ' + (maskLocked ? '' : 'replacing')} data-testid="mask-file">
        ${maskLocked
          ? html`This camera's mask is the picture <code>${maskFile}</code>, shaded where it is not floor.
            Polygons drawn here replace it when saved.
            <button onClick=${() => update({ replaceMaskFile: true })} data-testid="mask-replace">Replace it with polygons</button>`
          : html`Replacing <code>${maskFile}</code> (shown faded) with the polygons drawn here, once saved.
            <button onClick=${() => { if (ctx.current) ctx.current.masks.clearLayers(); update({ replaceMaskFile: false, masksDirty: false, masks: [] }); }} data-testid="mask-keep">Keep the picture</button>`}
      </div>` : null}
      <p class="hint">${mode === 'lens' ? '' : mode === 'points'
        ? 'Click a floor mark you measured (tile corner, tape), then type where it is in metres. 4 points at least, better 8, spread over the floor; drag a number to move it.'
        : 'Draw the polygons of floor this camera should map (the tools on the left); pixels outside every polygon are ignored. No polygon: the whole image.'}</p>
      ${mode === 'points' ? html`<table class="points" data-testid="points">
        <tr><th>#</th><th>u px</th><th>v px</th><th>x m</th><th>y m</th><th>error px</th><th>floor cm</th>
          <th title="the point's error under the fit of all the other points (leave-one-out)">others px</th><th></th></tr>
        ${points.map((p, i) => {
          const r = result && result.points && result.points[i];
          return html`<tr class=${r && r.outlier ? 'outlier' : ''} data-outlier=${r && r.outlier ? 'true' : 'false'}>
            <td>${i + 1}</td><td class="num">${fmt(p.u_px, 1)}</td><td class="num">${fmt(p.v_px, 1)}</td>
            <td><input class="coord" data-testid=${`x-${i}`} inputmode="decimal" value=${p.x_m} onInput=${(e) => setField(i, 'x_m', e.target.value)} /></td>
            <td><input class="coord" data-testid=${`y-${i}`} inputmode="decimal" value=${p.y_m} onInput=${(e) => setField(i, 'y_m', e.target.value)} /></td>
            <td class=${'num error-px ' + (r ? (r.error_px <= 1 ? 'good' : 'bad') : '')}>${r ? fmt(r.error_px, 2) : ''}</td>
            <td class="num">${r ? fmt(r.floor_error_m * 100, 1) : ''}</td>
            <td class="num" title=${r && r.outlier ? 'an outlier: the other points put it this far away' : ''}>${r ? fmt(r.predicted_error_px, 1) : ''}${
              r && r.outlier ? html` <span class="badge down">outlier</span>` : null}</td>
            <td><button class="small" onClick=${() => remove(i)} title="Remove this point">×</button></td></tr>`;
        })}
      </table>
      <div class="actions">
        <label>method
          <select value=${draft.method || ''} data-testid="method" onChange=${(e) => update({ method: e.target.value || undefined, result: null })}>
            <option value="">default</option><option value="pnp">camera pose (${boardLens ? 'the lens from the board' : 'intrinsics'})</option>
            <option value="lens">lens and pose (focal length, distortion; 6+ points)</option><option value="homography">floor homography</option>
          </select></label>
        <button class="primary" disabled=${busy} onClick=${calibrate} data-testid="calibrate">Calibrate</button>
        ${result ? html`<span class="result" data-testid="calibration-result">
            RMS <b data-testid="rms-px">${fmt(result.rms_px, 2)}</b> px · floor <b data-testid="floor-cm">${fmt(result.floor_rms_m * 100, 1)}</b> cm
            ${result.rms_px !== null && result.rms_px <= 1 && !(result.concerns && result.concerns.length) ? html`<span class="badge up">good</span>` : html`<span class="badge down">check the points</span>`}
            <span class="hint">${draft.calibrationPending ? "(pending until saved)" : "(saved)"}</span>
            ${result.intrinsics_from === 'board' ? html`<span class="hint" data-testid="intrinsics-from-board">with the lens from the board</span>` : null}</span>` : null}
        ${result && result.lens_fitted && result.intrinsics ? html`<span class="hint" data-testid="lens-fitted">lens fitted:
            focal length ${fmt(result.intrinsics.fx_px, 1)} px, k1 ${fmt(result.intrinsics.distortion[0], 3)}, k2 ${fmt(result.intrinsics.distortion[1], 3)}</span>` : null}
        ${result && result.concerns && result.concerns.length ? html`<div class="concerns" data-testid="calibration-concerns">
            <b>Not fit to save as it is:</b><ul>${result.concerns.map((c) => html`<li>${c}</li>`)}</ul>
            ${result.outliers && result.outliers.length ? html`<span class="hint">Correct or remove point${result.outliers.length > 1 ? 's' : ''} ${result.outliers.map((i) => i + 1).join(', ')}
              and calibrate again (without ${result.outliers.length > 1 ? 'them' : 'it'}:
              RMS ${fmt(result.rms_without_outliers_px, 2)} px).</span>` : null}</div>` : null}
        ${result && result.outlier_note && result.rms_px > result.max_rms_px ? html`<p class="hint">${result.outlier_note}</p>` : null}
        ${result && result.warnings && result.warnings.length
          ? html`<ul class="warnings">${result.warnings.map((w) => html`<li>${w}</li>`)}</ul>` : null}
        ${result && result.method === 'homography' && result.rms_px > 1
          ? html`<p class="hint" data-testid="homography-hint">A floor homography cannot follow lens distortion, which
              bends the floor's straight lines near the picture's edges. Choose <b>lens and pose</b> with 8 or more
              points spread over the picture (near its edges too), or give this camera its intrinsics first
              (<code>occmap calibrate</code> with a printed board, docs/own-cameras.md "Calibrate your cameras").</p>` : null}
        ${error ? html`<span class="error" data-testid="calibration-error">${error}</span>` : null}
      </div>` : null}
    </div>`;
}

// ---------------------------------------------------------------------------------------------
// The cameras' coverage (GET /api/coverage: the run's tables, as visibility.png) while `on`:
// asked again every 2 s, since a saved site rebuilds the tables in the background.
function useCoverage(on) {
  const [coverage, setCoverage] = useState(null);
  useEffect(() => {
    if (!on) return undefined;
    let stopped = false;
    let timer = null;
    const poll = () => getJSON('/api/coverage')
      .then((c) => { if (!stopped) setCoverage((old) => (old && old.version === c.version ? old : c)); })
      .catch(() => { if (!stopped) setCoverage(null); })
      .finally(() => { if (!stopped) timer = setTimeout(poll, 2000); });
    poll();
    return () => { stopped = true; clearTimeout(timer); };
  }, [on]);
  return on ? coverage : null;
}

function CoverageLegend({ coverage }) {
  if (!coverage) return html`<p class="hint" data-testid="coverage-legend">coverage: waiting for the tables…</p>`;
  const pct = (n) => (coverage.cells > 0 ? (100 * n) / coverage.cells : 0).toFixed(0);
  return html`<div class="legend" data-testid="coverage-legend">
    ${coverage.colors.map((c, k) => html`<span data-count=${k}><i class="sw" style=${`background:${c}`}></i>
      ${k === 0 ? 'unseen' : `${k} camera${k > 1 ? 's' : ''}`} (${pct(coverage.cells_seen_by[k])} %)</span>`)}
  </div>`;
}

function ZoneEditor({ site, zones, lines, setZonesLines }) {
  const div = useRef(null);
  const ctx = useRef(null);
  const [showCoverage, setShowCoverage] = useState(false);
  const [leafletMap, setLeafletMap] = useState(null);
  // A band being typed, by line: the page re-renders with every frame event, which would put
  // a controlled input's saved value back under the user's fingers before the change is done.
  const [bandText, setBandText] = useState({});
  const coverage = useCoverage(showCoverage);
  const readAll = () => {
    const c = ctx.current;
    const zs = []; const ls = [];
    c.zoneLayer.eachLayer((layer) => zs.push({
      name: layer.occmapName, polygon_m: ringOf(layer).map((ll) => [round(ll.lng, 3), round(ll.lat, 3)]),
      ...(layer.occmapDwell !== undefined ? { dwell_s: layer.occmapDwell } : {}),
    }));
    c.lineLayer.eachLayer((layer) => {
      const p = layer.getLatLngs();
      ls.push({
        name: layer.occmapName, a_m: [round(p[0].lng, 3), round(p[0].lat, 3)], b_m: [round(p[p.length - 1].lng, 3), round(p[p.length - 1].lat, 3)],
        // The counting rules go back as they came (a new line: the loader's defaults).
        ...(layer.occmapBand !== undefined ? { hysteresis_m: layer.occmapBand } : {}),
        ...(layer.occmapOnce !== undefined ? { once_per_track: layer.occmapOnce } : {}),
      });
    });
    setZonesLines(zs, ls);
  };
  const nextName = (prefix, layer) => {
    const names = new Set();
    layer.eachLayer((l) => names.add(l.occmapName));
    let i = 1;
    while (names.has(`${prefix}${i}`)) i += 1;
    return `${prefix}${i}`;
  };

  useEffect(() => {
    const floor = createFloorMap(div.current, site.grid);
    const zoneLayer = L.featureGroup().addTo(floor.map);
    const lineLayer = L.featureGroup().addTo(floor.map);
    floor.map.eachLayer((l) => { if (l.options) l.options.pmIgnore = true; });
    // Under the zones' drawings (the overlay pane, 400), over the live map it replaces.
    floor.map.createPane('coverage').style.zIndex = 350;
    ctx.current = { floor, zoneLayer, lineLayer, coverage: null };
    setLeafletMap(floor.map);
    const watch = (layer) => layer.on('pm:edit pm:dragend', readAll);
    for (const z of zones) {
      const p = L.polygon(z.polygon_m.map(([x, y]) => [y, x]), { color: '#2563eb', weight: 2, fillOpacity: 0.12 }).addTo(zoneLayer);
      p.occmapName = z.name; p.occmapDwell = z.dwell_s; watch(p);
    }
    for (const l of lines) {
      const p = L.polyline([[l.a_m[1], l.a_m[0]], [l.b_m[1], l.b_m[0]]], { color: '#7c3aed', weight: 3 }).addTo(lineLayer);
      p.occmapName = l.name; p.occmapBand = l.hysteresis_m; p.occmapOnce = l.once_per_track; watch(p);
    }
    geomanControls(floor.map, ['Polygon', 'Line']);
    twoPointLines(floor.map);
    floor.map.on('pm:create', ({ shape, layer }) => {
      floor.map.removeLayer(layer);
      if (shape === 'Polygon') {
        layer.setStyle({ color: '#2563eb', weight: 2, fillOpacity: 0.12 });
        layer.occmapName = nextName('zone', zoneLayer);
        zoneLayer.addLayer(layer);
      } else {
        layer.setStyle({ color: '#7c3aed', weight: 3 });
        layer.occmapName = nextName('line', lineLayer);
        lineLayer.addLayer(layer);
      }
      watch(layer);
      readAll();
    });
    floor.map.on('pm:remove', readAll);
    window.occmap = Object.assign(window.occmap || {}, {
      zoneMap: floor.map,
      setupFloorToClient: (x, y) => clientPoint(floor.map, [y, x]),
    });
    return () => floor.destroy();
  }, [JSON.stringify(site.grid)]);

  // The coverage picture instead of the live map while shown.
  useEffect(() => {
    const c = ctx.current;
    if (!c) return;
    if (c.coverage) { c.coverage.remove(); c.coverage = null; }
    c.floor.overlay.setOpacity(coverage ? 0 : 1);
    if (coverage) {
      c.coverage = L.imageOverlay(url('/api/coverage.png', { v: coverage.version }), c.floor.bounds, {
        pane: 'coverage', className: 'map-image coverage-image', interactive: false, pmIgnore: true,
      }).addTo(c.floor.map);
    }
  }, [coverage && coverage.version]);

  // Names typed in the list go onto the layers (and their labels).
  useEffect(() => {
    const c = ctx.current;
    if (!c) return;
    const label = (layer, name, dir) => {
      if (layer.getTooltip()) layer.setTooltipContent(name);
      else layer.bindTooltip(name, { permanent: true, direction: dir, className: 'zone-label' });
    };
    let i = 0;
    c.zoneLayer.eachLayer((layer) => { const z = zones[i++]; if (z) { layer.occmapName = z.name; label(layer, z.name, 'center'); } });
    i = 0;
    c.lineLayer.eachLayer((layer) => { const l = lines[i++]; if (l) { layer.occmapName = l.name; label(layer, l.name, 'right'); } });
  }, [zones, lines]);

  // A line's counting rules, typed in the list: onto its layer, then read back with the rest.
  const setRule = (i, key, value) => {
    const layer = ctx.current && ctx.current.lineLayer.getLayers()[i];
    if (!layer) return;
    if (key === 'band') layer.occmapBand = value;
    else layer.occmapOnce = value;
    readAll();
  };
  const rename = (kind, i, name) => {
    const zs = zones.map((z, j) => (kind === 'zone' && j === i ? { ...z, name } : z));
    const ls = lines.map((l, j) => (kind === 'line' && j === i ? { ...l, name } : l));
    setZonesLines(zs, ls);
  };
  const removeItem = (kind, i) => {
    if (kind === 'line') setBandText({});
    const c = ctx.current;
    const layers = (kind === 'zone' ? c.zoneLayer : c.lineLayer).getLayers();
    if (layers[i]) (kind === 'zone' ? c.zoneLayer : c.lineLayer).removeLayer(layers[i]);
    readAll();
  };
  const draw = (shape) => ctx.current && ctx.current.floor.map.pm.enableDraw(shape, shape === 'Line' ? {} : { snappable: false });

  return html`
    <div class="zone-editor">
      <div class="toolbar">
        <button onClick=${() => draw('Polygon')} data-testid="draw-zone">Draw a zone</button>
        <button onClick=${() => draw('Line')} data-testid="draw-line">Draw a counting line</button>
        <label class=${showCoverage ? 'on' : ''} title="How many cameras see each cell (as occmap lut's visibility.png)">
          <input type="checkbox" checked=${showCoverage} data-testid="show-coverage"
            onChange=${(e) => setShowCoverage(e.target.checked)} />camera coverage</label>
        <${DrawActions} map=${leafletMap} />
        <span class="hint">click the corners, then the first one again; a line is two clicks ("in" crosses from its right to its left)</span>
      </div>
      <div class="zone-map" ref=${div} data-testid="zone-map"></div>
      ${showCoverage ? html`<${CoverageLegend} coverage=${coverage} />` : null}
      <table class="zones" data-testid="zone-list">
        ${zones.map((z, i) => html`<tr><td>zone</td>
          <td><input value=${z.name} data-testid=${`zone-name-${i}`} onInput=${(e) => rename('zone', i, e.target.value)} /></td>
          <td class="hint">${z.polygon_m.length} corners</td>
          <td><button class="small" onClick=${() => removeItem('zone', i)}>×</button></td></tr>`)}
        ${lines.map((l, i) => html`<tr><td>line</td>
          <td><input value=${l.name} onInput=${(e) => rename('line', i, e.target.value)} /></td>
          <td class="hint">(${l.a_m.join(', ')}) → (${l.b_m.join(', ')}) m
            <label title="a track is on a side only beyond this distance from the line">band
              <input class="coord" data-testid=${`line-band-${i}`} inputmode="decimal" value=${bandText[i] ?? l.hysteresis_m ?? 0.2}
                onInput=${(e) => setBandText({ ...bandText, [i]: e.target.value })}
                onChange=${(e) => {
                  const v = Number(e.target.value);
                  if (e.target.value !== '' && Number.isFinite(v)) setRule(i, 'band', v);
                  setBandText({ ...bandText, [i]: undefined });
                }} /> m</label>
            <label title="a track counts at most once in each direction"><input type="checkbox" data-testid=${`line-once-${i}`}
              checked=${l.once_per_track ?? true} onChange=${(e) => setRule(i, 'once', e.target.checked)} />once a track</label></td>
          <td><button class="small" onClick=${() => removeItem('line', i)}>×</button></td></tr>`)}
      </table>
    </div>`;
}

// ---------------------------------------------------------------------------------------------
export function SetupView({ site, onSaved }) {
  const [camId, setCamId] = useState(site.cameras.length ? site.cameras[0].id : null);
  const [drafts, setDrafts] = useState(() => Object.fromEntries(
    site.cameras.map((c) => [c.id, { points: [], masks: c.mask_polygons_px || [], result: null }])));
  const [zones, setZones] = useState(site.zones || []);
  const [lines, setLines] = useState(site.lines || []);
  const [zonesDirty, setZonesDirty] = useState(false);
  const [saving, setSaving] = useState(false);
  const [message, setMessage] = useState(null);
  const [confirming, setConfirming] = useState(null);  // the concerns Save warns of

  const updateDraft = (id) => (change) => setDrafts((all) => {
    const d = all[id];
    const patch = typeof change === 'function' ? change(d) : change;
    return { ...all, [id]: { ...d, ...patch } };
  });
  const setZonesLines = (zs, ls) => { setZones(zs); setLines(ls); setZonesDirty(true); };

  const pendingCams = Object.entries(drafts).filter(([, d]) => d.calibrationPending).map(([id]) => id);
  const maskCams = Object.entries(drafts).filter(([, d]) => d.masksDirty).map(([id]) => id);
  const dirty = pendingCams.length > 0 || maskCams.length > 0 || zonesDirty;
  // A lens from the board is saved with the camera's pose: until then it only waits.
  const lensCams = Object.entries(drafts).filter(([, d]) => d.board && d.board.lensNew && !d.calibrationPending).map(([id]) => id);

  // Calibrations with outliers or a high RMS are saved only once confirmed (the server refuses
  // them without "force").
  const concerns = pendingCams.flatMap((id) => ((drafts[id].result && drafts[id].result.concerns) || []).map((c) => `${id}: ${c}`));
  function askSave() {
    if (concerns.length) { setConfirming(concerns); return; }
    save(false);
  }

  async function save(force) {
    setConfirming(null);
    setSaving(true);
    setMessage(null);
    const body = force ? { force: true } : {};
    if (pendingCams.length) body.calibrations = Object.fromEntries(pendingCams.map((id) => [id, 'pending']));
    if (maskCams.length) body.mask_polygons_px = Object.fromEntries(maskCams.map((id) => [id, drafts[id].masks]));
    if (zonesDirty) { body.zones = zones; body.lines = lines; }
    try {
      const res = await putJSON('/api/site', body);
      setMessage({ ok: true, text: `Saved ${res.site ? res.site.path : ''} (the previous file kept as .bak); the pipeline restarts on it.` });
      // The pending results were written (the server forgets them): the pictures show the saved
      // calibration's grid from now on.
      setDrafts((all) => Object.fromEntries(Object.entries(all).map(([id, d]) => [id, {
        ...d, calibrationPending: false, masksDirty: false,
        board: d.board && d.calibrationPending ? { ...d.board, lensNew: false } : d.board,
        result: d.calibrationPending && d.result ? { ...d.result, overlay_url: d.result.overlay_url.replace('&calibration=pending', '') } : d.result,
      }])));
      setZonesDirty(false);
      if (res.site) onSaved(res.site);
    } catch (e) {
      setMessage({ ok: false, text: e.message });
    } finally {
      setSaving(false);
    }
  }

  const camera = site.cameras.find((c) => c.id === camId);
  return html`
    <div class="setup">
      <div class="savebar">
        <span>${dirty ? html`Unsaved: ${[
          pendingCams.length ? `calibration of ${pendingCams.join(', ')}` : null,
          maskCams.length ? `masks of ${maskCams.map((id) => {
            const f = (site.cameras.find((c) => c.id === id) || {}).mask_file;
            return f ? `${id} (replacing ${f})` : id;
          }).join(', ')}` : null,
          zonesDirty ? 'zones and lines' : null].filter(Boolean).join('; ')}` : 'No unsaved changes.'}</span>
        ${lensCams.length ? html`<span class="hint" data-testid="lens-waiting">the lens of ${lensCams.join(', ')} is saved
          with the camera's pose: calibrate its floor points</span>` : null}
        <button class="primary" disabled=${!dirty || saving} onClick=${askSave} data-testid="save">Save to the site file</button>
        ${message ? html`<span class=${message.ok ? 'ok' : 'error'} data-testid="save-message">${message.text}</span>` : null}
      </div>
      ${confirming ? html`<div class="banner confirm" data-testid="save-confirm">
        <b>A calibration to save looks wrong:</b>
        <ul>${confirming.map((c) => html`<li>${c}</li>`)}</ul>
        <span>Saving replaces the camera's current calibration with it.</span>
        <button onClick=${() => setConfirming(null)} data-testid="save-cancel">Keep the current calibration</button>
        <button class="danger" onClick=${() => save(true)} data-testid="save-anyway">Save anyway</button></div>` : null}
      <div class="setup-cols">
        <section class="panel">
          <h2>Camera</h2>
          <div class="cam-tabs">
            ${site.cameras.map((c) => html`<button class=${c.id === camId ? 'on' : ''} data-camera=${c.id}
              onClick=${() => setCamId(c.id)}>${c.id}${c.has_calibration ? '' : ' (not calibrated)'}${drafts[c.id] && drafts[c.id].calibrationPending ? ' *' : ''}</button>`)}
          </div>
          ${camera ? html`<${CameraSetup} key=${camera.id} camera=${camera} draft=${drafts[camera.id]} update=${updateDraft(camera.id)} />` : html`<p>No cameras.</p>`}
        </section>
        <section class="panel">
          <h2>Zones and counting lines (metres)</h2>
          <${ZoneEditor} site=${site} zones=${zones} lines=${lines} setZonesLines=${setZonesLines} />
        </section>
      </div>
    </div>`;
}
