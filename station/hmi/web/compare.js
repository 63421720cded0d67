// The Compare tab: two runs of one press program, side by side on one colour scale (their
// thinning maps, the views turning together), or as a difference map: run B minus run A on A's
// surface, each element of A matched to the nearest of B by the station (GET /api/compare).
'use strict';

const compare = { runs: [], a: null, b: null, syncing: false };

function compareViews() {
  if (!compare.a) {
    compare.a = makeView($('cmp-view-a'), pickDifference);
    compare.b = makeView($('cmp-view-b'));
    if (!compare.a || !compare.b) return false;
    // Side by side, turning one turns the other.
    const link = (from, to) => from.controls.addEventListener('change', () => {
      if (compare.syncing || $('cmp-card-b').classList.contains('hidden')) return;
      compare.syncing = true;
      to.camera.position.copy(from.camera.position);
      to.controls.target.copy(from.controls.target);
      to.controls.update();
      compare.syncing = false;
    });
    link(compare.a, compare.b);
    link(compare.b, compare.a);
  }
  return true;
}

const runLabel = (x) => `${x.part_id} · ${x.started_utc}${x.verdict ? ' · ' + x.verdict : ''}`;

// The runs that have a result, newest first; B offers the runs of A's program.
async function loadCompareChoices() {
  const r = await api('/api/runs');
  if (!r.ok) return;
  compare.runs = r.body.runs.filter((x) => x.status === 'ok');
  const keepA = $('cmp-a').value;
  $('cmp-a').innerHTML = compare.runs.map((x) => `<option value="${esc(x.run_id)}">${esc(runLabel(x))}</option>`).join('');
  // By default the newest run against the one before it of the same program.
  const newest = compare.runs[0];
  const before = newest && compare.runs.find((x) => x.run_id !== newest.run_id && x.program === newest.program);
  if (compare.runs.some((x) => x.run_id === keepA)) $('cmp-a').value = keepA;
  else if (before) $('cmp-a').value = before.run_id;
  fillCompareB(newest && before ? newest.run_id : null);
}
function fillCompareB(preferred) {
  const a = compare.runs.find((x) => x.run_id === $('cmp-a').value);
  const same = a ? compare.runs.filter((x) => x.program === a.program && x.run_id !== a.run_id) : [];
  const keep = preferred || $('cmp-b').value;
  $('cmp-b').innerHTML = same.map((x) => `<option value="${esc(x.run_id)}">${esc(runLabel(x))}</option>`).join('');
  if (same.some((x) => x.run_id === keep)) $('cmp-b').value = keep;
  const ready = same.length > 0;
  $('cmp-side').disabled = !ready;
  $('cmp-diff').disabled = !ready;
  $('cmp-info').textContent = ready ? `Program ${a.program || '(none)'}: ${same.length + 1} runs with a result.`
    : 'There is no second run of this program with a result to compare with.';
}
$('cmp-a').addEventListener('change', () => fillCompareB(null));


async function showSideBySide() {
  if (!compareViews()) return;
  const ids = [$('cmp-a').value, $('cmp-b').value];
  const meshes = await Promise.all(ids.map((id) => api(`/api/runs/${encodeURIComponent(id)}/mesh`)));
  const bad = meshes.find((m) => !m.ok);
  if (bad) { $('cmp-info').textContent = bad.body.error; return; }
  // One colour scale for both, so that the same colour is the same thinning.
  const thinning = meshes.map((m) => (m.body.strain || []).map(thinningOf));
  let [lo, hi] = thinningRange(thinning[0]);
  [lo, hi] = thinningRange(thinning[1], lo, hi);
  $('cmp-card-b').classList.remove('hidden');
  [compare.a, compare.b].forEach((v, k) => {
    const m = meshes[k].body;
    v.put('mesh', colouredMesh(m.positions, m.indices, thinningColours(thinning[k], lo, hi)));
    v.resize();
  });
  compare.a.frame(compare.a.mesh.geometry.boundingSphere);
  compare.b.frame(compare.a.mesh.geometry.boundingSphere);
  for (const k of ['a', 'b']) {
    const run = compare.runs.find((x) => x.run_id === ids[k === 'a' ? 0 : 1]) || {};
    $(`cmp-title-${k}`).textContent = `Run ${k.toUpperCase()}: ${run.part_id || ''} · max thinning ${num(run.max_thinning_percent)} %`;
    $(`cmp-legend-${k}`).className = 'legend';
    $(`cmp-legend-${k}`).innerHTML = `<span>${num(lo)} %</span><span>thinning, one scale for both</span><span>${num(hi)} %</span>`;
  }
  $('cmp-info').textContent = 'Side by side: the thinning of both runs on one colour scale; turning one view turns the other.';
  $('cmp-pick').textContent = '';
  document.body.dataset.compare = 'side';
}

