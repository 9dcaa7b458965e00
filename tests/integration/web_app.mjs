// Browser tests of the web app and of cross-origin use (issue 11), in
// real Chromium (Debian's /usr/bin/chromium, driven by npm playwright-core;
// no browser download).  One browser for every case (a 2-core machine).
// Usage: node web_app.mjs OPEN_BASE TOKEN_BASE TOKEN ORIGIN_PORT EXAMPLES LOGDIR
// OPEN_BASE: a daemon without tokens, TOKEN_BASE one with TOKEN; both list
// http://localhost:ORIGIN_PORT with --cors-origin, and this script serves
// the plain test page there (and at http://127.0.0.1:ORIGIN_PORT, an
// unlisted origin).  Prints one JSON line per check: {desc, ok, detail}.
import http from 'node:http';
import fs from 'node:fs';
import path from 'node:path';
import { execFileSync } from 'node:child_process';
import { chromium } from 'playwright-core';

const [openBase, tokenBase, token, originPort, examples, logDir, cubeMesh, cubeSol, smallCube, cli] = process.argv.slice(2);
const report = (desc, ok, detail = '') => console.log(JSON.stringify({ desc, ok: !!ok, detail: String(detail).slice(0, 2000) }));
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
// Every wait below is a deadline, not a verdict (it ends as soon as the
// page is there): 10 times what an idle machine needs.  A 2D job's 60 s
// ran out at load 11-14 while the page was right, and at load 40 its 4.6
// CPU seconds took 293 s.
const WAIT = 10;

// The plain test page of "another origin": nothing but a script hook.
const server = http.createServer((req, res) => {
  res.writeHead(200, { 'Content-Type': 'text/html' });
  res.end('<!doctype html><html><head><link rel="icon" href="data:,"><title>other origin</title></head><body>other origin</body></html>');
});
await new Promise((r) => server.listen(Number(originPort), '127.0.0.1', r));

const browser = await chromium.launch({
  executablePath: '/usr/bin/chromium',
  headless: true,
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--disable-dev-shm-usage'],
});
const context = await browser.newContext({ acceptDownloads: true, viewport: { width: 1100, height: 1150 } });

async function newPage() {
  const page = await context.newPage();
  page.setDefaultTimeout(30000 * WAIT); // screenshots, clicks: deadlines too
  page.errors = [];
  page.on('console', (m) => { if (m.type() === 'error') page.errors.push(`${m.text()} ${m.location().url || ''}`); });
  page.on('pageerror', (e) => page.errors.push(String(e)));
  return page;
}

