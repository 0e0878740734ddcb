// vloc console: one WebSocket to vloc_console; everything is drawn from the
// messages it sends (see procs/vloc_console/console_json.cpp for their form).
'use strict';
const vloc = window.vloc = {
  sites: {},            // id -> {dr, localization, opt, frontend}
  tiePoints: {},        // current site -> tie_points message
  images: {},           // site -> [{pair, width, height}]
  procman: {},          // 'host:launcher pid' -> procman message (two launchers may share a host)
  tunnels: {},          // tunnel end name -> its TUNNEL_STATUS
  uav: [], mosaicSeq: 0,
  mayAct: false, connected: false,
  pair: null, userPair: false,   // {previous, current} shown in the images panel
  picks: [], pendingPick: null,
  stats: { messages: 0, traverses: 0, traverseLatencyMs: [], traverseAgeMs: [] },
};
const $ = (id) => document.getElementById(id);
let ws = null, nextId = 1;
const waiting = {};

// ---- connection
function connect() {
  ws = new WebSocket((location.protocol === 'https:' ? 'wss://' : 'ws://') + location.host + '/ws');
  ws.onopen = () => { vloc.connected = true; setConn(); authorize(); };
  ws.onclose = () => { vloc.connected = false; setConn(); setTimeout(connect, 1000); };
  ws.onmessage = (e) => { vloc.stats.messages++; dispatch(JSON.parse(e.data)); };
}
function setConn() {
  $('conn').textContent = vloc.connected ? 'live' : 'disconnected';
  $('conn').className = vloc.connected ? 'good' : 'bad';
}
function send(command) {
  command.id = nextId++;
  command.token = $('token').value;
  return new Promise((resolve) => {
    waiting[command.id] = resolve;
    if (!ws || ws.readyState !== 1) { delete waiting[command.id]; resolve({ ok: false, error: 'not connected' }); return; }
    ws.send(JSON.stringify(command));
  });
}
function notice(text, ok) { $('notice').textContent = text; $('notice').className = ok ? 'good' : 'bad'; }
async function authorize() {
  const r = await send({ type: 'auth' });
  vloc.mayAct = !!r.may_act;
  $('act').textContent = vloc.mayAct ? 'may act' : 'watching only';
  $('act').className = vloc.mayAct ? 'good' : '';
  drawProcs(); updatePicks();
}

// ---- messages
const handlers = {
  reply: (m) => { const w = waiting[m.id]; if (w) { delete waiting[m.id]; w(m); } },
  hello: () => {},
  traverse: onTraverse,
  site_pose: (m) => { if (m.source === 'dr') site(m.site).dr = m; dirtyMap(); },
  localization: (m) => {
    site(m.site).localization = m; dirtyMap();
    if (vloc.selected === m.site) showSite(m.site);
    if (isShown(m.site)) fillPairSelect();
  },
  frontend_status: (m) => { site(m.current).frontend = m; if (vloc.selected === m.current) showSite(m.current); autoPair(m.previous, m.current); },
  tie_points: (m) => { vloc.tiePoints[m.current] = m; autoPair(m.previous, m.current); if (isShown(m.current)) drawImages(); },
  images: (m) => { vloc.images[m.site] = m.pairs; fillImageSelects(); },
  procman: (m) => { vloc.procman[m.host + ':' + m.pid] = m; drawProcs(); },
  procman_gone: (m) => { delete vloc.procman[m.key]; drawProcs(); },
  tunnel: (m) => { vloc.tunnels[m.name] = m; drawTunnels(); },
  tunnel_gone: (m) => { delete vloc.tunnels[m.key]; drawTunnels(); },
  uav_state: (m) => { vloc.uav.push(m); if (vloc.uav.length > 5000) vloc.uav.shift(); dirtyUav(); },
  uav_history: (m) => { vloc.uav = m.states; dirtyUav(); },
  uav_mosaic: (m) => { vloc.mosaicSeq = m.seq; dirtyUav(); },
  orthoimage: (m) => {
    const img = new Image();
    img.onload = () => { vloc.ortho = Object.assign({ img }, m); dirtyMap(); };
    img.src = '/api/orthoimage';
  },
};
function dispatch(m) { const h = handlers[m.type]; if (h) h(m); }
function site(id) { return vloc.sites[id] || (vloc.sites[id] = { id }); }
function onTraverse(m) {
  for (const s of Object.values(vloc.sites)) delete s.opt;
  for (const s of m.sites) site(s.id).opt = s;
  vloc.lastTraverse = m;
  dirtyMap(() => {
    vloc.stats.traverses++;
    const now = Date.now();
    vloc.stats.traverseLatencyMs.push(now - m.console_us / 1000);
    vloc.stats.traverseAgeMs.push(now - m.utime / 1000);
  });
}

