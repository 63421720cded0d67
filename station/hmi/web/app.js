// The operator's panel. Everything it shows comes from the station's API (API.md); everything it
// does is a request to it. No workflow here: the station decides, the page shows.
'use strict';

const stats = { loadMs: null, latencies: [], events: 0 };  // read by the browser test
window.hmiStats = stats;
let csrf = '';
let role = 'operator';
let lastRunId = null;
let jobBusy = false;

const $ = (id) => document.getElementById(id);
const esc = (s) => String(s ?? '').replace(/[&<>"']/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;', "'": '&#39;' }[c]));
// A value that rounds to zero shows as 0, not -0.0.
const num = (v, d = 1) => {
  if (v === null || v === undefined || Number.isNaN(v)) return '–';
  const t = Number(v).toFixed(d);
  return /^-0\.?0*$/.test(t) ? t.slice(1) : t;
};

async function api(path, options = {}) {
  const init = { credentials: 'same-origin', headers: {} };
  if (options.body !== undefined) {
    init.method = 'POST';
    init.headers['Content-Type'] = 'application/json';
    init.headers['X-CSRF-Token'] = csrf;
    init.body = JSON.stringify(options.body);
  }
  const res = await fetch(path, init);
  const type = res.headers.get('Content-Type') || '';
  const body = type.includes('json') ? await res.json() : await res.text();
  if (res.status === 401 && path !== '/api/login') showLogin();
  return { ok: res.ok, status: res.status, body };
}

// ---- tabs ------------------------------------------------------------------------------------
function showTab(name) {
  document.querySelectorAll('.tab').forEach((b) => b.classList.toggle('active', b.dataset.tab === name));
  document.querySelectorAll('.panel').forEach((p) => p.classList.toggle('active', p.id === name));
  if (name === 'history') loadHistory();
  if (name === 'maintenance') loadMaintenance();
  if (name === 'result') { resize3d(); sectionChartResize(); }
  if (name === 'scan') liveCloudResize();
  if (name === 'compare') loadCompareChoices();
}
document.querySelectorAll('.tab').forEach((b) => b.addEventListener('click', () => showTab(b.dataset.tab)));

// ---- session ---------------------------------------------------------------------------------
function showLogin() { $('login').classList.remove('hidden'); $('login-user').focus(); }
async function loadSession() {
  const r = await api('/api/session');
  if (!r.ok) return false;
  const s = r.body;
  if (s.login_required && !s.logged_in) { showLogin(); return false; }
  csrf = s.csrf; role = s.role;
  $('who').textContent = s.login_required ? `${s.user} (${s.role})` : 'this station';
  $('tab-maintenance').classList.toggle('hidden', role !== 'maintenance');
  $('login').classList.add('hidden');
  return true;
}
$('login-form').addEventListener('submit', async (e) => {
  e.preventDefault();
  const r = await api('/api/login', { body: { user: $('login-user').value, password: $('login-password').value } });
  if (!r.ok) { $('login-error').textContent = r.body.error || 'refused'; return; }
  $('login-password').value = '';
  await start();
});

// ---- cell view -------------------------------------------------------------------------------
const interlockNames = [
  ['door_closed', 'Door', 'closed', 'OPEN'], ['e_stop_ok', 'E-stop', 'released', 'PRESSED'],
  ['light_curtain_clear', 'Light curtain', 'clear', 'INTERRUPTED'], ['part_clamped', 'Clamp', 'clamped', 'open'],
  ['air_ok', 'Air', 'on', 'LOW'], ['shutter_closed', 'Laser shutter', 'closed', 'open'],
];
function deviceChips(devices) {
  return devices.map((d) => `<span class="chip ${d.state === 'ready' || d.state === 'busy' ? 'ok' : d.state === 'faulted' ? 'bad' : ''}">${esc(d.name)}: ${esc(d.state)}</span>`).join('');
}
function renderCell(c) {
  $('cell-name').textContent = c.name;
  const plc = c.plc || {};
  if (plc.connected) {
    const i = plc.interlocks;
    $('interlocks').innerHTML = interlockNames.map(([k, label, good, bad]) => {
      const okNeutral = k === 'part_clamped' || k === 'shutter_closed';
      return `<span class="chip ${i[k] ? 'ok' : okNeutral ? '' : 'bad'}">${label}: ${i[k] ? good : bad}</span>`;
    }).join('') + `<span class="chip ${i.tripped ? 'bad' : 'ok'}">Interlock: ${i.tripped ? 'TRIPPED' : 'clear'}</span>`;
    for (const colour of ['red', 'amber', 'green'])
      document.querySelector(`.lamp.${colour}`).classList.toggle('on', !!plc.stack_light[colour]);
  } else {
    $('interlocks').innerHTML = `<span class="chip warn">PLC not connected${plc.error ? ': ' + esc(plc.error) : ''}</span>`;
  }
  $('devices').innerHTML = '<tr><th>Device</th><th>State</th><th>Model</th><th>Serial</th><th>Firmware</th><th>Address</th></tr>' +
    c.devices.map((d) => `<tr><td>${esc(d.name)}</td><td>${esc(d.state)}${d.last_fault ? '<br><small>' + esc(d.last_fault.text) + '</small>' : ''}</td>` +
      `<td>${esc(d.identity.vendor)} ${esc(d.identity.model)}</td><td>${esc(d.identity.serial)}</td><td>${esc(d.identity.firmware)}</td><td>${esc(d.identity.address)}</td></tr>`).join('');
  $('cell-calibration').innerHTML = calibrationHtml(c.calibration);
  renderLine(c.line);
  setBusy(c.job.busy, c.job);
}
// The line's PLC handshake (REGISTER_MAP.md, "Started by the line"), when the cell watches it.
function renderLine(line) {
  $('line').classList.toggle('hidden', !line);
  if (!line) return;
  const a = line.answer;
  const chip = (on, label) => `<span class="chip ${on ? 'ok' : ''}">${label}</span>`;
  $('line-state').innerHTML = (line.connected ? '' : `<span class="chip warn">not reached${line.error ? ': ' + esc(line.error) : ''}</span>`) +
    chip(a.ready, 'ready') + chip(a.busy, 'busy') + chip(a.done, 'done') +
    `<span class="chip">last answer: ${esc(a.verdict)}${a.error !== 'none' ? ' (' + esc(a.error) + ')' : ''}</span>` +
    (line.request.start ? `<span class="chip ok">request: program ${line.request.program_number}, part ${esc(line.request.part_id)}</span>` : '');
  $('line-last').textContent = line.last || '';
}
function calibrationHtml(cal) {
  const v = cal.last_verification;
  const cls = cal.verdict === 'passed' ? 'ok' : cal.verdict === 'not verified' ? 'warn' : 'bad';
  let html = `<div class="chips"><span class="chip ${cls}">Verification: ${esc(cal.verdict)}</span>` +
    `<span class="chip">In use: ${esc(cal.in_use.file || cal.in_use.note)}</span>` +
    (cal.sensors || []).map((s) => {
      if (s.usable) return `<span class="chip ok">${esc(s.sensor)}: ${esc(s.record_id)}, valid ${num(s.valid_days - s.age_days, 1)} days more</span>`;
      if (!s.in_use) return `<span class="chip warn">${esc(s.sensor)}: none in use (scans calibrate on their own scenes)</span>`;
      return `<span class="chip bad">${esc(s.sensor)}: ${esc(s.problem)}: run station calibrate ${esc(s.sensor)}</span>`;
    }).join('') + '</div>';
  if (v) html += '<table class="table"><tr><th>Check</th><th>Value</th><th>MPE</th><th></th></tr>' +
    v.checks.map((c) => `<tr><td>${esc(c.name)}</td><td>${num(c.value, 4)} ${esc(c.unit)}</td><td>${num(c.limit, 4)}</td><td>${c.passed ? 'PASS' : 'FAIL'}</td></tr>`).join('') +
    `</table><small>${esc(v.id)}, ${esc(v.created)}</small>`;
  return html;
}
async function pollCell() {
  const r = await api('/api/cell');
  if (r.ok) renderCell(r.body);
}

// The cell's health (GET /api/cell/health: the monitoring's findings, answered 200 even on a fault): what
// someone should act on (a calibration about to expire, the runs' disk nearly full, a device down) in the
// banner under the header, until it is mended.
async function pollHealth() {
  const r = await api('/api/cell/health');
  const findings = r.body && Array.isArray(r.body.findings) ? r.body.findings : [];
  const banner = $('banner');
  banner.classList.toggle('hidden', findings.length === 0);
  banner.classList.toggle('fault', findings.some((f) => f.level === 'fault'));
  banner.innerHTML = findings.map((f) => `<div>${f.level === 'fault' ? 'Fault' : 'Warning'}: ${esc(f.text)}</div>`).join('');
}

// ---- scan ------------------------------------------------------------------------------------
function setBusy(busy, job) {
  jobBusy = busy;
  $('start').disabled = busy;
  $('abort').disabled = !busy;
  $('verify').disabled = busy;
  $('calibrate').disabled = busy;
  if (busy && job) document.body.dataset.job = job.kind;
  else delete document.body.dataset.job;
}
function log(text) {
  const li = document.createElement('li');
  li.textContent = `${new Date().toLocaleTimeString()}  ${text}`;
  $('log').prepend(li);
}
function showFault(text, advice) {
  $('fault').innerHTML = `${esc(text)}${advice ? `<div class="advice">${esc(advice)}</div>` : ''}`;
  $('fault').classList.remove('hidden');
}
$('start').addEventListener('click', async () => {
  if (!$('scan-form').reportValidity()) return;
  $('fault').classList.add('hidden');
  $('log').innerHTML = '';
  delete document.body.dataset.finished;
  const r = await api('/api/scan/start', { body: { part_id: $('part-id').value.trim(), program: $('program').value.trim(),
    material: $('material').value, part_program: $('part-program').value } });
  if (!r.ok) { showFault(r.body.error || `refused (${r.status})`, r.body.advice); return; }
  setBusy(true, r.body.job);
});
$('abort').addEventListener('click', async () => {
  const r = await api('/api/scan/abort', { body: {} });
  if (!r.ok) showFault(r.body.error);
});

function onProgress(p) {
  const pct = p.steps ? Math.round((100 * p.step) / p.steps) : 0;
  $('bar-fill').style.width = `${pct}%`;
  $('doing').textContent = `${p.kind === 'verify' ? 'Verifying: ' : ''}${p.doing}  (step ${p.step} of ${p.steps})`;
  $('counts').textContent = `ETA ${Math.round(p.remaining_s)} s · ${p.profiles} profiles (${p.lost_profiles} lost) · ${p.positions} positions · ${Math.round(p.elapsed_s)} s`;
  if (p.devices) $('scan-devices').innerHTML = deviceChips(p.devices);
  document.body.dataset.progress = String(p.step);
}
function onFinished(f) {
  setBusy(false);
  if (f.kind === 'verify') { showVerify(f); return; }
  if (f.kind === 'calibrate') { showCalibrate(f); return; }
  $('bar-fill').style.width = f.ok ? '100%' : $('bar-fill').style.width;
  if (f.error) { showFault(f.error, f.advice); log(`ended: ${f.error}`); }
  else log(`done: ${f.verdict || ''} ${f.verdict_reason || ''}`);
  $('doing').textContent = f.ok ? `Done: ${f.part_id}` : 'Stopped';
  document.body.dataset.finished = f.ok ? 'ok' : 'error';
  if (f.run_id && f.ok) { loadResult(f.run_id); showTab('result'); }
}

// ---- live events -----------------------------------------------------------------------------
function connectEvents() {
  const es = new EventSource('/api/events');
  const on = (name, fn) => es.addEventListener(name, (e) => {
    const data = JSON.parse(e.data);
    if (data.t_ms) stats.latencies.push(Date.now() - data.t_ms);
    stats.events += 1;
    fn(data);
  });
  es.onopen = () => { $('live').className = 'live on'; };
  es.onerror = () => { $('live').className = 'live off'; };
  on('hello', (d) => { setBusy(d.job.busy, d.job); if (d.job.busy && d.job.kind === 'scan') liveCloudLoad(); });
  on('started', (d) => {
    setBusy(true, d);
    log(`${d.kind} started by ${d.by_line ? "the line's PLC" : d.user}${d.part_id ? ' for ' + d.part_id : ''}${d.part_program ? ' (' + d.part_program + ')' : ''}`);
    if (d.kind === 'scan') liveCloudReset();
  });
  on('cloud', liveCloudAdd);
  on('run', (d) => log(`run folder ${d.run_id}`));
  on('check', (d) => log(`check: ${d.text}`));
  on('progress', onProgress);
  on('safety', (d) => { log(`SAFETY: ${d.text}`); showFault(d.text, d.advice); });
  on('scan_done', (d) => log(d.completed ? `scan complete: ${d.sweeps} sweeps, ${d.views} views in ${num(d.wall_seconds)} s` : `scan aborted: ${d.abort_reason}`));
  on('stage', (d) => { log(`${d.stage}: ${d.text}`); $('doing').textContent = `Measuring: ${d.stage}`; });
  on('finished', onFinished);
  on('cell', () => pollCell());
  on('line', (d) => { if (d.text) log(`line: ${d.text}`); pollCell(); });
}

// ---- result ----------------------------------------------------------------------------------
let view = null;
function resize3d() { if (view) view.resize(); }
function init3d() {
  if (view) return view;
  view = makeView($('view3d'), pick);
  if (!view) return null;
  view.marker = new THREE.Mesh(new THREE.SphereGeometry(1, 16, 12), new THREE.MeshBasicMaterial({ color: 0xffffff }));
  view.marker.visible = false;
  view.scene.add(view.marker);
  view.mesh = null;
  view.elements = [];
  return view;
}
function pick(e) {
  if (!view || !view.mesh) return;
  const r = view.renderer.domElement.getBoundingClientRect();
  const ndc = new THREE.Vector2(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
  const ray = new THREE.Raycaster();
  ray.setFromCamera(ndc, view.camera);
  const hit = ray.intersectObject(view.mesh)[0];
  if (!hit) return;
  view.marker.position.copy(hit.point);
  view.marker.visible = true;
  view.draw();
  sectionTapped(hit.point);
  let best = null, bestD = Infinity;
  for (const el of view.elements) {
    const d = (el.x - hit.point.x) ** 2 + (el.y - hit.point.y) ** 2 + (el.z - hit.point.z) ** 2;
    if (d < bestD) { bestD = d; best = el; }
  }
  if (!best) return;
  $('pick').innerHTML = `Element ${best.element} at (${num(best.x)}, ${num(best.y)}, ${num(best.z)}) mm, ${num(Math.sqrt(bestD), 2)} mm from the tap:<br>` +
    `major <b>${num(best.major_engineering_percent)} %</b>, minor <b>${num(best.minor_engineering_percent)} %</b>, thinning <b>${num(best.thinning_percent)} %</b>, ` +
    `safety margin <b>${num(best.safety_margin_percent)} %</b> (${esc(best.zone)})`;
}
function parseCsv(text) {
  const lines = text.trim().split('\n');
  const head = lines.shift().split(',');
  return lines.map((l) => {
    const cells = l.split(',');
    const o = {};
    head.forEach((h, i) => { o[h] = h === 'zone' ? cells[i] : Number(cells[i]); });
    o.x = o.x_mm; o.y = o.y_mm; o.z = o.z_mm;
    return o;
  });
}
async function showMesh(runId, files) {
  const v = init3d();
  if (!v) return;
  const r = await api(`/api/runs/${encodeURIComponent(runId)}/mesh`);
  if (!r.ok) { $('pick').textContent = r.body.error; return; }
  const m = r.body;
  const vertices = m.positions.length / 3;
  const thinning = m.strain ? m.strain.map(thinningOf) : new Array(vertices).fill(null);
  const [lo, hi] = thinningRange(thinning);
  v.put('mesh', colouredMesh(m.positions, m.indices, thinningColours(thinning, lo, hi)));
  const s = v.mesh.geometry.boundingSphere;
  v.frame(s);
  v.marker.scale.setScalar(s.radius * 0.02);
  $('legend').innerHTML = `<span>${num(lo)} %</span><span>thinning</span><span>${num(hi)} %</span>`;
  v.elements = files.includes('elements.csv') ? parseCsv((await api(`/api/runs/${encodeURIComponent(runId)}/files/elements.csv`)).body) : [];
  resize3d();
  document.body.dataset.mesh = String(m.indices.length / 3);
}
async function loadResult(runId) {
  lastRunId = runId;
  const r = await api(`/api/runs/${encodeURIComponent(runId)}`);
  if (!r.ok) { $('verdict').className = 'verdict error'; $('verdict').textContent = r.body.error; return; }
  const rep = r.body.report;
  const run = r.body.run || {};
  const fileUrl = (n) => `/api/runs/${encodeURIComponent(runId)}/files/${n}`;
  if (rep) {
    $('verdict').className = `verdict ${rep.verdict}`;
    $('verdict').textContent = rep.verdict;
    $('verdict-reason').textContent = `${run.part_id || ''} · ${rep.program || ''} · ${rep.material} — ${rep.verdict_reason}. Max thinning ${num(rep.max_thinning_percent)} %, min safety margin ${num(rep.min_margin_percent)} %.${run.started_by ? ' Started by ' + run.started_by + '.' : ''}`;
    $('worst').innerHTML = '<tr><th>#</th><th>Element</th><th>Major %</th><th>Minor %</th><th>Thinning %</th><th>Margin %</th><th>Zone</th><th>Patch</th></tr>' +
      (rep.worst_spots || []).map((w, i) => `<tr><td>${i + 1}</td><td>${w.element}</td><td>${num(w.major_engineering_percent)}</td><td>${num(w.minor_engineering_percent)}</td><td>${num(w.thinning_percent)}</td><td>${num(w.safety_margin_percent)}</td><td>${esc(w.zone)}</td><td>${w.patch_elements}</td></tr>`).join('');
  } else {
    $('verdict').className = 'verdict error';
    $('verdict').textContent = run.outcome && run.outcome.completed === false ? 'aborted' : 'no report';
    $('verdict-reason').textContent = run.abort_reason || (run.outcome && run.outcome.abort_reason) || '';
    $('worst').innerHTML = '';
  }
  document.body.dataset.verdict = rep ? rep.verdict : 'none';
  const files = r.body.files || [];
  $('fld').src = files.includes('fld.png') ? fileUrl('fld.png') : '';
  $('fldlink').href = fileUrl('fld.png');
  $('pdf').href = fileUrl('report.pdf');
  $('pdf').classList.toggle('hidden', !files.includes('report.pdf'));
  if (files.includes('mesh.ply')) await showMesh(runId, files);
  await loadAnalysis(runId, files);
}

// ---- history ---------------------------------------------------------------------------------
let trendChart = null;
async function loadHistory() {
  const r = await api('/api/runs');
  if (!r.ok) return;
  const runs = r.body.runs;
  $('runs').innerHTML = '<tr><th>Started (UTC)</th><th>Part</th><th>Program</th><th>Verdict</th><th>Max thinning %</th><th>Min margin %</th><th>Status</th></tr>' +
    runs.map((x) => `<tr data-run="${esc(x.run_id)}"><td>${esc(x.started_utc)}</td><td>${esc(x.part_id)}</td><td>${esc(x.program)}</td>` +
      `<td class="verdict-cell ${esc(x.verdict || x.status)}">${esc(x.verdict || x.status)}</td><td>${num(x.max_thinning_percent)}</td><td>${num(x.min_margin_percent)}</td><td>${esc(x.status)}${x.reason ? ': ' + esc(x.reason) : ''}</td></tr>`).join('');
  $('runs').querySelectorAll('tr[data-run]').forEach((tr) => tr.addEventListener('click', () => { loadResult(tr.dataset.run); showTab('result'); }));
  const programs = [...new Set(runs.map((x) => x.program).filter((p) => p))];
  $('programs').innerHTML = programs.map((p) => `<option value="${esc(p)}">`).join('');
  const sel = $('trend-program');
  const keep = sel.value;
  sel.innerHTML = programs.map((p) => `<option>${esc(p)}</option>`).join('');
  if (programs.includes(keep)) sel.value = keep;
  drawTrend(runs);
}
function drawTrend(runs) {
  if (typeof Chart === 'undefined') return;
  const program = $('trend-program').value;
  const points = runs.filter((x) => x.program === program && x.min_margin_percent !== null).reverse();
  const data = { labels: points.map((x) => x.part_id), datasets: [{ label: 'min safety margin %', data: points.map((x) => x.min_margin_percent), borderColor: '#2f81f7', backgroundColor: '#2f81f7' }] };
  if (trendChart) { trendChart.data = data; trendChart.update(); return; }
  trendChart = new Chart($('trend'), { type: 'line', data, options: { animation: false, plugins: { legend: { labels: { color: '#e8edf2' } } }, scales: { x: { ticks: { color: '#9aa6b2' } }, y: { ticks: { color: '#9aa6b2' } } } } });
}
$('trend-program').addEventListener('change', loadHistory);

// ---- maintenance -----------------------------------------------------------------------------
async function loadMaintenance() {
  const c = await api('/api/calibration');
  if (c.ok) $('calibration').innerHTML = calibrationHtml(c.body);
  loadSettings();
  const a = await api('/api/actions');
  if (a.ok) $('actions').innerHTML = '<tr><th>Time (UTC)</th><th>Who</th><th>Role</th><th>Action</th><th>Details</th></tr>' +
    a.body.actions.slice().reverse().map((x) => `<tr><td>${esc(x.time)}</td><td>${esc(x.user)}</td><td>${esc(x.role)}</td><td>${esc(x.action)}</td><td>${esc(JSON.stringify(x.detail))}</td></tr>`).join('');
}
function showVerify(f) {
  $('verify-result').innerHTML = f.error ? `<div class="fault">${esc(f.error)}</div>` :
    `<div class="chips"><span class="chip ${f.verdict === 'passed' ? 'ok' : 'bad'}">Verification ${esc(f.verdict)} (${esc(f.record_id)})</span></div>`;
  loadMaintenance();
  pollCell();
}
function showCalibrate(f) {
  $('verify-result').innerHTML = f.error ? `<div class="fault">${esc(f.error)}</div>` :
    '<div class="chips">' + f.sensors.map((s) =>
      `<span class="chip ${s.in_use ? 'ok' : 'bad'}">Calibration of the ${esc(s.sensor)} ${esc(s.verdict)}` +
      `${s.in_use ? ', now in use' : ', NOT in use'} (${esc(s.record_id)})</span>` +
      s.drift.map((d) => `<span class="chip warn">Drift: ${esc(d)}</span>`).join('')).join('') + '</div>';
  loadMaintenance();
  pollCell();
}
$('calibrate').addEventListener('click', async () => {
  $('verify-result').textContent = 'Calibrating the digitizer on the reference sphere…';
  const r = await api('/api/calibrate', { body: { sensors: 'digitizer' } });
  if (!r.ok) $('verify-result').innerHTML = `<div class="fault">${esc(r.body.error)}</div>`;
});
$('verify').addEventListener('click', async () => {
  $('verify-result').textContent = 'Verifying on the reference sphere…';
  const r = await api('/api/verify', { body: {} });
  if (!r.ok) $('verify-result').innerHTML = `<div class="fault">${esc(r.body.error)}</div>`;
});

// ---- start -----------------------------------------------------------------------------------
async function start() {
  if (!(await loadSession())) return;
  const m = await api('/api/materials');
  if (m.ok) $('material').innerHTML = m.body.materials.map((n) => `<option ${n === m.body.default ? 'selected' : ''}>${esc(n)}</option>`).join('');
  connectEvents();
  await pollCell();
  setInterval(pollCell, 1500);
  pollHealth();
  setInterval(pollHealth, 30000);
  loadHistory();
  stats.loadMs = Math.round(performance.now());
  document.body.dataset.ready = '1';
}
start();