// the clamp through its fields (kind, centre, radius; no JSON)
const clamp2d = { kind: 'ball', center: [0.5, 0.5], radius: 0.04 };
const clamp3d = { kind: 'ball', center: [0, 0, 0], radius: 0.2 };
async function fillClamp(page, c) {
  await page.selectOption('#p-clamp', c.kind);
  if (c.kind === 'ball') {
    for (const [k, id] of ['x', 'y', 'z'].entries()) await page.fill(`#p-clamp-${id}`, c.center[k] === undefined ? '' : String(c.center[k]));
    await page.fill('#p-clamp-radius', String(c.radius));
  } else if (c.refs) await page.fill('#p-clamp-refs', c.refs.join(', '));
}
async function fillJob(page, dir, clamp, extra = {}) {
  // 3D: a small cube ([-0.4, 0.4]^3) grown onto a ball of radius 0.95 (its
  // result is larger than the template's bounding sphere), in the cube
  // [-1, 1]^3 of tests/integration/lib.sh make_case
  const files = dir === '3d' ? [smallCube, cubeMesh, cubeSol]
    : ['template.mesh', 'background.mesh.gz', 'background.sol.gz'].map((f) => path.join(examples, dir, f));
  await page.setInputFiles('#f-template', files[0]);
  await page.setInputFiles('#f-target_mesh', files[1]);
  await page.setInputFiles('#f-target_sol', files[2]);
  await page.waitForSelector('#p-clamp');
  await fillClamp(page, clamp);
  for (const [k, v] of Object.entries(extra)) {
    // a field of the folded section (advanced) is filled as a user does: unfolded first
    if (await page.$eval(`#p-${k}`, (e) => !!e.closest('details:not([open])'))) await page.click(`#p-${k} >> xpath=ancestor::details/summary`);
    await page.fill(`#p-${k}`, String(v));
  }
}
// The job's results summary, read by the test itself (not through the page).
const summaryOf = async (base, id) => (await fetch(`${base}/v1/jobs/${id}/results`)).json();
const jobId = (page) => page.$eval('#job-id', (e) => e.textContent);
// The log axis's labels: each one that is shown says its tick's value.
const logAxis = (page) => page.evaluate(() => {
  const a = window.shapematch.current.plot.axes[2];
  return { splits: a._splits, values: a._values };
});
function labelsRight({ splits, values }) {
  const shown = values.map((v, i) => [v, splits[i]]).filter(([v]) => v !== '' && v != null);
  return shown.length >= 2 && shown.every(([v, s]) => Number.isFinite(Number(v)) && Math.abs(Number(v) / s - 1) < 0.01);
}
// Nothing sticks out of the page or out of the job panel.
const overflow = (page) => page.evaluate(() => {
  const panel = document.querySelector('#job-panel').getBoundingClientRect();
  const out = [];
  for (const sel of ['#plot canvas', '#view2d', '#view3d', '#warnings', '#outcome', '#downloads', '#scale'])
    for (const e of document.querySelectorAll(sel)) {
      const r = e.getBoundingClientRect();
      if (r.width > 0 && (r.right > panel.right + 0.5 || r.left < panel.left - 0.5)) out.push(`${sel} ${r.left}-${r.right} outside ${panel.left}-${panel.right}`);
    }
  const doc = document.documentElement;
  if (doc.scrollWidth > doc.clientWidth) out.push(`page ${doc.scrollWidth} wide in ${doc.clientWidth}`);
  return out;
});
const status = (page) => page.$eval('#status', (e) => e.textContent);
async function waitStatus(page, want, ms) {
  await page.waitForFunction((w) => ['successful', 'failed', 'dismissed'].includes(document.querySelector('#status').textContent) || document.querySelector('#status').textContent === w, want, { timeout: ms * WAIT });
  return status(page);
}

const t0 = Date.now();
async function run(desc, fn) {
  const t = Date.now();
  try { await fn(); } catch (e) { report(desc, false, e.stack || e); }
  console.error(`${desc}: ${((Date.now() - t) / 1000).toFixed(1)} s (at ${((Date.now() - t0) / 1000).toFixed(1)} s)`);
}

