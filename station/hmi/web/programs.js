// The cell's part programs on the scan page: the list to choose from (GET /api/programs) and the
// chosen program's nominal model in a 3D view before the scan (GET /api/programs/NAME/model.stl).
// Choosing a program also takes its material; the scan then runs the program's plan.
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
  v.resize();
  const res = await fetch(`/api/programs/${encodeURIComponent(name)}/model.stl`, { credentials: 'same-origin' });
  if ($('part-program').value !== name) return;  // chosen another meanwhile
  if (!res.ok) { $('program-info').textContent = `the model cannot be shown (${res.status})`; return; }
  const geometry = new THREE.STLLoader().parse(await res.arrayBuffer());
  geometry.computeBoundingSphere();
  const mesh = new THREE.Mesh(geometry, new THREE.MeshLambertMaterial({ color: 0x9aa4b0, side: THREE.DoubleSide }));
  v.put('model', mesh);
  v.frame(geometry.boundingSphere);
  v.draw();
  const triangles = geometry.getAttribute('position').count / 3;
  $('program-info').textContent = $('program-info').textContent.replace('loading the model…', `${triangles} triangles`);
  document.body.dataset.programShown = name;
}

$('part-program').addEventListener('change', () => showProgram($('part-program').value));
loadPrograms();