async function showDifference() {
  if (!compareViews()) return;
  const strain = $('cmp-strain').value;
  const r = await api(`/api/compare?a=${encodeURIComponent($('cmp-a').value)}&b=${encodeURIComponent($('cmp-b').value)}&strain=${strain}`);
  if (!r.ok) { $('cmp-info').textContent = r.body.error; return; }
  const c = r.body;
  compare.last = c;
  $('cmp-pick').textContent = 'Tap the surface to read the difference there.';
  const name = { thinning: 'thinning', major: 'major strain', minor: 'minor strain' }[c.strain];
  // Symmetric about zero, so that white is "no change".
  const span = Math.max(0.5, Math.abs(c.min), Math.abs(c.max));
  $('cmp-card-b').classList.add('hidden');
  const v = compare.a;
  if (c.mesh) {
    const colours = [];
    for (const d of c.mesh.difference) colours.push(...(d === null ? [0.35, 0.35, 0.35] : divergingRamp(d / span)));
    v.put('mesh', colouredMesh(c.mesh.positions, c.mesh.indices, colours));
  } else {
    // No fitted surface for A: the elements themselves, as points.
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.Float32BufferAttribute(c.elements.xyz, 3));
    g.setAttribute('color', new THREE.Float32BufferAttribute(c.elements.difference.flatMap((d) => (d === null ? [0.35, 0.35, 0.35] : divergingRamp(d / span))), 3));
    g.computeBoundingSphere();
    v.put('mesh', new THREE.Points(g, new THREE.PointsMaterial({ size: 1.6, vertexColors: THREE.VertexColors })));
  }
  v.resize();
  v.frame(v.mesh.geometry.boundingSphere);
  $('cmp-title-a').textContent = `${name}: run B (${c.b.part_id}) minus run A (${c.a.part_id}), on A's surface`;
  $('cmp-legend-a').className = 'legend diverging';
  $('cmp-legend-a').innerHTML = `<span>${num(-span)} pp</span><span>0: no change</span><span>+${num(span)} pp</span>`;
  $('cmp-info').innerHTML = `${c.matched} of ${c.a.elements} elements of A matched within ${num(c.max_distance_mm, 2)} mm ` +
    `(grey: no element of B there). B − A: mean <b>${num(c.mean, 2)}</b>, RMS <b>${num(c.rms, 2)}</b>, ` +
    `from <b>${num(c.min, 2)}</b> to <b>${num(c.max, 2)}</b> percentage points.`;
  document.body.dataset.compare = 'diff';
  document.body.dataset.compareMatched = String(c.matched);
}

// A tap on the difference map: the nearest element of A that has a match, and its B − A.
function pickDifference(e) {
  const c = compare.last, v = compare.a;
  if (document.body.dataset.compare !== 'diff' || !c || !v.mesh) return;
  const r = v.renderer.domElement.getBoundingClientRect();
  const ray = new THREE.Raycaster();
  ray.setFromCamera(new THREE.Vector2(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1), v.camera);
  const hit = ray.intersectObject(v.mesh)[0];
  if (!hit) return;
  let best = -1, bestD = Infinity;
  const xyz = c.elements.xyz;
  for (let i = 0; i < c.elements.difference.length; ++i) {
    if (c.elements.difference[i] === null) continue;
    const d = (xyz[3 * i] - hit.point.x) ** 2 + (xyz[3 * i + 1] - hit.point.y) ** 2 + (xyz[3 * i + 2] - hit.point.z) ** 2;
    if (d < bestD) { bestD = d; best = i; }
  }
  if (best < 0) return;
  const dv = c.elements.difference[best];
  $('cmp-pick').innerHTML = `Element ${best} of A at (${num(xyz[3 * best])}, ${num(xyz[3 * best + 1])}, ${num(xyz[3 * best + 2])}) mm, ` +
    `${num(Math.sqrt(bestD), 2)} mm from the tap: B − A <b>${dv > 0 ? '+' : ''}${num(dv, 2)}</b> percentage points of ${esc(c.strain)}`;
}

$('cmp-side').addEventListener('click', showSideBySide);
$('cmp-diff').addEventListener('click', showDifference);
$('cmp-strain').addEventListener('change', () => { if (document.body.dataset.compare === 'diff') showDifference(); });
