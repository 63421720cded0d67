// End-to-end test of the operator's panel in a real browser: starts `station hmi` on the embedded
// virtual cell, drives Debian's chromium (headless) with puppeteer-core, and goes the operator's
// path: open the panel, start a scan of the sample part, see the progress move and the cloud grow
// sweep by sweep, see the verdict and the 3D strain map, pick a spot on it, show the major-strain
// arrows, cut a section and see its strain profile, open the FLD and the PDF; a scan stopped by the
// door; a second scan of the same program compared with the first (side by side and as a
// difference map); the maintenance settings changed; the runs in the history. The new controls are
// tapped (a touch screen), not clicked.
// Fails on any error in the browser's console. Prints the page's load time and how late the live
// events reach the page (publishing time on the station to arrival in the page, same clock).
//
//   node panel_e2e.mjs STATION_EXE WORK_DIR [SCREENSHOT_DIR]
// Exit 0: passed; 1: failed (the reason printed); 77: skipped, chromium not found.
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';

const [stationExe, workDir, shotDir] = process.argv.slice(2).map((p) => p && path.resolve(p));
const chromium = process.env.STAMPSCAN_CHROMIUM || '/usr/bin/chromium';
if (!fs.existsSync(chromium)) {
  console.log(`SKIPPED: chromium not found at ${chromium} (install the Debian package chromium; scripts/setup.sh does)`);
  process.exit(77);
}
const puppeteer = (await import('puppeteer-core')).default;

const fail = (why) => { throw new Error(why); };
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
// A fresh runs folder each time, so the history shows this test's run alone.
fs.rmSync(path.join(workDir, 'runs'), { recursive: true, force: true });
fs.mkdirSync(workDir, { recursive: true });
if (shotDir) fs.mkdirSync(shotDir, { recursive: true });
const readyFile = path.join(workDir, 'ready.txt');
fs.rmSync(readyFile, { force: true });

const station = spawn(stationExe, ['hmi', '--listen', '127.0.0.1:0', '--ready-file', readyFile, '-o', path.join(workDir, 'runs')],
  { cwd: workDir, stdio: ['ignore', 'inherit', 'inherit'] });
let browser = null;
const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'stampscan-chromium-'));
const consoleErrors = [];

async function waitFor(page, what, fn, timeoutMs, ...args) {
  try {
    // A job that ends in an error ends the wait at once (its reason is then in the failure).
    await page.waitForFunction(`(${fn})(...${JSON.stringify(args)}) || document.body.dataset.finished === 'error'`, { timeout: timeoutMs, polling: 100 });
    if (await page.evaluate(() => document.body.dataset.finished === 'error')) throw new Error('the job failed');
  } catch (e) {
    const fault = await page.evaluate(() => document.getElementById('fault').innerText).catch(() => '');
    fail(`${what} did not happen within ${timeoutMs / 1000} s${fault ? ` (the page shows: ${fault})` : ''}`);
  }
}
async function shot(page, name) {
  // From the top: a tap scrolls, and a full-page shot of a scrolled page paints the sticky header mid-page.
  if (shotDir) {
    await page.evaluate(() => window.scrollTo(0, 0));
    await page.screenshot({ path: path.join(shotDir, name), fullPage: true });
  }
}