// ---- traverse map
let mapDirty = false, mapDone = [];
function dirtyMap(done) {
  if (done) mapDone.push(done);
  if (mapDirty) return;
  mapDirty = true;
  requestAnimationFrame(() => { mapDirty = false; drawMap(); const d = mapDone; mapDone = []; d.forEach((f) => f()); });
}
function positions(s) { return [s.dr, s.localization && s.localization.ok ? s.localization : null, s.opt].filter(Boolean); }
function mapTransform() {
  const c = $('map');
  let xs = [], ys = [];
  for (const s of Object.values(vloc.sites)) for (const p of positions(s)) { xs.push(p.x); ys.push(p.y); }
  if (!xs.length) { xs = [0, 10]; ys = [0, 10]; }
  const x0 = Math.min(...xs) - 3, x1 = Math.max(...xs) + 3, y0 = Math.min(...ys) - 3, y1 = Math.max(...ys) + 3;
  const k = Math.min(c.width / (x1 - x0), c.height / (y1 - y0));
  const ox = (c.width - k * (x1 - x0)) / 2, oy = (c.height - k * (y1 - y0)) / 2;
  return { k, toPx: (x, y) => [ox + k * (x - x0), c.height - oy - k * (y - y0)] };
}
function ellipse(g, t, p, colour) {
  const a = p.cxx, b = p.cxy, d = p.cyy;
  if (![a, b, d].every(Number.isFinite)) return;
  const tr = (a + d) / 2, det = Math.sqrt(Math.max(0, ((a - d) / 2) ** 2 + b * b));
  const l1 = Math.max(0, tr + det), l2 = Math.max(0, tr - det), ang = 0.5 * Math.atan2(2 * b, a - d);
  const [px, py] = t.toPx(p.x, p.y);
  g.strokeStyle = colour;
  g.beginPath();
  g.ellipse(px, py, Math.min(2 * Math.sqrt(l1) * t.k, 2000), Math.min(2 * Math.sqrt(l2) * t.k, 2000), -ang, 0, 2 * Math.PI);
  g.stroke();
}
function drawTrack(g, t, key, colour) {
  const ids = Object.keys(vloc.sites).map(Number).sort((a, b) => a - b);
  g.strokeStyle = colour; g.fillStyle = colour; g.beginPath();
  let first = true;
  for (const id of ids) {
    const p = key === 'localization' ? (vloc.sites[id].localization && vloc.sites[id].localization.ok && vloc.sites[id].localization) : vloc.sites[id][key];
    if (!p) continue;
    const [x, y] = t.toPx(p.x, p.y);
    if (first) g.moveTo(x, y); else g.lineTo(x, y);
    first = false;
  }
  g.stroke();
  for (const id of ids) {
    const s = vloc.sites[id];
    const p = key === 'localization' ? (s.localization && s.localization.ok && s.localization) : s[key];
    if (!p) continue;
    const [x, y] = t.toPx(p.x, p.y);
    g.beginPath(); g.arc(x, y, 4, 0, 2 * Math.PI); g.fill();
    ellipse(g, t, p, colour);
  }
}
function drawMap() {
  const c = $('map'), g = c.getContext('2d'), t = mapTransform();
  g.clearRect(0, 0, c.width, c.height);
  const o = vloc.ortho;
  if (o) {  // north up: pixel (0, 0) at (x_min, y_max)
    const [x0, y0] = t.toPx(o.x_min, o.y_max);
    g.drawImage(o.img, x0, y0, o.width * o.m_per_px * t.k, o.height * o.m_per_px * t.k);
  }
  g.lineWidth = 1.5;
  drawTrack(g, t, 'dr', '#999');
  drawTrack(g, t, 'localization', '#27c');
  drawTrack(g, t, 'opt', '#1a1');
  g.fillStyle = '#000'; g.font = '11px sans-serif';
  for (const s of Object.values(vloc.sites)) {
    const p = s.opt || s.dr;
    if (!p) continue;
    const [x, y] = t.toPx(p.x, p.y);
    g.fillText(String(s.id), x + 6, y - 6);
    if (s.frontend && !s.frontend.ok && !(s.localization && s.localization.ok)) { g.strokeStyle = '#e22'; g.strokeRect(x - 7, y - 7, 14, 14); }
  }
  vloc.stats.mapSites = Object.values(vloc.sites).filter((s) => s.opt || s.dr).length;
}
function siteAt(cx, cy) {
  const t = mapTransform();
  let best = null, bestD = 14;
  for (const s of Object.values(vloc.sites)) for (const p of positions(s)) {
    const [x, y] = t.toPx(p.x, p.y), d = Math.hypot(x - cx, y - cy);
    if (d < bestD) { bestD = d; best = s.id; }
  }
  return best;
}
function canvasPoint(c, e) {
  const r = c.getBoundingClientRect();
  return [(e.clientX - r.left) * c.width / r.width, (e.clientY - r.top) * c.height / r.height];
}
function showSite(id) {
  vloc.selected = id;
  const s = vloc.sites[id] || {};
  const f = (p) => p ? `x ${p.x.toFixed(3)} y ${p.y.toFixed(3)} z ${p.z.toFixed(3)} m, yaw ${(p.yaw * 180 / Math.PI).toFixed(2)} deg, sigma_xy ${Math.sqrt(p.cxx).toFixed(3)} ${Math.sqrt(p.cyy).toFixed(3)} m` : '-';
  let text = `site ${id}\nDR         ${f(s.dr)}\noptimised  ${f(s.opt)}\n`;
  const l = s.localization;
  text += l ? `BA vs ${l.reference}: ${l.status} - ${l.message}\n  used ${l.used}, rejected ${l.rejected}, observations ${l.observations}, rms ${l.initial_rms_px} -> ${l.final_rms_px} px, ${l.iterations} it, ${l.solve_seconds.toFixed(2)} s\n  ${f(l)}\n` : 'BA: none\n';
  const fe = s.frontend;
  text += fe ? `FRONTEND ${fe.previous} -> ${fe.current}: ${fe.status}${fe.message ? ' - ' + fe.message : ''} (${fe.total_seconds.toFixed(2)} s)\n` + fe.stages.map((st) => `  ${st.name.padEnd(22)} ${String(st.count).padStart(6)} ${st.seconds.toFixed(3)} s`).join('\n') : 'FRONTEND_STATUS: none';
  $('site-info').textContent = text;
}