// ------------------------------------------------ the app, a 2D job
await run('the app: a 2D job', async () => {
  const page = await newPage();
  const resp = await page.goto(`${openBase}/`);
  report('GET / in a browser is the web app (text/html)', resp.status() === 200 && (resp.headers()['content-type'] || '').startsWith('text/html'), resp.status());
  // the form's sections are the schema's x-groups (the parameter table's
  // group column), in their order; each field in its row's group; the
  // advanced one folded until opened
  await page.waitForSelector('#p-clamp');
  const schemaDoc = await (await fetch(`${openBase}/v1/params.schema.json`)).json();
  const form = await page.evaluate(() => [...document.querySelectorAll('#params .param-group')].map((g) => ({
    group: g.dataset.group, tag: g.tagName, open: g.tagName === 'DETAILS' ? g.open : true,
    fields: [...g.querySelectorAll('[id^="p-"]')].map((e) => e.id.slice(2)).filter((n) => !n.startsWith('clamp-')),
  })));
  const wantGroups = schemaDoc['x-groups'].map((g) => g.name);
  const misplaced = form.flatMap((g) => g.fields.filter((f) => (schemaDoc.properties[f] || {})['x-group'] !== g.group).map((f) => `${f} in ${g.group}`));
  const every = form.flatMap((g) => g.fields).sort().join(',') === Object.keys(schemaDoc.properties).sort().join(',');
  report('the form is grouped: inputs, clamp, stop rules, advanced (folded), from the schema\'s x-groups, each field in its group',
    JSON.stringify(form.map((g) => g.group)) === JSON.stringify(wantGroups) && wantGroups.join() === 'inputs,clamp,stop,advanced' &&
    misplaced.length === 0 && every && form.find((g) => g.group === 'advanced').tag === 'DETAILS' && !form.find((g) => g.group === 'advanced').open,
    `${JSON.stringify(form)} misplaced ${misplaced}`);
  await page.screenshot({ path: path.join(logDir, 'web-app-form-1100.png'), fullPage: true });
  // 1500 iterations: long enough to be seen running, short enough to end
  // (with the target-side term the step rule no longer ends this run early;
  // 4000 with live_every 1 outlasted a minute on a loaded machine)
  await fillJob(page, '2d', clamp2d, { live_every: 1, max_iter: 1500, tol_stall: 0, tol_step: 1e-12 });
  const jobName = 'disk → star, 2D «test»';
  await page.fill('#f-name', jobName);
  await page.click('#submit');
  await page.waitForFunction(() => Number(document.querySelector('#plot').dataset.points || 0) >= 5, null, { timeout: 30000 * WAIT });
  const live = await status(page);
  await page.screenshot({ path: path.join(logDir, 'web-app-2d-running.png') });
  report('at least 5 plot points arrive from the event stream while the job runs', live === 'running', live);
  const final = await waitStatus(page, 'successful', 120000);
  report('the job\'s status becomes successful', final === 'successful', final);
  await page.waitForFunction(() => document.querySelector('#view2d').dataset.drawn === 'final', null, { timeout: 15000 * WAIT });
  const drawn = await page.$eval('#view2d', (c) => {
    const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    let ink = 0;
    for (let i = 3; i < d.length; i += 4) if (d[i] > 0) ink++;
    return { elements: Number(c.dataset.elements), ink, hidden: c.hidden, live: Number(c.dataset.liveDraws || 0) };
  });
  report('the canvas drew the live shape while the job ran', drawn.live >= 1, JSON.stringify(drawn));
  report('the canvas draws the final shape (778 triangles, pixels inked)', drawn.elements === 778 && drawn.ink > 2000 && !drawn.hidden, JSON.stringify(drawn));
  const reason = await page.$eval('#stop-reason', (e) => e.textContent);
  report('the stop reason is shown', /stop: \w+/.test(reason), reason);
  const id = await jobId(page);
  const sum = await summaryOf(openBase, id);
  const outcome = await page.$eval('#outcome', (e) => ({ kind: e.dataset.outcome, text: e.textContent, hidden: e.hidden }));
  report('the outcome is shown: "converged" as the summary says', sum.converged === true && outcome.kind === 'converged' && outcome.text === 'converged' && !outcome.hidden,
    `${JSON.stringify(outcome)} summary converged ${sum.converged}`);
  const axis = await logAxis(page);
  report('the log axis labels say their ticks\' values (1e-4 is not "0")', labelsRight(axis) && axis.splits.some((v, i) => v < 2e-4 && axis.values[i]),
    JSON.stringify(axis));
  const scale = await page.$eval('#scale', (e) => ({ hidden: e.hidden, max: Number(e.dataset.max), label: document.querySelector('#scale-max').textContent, bar: getComputedStyle(document.querySelector('#scale-bar')).backgroundImage }));
  report('a colour scale for |d| is shown, up to the largest |d| on the boundary (the summary\'s boundary_max)',
    !scale.hidden && Math.abs(scale.max / sum.boundary_max - 1) < 1e-6 && Number(scale.label) > 0 && Math.abs(Number(scale.label) / sum.boundary_max - 1) < 0.01 && /gradient/.test(scale.bar),
    `${JSON.stringify(scale)} boundary_max ${sum.boundary_max}`);
  // the picture of README.md (web/screenshot.png is a copy): the job panel
  // at the end, with the target overlaid.  The target overlay: the zero
  // level set of target_sol; at the converged
  // shape's boundary vertices, the distance to it is the |d| the core
  // sampled there (to the background's resolution)
  await page.waitForFunction(() => ['shown', 'none'].includes(document.querySelector('#target-toggle').dataset.state), null, { timeout: 20000 * WAIT });
  const overlay = await page.evaluate(() => {
    const c = window.shapematch.current;
    const sg = c.target ? c.target.segments : [];
    const { xyz, distance } = c.last.mesh;
    const segDist = (x, y) => {
      let best = Infinity;
      for (let i = 0; i < sg.length; i += 4) {
        const [ax, ay, bx, by] = [sg[i], sg[i + 1], sg[i + 2], sg[i + 3]];
        const l2 = (bx - ax) ** 2 + (by - ay) ** 2;
        const t = l2 > 0 ? Math.max(0, Math.min(1, ((x - ax) * (bx - ax) + (y - ay) * (by - ay)) / l2)) : 0;
        best = Math.min(best, Math.hypot(x - ax - t * (bx - ax), y - ay - t * (by - ay)));
      }
      return best;
    };
    const verts = [...new Set(c.view.edgesOf.edges.flat())];
    let worst = 0;
    for (const v of verts) worst = Math.max(worst, Math.abs(segDist(xyz[2 * v], xyz[2 * v + 1]) - Math.abs(distance[v])));
    return { state: document.querySelector('#target-toggle').dataset.state, note: document.querySelector('#target-note').textContent,
      segments: sg.length / 4, vertices: verts.length, worst, framing: c.view.framing(c.last.mesh) };
  });
  report('the target\'s zero level set is overlaid in 2D: the boundary vertices lie at |d| from it (within the background\'s resolution)',
    overlay.state === 'shown' && overlay.segments > 100 && overlay.worst < sum.resolution && overlay.framing.inside === 1,
    `${JSON.stringify(overlay)} resolution ${sum.resolution}`);
  await page.locator('#job-panel').screenshot({ path: path.join(logDir, 'web-app-readme.png'), scale: 'css' });
  await page.click('#refresh');
  await page.waitForFunction((i) => [...document.querySelectorAll('#jobs td')].some((t) => t.textContent === i), id, { timeout: 5000 * WAIT }).catch(() => {});
  const listed = await page.$$eval('#jobs td', (t) => t.map((x) => x.textContent));
  let cliOut = '';
  try { cliOut = execFileSync(cli, ['status', '--server', openBase, listed.find((t) => t === id) || 'none'], { encoding: 'utf8' }); } catch (e) { cliOut = `${e.status} ${e.stderr}`; }
  report('the job list shows the full job id, which `shapematch status` accepts', /^[0-9a-f]{32}$/.test(id) && listed.includes(id) && cliOut.includes('successful'),
    `${id} ${JSON.stringify(listed)} ${cliOut}`);
  // the job's name: given in the form, in the status document, the list,
  // the job's title and `shapematch status`
  const doc = await (await fetch(`${openBase}/v1/jobs/${id}`)).json();
  const rowName = await page.$eval(`#jobs tr:has(code.job-id:text-is("${id}")) td.job-name`, (e) => e.textContent).catch((e) => String(e));
  const titleName = await page.$eval('#job-name', (e) => e.textContent);
  report('the job\'s name is in its status document, the job list, the job\'s title and `shapematch status`',
    doc.name === jobName && rowName === jobName && titleName === jobName && cliOut.includes(`name      ${jobName}\n`),
    `doc ${doc.name} row ${rowName} title ${titleName} cli ${cliOut}`);
  // the headline's figures, each read back against the summary's member
  // of the same name (the distances when the summary has them)
  const figs = await page.$$eval('#headline [data-figure]', (l) => l.map((e) => ({ name: e.dataset.figure, value: Number(e.dataset.value), text: e.textContent })));
  const member = (name) => name.split('.').reduce((o, k) => (o == null ? o : o[k]), sum);
  const figNames = figs.map((f) => f.name);
  const wantFigs = sum.distance ? ['distance.result_to_target.rms', 'distance.result_to_target.max', 'distance.target_to_result.rms', 'distance.target_to_result.max']
    : ['boundary_rms', 'boundary_max'];
  report('the headline shows the summary\'s named figures (RMS and max, the L2 norm by its name), each equal to the summary\'s',
    figs.length >= 3 && wantFigs.every((n) => figNames.includes(n)) && figNames.includes('boundary_l2') &&
    figs.every((f) => f.value === member(f.name) && Math.abs(Number(f.text) / f.value - 1) < 0.01),
    `${JSON.stringify(figs)}`);
  // 1400 px wide: the form and the job side by side, the batch panel and
  // the job list across the page, nothing overflowing
  await page.setViewportSize({ width: 1400, height: 1100 });
  await sleep(400);
  const wide = await page.evaluate(() => {
    const r = (s) => document.querySelector(s).getBoundingClientRect();
    return { form: r('#submit-panel'), job: r('#job-panel'), batches: r('#batches-panel'), main: r('main') };
  });
  const over1400 = await overflow(page);
  report('at 1400 px the form and the job sit side by side, the batch panel spans the page, nothing overflows',
    over1400.length === 0 && wide.job.left > wide.form.right && wide.batches.width > 0.9 * wide.main.width,
    `${over1400.join('; ')} ${JSON.stringify(wide)}`);
  await page.screenshot({ path: path.join(logDir, 'web-app-1400.png'), fullPage: true });
  await page.setViewportSize({ width: 1100, height: 1150 });
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#downloads a[data-file="result.vtu"]')]);
  const file = path.join(logDir, 'web-app-result.vtu');
  await download.saveAs(file);
  const vtu = fs.readFileSync(file, 'utf8');
  const pieces = /<Piece NumberOfPoints="(\d+)" NumberOfCells="(\d+)"/.exec(vtu);
  report('result.vtu downloads and parses (a VTK UnstructuredGrid with the template\'s 440 points, its 778 triangles and boundary edges as cells)',
    download.suggestedFilename() === 'result.vtu' && vtu.includes('<VTKFile') && vtu.trim().endsWith('</VTKFile>') && pieces && pieces[1] === '440' && Number(pieces[2]) >= 778,
    `${download.suggestedFilename()} ${vtu.slice(0, 200)}`);
  await page.screenshot({ path: path.join(logDir, 'web-app-2d-final.png') });
  const rows = await page.$$eval('#jobs tr', (t) => t.length);
  report('the job list shows the job', rows >= 1, rows);
  report('no console errors in the 2D job', page.errors.length === 0, page.errors.join('\n'));
  await page.close();
});

