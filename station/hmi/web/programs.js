// The cell's part programs on the scan page: the list to choose from (GET /api/programs) and the
// chosen program's nominal model in a 3D view before the scan (GET /api/programs/NAME/model.stl),
// with what its plan is predicted to see marked on it (GET /api/programs/NAME/coverage): seen by the
// laser, by the cameras, by both, or by neither. A program not planned yet offers Plan, which plans
// it from its model for the cell (POST /api/programs/NAME/plan, maintenance). Choosing a program
// also takes its material; the scan then runs the program's plan.
'use strict';

const programs = { list: [], view: null };

async function loadPrograms() {
  const r = await api('/api/programs');
  if (!r.ok) return;
  programs.list = r.body.programs;
  const keep = $('part-program').value;
  $('part-program').innerHTML = '<option value="">the sample region (built-in plan)</option>' +
    programs.list.map((p) => `<option value="${esc(p.name)}">${esc(p.name)}${p.description ? ` — ${esc(p.description)}` : ''}</option>`).join('');
  if (programs.list.some((p) => p.name === keep)) $('part-program').value = keep;
}

async function showProgram(name) {
  const card = $('program-card');
  if (!name) { card.classList.add('hidden'); return; }
  const p = programs.list.find((x) => x.name === name) || { name };
  $('program-info').textContent = `${p.grid || ''} grid ${num(p.pitch_mm, 2)} mm · ${p.material || ''} ${num(p.sheet_thickness_mm, 2)} mm` +
    `${p.note ? ` · ${p.note}` : ''} · loading the model…`;
  card.classList.remove('hidden');
  if (p.material && [...$('material').options].some((o) => o.value === p.material)) $('material').value = p.material;
  if (!programs.view) programs.view = makeView($('program-view'));
  const v = programs.view;
  if (!v) return;
  v.put('coverage', null);
  $('coverage-info').textContent = '';
  v.resize();
  const res = await fetch(`/api/programs/${encodeURIComponent(name)}/model.stl`, { credentials: 'same-origin' });
  if ($('part-program').value !== name) return;  // chosen another meanwhile
  if (!res.ok) { $('program-info').textContent = `the model cannot be shown (${res.status})`; return; }
  const geometry = new THREE.STLLoader().parse(await res.arrayBuffer());
  geometry.computeBoundingSphere();
  // Pushed back in depth a little, so that the coverage's samples on its surface are drawn over it.
  const mesh = new THREE.Mesh(geometry, new THREE.MeshLambertMaterial({ color: 0x9aa4b0, side: THREE.DoubleSide,
    polygonOffset: true, polygonOffsetFactor: 2, polygonOffsetUnits: 4 }));
  v.put('model', mesh);
  v.frame(geometry.boundingSphere);
  v.draw();
  const triangles = geometry.getAttribute('position').count / 3;
  $('program-info').textContent = $('program-info').textContent.replace('loading the model…', `${triangles} triangles`);
  document.body.dataset.programShown = name;
  $('plan-program').classList.toggle('hidden', p.has_plan !== false);
  if (p.has_plan === false) $('coverage-info').textContent = 'This program has no scan plan yet: Plan makes one from its model for this cell.';
  else showCoverage(name);
}

// Plans the chosen program from its model, then shows what the new plan is predicted to see.
async function planProgram() {
  const name = $('part-program').value;
  if (!name) return;
  $('plan-program').disabled = true;
  $('coverage-info').textContent = 'planning from the model…';
  const r = await api(`/api/programs/${encodeURIComponent(name)}/plan`, { body: {} });
  $('plan-program').disabled = false;
  if (!r.ok) { $('coverage-info').textContent = `not planned: ${r.body.error || r.status}`; return; }
  const p = programs.list.find((x) => x.name === name);
  if (p) p.has_plan = true;
  $('plan-program').classList.add('hidden');
  showCoverage(name);
}

// Sample colours: both sensors green, the laser alone blue, the cameras alone amber, neither red.
const coverageColours = { 0: [0.85, 0.15, 0.15], 1: [0.2, 0.45, 0.95], 2: [0.95, 0.7, 0.1], 3: [0.2, 0.75, 0.35] };

async function showCoverage(name) {
  $('coverage-info').textContent = 'predicting what the plan sees…';
  const r = await api(`/api/programs/${encodeURIComponent(name)}/coverage`);
  if ($('part-program').value !== name) return;
  if (!r.ok) { $('coverage-info').textContent = `no prediction: ${r.body.error || r.status}`; return; }
  const c = r.body;
  const v = programs.view;
  if (v) {
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.Float32BufferAttribute(c.xyz, 3));
    const colours = [];
    for (const s of c.seen) colours.push(...coverageColours[s]);
    g.setAttribute('color', new THREE.Float32BufferAttribute(colours, 3));
    v.put('coverage', new THREE.Points(g, new THREE.PointsMaterial({ size: c.spacing_mm, vertexColors: THREE.VertexColors })));
  }
  const pct = (x) => `${num(100 * x, 1)} %`;
  const unseen = c.seen.filter((s) => s === 0).length;
  $('coverage-info').innerHTML = `The plan (${c.sweeps} laser passes, ${c.views} stereo views) is predicted to see ` +
    `${pct(c.either)} of the grid area (${num(c.grid_area_mm2, 0)} mm²): ` +
    `<span style="color:#3373f2">■</span> the laser ${pct(c.laser)}, <span style="color:#f2b31a">■</span> the cameras ${pct(c.stereo)}, ` +
    `<span style="color:#33bf59">■</span> both; <span style="color:#d92626">■</span> neither: ${unseen ? `${unseen} samples ${num(c.spacing_mm, 0)} mm apart` : 'none'}.` +
    (c.views > 0 && c.stereo === 0 ? ' The cameras see none of it whole: from their poses, at their resolution, the printed lines are too thin or too oblique to locate.' : '');
  document.body.dataset.coverageShown = name;
}

$('part-program').addEventListener('change', () => showProgram($('part-program').value));
$('plan-program').addEventListener('click', planProgram);
loadPrograms();