// ---- images and tie points
function autoPair(previous, current) {
  if (!vloc.userPair && (!vloc.pair || current >= vloc.pair.current)) setPair(previous, current, false);
  else fillPairSelect();
}
function setPair(previous, current, byUser) {
  vloc.pair = { previous, current };
  if (byUser) vloc.userPair = true;
  vloc.picks = []; vloc.pendingPick = null;
  fillPairSelect(); fillImageSelects(); updatePicks();
}
vloc.selectPair = (p, c) => setPair(p, c, true);
function isShown(current) { return vloc.pair && vloc.pair.current === current; }
function fillPairSelect() {
  const sel = $('pair-select'), pairs = new Set();
  for (const s of Object.values(vloc.sites)) if (s.frontend) pairs.add(s.frontend.previous + '>' + s.frontend.current);
  for (const t of Object.values(vloc.tiePoints)) pairs.add(t.previous + '>' + t.current);
  if (vloc.pair) pairs.add(vloc.pair.previous + '>' + vloc.pair.current);
  const want = vloc.pair ? vloc.pair.previous + '>' + vloc.pair.current : '';
  sel.innerHTML = [...pairs].sort((a, b) => Number(a.split('>')[1]) - Number(b.split('>')[1]))
    .map((p) => `<option value="${p}"${p === want ? ' selected' : ''}>${p.replace('>', ' -> ')}</option>`).join('');
  $('pair-title').textContent = vloc.pair ? `site ${vloc.pair.previous} -> ${vloc.pair.current}` + pairState() : '';
}
// What the front end and the BA made of the shown pair, for its title.
function pairState() {
  const s = vloc.sites[vloc.pair.current] || {}, f = s.frontend, l = s.localization;
  if (l && l.reference === vloc.pair.previous) return `: BA ${l.status}, ${l.used} tie points, rms ${Number(l.final_rms_px).toFixed(2)} px`;
  if (f && f.previous === vloc.pair.previous && !f.ok) return `: front end ${f.status} - pick tie points by hand`;
  return '';
}
function fillImageSelects() {
  if (!vloc.pair) return;
  for (const [id, siteId] of [['prev-image', vloc.pair.previous], ['cur-image', vloc.pair.current]]) {
    const sel = $(id), old = sel.value, list = vloc.images[siteId] || [];
    sel.innerHTML = list.map((p) => `<option value="${p.pair}">left ${p.pair}</option>`).join('');
    if (list.some((p) => String(p.pair) === old)) sel.value = old;
  }
  loadImages();
}
const loaded = { prev: null, cur: null };
function loadImages() {
  for (const [which, siteId, sel] of [['prev', vloc.pair.previous, 'prev-image'], ['cur', vloc.pair.current, 'cur-image']]) {
    const pair = $(sel).value;
    if (pair === '') { loaded[which] = null; continue; }
    const key = siteId + '/' + pair;
    if (loaded[which] && loaded[which].key === key) continue;
    const img = new Image();
    loaded[which] = { key, site: siteId, pair: Number(pair), img, ready: false };
    img.onload = () => { loaded[which].ready = true; drawImages(); };
    img.src = `/api/image?site=${siteId}&pair=${pair}`;
  }
  drawImages();
}
function residualColour(r) {
  if (r === undefined || r === null) return '#4af';
  return r < 0.05 ? '#2d2' : r < 0.2 ? '#dd2' : '#e22';
}
function drawImages() {
  for (const which of ['prev', 'cur']) {
    const c = $(which + '-canvas'), g = c.getContext('2d'), l = loaded[which];
    if (!l || !l.ready) { g.clearRect(0, 0, c.width, c.height); continue; }
    if (c.width !== l.img.width) { c.width = l.img.width; c.height = l.img.height; }
    g.drawImage(l.img, 0, 0);
    const s = Math.max(2, c.width / 200);
    const tp = vloc.pair && vloc.tiePoints[vloc.pair.current];
    if (tp && tp.previous === vloc.pair.previous) for (const p of tp.points) {
      const o = which === 'prev' ? p.previous : p.current;
      if (!o || o.pair !== l.pair) continue;
      g.fillStyle = residualColour(p.residual_m);
      g.beginPath(); g.arc(o.u, o.v, s, 0, 2 * Math.PI); g.fill();
    }
    g.strokeStyle = '#f0f'; g.lineWidth = s / 2; g.fillStyle = '#f0f'; g.font = `${4 * s}px sans-serif`;
    const picks = vloc.picks.concat(vloc.pendingPick ? [vloc.pendingPick] : []);
    picks.forEach((p, i) => {
      const u = p[which === 'prev' ? 'previous_u' : 'current_u'], v = p[which === 'prev' ? 'previous_v' : 'current_v'];
      const pair = p[which === 'prev' ? 'previous_pair' : 'current_pair'];
      if (u === undefined || pair !== l.pair) return;
      g.beginPath(); g.moveTo(u - 3 * s, v); g.lineTo(u + 3 * s, v); g.moveTo(u, v - 3 * s); g.lineTo(u, v + 3 * s); g.stroke();
      g.fillText(String(i + 1), u + 3 * s, v - 3 * s);
    });
  }
}
// Image px of a click (pixel centres at integers).
function imagePoint(c, e) { const [x, y] = canvasPoint(c, e); return [x - 0.5, y - 0.5]; }
// Client (page) coordinates of image px (u, v) of a canvas: for tests.
vloc.imageToClient = (which, u, v) => {
  const c = $(which + '-canvas'), r = c.getBoundingClientRect();
  return [r.left + (u + 0.5) * r.width / c.width, r.top + (v + 0.5) * r.height / c.height];
};
// Client coordinates of a site on the map (optimised, else DR): for tests.
vloc.siteToClient = (id) => {
  const s = vloc.sites[id], p = s && (s.opt || s.dr), c = $('map'), r = c.getBoundingClientRect();
  if (!p) return null;
  const [x, y] = mapTransform().toPx(p.x, p.y);
  return [r.left + x * r.width / c.width, r.top + y * r.height / c.height];
};
vloc.imagesReady = () => !!(loaded.prev && loaded.prev.ready && loaded.cur && loaded.cur.ready);
function onImageClick(which, e) {
  if (!$('manual').checked || !loaded[which] || !loaded[which].ready) return;
  const [u, v] = imagePoint($(which + '-canvas'), e);
  const l = loaded[which];
  if (which === 'prev') vloc.pendingPick = { previous_pair: l.pair, previous_u: u, previous_v: v };
  else if (vloc.pendingPick) {
    vloc.picks.push(Object.assign(vloc.pendingPick, { current_pair: l.pair, current_u: u, current_v: v }));
    vloc.pendingPick = null;
  } else notice('click the point in the previous image first', false);
  updatePicks(); drawImages();
}
function updatePicks() {
  $('picks').textContent = `${vloc.picks.length} picks` + (vloc.pendingPick ? ' (+1 waiting for the current image)' : '');
  $('send-ties').disabled = !vloc.mayAct || !vloc.picks.length || !vloc.pair;
}
async function sendTies() {
  const r = await send({ type: 'manual_tie', previous_site: vloc.pair.previous, current_site: vloc.pair.current, points: vloc.picks });
  notice(r.ok ? `${r.points} tie points sent for ${vloc.pair.previous} -> ${vloc.pair.current}` : r.error, r.ok);
  if (r.ok) { vloc.picks = []; updatePicks(); drawImages(); }
  vloc.lastTieReply = r;
}