// ------------------------------------------------ the app, a 3D job
await run('the app: a 3D job', async () => {
  const page = await newPage();
  await page.goto(`${openBase}/`);
  await fillJob(page, '3d', clamp3d, { live_every: 1, max_iter: 150, tol_stall: 0, tol_step: 1e-12 });
  await page.click('#submit');
  await page.waitForFunction(() => document.querySelector('#view3d canvas') && document.querySelector('#view3d').dataset.drawn, null, { timeout: 60000 * WAIT });
  // taken at the first live shape; a screenshot of WebGL (SwiftShader)
  // can take seconds on a loaded machine, so the job may be over by then
  const live3d = await status(page);
  await page.screenshot({ path: path.join(logDir, 'web-app-3d-running.png') });
  const final = await waitStatus(page, 'successful', 90000);
  await page.waitForFunction(() => document.querySelector('#view3d').dataset.drawn === 'final', null, { timeout: 20000 * WAIT });
  await sleep(200);
  const view = await page.$eval('#view3d', (v) => {
    const c = v.querySelector('canvas');
    const gl = c.getContext('webgl2') || c.getContext('webgl');
    const px = new Uint8Array(c.width * c.height * 4);
    gl.readPixels(0, 0, c.width, c.height, gl.RGBA, gl.UNSIGNED_BYTE, px);
    let coloured = 0;
    for (let i = 0; i < px.length; i += 4) if (!(px[i] > 245 && px[i + 1] > 245 && px[i + 2] > 245)) coloured++;
    return { live: Number(v.dataset.liveDraws || 0), hidden: v.hidden, elements: Number(v.dataset.elements), coloured, canvas2dHidden: document.querySelector('#view2d').hidden };
  });
  report('the three.js view showed the live shape while the 3D job ran (before the final one)', view.live >= 1, `${live3d} ${JSON.stringify(view)}`);
  report('a 3D job ends successful and shows the three.js view of its final boundary surface',
    final === 'successful' && !view.hidden && view.canvas2dHidden && view.elements > 0 && view.coloured > 5000, `${final} ${JSON.stringify(view)}`);
  await page.screenshot({ path: path.join(logDir, 'web-app-3d-final.png') });
  // the camera: the grown shape (radius 0.95 from the template's 0.69) in
  // view, filling it; a zoom by the user sticks until "Reset view"
  await page.waitForFunction(() => ['shown', 'none'].includes(document.querySelector('#target-toggle').dataset.state), null, { timeout: 20000 * WAIT });
  const surf = await page.evaluate(() => {
    const t = window.shapematch.current.target;
    const p = t ? t.positions : [];
    let worst = 0;
    for (let i = 0; i < p.length; i += 3) worst = Math.max(worst, Math.abs(Math.hypot(p[i], p[i + 1], p[i + 2]) - 0.95));
    return { state: document.querySelector('#target-toggle').dataset.state, triangles: p.length / 9, worst, shown: window.shapematch.current.view.targetMesh?.visible };
  });
  // linear interpolation of the exact distance on 0.1 elements: h^2/(2R) ~ 5.3e-3
  report('the target\'s surface (the zero level set of target_sol) is overlaid in 3D: on the sphere of radius 0.95',
    surf.state === 'shown' && surf.shown && surf.triangles > 500 && surf.worst < 0.0053, JSON.stringify(surf));
  const framing = () => page.evaluate(() => window.shapematch.current.view.framing());
  const fitted = await framing();
  report('the 3D camera frames the grown result (every boundary vertex in view, filling it)', fitted.inside === 1 && fitted.extent > 0.6 && fitted.points > 100, JSON.stringify(fitted));
  const box = await page.locator('#view3d canvas').boundingBox();
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  for (let i = 0; i < 8; i++) await page.mouse.wheel(0, -200);
  await sleep(300);
  const zoomed = await framing();
  const resetShown = await page.isVisible('#reset-view');
  await page.click('#reset-view');
  const reset = await framing();
  report('a zoom by the user is kept; "Reset view" frames the shape again', zoomed.extent > 1.05 && resetShown && reset.inside === 1 && Math.abs(reset.extent - fitted.extent) < 0.05,
    `zoomed ${JSON.stringify(zoomed)} reset ${JSON.stringify(reset)}`);
  report('no console errors in the 3D job', page.errors.length === 0, page.errors.join('\n'));
  await page.close();
});

