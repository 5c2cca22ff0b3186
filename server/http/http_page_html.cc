// The read-only web page of forestmapd --http (http_page.h): plain HTML, a canvas and fetch();
// nothing to build or download. The map shown is #map=NAME (default: the first map), optionally
// &at=X,Y,WIDTH_M. When the map is drawn, <body data-drawn="N" data-view="trees|density"> says
// how many trees and how (the browser tests wait for it); a map of over 100,000 trees shows its
// density until the view holds fewer. A clicked tree is named in the corner. The map's survey
// boundary is a dashed outline (data-boundary="N": its polygons).

#include "server/http/http_page.h"

namespace forestmap::server {

const char* const kHttpPageHtml = R"html(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>ForestMap</title>
<style>
 body { margin: 0; font: 13px sans-serif; display: flex; height: 100vh; }
 #side { width: 300px; overflow: auto; padding: 8px; border-right: 1px solid #ccc; }
 #side h2 { font-size: 14px; margin: 12px 0 4px; }
 #side a { display: block; padding: 2px 0; }
 table { border-collapse: collapse; } td, th { padding: 1px 6px; text-align: right; }
 #main { flex: 1; position: relative; }
 canvas { width: 100%; height: 100%; display: block; background: #f5f7f0; cursor: grab; }
 #info { position: absolute; left: 8px; top: 6px; background: #fffc; padding: 2px 6px; }
</style></head>
<body>
<div id="side"><h2>Maps</h2><div id="maps"></div>
<h2>Versions</h2><table id="versions"></table>
<h2>Last relocalizations</h2><table id="answers"></table></div>
<div id="main"><canvas id="map"></canvas><div id="info">loading...</div></div>
<script>
const canvas = document.getElementById('map'), ctx = canvas.getContext('2d');
// Trees drawn one by one at most: a larger map shows its density (trees per cell, from the
// server) until the view holds fewer, whose trees are then fetched for the view alone.
const kDrawLimit = 100000;
let trees = [], answers = [], view = null, current = null, density = null, refreshing = 0;
let boundary = [];  // the map's survey boundary: polygons of rings of [x, y]
// With tokens, the server's cookie (set on the first visit, /?token=...) goes with every call.
const get = url => fetch(url, { credentials: 'same-origin' }).then(r => r.json());
const mapUrl = (name, what) => '/api/maps/' + encodeURIComponent(name) + '/' + what;
function fit() {
  let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
  if (density) { x0 = density.min_x; y0 = density.min_y;
                 x1 = x0 + density.columns * density.cell_m; y1 = y0 + density.rows * density.cell_m; }
  for (const t of trees) { x0 = Math.min(x0, t[0]); x1 = Math.max(x1, t[0]);
                           y0 = Math.min(y0, t[1]); y1 = Math.max(y1, t[1]); }
  for (const polygon of boundary) for (const [x, y] of polygon[0]) {
    x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y); }
  if (!isFinite(x0)) return;
  const s = 0.95 * Math.min(canvas.width / (x1 - x0 + 1), canvas.height / (y1 - y0 + 1));
  view = { s, cx: (x0 + x1) / 2, cy: (y0 + y1) / 2 };
}
const px = (x, y) => [canvas.width / 2 + (x - view.cx) * view.s,
                      canvas.height / 2 - (y - view.cy) * view.s];
// The world box the canvas shows: [x0, y0, x1, y1].
const viewBox = () => [view.cx - canvas.width / 2 / view.s, view.cy - canvas.height / 2 / view.s,
                       view.cx + canvas.width / 2 / view.s, view.cy + canvas.height / 2 / view.s];
// Trees in the view by the density cells it touches (an upper bound).
function treesInView() {
  const [x0, y0, x1, y1] = viewBox(), d = density;
  const c0 = Math.max(0, Math.floor((x0 - d.min_x) / d.cell_m)), c1 = Math.min(d.columns - 1, Math.floor((x1 - d.min_x) / d.cell_m));
  const r0 = Math.max(0, Math.floor((y0 - d.min_y) / d.cell_m)), r1 = Math.min(d.rows - 1, Math.floor((y1 - d.min_y) / d.cell_m));
  let n = 0;
  for (let r = r0; r <= r1; ++r) for (let c = c0; c <= c1; ++c) n += d.counts[r * d.columns + c];
  return n;
}
function drawDensity() {
  const d = density, max = d.counts.reduce((a, b) => Math.max(a, b), 1), side = d.cell_m * view.s;
  for (let r = 0; r < d.rows; ++r) for (let c = 0; c < d.columns; ++c) {
    const n = d.counts[r * d.columns + c];
    if (!n) continue;
    const [u, v] = px(d.min_x + c * d.cell_m, d.min_y + (r + 1) * d.cell_m);
    ctx.fillStyle = `rgba(33, 107, 51, ${(0.15 + 0.85 * Math.log1p(n) / Math.log1p(max)).toFixed(3)})`;
    ctx.fillRect(u, v, side + 0.5, side + 0.5);
  }
}
function draw() {
  canvas.width = canvas.clientWidth; canvas.height = canvas.clientHeight;
  if (!view) fit();
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  if (!view) return;
  if (density && !trees.length) drawDensity();
  ctx.beginPath();
  for (const polygon of boundary) for (const ring of polygon) ring.forEach(([x, y], i) => {
    const [u, v] = px(x, y);
    i ? ctx.lineTo(u, v) : ctx.moveTo(u, v);
    if (i === ring.length - 1) ctx.closePath();
  });
  ctx.setLineDash([8, 3]); ctx.strokeStyle = '#593f99'; ctx.lineWidth = 1.8; ctx.stroke();
  ctx.setLineDash([]); ctx.lineWidth = 1;
  for (const t of trees) {
    const [u, v] = px(t[0], t[1]);
    const r = Math.max(1.5, 0.5 * (t[2] === null ? 0.2 : t[2]) * view.s);
    ctx.beginPath(); ctx.arc(u, v, r, 0, 2 * Math.PI);
    if (t[3] && t[2] !== null) { ctx.fillStyle = '#216b33'; ctx.fill(); }
    else { ctx.strokeStyle = t[3] ? '#216b33' : '#ee8c1a'; ctx.stroke(); }
  }
  for (const a of answers) {
    if (a.map !== current || a.x === undefined) continue;
    const [u, v] = px(a.x, a.y);
    ctx.fillStyle = '#d01818'; ctx.fillRect(u - 4, v - 4, 8, 8);
  }
  const bar = Math.pow(10, Math.floor(Math.log10(canvas.width / view.s / 5)));
  ctx.fillStyle = '#111'; ctx.fillRect(10, canvas.height - 16, bar * view.s, 3);
  ctx.fillText(bar + ' m', 14 + bar * view.s, canvas.height - 11);
  // For scripts and headless browsers: what is drawn, once it is.
  document.body.dataset.drawn = trees.length;
  document.body.dataset.view = density && !trees.length ? 'density' : 'trees';
  document.body.dataset.boundary = boundary.length;
}
// A large map: the trees of the view when it holds few enough, else its density.
async function refreshTrees() {
  if (!density || !view) return;
  const ticket = ++refreshing;
  let fetched = [];
  if (treesInView() <= kDrawLimit) {
    fetched = (await get(mapUrl(current, 'trees') + '?bbox=' + viewBox().map(v => v.toFixed(3)).join(','))).trees;
  }
  if (ticket === refreshing) { trees = fetched; draw(); }
}
let refreshTimer = null;
const refreshSoon = () => { clearTimeout(refreshTimer); refreshTimer = setTimeout(refreshTrees, 250); };
function setInfo(text) { document.getElementById('info').textContent = text; }
async function show(map, at) {
  current = map.name; view = null; trees = []; density = null;
  boundary = (await get(mapUrl(map.name, 'boundary'))).polygons;
  if (map.trees > kDrawLimit) density = await get(mapUrl(map.name, 'density'));
  else trees = (await get(mapUrl(map.name, 'trees'))).trees;
  setInfo(map.name + ': ' + map.trees + ' trees, version ' + map.version + (map.crs ? ', ' + map.crs : '') +
          (density ? ' (density: zoom in for trees; ' : ' (') + 'drag to pan, wheel to zoom, click a tree)');
  const versions = await get(mapUrl(map.name, 'versions'));
  document.getElementById('versions').innerHTML = '<tr><th>v</th><th>kind</th><th>trees</th></tr>' +
      versions.map(v => `<tr><td>${v.version}</td><td>${v.kind}</td><td>${v.trees}</td></tr>`).join('');
  draw();
  if (at) { view = { s: canvas.width / at[2], cx: at[0], cy: at[1] }; draw(); await refreshTrees(); }
}
async function showAnswers() {
  answers = await get('/api/relocalizations');
  document.getElementById('answers').innerHTML = '<tr><th>map</th><th>status</th><th>x</th><th>y</th></tr>' +
      answers.map(a => `<tr><td>${a.map}</td><td>${a.status}</td><td>${a.x === undefined ? '' : a.x.toFixed(2)}</td>` +
                       `<td>${a.y === undefined ? '' : a.y.toFixed(2)}</td></tr>`).join('');
}
// #map=NAME[&at=X,Y,WIDTH_M]: the map, and optionally the view's centre and width.
async function load() {
  const maps = await get('/api/maps');
  document.getElementById('maps').innerHTML = maps.map(m =>
      `<a href="#map=${encodeURIComponent(m.name)}">${m.name}</a>` +
      `<small>${m.trees} trees, v${m.version} ${m.crs}</small>`).join('');
  await showAnswers();
  const wanted = decodeURIComponent((location.hash.match(/map=([^&]*)/) || [])[1] || '');
  const at = ((location.hash.match(/at=([^&]*)/) || [])[1] || '').split(',').map(Number);
  const map = maps.find(m => m.name === wanted) || maps[0];
  if (map) await show(map, at.length === 3 && at.every(isFinite) && at[2] > 0 ? at : null);
  else setInfo('no maps');
}
// Click (without dragging) a tree: its id, place, DBH and status.
function identify(e) {
  const rect = canvas.getBoundingClientRect();
  let best = null, bestD = 8;  // px
  for (const t of trees) {
    const [u, v] = px(t[0], t[1]);
    const d = Math.hypot(u - (e.clientX - rect.left), v - (e.clientY - rect.top));
    if (d < bestD) { best = t; bestD = d; }
  }
  if (!best) return;
  setInfo(`tree ${best[4]}: x ${best[0].toFixed(2)}, y ${best[1].toFixed(2)}, DBH ` +
          (best[2] === null ? 'unknown' : (best[2] * 100).toFixed(1) + ' cm') + ', ' +
          (best[3] ? 'confirmed' : 'candidate'));
  document.body.dataset.identified = best[4];
}
let drag = null, moved = false;
canvas.onmousedown = e => { drag = [e.clientX, e.clientY]; moved = false; };
window.onmouseup = e => { if (drag && !moved && view) identify(e); if (drag && moved) refreshSoon(); drag = null; };
canvas.onmousemove = e => {
  if (!drag || !view) return;
  moved = moved || Math.hypot(e.clientX - drag[0], e.clientY - drag[1]) > 3;
  view.cx -= (e.clientX - drag[0]) / view.s; view.cy += (e.clientY - drag[1]) / view.s;
  drag = [e.clientX, e.clientY]; draw();
};
canvas.onwheel = e => {
  e.preventDefault();
  if (view) { view.s *= e.deltaY < 0 ? 1.25 : 0.8; draw(); refreshSoon(); }
};
window.onhashchange = load; window.onresize = draw;
// The drones' answers, live.
setInterval(() => showAnswers().then(draw), 3000);
load();
</script></body></html>
)html";

}  // namespace forestmap::server
