// Browser tests of the web app's landmarks and alignment (issue 22), warp
// (issue 24) and clamps by physical name (issue 27), in real Chromium
// (Debian's /usr/bin/chromium, npm playwright-core), one browser.
// Usage: node web_tools.mjs BASE EXAMPLE_2D WORK LOGDIR
// WORK holds tests/cli/align_inputs.py's files (moved.mesh, lm_*.csv),
// lm_one*.csv and case/{cored.msh,box.mesh,box.sol} (web_tools.sh).
// Prints one JSON line per check: {desc, ok, detail}.
import fs from 'node:fs';
import path from 'node:path';
import { chromium } from 'playwright-core';

const [base, ex, work, logDir] = process.argv.slice(2);
const report = (desc, ok, detail = '') => console.log(JSON.stringify({ desc, ok: !!ok, detail: String(detail).slice(0, 2000) }));

const browser = await chromium.launch({
  executablePath: '/usr/bin/chromium',
  headless: true,
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--disable-dev-shm-usage'],
});
const context = await browser.newContext({ acceptDownloads: true, viewport: { width: 1100, height: 1400 } });

async function newPage() {
  const page = await context.newPage();
  page.errors = [];
  page.posts = 0;
  page.on('console', (m) => { if (m.type() === 'error' && !/status of 4\d\d/.test(m.text())) page.errors.push(`${m.text()} ${m.location().url || ''}`); });
  page.on('pageerror', (e) => page.errors.push(String(e)));
  page.on('request', (r) => { if (r.method() === 'POST' && r.url().endsWith('/v1/jobs')) page.posts++; });
  await page.goto(`${base}/`);
  await page.waitForSelector('#p-clamp');
  return page;
}

// The Vertices of a Medit ASCII mesh: [[x, y], ...].
function meditVertices(text) {
  const tok = text.split(/\s+/).filter(Boolean);
  const at = tok.indexOf('Vertices');
  const dim = Number(tok[tok.indexOf('Dimension') + 1]);
  const n = Number(tok[at + 1]);
  const out = [];
  for (let i = 0; i < n; i++) out.push(tok.slice(at + 2 + i * (dim + 1), at + 2 + i * (dim + 1) + dim).map(Number));
  return out;
}
const worst = (a, b) => Math.max(...a.map((p, i) => Math.hypot(...p.map((x, k) => x - b[i][k]))));

// examples/2d's template moved by a 30 degree rotation about the origin,
// then (40, -30) (tests/cli/align_inputs.py); its clamp ball moved along
const ANGLE = Math.PI / 6, SHIFT = [40, -30];
const move = ([x, y]) => [Math.cos(ANGLE) * x - Math.sin(ANGLE) * y + SHIFT[0], Math.sin(ANGLE) * x + Math.cos(ANGLE) * y + SHIFT[1]];
const centre = move([0.5, 0.5]);
const moved = path.join(work, 'moved.mesh');
async function fillAligned(page, tl, gl, align = 'rigid') {
  await page.setInputFiles('#f-template', moved);
  await page.setInputFiles('#f-target_mesh', path.join(ex, 'background.mesh.gz'));
  await page.setInputFiles('#f-target_sol', path.join(ex, 'background.sol.gz'));
  await page.selectOption('#p-clamp', 'ball');
  await page.fill('#p-clamp-x', String(centre[0]));
  await page.fill('#p-clamp-y', String(centre[1]));
  await page.fill('#p-clamp-radius', '0.04');
  await page.selectOption('#p-align', align);
  await page.setInputFiles('#f-template_landmarks', tl ? path.join(work, tl) : []);
  await page.setInputFiles('#f-target_landmarks', gl ? path.join(work, gl) : []);
}
const text = (page, sel) => page.$eval(sel, (e) => e.textContent);
const status = (page) => text(page, '#status');
async function waitFinal(page, ms) {
  await page.waitForFunction(() => ['successful', 'failed', 'dismissed'].includes(document.querySelector('#status').textContent), null, { timeout: ms });
  return status(page);
}

