// The read-only web page of forestmapd --http (http_page.h): plain HTML, a canvas and fetch();
// nothing to build or download. The map shown is #map=NAME (default: the first map). When its
// trees are drawn, <body data-drawn="N"> says how many (the browser test waits for it).

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
let trees = [], answers = [], view = null, current = null;
// With tokens, the server's cookie (set on the first visit, /?token=...) goes with every call.
const get = url => fetch(url, { credentials: 'same-origin' }).then(r => r.json());
function fit() {
  if (!trees.length) return;
  let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
  for (const t of trees) { x0 = Math.min(x0, t[0]); x1 = Math.max(x1, t[0]);
                           y0 = Math.min(y0, t[1]); y1 = Math.max(y1, t[1]); }
  const s = 0.95 * Math.min(canvas.width / (x1 - x0 + 1), canvas.height / (y1 - y0 + 1));
  view = { s, cx: (x0 + x1) / 2, cy: (y0 + y1) / 2 };
}
const px = (x, y) => [canvas.width / 2 + (x - view.cx) * view.s,
                      canvas.height / 2 - (y - view.cy) * view.s];
function draw() {
  canvas.width = canvas.clientWidth; canvas.height = canvas.clientHeight;
  if (!view) fit();
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  if (!view) return;
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
  document.body.dataset.drawn = trees.length;
}
async function show(name) {
  current = name;
  const data = await get('/api/maps/' + encodeURIComponent(name) + '/trees');
  trees = data.trees; view = null;
  document.getElementById('info').textContent =
      name + ': ' + trees.length + ' trees, version ' + data.map.version +
      (data.map.crs ? ', ' + data.map.crs : '') + ' (drag to pan, wheel to zoom)';
  const versions = await get('/api/maps/' + encodeURIComponent(name) + '/versions');
  document.getElementById('versions').innerHTML = '<tr><th>v</th><th>kind</th><th>trees</th></tr>' +
      versions.map(v => `<tr><td>${v.version}</td><td>${v.kind}</td><td>${v.trees}</td></tr>`).join('');
  draw();
}
async function load() {
  const maps = await get('/api/maps');
  document.getElementById('maps').innerHTML = maps.map(m =>
      `<a href="#map=${encodeURIComponent(m.name)}">${m.name}</a>` +
      `<small>${m.trees} trees, v${m.version} ${m.crs}</small>`).join('');
  answers = await get('/api/relocalizations');
  document.getElementById('answers').innerHTML = '<tr><th>map</th><th>status</th><th>x</th><th>y</th></tr>' +
      answers.map(a => `<tr><td>${a.map}</td><td>${a.status}</td><td>${a.x === undefined ? '' : a.x.toFixed(2)}</td>` +
                       `<td>${a.y === undefined ? '' : a.y.toFixed(2)}</td></tr>`).join('');
  const wanted = decodeURIComponent((location.hash.match(/map=([^&]*)/) || [])[1] || '');
  const name = wanted || (maps.length ? maps[0].name : null);
  if (name) await show(name); else document.getElementById('info').textContent = 'no maps';
}
let drag = null;
canvas.onmousedown = e => { drag = [e.clientX, e.clientY]; };
window.onmouseup = () => { drag = null; };
canvas.onmousemove = e => {
  if (!drag || !view) return;
  view.cx -= (e.clientX - drag[0]) / view.s; view.cy += (e.clientY - drag[1]) / view.s;
  drag = [e.clientX, e.clientY]; draw();
};
canvas.onwheel = e => { e.preventDefault(); if (view) { view.s *= e.deltaY < 0 ? 1.25 : 0.8; draw(); } };
window.onhashchange = load; window.onresize = draw;
load();
</script></body></html>
)html";

}  // namespace forestmap::server
