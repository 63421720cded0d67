// The Result tab's analysis: arrows of the major-strain direction on every grid element (the
// measurement's own direction, GET /api/runs/{id}/elements) and a section cut placed with a slider
// along x, y or z, its strain profile (GET /api/runs/{id}/section, computed by the station) plotted
// with Chart.js. The page draws; the station measures and cuts.
'use strict';

const analysis = { runId: null, elements: null, arrows: null, axis: null, at: 0, box: null, chart: null,
                   inFlight: false, pending: false };

// Arrows: a bar along the major direction through the element, its length growing with the major
// strain, with heads pointing out where the sheet is stretched (major > 0), in where it is compressed.
// The heads open in the surface (across the direction, about the element's normal), and the arrow is
// lifted a little off the surface along the normal so that the surface hides only the far side's.
function arrowGeometry(e) {
  const seg = [];
  let maxMajor = 1e-9;
  for (const m of e.major) maxMajor = Math.max(maxMajor, Math.abs(m));
  const n = e.thickness.length;
  const V = (a, i) => new THREE.Vector3(a[3 * i], a[3 * i + 1], a[3 * i + 2]);
  for (let i = 0; i < n; ++i) {
    const d = V(e.major_direction, i);
    if (d.lengthSq() < 0.5) continue;  // no direction measured for this element
    const normal = e.normal ? V(e.normal, i) : new THREE.Vector3(0, 0, 1);
    const len = 2.2 * (0.25 + 0.75 * Math.abs(e.major[i]) / maxMajor);  // mm; the grid's pitch is 2.54
    let side = new THREE.Vector3().crossVectors(normal, d);
    if (side.lengthSq() < 1e-6) side = new THREE.Vector3().crossVectors(new THREE.Vector3(0, 0, 1), d);
    side.normalize();
    const p = V(e.xyz, i).addScaledVector(normal, 0.3);
    const head = 0.45, out = e.major[i] >= 0 ? 1 : -1;
    for (const s of [1, -1]) {
      const tip = p.clone().addScaledVector(d, (s * len) / 2);
      const back = tip.clone().addScaledVector(d, -s * out * head);
      seg.push(p, tip, tip, back.clone().addScaledVector(side, head * 0.6), tip, back.clone().addScaledVector(side, -head * 0.6));
    }
  }
  return new THREE.BufferGeometry().setFromPoints(seg);
}

function showArrows(on) {
  if (!view) return;
  $('arrows').setAttribute('aria-pressed', on ? 'true' : 'false');
  $('arrows').classList.toggle('on', on);
  if (on && !analysis.arrows && analysis.elements && analysis.elements.has_directions) {
    analysis.arrows = new THREE.LineSegments(arrowGeometry(analysis.elements), new THREE.LineBasicMaterial({ color: 0x000000 }));
  }
  view.put('arrowLines', on ? analysis.arrows : null);
  document.body.dataset.arrows = on && analysis.arrows ? String(analysis.arrows.geometry.attributes.position.count / 12) : '0';
}
$('arrows').addEventListener('click', () => showArrows($('arrows').getAttribute('aria-pressed') !== 'true'));

// ---- the section -----------------------------------------------------------------------------
function sectionPlane() {
  const b = analysis.box, size = new THREE.Vector3(), c = new THREE.Vector3();
  b.getSize(size).multiplyScalar(1.1).addScalar(4);
  b.getCenter(c);
  // PlaneGeometry lies in x-y facing +z: turned about y it faces x (its width then runs along z),
  // turned about x it faces y (its height then runs along z).
  const dims = { x: [size.z, size.y], y: [size.x, size.z], z: [size.x, size.y] }[analysis.axis];
  const plane = new THREE.Mesh(new THREE.PlaneGeometry(dims[0], dims[1]),
    new THREE.MeshBasicMaterial({ color: 0xffffff, transparent: true, opacity: 0.25, side: THREE.DoubleSide, depthWrite: false }));
  if (analysis.axis === 'x') { plane.rotation.set(0, Math.PI / 2, 0); plane.position.set(analysis.at, c.y, c.z); }
  if (analysis.axis === 'y') { plane.rotation.set(Math.PI / 2, 0, 0); plane.position.set(c.x, analysis.at, c.z); }
  if (analysis.axis === 'z') plane.position.set(c.x, c.y, analysis.at);
  return plane;
}

function setSection(axis) {
  analysis.axis = axis;
  document.querySelectorAll('.section-axis').forEach((b) => b.classList.toggle('on', b.dataset.axis === axis));
  $('section-controls').classList.toggle('hidden', !axis);
  $('section-card').classList.toggle('hidden', !axis);
  if (!axis) {
    if (view) { view.put('sectionPlane', null); view.put('sectionPoints', null); }
    delete document.body.dataset.section;
    return;
  }
  const k = { x: 'x', y: 'y', z: 'z' }[axis];
  const lo = analysis.box.min[k], hi = analysis.box.max[k];
  const slider = $('section-at');
  slider.min = lo.toFixed(1); slider.max = hi.toFixed(1); slider.step = '0.1';
  slider.value = ((lo + hi) / 2).toFixed(1);
  moveSection(Number(slider.value));
  sectionChartResize();
}