// ------------------------------------------------ an invalid parameter
await run('the app: invalid parameters', async () => {
  const page = await newPage();
  await page.goto(`${openBase}/`);
  await fillJob(page, '2d', clamp2d, { max_iter: '0' });
  await page.click('#submit');
  const local = await page.$eval('.err[data-for="params.max_iter"]', (e) => e.textContent);
  report('an out-of-range value is flagged before submit, next to its field', /max_iter: must be >= 1/.test(local), local);
  await page.fill('#p-max_iter', '');
  await page.fill('#p-clamp-radius', '-1');
  const [resp] = await Promise.all([page.waitForResponse((r) => r.url().endsWith('/v1/jobs') && r.request().method() === 'POST'), page.click('#submit')]);
  const problem = await resp.json();
  await page.waitForFunction(() => document.querySelector('.err[data-for="params.clamp"]').textContent, null, { timeout: 5000 * WAIT });
  const shown = await page.$eval('.err[data-for="params.clamp"]', (e) => e.textContent);
  report('the server\'s 422 message is shown next to its field', resp.status() === 422 && shown === problem.detail && /radius/.test(shown), `${resp.status()} ${shown} / ${problem.detail}`);
  // the same form, corrected, with 5 iterations: finished, not converged
  await page.fill('#p-clamp-radius', '0.04');
  await page.fill('#p-max_iter', '5');
  await page.click('#submit');
  const final = await waitStatus(page, 'successful', 60000);
  await page.waitForFunction(() => document.querySelector('#view2d').dataset.drawn === 'final', null, { timeout: 15000 * WAIT });
  const sum = await summaryOf(openBase, await jobId(page));
  const outcome = await page.$eval('#outcome', (e) => ({ kind: e.dataset.outcome, text: e.textContent, hidden: e.hidden }));
  report('a job that finished without converging is shown "not converged: <reason>"',
    final === 'successful' && sum.converged === false && outcome.kind === 'not-converged' && !outcome.hidden && outcome.text.startsWith('not converged: ') && outcome.text.includes(sum.stop_reason),
    `${final} ${JSON.stringify(outcome)} summary ${sum.converged} ${sum.stop_reason}`);
  const warnings = await page.$$eval('#warnings li', (l) => l.map((x) => ({ code: x.dataset.code, text: x.textContent })));
  const want = (sum.warnings || []).map((w) => w.code);
  report('every warning of the summary is shown, with its message', want.length >= 1 && warnings.length === want.length &&
    want.every((c, i) => warnings[i].code === c && warnings[i].text.includes(sum.warnings[i].message)), `${JSON.stringify(warnings)} / ${want}`);
  // 800 px wide: one column, nothing overflows
  await page.setViewportSize({ width: 800, height: 1100 });
  await sleep(400);
  const over = await overflow(page);
  const plotWidth = await page.$eval('#plot canvas', (c) => c.getBoundingClientRect().width);
  report('at 800 px wide nothing overflows (the plot follows the panel)', over.length === 0 && plotWidth > 400, `${over.join('; ')} plot ${plotWidth}`);
  await page.screenshot({ path: path.join(logDir, 'web-app-800.png'), fullPage: true });
  await page.close();
});

