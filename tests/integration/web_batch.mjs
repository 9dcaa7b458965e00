// The web app's batch view (web/batch.js) in real Chromium (Debian's
// chromium, npm playwright-core): the batch of web_batch.sh (disks matched
// onto circles of the given radii) opened by #batch=ID while it runs; the
// per-target table follows it to the end, by the batch's event stream
// (one GET of the document, then /events: no polling); then the model: one slider per
// written mode (at most 5), the variance plot drawn, and mode 1 at +-3
// standard deviations moves the boundary's mean radius by 6 sigma, where
// sigma is the spread of the generating radii (their sample standard
// deviation, within 25%: the matches are not exact circles) -- a figure
// from the radii alone, not from the model's files.  The jobs list offers
// the model job its batch view (not the match view).  No console error.
// Prints one JSON line per check: {desc, ok, detail}.
import { chromium } from 'playwright-core';

const [base, id, radiiText, logDir] = process.argv.slice(2);
const radii = radiiText.split(' ').map(Number);
const report = (desc, ok, detail = '') => console.log(JSON.stringify({ desc, ok: !!ok, detail: String(detail).slice(0, 2000) }));

const browser = await chromium.launch({
  executablePath: '/usr/bin/chromium',
  headless: true,
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--disable-dev-shm-usage'],
});
try {
  const page = await browser.newPage({ viewport: { width: 1100, height: 1400 } });
  const errors = [];
  page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  page.on('pageerror', (e) => errors.push(String(e)));
  const asked = [];
  page.on('request', (q) => asked.push(new URL(q.url()).pathname));
  await page.goto(`${base}/#batch=${id}`);
  await page.waitForSelector('#batch-panel:not([hidden])', { timeout: 10000 });
  await page.waitForFunction((n) => document.querySelectorAll('#batch-targets tr').length === n, radii.length, { timeout: 10000 });
  report('#batch=ID opens the batch: one row per target', true);
  await page.waitForSelector('#batch-model:not([hidden])', { timeout: 60000 });
  const rows = await page.$$eval('#batch-targets tr', (trs) => trs.map((tr) => tr.dataset.status));
  const status = await page.textContent('#batch-status');
  const summary = await page.textContent('#batch-summary');
  report('the table follows the batch to its end: every target successful, the batch too',
    status === 'successful' && rows.every((s) => s === 'successful') && summary.includes(`${radii.length} of ${radii.length}`), `${status} ${rows} ${summary}`);
  const docs = asked.filter((p) => p === `/v1/batches/${id}`).length;
  const streams = asked.filter((p) => p === `/v1/batches/${id}/events`).length;
  const first = await page.evaluate(() => window.shapematchBatch.current.firstStatus);
  report(`the view follows the batch by its event stream: one GET of the document (${first}), then /events (no polling)`,
    docs === 1 && streams >= 1 && first !== 'successful', `document ${docs}, events ${streams}, first status ${first}`);
  const sliders = await page.$$eval('#batch-modes input[type=range]', (s) => s.map((x) => [x.min, x.max]));
  const written = await page.evaluate(() => window.shapematchBatch.current.model.modes.length);
  report('one slider per written mode (at most 5), each from -3 to +3 sigma',
    sliders.length === Math.min(5, radii.length - 1) && sliders.length === written && sliders.every(([a, b]) => a === '-3' && b === '3'), JSON.stringify(sliders));
  const plotted = await page.$eval('#batch-variance', (el) => el.querySelector('canvas') !== null && el.textContent.includes('cumulative'));
  const ve = await page.evaluate(() => window.shapematchBatch.current.model.summary.variance_explained);
  report('the variance plot is drawn (per mode and cumulative)', plotted && ve.length >= 1, JSON.stringify(ve));

  // the mean radius of the boundary shown (2D: the vertices farthest out
  // are the boundary of a disk; their mean distance from the centroid)
  const radius = () => page.evaluate(() => {
    const m = window.shapematchBatch.current.model, xyz = m.shown, n = xyz.length / 2;
    let cx = 0, cy = 0;
    for (let v = 0; v < n; v++) { cx += xyz[2 * v] / n; cy += xyz[2 * v + 1] / n; }
    const r = [];
    for (let v = 0; v < n; v++) r.push(Math.hypot(xyz[2 * v] - cx, xyz[2 * v + 1] - cy));
    r.sort((a, b) => b - a);
    const k = Math.max(1, Math.round(n * 0.15));
    return r.slice(0, k).reduce((a, b) => a + b, 0) / k;
  });
  const canvasData = () => page.$eval('#batch-view2d', (c) => c.toDataURL());
  const r0 = await radius(), img0 = await canvasData();
  await page.fill('#batch-mode-1', '3');
  await page.dispatchEvent('#batch-mode-1', 'input');
  const rPlus = await radius(), imgPlus = await canvasData();
  await page.fill('#batch-mode-1', '-3');
  await page.dispatchEvent('#batch-mode-1', 'input');
  const rMinus = await radius();
  const mean = radii.reduce((a, b) => a + b, 0) / radii.length;
  const sd = Math.sqrt(radii.reduce((a, r) => a + (r - mean) ** 2, 0) / (radii.length - 1));
  const sigma = Math.abs(rPlus - rMinus) / 6;
  report(`mode 1 at +-3 sigma: the radius moves by 6 sigma, sigma ${sigma.toFixed(4)} against the radii's ${sd.toFixed(4)}; the mean's radius ${r0.toFixed(3)} near their mean ${mean.toFixed(3)}`,
    Math.abs(sigma / sd - 1) < 0.25 && Math.abs(r0 - mean) < 0.05 && img0 !== imgPlus, `r0 ${r0} r+ ${rPlus} r- ${rMinus}`);
  await page.screenshot({ path: `${logDir}/web_batch.png`, fullPage: true });
  // the batch view across the page (not the form's column), its variance
  // plot the width of its column, at 1400 px and at 800 px; nothing
  // sticks out of the panel
  const layout = async (width) => {
    await page.setViewportSize({ width, height: 1400 });
    await new Promise((r) => setTimeout(r, 400));
    await page.screenshot({ path: `${logDir}/web_batch_${width}.png`, fullPage: true });
    return page.evaluate(() => {
      const r = (s) => document.querySelector(s).getBoundingClientRect();
      const panel = r('#batches-panel'), main = r('main'), plot = r('#batch-variance canvas'), box = r('#batch-variance');
      const table = r('#batch-targets').width;
      return { panel: panel.width / main.width, plot: plot.width, box: box.width, table,
        inside: plot.right <= panel.right + 0.5 && table <= panel.width, page: document.documentElement.scrollWidth <= document.documentElement.clientWidth };
    });
  };
  const wide = await layout(1400), narrow = await layout(800);
  report('the batch view spans the page at 1400 and 800 px, its variance plot the width of its column (>= 400 px), nothing overflowing',
    wide.panel > 0.95 && narrow.panel > 0.95 && wide.plot >= 400 && narrow.plot >= 400 && Math.abs(wide.plot - wide.box) < 3 &&
    wide.inside && narrow.inside && wide.page && narrow.page, JSON.stringify({ wide, narrow }));
  await page.setViewportSize({ width: 1100, height: 1400 });

  // the jobs list: the model job (processID shape-model) offers its batch
  // view, not the match view it has no result for; a target keeps 'view'
  await page.goto(`${base}/`);
  await page.waitForSelector('#batch-panel', { state: 'attached' });
  const rowOf = (jid) => page.waitForFunction((j) => [...document.querySelectorAll('#jobs tr')]
    .find((tr) => tr.querySelector('.job-id')?.textContent === j), jid, { timeout: 10000 });
  await rowOf(id);
  const actions = await page.$$eval('#jobs tr', (trs) => Object.fromEntries(trs.map((tr) =>
    [tr.querySelector('.job-id').textContent, tr.querySelector('button')?.dataset.action])));
  const hiddenBefore = await page.$eval('#batch-panel', (p) => p.hidden);
  await page.click(`#jobs tr:has(code.job-id:text-is("${id}")) button[data-action=batch]`);
  await page.waitForSelector('#batch-panel:not([hidden])', { timeout: 10000 });
  await page.waitForFunction((n) => document.querySelectorAll('#batch-targets tr').length === n, radii.length, { timeout: 10000 });
  const shown = await page.textContent('#batch-id');
  const hash = await page.evaluate(() => location.hash);
  const targetsView = Object.entries(actions).filter(([k]) => k !== id).every(([, a]) => a === 'view');
  report("the jobs list offers the model job's batch view ('batch', not 'view'), and it opens it",
    actions[id] === 'batch' && targetsView && hiddenBefore && shown === id && hash === `#batch=${id}`,
    `${JSON.stringify(actions)} hidden ${hiddenBefore} shown ${shown} hash ${hash}`);
  report('no console or page error', errors.length === 0, errors.join('\n'));
} finally {
  await browser.close();
}