// ---- UAV
let uavDirty = false, mosaicShown = 0, mosaicAt = 0;
function dirtyUav() { if (!uavDirty) { uavDirty = true; requestAnimationFrame(() => { uavDirty = false; drawUav(); }); } }
function plot(c, xs, ys, colour, equal) {
  const g = c.getContext('2d');
  g.clearRect(0, 0, c.width, c.height);
  const ok = xs.map((x, i) => Number.isFinite(x) && Number.isFinite(ys[i]));
  const fx = xs.filter((x, i) => ok[i]), fy = ys.filter((y, i) => ok[i]);
  if (fx.length < 1) return;
  let x0 = Math.min(...fx), x1 = Math.max(...fx) + 1e-9, y0 = Math.min(...fy), y1 = Math.max(...fy) + 1e-9;
  let kx = (c.width - 20) / (x1 - x0), ky = (c.height - 20) / (y1 - y0);
  if (equal) kx = ky = Math.min(kx, ky);
  g.strokeStyle = colour; g.beginPath();
  fx.forEach((x, i) => { const px = 10 + kx * (x - x0), py = c.height - 10 - ky * (fy[i] - y0); if (i) g.lineTo(px, py); else g.moveTo(px, py); });
  g.stroke();
  g.fillStyle = '#333'; g.fillText(`${y1.toFixed(1)}`, 2, 10); g.fillText(`${y0.toFixed(1)}`, 2, c.height - 2);
}
function drawUav() {
  const u = vloc.uav;
  if (u.length) {
    const last = u[u.length - 1];
    $('uav-state').textContent = `frame ${last.frame}: ${last.status}${last.message ? ' (' + last.message + ')' : ''}, height ${Number(last.height).toFixed(1)} m, ${last.gps_aided ? 'GPS aided' : 'vision only'}, inliers ${last.inliers}`;
    plot($('uav-route'), u.map((s) => s.east), u.map((s) => s.north), '#27c', true);
    plot($('uav-height'), u.map((s) => s.frame), u.map((s) => s.height), '#c72', false);
  }
  if (vloc.mosaicSeq !== mosaicShown && Date.now() - mosaicAt > 1000) {
    mosaicShown = vloc.mosaicSeq; mosaicAt = Date.now();
    $('uav-mosaic').src = `/api/uav_mosaic?seq=${mosaicShown}`;
  }
}