// ------------------------------------------------ a token typed in
await run('the app with a token', async () => {
  const page = await newPage();
  const resp = await page.goto(`${tokenBase}/`);
  report('the page loads from a daemon with tokens (no token yet)', resp.status() === 200, resp.status());
  await page.fill('#token', token);
  await page.dispatchEvent('#token', 'change');
  await fillJob(page, '2d', clamp2d, { max_iter: 30 });
  await page.click('#submit');
  const final = await waitStatus(page, 'successful', 60000);
  const points = await page.$eval('#plot', (e) => Number(e.dataset.points || 0));
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#downloads a[data-file="history.csv"]')]);
  const csv = fs.readFileSync(await download.path(), 'utf8');
  report('with the token typed in: submit, events (access_token), status and a download work',
    final === 'successful' && points > 0 && csv.split('\n').length > 2, `${final} points ${points} ${csv.slice(0, 100)}`);
  report('no console errors with a token', page.errors.length === 0, page.errors.join('\n'));
  await page.close();
});

// ------------------------------------------------ from another origin
const files2d = ['template.mesh', 'background.mesh.gz', 'background.sol.gz'].map((f) => fs.readFileSync(path.join(examples, '2d', f)).toString('base64'));
async function crossOrigin(page, base, tok, withAuth) {
  return page.evaluate(async ({ base, tok, files, withAuth }) => {
    const out = {};
    const fd = new FormData();
    const blob = (b64) => new Blob([Uint8Array.from(atob(b64), (c) => c.charCodeAt(0))]);
    fd.append('template', blob(files[0]), 'template.mesh');
    fd.append('target_mesh', blob(files[1]), 'background.mesh.gz');
    fd.append('target_sol', blob(files[2]), 'background.sol.gz');
    fd.append('params', JSON.stringify({ clamp: { kind: 'ball', center: [0.5, 0.5], radius: 0.04 }, max_iter: 20 }));
    try {
      const r = await fetch(`${base}/v1/jobs`, { method: 'POST', body: fd, headers: withAuth ? { Authorization: `Bearer ${tok}` } : {} });
      out.post = r.status;
      out.location = r.headers.get('Location');
      out.id = (await r.json()).jobID;
    } catch (e) { out.postError = String(e); }
    if (!out.id) return out;
    out.events = await new Promise((resolve) => {
      const es = new EventSource(`${base}/v1/jobs/${out.id}/events?access_token=${encodeURIComponent(tok)}`);
      let progress = 0;
      es.addEventListener('progress', () => { progress++; });
      es.addEventListener('status', (e) => { es.close(); resolve({ progress, status: JSON.parse(e.data).status }); });
      es.onerror = () => { if (es.readyState === EventSource.CLOSED) resolve({ progress, error: 'closed' }); };
      setTimeout(() => { es.close(); resolve({ progress, error: 'timeout' }); }, 30000);
    });
    try {
      const r = await fetch(`${base}/v1/jobs/${out.id}/results/mesh?format=mesh&access_token=${encodeURIComponent(tok)}`);
      out.download = r.status;
      out.disposition = r.headers.get('Content-Disposition');
      out.mesh = (await r.text()).includes('Vertices');
    } catch (e) { out.downloadError = String(e); }
    return out;
  }, { base, tok, files: files2d, withAuth });
}