function moveSection(at) {
  analysis.at = at;
  $('section-value').textContent = `${analysis.axis} = ${at.toFixed(1)} mm`;
  if (view) view.put('sectionPlane', sectionPlane());
  requestSection();
}

// One request at a time: while the finger drags, the last position is asked for once the answer
// to the one before is in.
async function requestSection() {
  if (analysis.inFlight) { analysis.pending = true; return; }
  analysis.inFlight = true;
  const runId = analysis.runId, axis = analysis.axis, at = analysis.at;
  const r = await api(`/api/runs/${encodeURIComponent(runId)}/section?axis=${axis}&at=${at}`);
  analysis.inFlight = false;
  if (analysis.runId === runId && analysis.axis) {
    if (r.ok) showSection(r.body); else $('section-info').textContent = r.body.error;
  }
  if (analysis.pending) { analysis.pending = false; requestSection(); }
}

function showSection(s) {
  $('section-info').textContent = s.points.length
    ? `${s.points.length} grid elements within ${num(s.width_mm / 2, 2)} mm of ${s.axis} = ${num(s.at_mm, 1)} mm; along the cut ${num(s.points[s.points.length - 1].along_mm, 1)} mm`
    : `no grid element within ${num(s.width_mm / 2, 2)} mm of ${s.axis} = ${num(s.at_mm, 1)} mm: move the section`;
  // The cut's elements lit in the 3D view.
  if (view) {
    const g = new THREE.BufferGeometry().setFromPoints(s.points.map((p) => new THREE.Vector3(p.x, p.y, p.z)));
    const pts = new THREE.Points(g, new THREE.PointsMaterial({ color: 0xffffff, size: 1.4, depthTest: false }));
    pts.renderOrder = 3;
    view.put('sectionPoints', pts);
  }
  const series = (key) => s.points.map((p) => ({ x: p.along_mm, y: p[key] }));
  const data = { datasets: [
    { label: 'major %', data: series('major_percent'), borderColor: '#ff5252', backgroundColor: '#ff5252' },
    { label: 'minor %', data: series('minor_percent'), borderColor: '#2f81f7', backgroundColor: '#2f81f7' },
    { label: 'thinning %', data: series('thinning_percent'), borderColor: '#f0e020', backgroundColor: '#f0e020' }] };
  if (typeof Chart !== 'undefined') {
    if (analysis.chart) { analysis.chart.data = data; analysis.chart.update(); } else {
      analysis.chart = new Chart($('section-chart'), { type: 'line', data, options: {
        animation: false, parsing: true, showLine: true,
        plugins: { legend: { labels: { color: '#e8edf2', font: { size: 16 } } } },
        scales: { x: { type: 'linear', title: { display: true, text: 'along the section (mm)', color: '#9aa6b2' }, ticks: { color: '#9aa6b2' } },
                  y: { title: { display: true, text: '%', color: '#9aa6b2' }, ticks: { color: '#9aa6b2' } } } } });
    }
  }
  document.body.dataset.section = String(s.points.length);
}
function sectionChartResize() { if (analysis.chart) analysis.chart.resize(); }

document.querySelectorAll('.section-axis').forEach((b) => b.addEventListener('click', () => setSection(b.dataset.axis)));
$('section-off').addEventListener('click', () => setSection(null));
$('section-at').addEventListener('input', () => moveSection(Number($('section-at').value)));
// Steps of one grid pitch for a finger that cannot drag precisely.
const stepSection = (s) => {
  const slider = $('section-at');
  slider.value = String(Math.min(Math.max(Number(slider.value) + s * 2.54, Number(slider.min)), Number(slider.max)));
  moveSection(Number(slider.value));
};
$('section-minus').addEventListener('click', () => stepSection(-1));
$('section-plus').addEventListener('click', () => stepSection(1));

// ---- a run's analysis, when its result is shown ------------------------------------------------
async function loadAnalysis(runId, files) {
  setSection(null);
  if (view && analysis.arrows) { view.put('arrowLines', null); analysis.arrows.geometry.dispose(); }
  Object.assign(analysis, { runId, elements: null, arrows: null });
  const tools = document.querySelectorAll('#arrows, .section-axis, #section-off');
  tools.forEach((b) => { b.disabled = true; });
  $('arrows-note').textContent = '';
  if (!files.includes('cloud4d.ply')) return;
  const r = await api(`/api/runs/${encodeURIComponent(runId)}/elements`);
  if (!r.ok || analysis.runId !== runId) { if (!r.ok) $('arrows-note').textContent = r.body.error; return; }
  const e = r.body;
  analysis.elements = e;
  const box = new THREE.Box3();
  for (let i = 0; i < e.xyz.length; i += 3) box.expandByPoint(new THREE.Vector3(e.xyz[i], e.xyz[i + 1], e.xyz[i + 2]));
  analysis.box = box;
  tools.forEach((b) => { b.disabled = false; });
  $('arrows').disabled = !e.has_directions;
  if (e.note) $('arrows-note').textContent = e.note;
  showArrows(e.has_directions && $('arrows').classList.contains('on'));
  document.body.dataset.elements = String(e.elements);
}

// A tap on the surface while a section is on places the section there.
function sectionTapped(point) {
  if (!analysis.axis) return;
  const slider = $('section-at');
  slider.value = String(point[analysis.axis]);
  moveSection(Number(slider.value));
}
