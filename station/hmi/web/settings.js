// The Maintenance tab's cell settings (GET and POST /api/settings, maintenance role): the few
// calibration rules the station applies at once, each with its range; the station checks and keeps
// them (in the cell file when there is one) and writes who changed what to the actions log.
'use strict';

let settingsShown = null;

async function loadSettings() {
  if (role !== 'maintenance') return;
  const r = await api('/api/settings');
  if (!r.ok) { $('settings-result').innerHTML = `<div class="fault">${esc(r.body.error)}</div>`; return; }
  showSettings(r.body);
}
function showSettings(s) {
  settingsShown = s;
  $('settings-note').textContent = s.note;
  $('settings-form').innerHTML = s.ranges.map((r) =>
    `<label>${esc(r.what)} <small>(${esc(r.key)}, ${r.min}–${r.max} ${esc(r.unit)})</small>` +
    `<span class="setting"><input name="${esc(r.key)}" type="number" inputmode="decimal" step="any" min="${r.min}" max="${r.max}" value="${s.settings[r.key]}"> ${esc(r.unit)}</span></label>`).join('');
  document.body.dataset.settings = 'loaded';
}
$('settings-form').addEventListener('submit', (e) => e.preventDefault());
$('settings-save').addEventListener('click', async () => {
  if (!settingsShown) return;
  // Only what was changed goes to the station.
  const changes = {};
  for (const input of $('settings-form').querySelectorAll('input')) {
    const v = Number(input.value);
    if (input.value.trim() === '' || Number.isNaN(v)) { $('settings-result').innerHTML = `<div class="fault">${esc(input.name)}: enter a number</div>`; return; }
    if (v !== settingsShown.settings[input.name]) changes[input.name] = v;
  }
  if (!Object.keys(changes).length) { $('settings-result').textContent = 'Nothing changed.'; return; }
  const r = await api('/api/settings', { body: changes });
  if (!r.ok) { $('settings-result').innerHTML = `<div class="fault">${esc(r.body.error)}</div>`; return; }
  showSettings(r.body);
  $('settings-result').innerHTML = `<div class="chips"><span class="chip ok">Saved: ${Object.entries(changes).map(([k, v]) => `${esc(k)} = ${v}`).join(', ')}</span></div>`;
  document.body.dataset.settingsSaved = Object.keys(changes).join(',');
  loadMaintenance();
  pollCell();
});