// ------------------------------------------------ a template from a surface
await run('a template from a surface', async () => {
  const page = await newPage();
  await page.goto(`${openBase}/`);
  await page.waitForSelector('#p-clamp');
  // a closed curve (a circle about the 2D example's centre) as an OBJ polyline
  const obj = path.join(logDir, 'web-app-circle.obj');
  const n = 48;
  fs.writeFileSync(obj, [...Array(n).keys()].map((i) => `v ${0.5 + 0.3 * Math.cos((2 * Math.PI * i) / n)} ${0.5 + 0.3 * Math.sin((2 * Math.PI * i) / n)} 0`).join('\n')
    + `\nl ${[...Array(n).keys()].map((i) => i + 1).join(' ')} 1\n`);
  await page.setInputFiles('#f-template_surface', obj);
  await page.setInputFiles('#f-target_mesh', path.join(examples, '2d', 'background.mesh.gz'));
  await page.setInputFiles('#f-target_sol', path.join(examples, '2d', 'background.sol.gz'));
  await page.fill('#p-template_size', '0.05');
  await page.fill('#p-max_iter', '20');
  await page.click('#submit');
  const final = await waitStatus(page, 'successful', 120000);
  const sum = await summaryOf(openBase, await jobId(page));
  const m = (sum.template || {}).meshed || {};
  report('the form\'s template_surface file and template_size: the daemon meshes the curve (nglib, size 0.05) and the job ends successful, 0 inverted',
    final === 'successful' && m.mesher === 'nglib' && m.size === 0.05 && sum.inverted_elements === 0, `${final} ${JSON.stringify(m)}`);
  await page.close();
});