const t0 = Date.now();
async function run(desc, fn) {
  const t = Date.now();
  try { await fn(); } catch (e) { report(desc, false, e.stack || e); }
  console.error(`${desc}: ${((Date.now() - t) / 1000).toFixed(1)} s (at ${((Date.now() - t0) / 1000).toFixed(1)} s)`);
}

// One page for every case (a page load and the example's uploads chosen
// once: the suite's time on a loaded 2-core machine).
const page = await newPage();

// ------------------------------------------------ landmarks in the form
await run('landmarks: the form', async () => {
  await fillAligned(page, 'lm_template.csv', null);
  await page.waitForFunction(() => document.querySelector('.hint[data-for="template_landmarks"]').textContent, null, { timeout: 5000 });
  const hint = await text(page, '.hint[data-for="template_landmarks"]');
  report('a landmark file\'s hint says what it holds (4 points of 2 coordinates, its header skipped)', hint === '4 points of 2 coordinates', hint);
  await page.click('#submit');
  const alone = await text(page, '.err[data-for="target_landmarks"]');
  report('one landmark file alone is refused before any request, next to the missing one', /give both landmark files/.test(alone) && page.posts === 0, `${alone} (${page.posts} POST)`);
  await fillAligned(page, 'lm_template.csv', 'lm_target.csv', '');
  await page.click('#submit');
  const none = await text(page, '.err[data-for="params.align"]');
  report('landmarks without an alignment are refused before any request, next to align', /choose rigid, similarity or affine/.test(none) && page.posts === 0, `${none} (${page.posts} POST)`);
  // what the daemon checks: one pair is too few in 2D
  await fillAligned(page, 'lm_one.csv', 'lm_one_target.csv');
  const [resp] = await Promise.all([page.waitForResponse((r) => r.url().endsWith('/v1/jobs') && r.request().method() === 'POST'), page.click('#submit')]);
  const problem = await resp.json();
  await page.waitForFunction(() => document.querySelector('.err[data-for="template_landmarks"]').textContent, null, { timeout: 5000 });
  const shown = await text(page, '.err[data-for="template_landmarks"]');
  report('the daemon\'s 422 for one landmark pair in 2D is shown next to template_landmarks', resp.status() === 422 && shown === problem.detail && /needs at least 2/.test(shown),
    `${resp.status()} ${shown} / ${problem.detail}`);
});

// ------------------------------------------------ an aligned job, then warp
let id;
await run('align rigid with landmarks', async () => {
  await page.setInputFiles('#f-template_landmarks', path.join(work, 'lm_template.csv'));
  await page.setInputFiles('#f-target_landmarks', path.join(work, 'lm_target.csv'));
  await page.click('#submit');
  const final = await waitFinal(page, 60000);
  id = await text(page, '#job-id');
  await page.waitForFunction(() => document.querySelector('#alignment').dataset.source === 'summary', null, { timeout: 10000 });
  await page.waitForSelector('#outcome[data-outcome]', { timeout: 10000 });
  const sum = await (await fetch(`${base}/v1/jobs/${id}/results`)).json();
  const shown = await page.$eval('#alignment', (b) => ({ seen: b.dataset.seen, mode: b.dataset.mode, title: b.querySelector('.alignment-title')?.textContent,
    cells: [...b.querySelectorAll('table.matrix td')].map((td) => Number(td.dataset.value)), hidden: b.hidden }));
  const outcome = await page.$eval('#outcome', (e) => e.dataset.outcome);
  report('the job (moved 30 degrees and 100 diameters, align rigid, landmarks) converges', final === 'successful' && outcome === 'converged' && sum.converged === true,
    `${final} ${outcome} ${sum.stop_reason}`);
  report('the alignment event is shown while the job runs, then summary.json\'s alignment', /^event( event)* summary$/.test(shown.seen || ''),
    shown.seen);
  // the matrix shown is the summary's (2x3 of the 3x3), and near the
  // known motion's inverse: rotation by -30 degrees, b = -R(-30) SHIFT
  // (the least squares on the distance moves it off the landmark start,
  // which is exact: the template is not the target's shape)
  const m = sum.alignment?.matrix || [];
  const same = shown.cells.length === 6 && shown.cells.every((v, i) => v === m[i]);
  const angle = Math.atan2(-m[3], m[0]) * 180 / Math.PI;
  const c = Math.cos(-ANGLE), s = Math.sin(-ANGLE);
  const b = [-(c * SHIFT[0] - s * SHIFT[1]), -(s * SHIFT[0] + c * SHIFT[1])];
  const off = Math.hypot(m[2] - b[0], m[5] - b[1]);
  report('the alignment block: mode rigid, 4 landmarks, the matrix of summary.json (within 0.5 degree and 0.3 of the known motion)',
    !shown.hidden && shown.mode === 'rigid' && /4 landmarks/.test(shown.title) && same && Math.abs(angle - 30) < 0.5 && off < 0.3,
    `${shown.title} cells ${shown.cells} summary ${m} angle ${angle} offset ${off}`);
});

