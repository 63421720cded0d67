// The Scan tab's live cloud: the grid elements each sweep adds as the station measures them
// (`cloud` events; GET /api/scan/cloud for a page opened mid-scan), coloured by thinning. The
// station decimates them (API.md); the page only draws what it is sent.
'use strict';

const live = { view: null, xyz: [], thickness: [], measured: 0, batches: 0, userMoved: false };

function liveView() {
  if (live.view) return live.view;
  live.view = makeView($('live-view'));
  // Once the operator turns the view, new sweeps no longer reframe it.
  if (live.view) live.view.controls.addEventListener('start', () => { live.userMoved = true; });
  return live.view;
}
function liveCloudResize() { if (live.view) live.view.resize(); }

function liveCloudDraw() {
  const v = liveView();
  document.body.dataset.liveCloud = String(live.thickness.length);
  document.body.dataset.liveBatches = String(live.batches);
  $('live-count').textContent = live.thickness.length
    ? `${live.measured} grid elements measured so far${live.thickness.length < live.measured ? ` (${live.thickness.length} shown)` : ''}`
    : 'the grid elements appear sweep by sweep';
  if (!v) return;
  if (!live.thickness.length) { v.put('points', null); return; }
  const thinning = live.thickness.map((t) => (1 - Math.exp(t)) * 100);
  const hi = Math.max(1, ...thinning);
  const colours = [];
  for (const t of thinning) colours.push(...ramp(Math.max(t, 0) / hi));
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.Float32BufferAttribute(live.xyz, 3));
  g.setAttribute('color', new THREE.Float32BufferAttribute(colours, 3));
  g.computeBoundingSphere();
  v.put('points', new THREE.Points(g, new THREE.PointsMaterial({ size: 1.6, vertexColors: THREE.VertexColors })));
  if (!live.userMoved) v.frame(g.boundingSphere);
}

function liveCloudReset() {
  Object.assign(live, { xyz: [], thickness: [], measured: 0, batches: 0, userMoved: false });
  liveCloudDraw();
}
function liveCloudAdd(d) {
  if (d.kind !== 'scan') return;
  live.xyz.push(...d.xyz);
  live.thickness.push(...d.thickness);
  live.measured = d.measured;
  live.batches += 1;
  liveCloudDraw();
}
// A page opened mid-scan: everything so far.
async function liveCloudLoad() {
  const r = await api('/api/scan/cloud');
  if (!r.ok) return;
  Object.assign(live, { xyz: r.body.xyz, thickness: r.body.thickness, measured: r.body.measured, batches: r.body.batches });
  liveCloudDraw();
}