// ------------------------------------------------ a template from a label map
await run('a template from a label map', async () => {
  const page = await newPage();
  await page.goto(`${openBase}/`);
  await page.waitForSelector('#p-template_label');
  const image = path.join(examples, 'image', 'sphere.nii.gz');
  await page.setInputFiles('#f-template_image', image);
  await page.setInputFiles('#f-target_image', image);
  await page.fill('#p-label', '1');
  await page.fill('#p-max_iter', '3');
  // a label the image does not hold: the daemon's 422 next to the file
  await page.fill('#p-template_label', '7');
  const [resp] = await Promise.all([page.waitForResponse((r) => r.url().endsWith('/v1/jobs') && r.request().method() === 'POST'), page.click('#submit')]);
  const problem = await resp.json();
  await page.waitForFunction(() => document.querySelector('.err[data-for="template_image"]').textContent, null, { timeout: 5000 * WAIT });
  const shown = await page.$eval('.err[data-for="template_image"]', (e) => e.textContent);
  report('the form\'s template_image with template_label 7 (absent): the 422 next to template_image',
    resp.status() === 422 && shown === problem.detail && /label-empty: no voxel of the image has label 7/.test(shown), `${resp.status()} ${shown}`);
  await page.fill('#p-template_label', '1');
  await page.click('#submit');
  const final = await waitStatus(page, 'successful', 120000);
  const sum = await summaryOf(openBase, await jobId(page));
  const m = (sum.template || {}).meshed || {};
  report('the form\'s template_image and template_label 1: the daemon meshes the label (nglib) and the job ends successful, 0 inverted',
    final === 'successful' && m.mesher === 'nglib' && m.from === 'image' && m.label === 1 && sum.inverted_elements === 0, `${final} ${JSON.stringify(m)}`);
  await page.close();
});

await run('another origin', async () => {
  const listed = await newPage();
  await listed.goto(`http://localhost:${originPort}/`);
  const a = await crossOrigin(listed, tokenBase, token, true);
  report('listed origin: fetch multipart POST with Authorization (201, Location readable)', a.post === 201 && a.location === `/v1/jobs/${a.id}`, JSON.stringify(a));
  report('listed origin: EventSource with access_token follows the job to successful', a.events && a.events.status === 'successful' && a.events.progress > 0, JSON.stringify(a.events));
  report('listed origin: the result downloads (Content-Disposition exposed)', a.download === 200 && a.mesh && /attachment/.test(a.disposition || ''), JSON.stringify(a));
  report('no console errors on the listed origin', listed.errors.length === 0, listed.errors.join('\n'));
  await listed.close();

  const unlisted = await newPage();
  await unlisted.goto(`http://127.0.0.1:${originPort}/`);
  const b = await unlisted.evaluate(async (base) => {
    const out = {};
    try { await (await fetch(`${base}/v1/processes`)).json(); out.read = 'allowed'; } catch (e) { out.read = `blocked: ${e}`; }
    const fd = new FormData();
    fd.append('params', '{}');
    try { await fetch(`${base}/v1/jobs`, { method: 'POST', body: fd }); out.post = 'allowed'; } catch (e) { out.post = `blocked: ${e}`; }
    return out;
  }, openBase);
  report('unlisted origin: the browser blocks reading the daemon\'s replies', b.read.startsWith('blocked') && b.post.startsWith('blocked'), JSON.stringify(b));
  await unlisted.close();
});

await browser.close();
server.close();