try {
  for (let i = 0; !fs.existsSync(readyFile) || !fs.readFileSync(readyFile, 'utf8').trim(); ++i) {
    if (station.exitCode !== null) fail(`station hmi exited with ${station.exitCode} before serving`);
    if (i > 600) fail('station hmi did not serve within 60 s');
    await sleep(100);
  }
  const url = fs.readFileSync(readyFile, 'utf8').trim();
  browser = await puppeteer.launch({
    executablePath: chromium,
    headless: true,
    userDataDir,
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync',
      // WebGL on the CPU (SwiftShader) for the 3D view, as there is no GPU here.
      '--enable-unsafe-swiftshader', '--use-angle=swiftshader', '--window-size=1400,1000'],
  });
  const page = await browser.newPage();
  await page.setViewport({ width: 1400, height: 1000, hasTouch: true });
  const tap = async (selector) => { const el = await page.$(selector); if (!el) fail(`no ${selector} on the page`); await el.tap(); };
  page.on('console', (m) => { if (m.type() === 'error') consoleErrors.push(m.text()); });
  page.on('pageerror', (e) => consoleErrors.push(String(e)));

  const t0 = Date.now();
  await page.goto(url, { waitUntil: 'load' });
  await waitFor(page, 'the panel being ready', () => document.body.dataset.ready === '1', 20000);
  const loadMs = Date.now() - t0;
  const nav = await page.evaluate(() => { const n = performance.getEntriesByType('navigation')[0]; return { load: n.loadEventEnd, dcl: n.domContentLoadedEventEnd }; });
  await waitFor(page, 'the cell view showing the PLC', () => document.getElementById('interlocks').innerText.includes('Door'), 20000);
  await shot(page, '1-cell.png');

  // A part program chosen on the scan page shows its nominal model in 3D; back to the sample region.
  await page.click('button[data-tab="scan"]');
  await waitFor(page, 'the part programs listed', () => document.getElementById('part-program').options.length > 1, 20000);
  await page.select('#part-program', 'sim-dome-circle');
  await waitFor(page, 'the program\'s model in 3D', () => document.body.dataset.programShown === 'sim-dome-circle', 60000);
  // With what its plan is predicted to see marked on it, and said in words.
  await waitFor(page, 'the plan\'s predicted coverage on the model', () => document.body.dataset.coverageShown === 'sim-dome-circle', 60000);
  const coverageText = await page.$eval('#coverage-info', (e) => e.textContent);
  if (!/predicted to see \d+(\.\d)? % of the grid area/.test(coverageText)) throw new Error(`the coverage is not said: ${coverageText}`);
  await shot(page, '2-program.png');
  await page.select('#part-program', '');

  // The scan of the sample part.
  await page.$eval('#part-id', (el) => { el.value = ''; });
  await page.type('#part-id', 'sample-e2e');
  await page.click('#start');
  await waitFor(page, 'progress', () => Number(document.body.dataset.progress || 0) >= 1, 60000);
  const first = await page.evaluate(() => Number(document.body.dataset.progress));
  await waitFor(page, 'the progress moving on', (f) => Number(document.body.dataset.progress) > f, 60000, first);
  // The cloud grows as the sweeps are measured: points first, then more of them.
  await waitFor(page, 'the live cloud', () => Number(document.body.dataset.liveCloud || 0) > 0, 120000);
  const firstCloud = await page.evaluate(() => Number(document.body.dataset.liveCloud));
  await waitFor(page, 'the live cloud growing', (n) => Number(document.body.dataset.liveCloud) > n, 120000, firstCloud);
  const grownCloud = await page.evaluate(() => ({ points: Number(document.body.dataset.liveCloud), batches: Number(document.body.dataset.liveBatches) }));
  await shot(page, '2-scan-progress.png');
  // A second start while the scan runs is refused, with the reason, on the page too.
  const session = await (await fetch(`${url}api/session`)).json();
  const second = await fetch(`${url}api/scan/start`, { method: 'POST', headers: { 'Content-Type': 'application/json', 'X-CSRF-Token': session.csrf }, body: '{"part_id":"second"}' });
  const refused = { status: second.status, body: await second.json() };
  if (refused.status !== 409 || !/running/.test(refused.body.error)) fail(`a second start was not refused with 409: ${JSON.stringify(refused)}`);

  await waitFor(page, 'the verdict', () => ['good', 'marginal', 'failed'].includes(document.body.dataset.verdict), 240000);
  await waitFor(page, 'the 3D map', () => Number(document.body.dataset.mesh || 0) > 0, 30000);
  const verdict = await page.$eval('#verdict', (el) => el.innerText);
  await sleep(500);
  // Tap the middle of the surface and read its strains.
  await shot(page, '3-result.png');
  const box = await (await page.$('#view3d canvas')).boundingBox();
  // Tap the middle, then around it, until a tap lands on the surface.
  for (const [fx, fy] of [[0.5, 0.5], [0.45, 0.55], [0.55, 0.45], [0.4, 0.4], [0.6, 0.6]]) {
    await page.mouse.click(box.x + box.width * fx, box.y + box.height * fy);
    await sleep(300);
    if (await page.$eval('#pick', (el) => el.innerText.includes('safety margin'))) break;
  }
  await waitFor(page, 'a picked spot', () => document.getElementById('pick').innerText.includes('safety margin'), 5000);
  const picked = await page.$eval('#pick', (el) => el.innerText);
  await shot(page, '3-result-picked.png');

  // The arrows of the major strain's direction on every element, then a section cut.
  await waitFor(page, 'the grid elements for the arrows', () => Number(document.body.dataset.elements || 0) > 0 && !document.getElementById('arrows').disabled, 20000);
  await tap('#arrows');
  await waitFor(page, 'the arrows', () => Number(document.body.dataset.arrows || 0) > 0, 10000);
  const arrows = await page.evaluate(() => Number(document.body.dataset.arrows));
  await tap('.section-axis[data-axis="x"]');
  await waitFor(page, 'the section profile', () => Number(document.body.dataset.section || 0) > 0, 20000);
  const sectionAt = await page.$eval('#section-value', (el) => el.innerText);
  await tap('#section-plus');
  // Moved one pitch on, and the profile is the one of the new place (no request still under way).
  await waitFor(page, 'the section moving on', (before) => {
    const at = Number(document.getElementById('section-at').value).toFixed(1);
    return document.getElementById('section-value').innerText !== before && !analysis.inFlight && !analysis.pending &&
      document.getElementById('section-info').innerText.includes(`= ${at} mm`);
  }, 20000, sectionAt);
  const section = await page.evaluate(() => ({ at: document.getElementById('section-value').innerText, points: Number(document.body.dataset.section),
    plotted: analysis.chart ? analysis.chart.data.datasets.map((d) => d.data.length) : [] }));
  if (!section.plotted.length || section.plotted.some((n) => n !== section.points)) fail(`the section's profile is not plotted: ${JSON.stringify(section)}`);
  await shot(page, '3-result-arrows-section.png');
  const firstRun = await page.evaluate(() => lastRunId);
  const fld = await page.$eval('#fld', (img) => ({ w: img.naturalWidth, h: img.naturalHeight }));
  if (!fld.w) fail('the FLD image did not load');
  const files = await page.evaluate(async () => {
    const get = async (href) => { const r = await fetch(href); const b = new Uint8Array(await r.arrayBuffer()); return { status: r.status, type: r.headers.get('Content-Type'), head: String.fromCharCode(...b.slice(0, 5)), size: b.length }; };
    return { pdf: await get(document.getElementById('pdf').href), fld: await get(document.getElementById('fldlink').href) };
  });
  if (files.pdf.status !== 200 || files.pdf.type !== 'application/pdf' || files.pdf.head !== '%PDF-') fail(`the PDF did not open: ${JSON.stringify(files.pdf)}`);
  if (files.fld.status !== 200 || files.fld.type !== 'image/png') fail(`the FLD did not open: ${JSON.stringify(files.fld)}`);
  // Open the PDF as the operator does (its own tab).
  const pdfPage = await browser.newPage();
  const pdfResponse = await pdfPage.goto(files.pdf ? await page.$eval('#pdf', (a) => a.href) : '', { waitUntil: 'load' }).catch((e) => e);
  if (pdfResponse instanceof Error) {
    // Headless chromium may hand a PDF to its downloader instead of showing it; the fetch above read it.
    if (!/ERR_ABORTED/.test(String(pdfResponse))) fail(`the PDF tab did not open: ${pdfResponse}`);
  } else if (pdfResponse.status() !== 200) fail(`the PDF tab answered ${pdfResponse.status()}`);
  await pdfPage.close();

  // The door opened on the virtual PLC mid-scan: the scan stops and the page says why and what to do.
  await page.click('button[data-tab="scan"]');
  await page.$eval('#part-id', (el) => { el.value = 'door-e2e'; });
  await page.click('#start');
  await waitFor(page, 'progress of the second scan', () => document.body.dataset.job === 'scan' && Number(document.body.dataset.progress || 0) >= 2, 60000);
  station.kill('SIGUSR1');
  await page.waitForFunction(() => document.body.dataset.finished === 'error', { timeout: 60000 }).catch(() => fail('the door did not stop the scan'));
  const doorFault = await page.$eval('#fault', (el) => el.innerText);
  if (!/door/i.test(doorFault) || !/Close the cell door/.test(doorFault)) fail(`the page does not say the door stopped the scan: ${doorFault}`);
  await shot(page, '4-door-opened.png');
  station.kill('SIGUSR2');
  await page.evaluate(() => { delete document.body.dataset.finished; });

  // A second part of the same program, then the two compared.
  await page.waitForFunction(() => !document.getElementById('start').disabled, { timeout: 30000 }).catch(() => fail('Start did not come back after the door'));
  await page.$eval('#part-id', (el) => { el.value = 'sample-e2e-2'; });
  await tap('#start');
  await waitFor(page, 'the second part\'s result', (first) => document.body.dataset.finished === 'ok' && lastRunId !== first && Number(document.body.dataset.mesh || 0) > 0, 300000, firstRun);
  await tap('button[data-tab="compare"]');
  await waitFor(page, 'two runs of one program to compare', () => document.getElementById('cmp-b').options.length > 0 && !document.getElementById('cmp-side').disabled, 10000);
  await tap('#cmp-side');
  await waitFor(page, 'the two runs side by side', () => document.body.dataset.compare === 'side', 20000);
  await shot(page, '5-compare-side-by-side.png');
  await tap('#cmp-diff');
  await waitFor(page, 'the difference map', () => document.body.dataset.compare === 'diff' && Number(document.body.dataset.compareMatched || 0) > 0, 20000);
  const comparison = await page.$eval('#cmp-info', (el) => el.innerText);
  // A finger on the map reads the difference there.
  const diffBox = await (await page.$('#cmp-view-a canvas')).boundingBox();
  for (const [fx, fy] of [[0.5, 0.5], [0.45, 0.55], [0.55, 0.45], [0.4, 0.4], [0.6, 0.6]]) {
    await page.touchscreen.tap(diffBox.x + diffBox.width * fx, diffBox.y + diffBox.height * fy);
    await sleep(300);
    if (await page.$eval('#cmp-pick', (el) => el.innerText.includes('B − A'))) break;
  }
  await waitFor(page, 'the difference read at a tapped spot', () => document.getElementById('cmp-pick').innerText.includes('B − A'), 5000);
  const diffPicked = await page.$eval('#cmp-pick', (el) => el.innerText);
  await shot(page, '6-compare-difference.png');

  await page.click('button[data-tab="history"]');
  await waitFor(page, 'the run in the history', () => document.getElementById('runs').innerText.includes('sample-e2e'), 10000);
  await shot(page, '7-history.png');
  await page.click('button[data-tab="maintenance"]');
  await waitFor(page, 'the actions log', () => document.getElementById('actions').innerText.includes('scan start'), 10000);
  // Maintenance (the loopback panel's local user) sets the calibration's validity.
  await waitFor(page, 'the cell settings', () => document.body.dataset.settings === 'loaded', 10000);
  await page.$eval('#settings-form input[name="validity_days"]', (el) => { el.value = '5'; });
  await tap('#settings-save');
  await waitFor(page, 'the settings saved', () => document.body.dataset.settingsSaved === 'validity_days' &&
    document.getElementById('actions').innerText.includes('settings change'), 10000);
  const settings = await (await fetch(`${url}api/settings`)).json();
  if (settings.settings.validity_days !== 5) fail(`the validity did not change: ${JSON.stringify(settings)}`);
  await shot(page, '8-maintenance.png');

  const stats = await page.evaluate(() => window.hmiStats);
  const lat = stats.latencies.slice().sort((a, b) => a - b);
  const q = (p) => lat[Math.min(lat.length - 1, Math.floor(p * lat.length))];
  console.log(`page load: ${loadMs} ms to ready (navigation load event ${Math.round(nav.load)} ms, DOMContentLoaded ${Math.round(nav.dcl)} ms)`);
  console.log(`live events: ${stats.events} received; latency from publishing to the page: median ${q(0.5)} ms, 95th percentile ${q(0.95)} ms, max ${lat[lat.length - 1]} ms`);
  console.log(`door opened mid-scan, the page shows: ${doorFault.replace(/\s+/g, ' ')}`);
  console.log(`live cloud: ${firstCloud} points at first, then ${grownCloud.points} after ${grownCloud.batches} batches`);
  console.log(`result: ${arrows} major-strain arrows; section ${section.at} with ${section.points} elements plotted`);
  console.log(`comparison: ${comparison.replace(/\s+/g, ' ')} Tapped: ${diffPicked.replace(/\s+/g, ' ')}`);
  console.log(`verdict: ${verdict.replace(/\s+/g, ' ')}; picked: ${picked.replace(/\s+/g, ' ')}; FLD ${fld.w}x${fld.h}; PDF ${files.pdf.size} bytes`);
  if (consoleErrors.length) fail(`errors in the browser console:\n  ${consoleErrors.join('\n  ')}`);
  console.log('PASSED');
  await browser.close();
  browser = null;
  station.kill('SIGTERM');
  process.exitCode = 0;
} catch (e) {
  console.log(`FAILED: ${e.message}`);
  if (consoleErrors.length) console.log(`browser console errors:\n  ${consoleErrors.join('\n  ')}`);
  process.exitCode = 1;
} finally {
  if (browser) await browser.close().catch(() => {});
  if (station.exitCode === null) station.kill('SIGTERM');
  await new Promise((r) => (station.exitCode !== null ? r() : station.once('exit', r)));
  fs.rmSync(userDataDir, { recursive: true, force: true });
}