async function warp(body, direction = 'forward') {
  await page.setInputFiles('#warp-file', []);
  await page.fill('#warp-text', body);
  await page.selectOption('#warp-direction', direction);
  await page.click('#warp-go');
  await page.waitForFunction(() => ['done', 'error'].includes(document.querySelector('#warp').dataset.state), null, { timeout: 20000 });
  return page.evaluate(() => ({
    state: document.querySelector('#warp').dataset.state,
    error: document.querySelector('#warp-error').textContent,
    summary: document.querySelector('#warp-summary')?.textContent,
    rows: [...document.querySelectorAll('#warp-table tbody tr')].map((tr) => [...tr.cells].map((td) => Number(td.textContent))),
    outsideRows: document.querySelectorAll('#warp-table tr.outside').length,
  }));
}

await run('warp', async () => {
  if (!id) throw new Error('no finished job');
  await page.waitForSelector('#warp-go', { timeout: 5000 });
  const tpl = meditVertices(fs.readFileSync(moved, 'utf8')).slice(0, 6);
  const result = meditVertices(await (await fetch(`${base}/v1/jobs/${id}/results/mesh?format=mesh`)).text()).slice(0, 6);
  // the file's own digits: the pasted text is what a user would copy
  const lines = fs.readFileSync(moved, 'utf8').split('\n');
  const at = lines.findIndex((l) => l.trim() === 'Vertices');
  const pasted = lines.slice(at + 2, at + 8).map((l) => l.trim().split(/\s+/).slice(0, 2).join(',')).join('\n');
  const fwd = await warp(`x,y\n${pasted}`);
  const fwdErr = worst(fwd.rows.map((r) => r.slice(0, 2)), result);
  report('warp forward: template vertices pasted go to the result\'s vertices (exactly, to 1e-12), all inside',
    fwd.state === 'done' && fwd.rows.length === 6 && fwdErr < 1e-12 && fwd.rows.every((r) => r[2] === 1) && /6 points warped forward; 0 outside/.test(fwd.summary),
    `${JSON.stringify(fwd)} error ${fwdErr}`);
  const back = await warp(fwd.rows.map((r) => `${r[0]},${r[1]}`).join('\n'), 'inverse');
  const backErr = worst(back.rows.map((r) => r.slice(0, 2)), tpl);
  report('warp inverse: those images come back to the template\'s vertices (to 1e-9 of the diameter)', back.state === 'done' && back.rows.length === 6 && backErr < 5e-10,
    `${JSON.stringify(back.rows)} error ${backErr}`);
  const far = await warp(`${pasted}\n1000,1000`);
  report('a point far outside is flagged: inside 0, its row marked, counted in the summary', far.rows.length === 7 && far.rows[6][2] === 0 && far.outsideRows === 1 && /1 outside/.test(far.summary),
    JSON.stringify(far));
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#warp-download')]);
  const csv = fs.readFileSync(await download.path(), 'utf8').trim().split('\n');
  report('the warped CSV downloads: header with inside, every point', download.suggestedFilename() === 'points-target.csv' && csv[0] === 'x,y,inside' && csv.length === 8 && csv[7].endsWith(',0'),
    `${download.suggestedFilename()} ${csv.join(' | ')}`);
  // a mesh: the template itself goes onto the result mesh
  await page.fill('#warp-text', '');
  await page.setInputFiles('#warp-file', moved);
  await page.selectOption('#warp-direction', 'forward');
  await page.click('#warp-go');
  await page.waitForFunction(() => ['done', 'error'].includes(document.querySelector('#warp').dataset.state) && document.querySelector('#warp-download'), null, { timeout: 20000 });
  const [meshDl] = await Promise.all([page.waitForEvent('download'), page.click('#warp-download')]);
  const warped = meditVertices(fs.readFileSync(await meshDl.path(), 'utf8'));
  const all = meditVertices(await (await fetch(`${base}/v1/jobs/${id}/results/mesh?format=mesh`)).text());
  const meshErr = warped.length === all.length ? worst(warped, all) : Infinity;
  report('the template mesh uploaded and warped forward downloads as the result mesh (440 vertices, to 1e-12)', meshDl.suggestedFilename() === 'moved-target.mesh' && warped.length === 440 && meshErr < 1e-12,
    `${meshDl.suggestedFilename()} ${warped.length} vertices, error ${meshErr}`);
  const bad = await warp('0.5,0.5\n0.6,x\n');
  report('a malformed line: the daemon\'s 400 is shown, naming the line', bad.state === 'error' && /^400: .*line 2/.test(bad.error), bad.error);
  await page.setInputFiles('#warp-file', []);
  await warp(`x,y\n${pasted}\n1000,1000`);
  // the alignment block and the warp panel in one picture
  await page.locator('#job-panel').screenshot({ path: path.join(logDir, 'web-tools-warp.png') });
});