// ---- processes
function drawProcs() {
  const rows = [];
  for (const key of Object.keys(vloc.procman).sort()) for (const p of vloc.procman[key].procs) {
    const host = vloc.procman[key].host;
    const b = (a) => `<button data-host="${esc(host)}" data-target="${esc(p.name)}" data-action="${a}"${vloc.mayAct ? '' : ' disabled'}>${a}</button>`;
    rows.push(`<tr data-proc="${esc(p.name)}"><td>${esc(host)}</td><td>${esc(p.name)}</td><td>${esc(p.group)}</td><td class="${p.state === 'running' ? 'good' : 'bad'}">${p.state}</td><td>${p.pid}</td><td class="restarts">${p.restarts}</td><td>${Number(p.cpu_percent).toFixed(1)}</td><td>${(p.rss_bytes / 1048576).toFixed(1)}</td><td>${Number(p.uptime_seconds).toFixed(0)}</td><td>${b('start')} ${b('stop')} ${b('restart')}</td></tr>`);
  }
  $('procs').querySelector('tbody').innerHTML = rows.join('');
}
function drawTunnels() {
  const kB = (v) => v === null ? '-' : (v / 1000).toFixed(1);
  const rows = Object.keys(vloc.tunnels).sort().map((name) => {
    const t = vloc.tunnels[name];
    const link = t.connected ? 'up' : `down (${t.seconds_since_peer === null || t.seconds_since_peer < 0 ? 'never heard' : Number(t.seconds_since_peer).toFixed(0) + ' s'})`;
    const dropped = `${t.dropped}` + (t.dropped ? ` (full ${t.dropped_queue_full}, large ${t.dropped_too_large}, channels ${t.dropped_too_many_channels})` : '');
    const latency = t.latency_samples ? `${Number(t.latency_median_ms).toFixed(0)} / ${Number(t.latency_max_ms).toFixed(0)}` : '-';
    return `<tr data-tunnel="${esc(name)}"><td>${esc(name)}</td><td>${esc(t.peer)}</td><td class="${t.connected ? 'good' : 'bad'}">${esc(link)}</td><td>${kB(t.tx_bytes_per_s)}</td><td>${kB(t.rx_bytes_per_s)}</td><td>${t.cap_bytes_per_s ? kB(t.cap_bytes_per_s) : 'none'}</td><td>${t.queued}</td><td>${(t.queued_bytes / 1e6).toFixed(1)} (${(t.queued_bytes_high_water / 1e6).toFixed(1)})</td><td class="${t.dropped ? 'bad' : ''}">${esc(dropped)}</td><td>${latency}</td></tr>`;
  });
  $('tunnels').querySelector('tbody').innerHTML = rows.join('');
}
function esc(s) { return String(s).replace(/[&<>"']/g, (ch) => `&#${ch.charCodeAt(0)};`); }
async function onProcButton(e) {
  const b = e.target.closest('button');
  if (!b) return;
  const r = await send({ type: 'order', host: b.dataset.host, target: b.dataset.target, target_kind: 'process', action: b.dataset.action });
  notice(r.ok ? `${b.dataset.action} ${b.dataset.target} sent` : r.error, r.ok);
  vloc.lastOrderReply = r;
}

// ---- wiring
function init() {
  const m = /token=([^&]*)/.exec(location.hash);
  if (m) $('token').value = decodeURIComponent(m[1]);
  $('token').addEventListener('change', authorize);
  $('map').addEventListener('click', (e) => {
    const [x, y] = canvasPoint($('map'), e), id = siteAt(x, y);
    if (id === null) return;
    showSite(id);
    const s = vloc.sites[id];
    if (s.frontend) setPair(s.frontend.previous, id, true);
  });
  $('pair-select').addEventListener('change', () => { const [p, c] = $('pair-select').value.split('>').map(Number); setPair(p, c, true); });
  $('prev-image').addEventListener('change', loadImages);
  $('cur-image').addEventListener('change', loadImages);
  $('prev-canvas').addEventListener('click', (e) => onImageClick('prev', e));
  $('cur-canvas').addEventListener('click', (e) => onImageClick('cur', e));
  $('send-ties').addEventListener('click', sendTies);
  $('clear-ties').addEventListener('click', () => { vloc.picks = []; vloc.pendingPick = null; updatePicks(); drawImages(); });
  $('procs').addEventListener('click', onProcButton);
  connect();
  dirtyMap();
}
init();