// ------------------------------------------------ a clamp by physical name
await run('clamp by name', async () => {
  const p = page;
  await p.setInputFiles('#f-template_landmarks', []);
  await p.setInputFiles('#f-target_landmarks', []);
  await p.selectOption('#p-align', '');
  await p.setInputFiles('#f-template', path.join(work, 'case', 'cored.msh'));
  await p.setInputFiles('#f-target_mesh', path.join(work, 'case', 'box.mesh'));
  await p.setInputFiles('#f-target_sol', path.join(work, 'case', 'box.sol'));
  await p.selectOption('#p-clamp', 'elements');
  await p.fill('#p-clamp-refs', 'cor');
  await p.fill('#p-max_iter', '5');
  const [resp] = await Promise.all([p.waitForResponse((r) => r.url().endsWith('/v1/jobs') && r.request().method() === 'POST'), p.click('#submit')]);
  const problem = await resp.json();
  await p.waitForFunction(() => document.querySelector('.err[data-for="params.clamp"]').textContent, null, { timeout: 5000 });
  const shown = await text(p, '.err[data-for="params.clamp"]');
  report('an unknown physical name in the clamp field: the daemon\'s 422 next to it, listing the names', resp.status() === 422 && shown === problem.detail &&
    shown.includes('no physical group named "cor" of elements') && shown.includes('"core" (7)'), `${resp.status()} ${shown}`);
  await p.fill('#p-clamp-refs', 'core');
  const [ok] = await Promise.all([p.waitForResponse((r) => r.url().endsWith('/v1/jobs') && r.request().method() === 'POST'), p.click('#submit')]);
  // the panel still shows the warp case's finished job until it follows
  // this one: wait for its id first, or its old status ends the wait
  const jobID = ok.status() === 201 ? (await ok.json()).jobID : '';
  await p.waitForFunction((j) => document.querySelector('#job-id').textContent === j, jobID, { timeout: 10000 });
  const final = await waitFinal(p, 30000);
  report('the clamp field takes a physical name (refs "core"): accepted, the job ends successful', ok.status() === 201 && final === 'successful',
    `${ok.status()} ${final}`);
});
report('no console errors', page.errors.length === 0, page.errors.join('\n'));

await browser.close();
