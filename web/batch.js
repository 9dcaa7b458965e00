// The batch view of the web app (docs/api.md "Batches"): open a batch by
// id (or #batch=ID in the address), follow its targets' status and the
// whole batch's progress and ETA (GET /v1/batches/{id}, then its event
// stream until the batch is final), then show its shape model: the mean
// shape (view.js: the 2D canvas or the three.js view) with one slider
// per mode, from -3 to +3 standard deviations (shape = mean + sum of t_k
// times mode_K.sol, which holds one standard deviation of mode K), and
// the variance each mode explains (uPlot: per mode and cumulative).
// Its own module, loaded by index.html next to app.js; it reads the same
// token field.
import uPlot from './uplot.js';
import { View2d, View3d, fmtNum } from './view.js';
import { parseMeditAscii } from './target.js';

const $ = (id) => document.getElementById(id);
const token = () => $('token').value.trim();
const authHeaders = () => (token() ? { Authorization: `Bearer ${token()}` } : {});
// EventSource sends no header: the token as the access_token parameter
const withToken = (path) => (token() ? `${path}${path.includes('?') ? '&' : '?'}access_token=${encodeURIComponent(token())}` : path);
const SLIDERS = 5; // the first modes get a slider
const FINAL = new Set(['successful', 'failed', 'dismissed']);

let batch = null; // {id, es, doc, model: {mean, modes, view, t}, plot}
// for the browser tests
window.shapematchBatch = { get current() { return batch; } };

// mean.mesh (Medit ASCII, as the model writes it) into view.js's mesh
// shape (target.js reads Medit).
export function meanMesh(text) {
  const m = parseMeditAscii(new TextEncoder().encode(text));
  if (!m.xyz) throw new Error('mean.mesh has no vertices');
  const empty = new Int32Array(0);
  return { dim: m.dim, xyz: m.xyz, tris: m.tris || empty, tets: m.tets || empty, facets: empty, distance: null };
}

// mode_K.sol (one vector per vertex) into a Float64Array of nv * dim.
export function parseSolVectors(text, nv, dim) {
  const w = text.replace(/#[^\n]*/g, ' ').split(/\s+/).filter(Boolean);
  const i = w.indexOf('SolAtVertices');
  if (i < 0 || Number(w[i + 1]) !== nv || Number(w[i + 2]) !== 1 || Number(w[i + 3]) !== 2) throw new Error('not a vector field of the mean shape');
  const at = i + 4;
  const out = new Float64Array(nv * dim);
  for (let k = 0; k < nv * dim; k++) out[k] = Number(w[at + k]);
  return out;
}

async function getText(path) {
  const r = await fetch(path, { headers: authHeaders() });
  if (!r.ok) throw new Error(`${path}: ${r.status}`);
  return r.text();
}

function showTargets(doc) {
  const eta = doc.eta == null ? '–' : `${fmtNum(doc.eta)} s`;
  $('batch-status').textContent = doc.status;
  $('batch-progress').value = doc.progress;
  $('batch-summary').textContent = `${doc.counts.successful} of ${doc.counts.total} targets successful, ${doc.counts.failed} failed · ${doc.progress}% · ETA ${eta}`;
  $('batch-message').textContent = doc.message || '';
  const rows = doc.targets.map((t) => {
    const tr = document.createElement('tr');
    tr.dataset.status = t.status;
    for (const text of [t.name, t.status, t.progress == null ? '' : `${t.progress}%`, t.message || '']) {
      const td = document.createElement('td');
      td.textContent = text;
      tr.append(td);
    }
    return tr;
  });
  $('batch-targets').replaceChildren(...rows);
}

// The shape at the sliders' values: mean + sum t_k mode_k, drawn.
function redraw() {
  const m = batch.model;
  const xyz = Float64Array.from(m.mean.xyz);
  m.modes.forEach((mode, k) => {
    const t = m.t[k];
    if (t) for (let i = 0; i < xyz.length; i++) xyz[i] += t * mode[i];
  });
  m.shown = xyz; // for the browser tests
  m.view.show({ ...m.mean, xyz });
}

function sliders(n) {
  const box = $('batch-modes');
  box.replaceChildren();
  for (let k = 0; k < n; k++) {
    const label = document.createElement('label');
    const input = Object.assign(document.createElement('input'), { type: 'range', min: -3, max: 3, step: 0.1, value: 0 });
    input.id = `batch-mode-${k + 1}`;
    const out = document.createElement('output');
    out.textContent = '0 σ';
    input.oninput = () => {
      batch.model.t[k] = Number(input.value);
      out.textContent = `${input.value} σ`;
      redraw();
    };
    label.style.display = 'block';
    label.append(`mode ${k + 1} `, input, ' ', out);
    box.append(label);
  }
}

function variancePlot(ve) {
  const x = ve.map((_, k) => k + 1);
  let sum = 0;
  const cum = ve.map((v) => (sum += v));
  const box = $('batch-variance');
  box.replaceChildren();
  // the whole width of its column, followed when the window changes
  const width = () => Math.max(280, box.clientWidth || 480);
  const plot = new uPlot({
    width: width(), height: 260,
    scales: { x: { time: false, range: [0.5, Math.max(1.5, ve.length + 0.5)] }, y: { range: [0, 1] } },
    series: [{ label: 'mode' }, { label: 'explained', stroke: '#3d7bd9', width: 2, points: { size: 8 } },
      { label: 'cumulative', stroke: '#d9503d', width: 2, dash: [4, 3], points: { size: 6 } }],
    axes: [{ label: 'mode', incrs: [1, 2, 5, 10], values: (u, vals) => vals.map((v) => (Number.isInteger(v) ? String(v) : '')) },
      { label: 'variance fraction', size: 60, values: (u, vals) => vals.map((v) => v.toFixed(1)) }],
  }, [x, ve, cum], box);
  const ro = new ResizeObserver(() => { if (Math.abs(plot.width - width()) > 2) plot.setSize({ width: width(), height: 260 }); });
  ro.observe(box);
  plot.ro = ro;
  return plot;
}

async function loadModel(id) {
  const r = await fetch(`v1/batches/${id}/model`, { headers: authHeaders() });
  if (!r.ok) return;
  const info = await r.json();
  const mean = meanMesh(await getText(`v1/batches/${id}/model/mean.mesh`));
  const nv = mean.xyz.length / mean.dim;
  const written = info.files.filter((f) => /^mode_\d+\.sol$/.test(f.name)).length;
  const n = Math.min(SLIDERS, written);
  const modes = [];
  for (let k = 1; k <= n; k++) modes.push(parseSolVectors(await getText(`v1/batches/${id}/model/mode_${k}.sol`), nv, mean.dim));
  const canvas = $('batch-view2d'), div = $('batch-view3d');
  canvas.hidden = mean.dim !== 2;
  div.hidden = mean.dim !== 3;
  const view = mean.dim === 2 ? new View2d(canvas) : new View3d(div);
  batch.model = { mean, modes, view, t: modes.map(() => 0), summary: info.summary };
  sliders(n);
  redraw();
  batch.plot = variancePlot(info.summary.variance_explained || []);
  $('batch-model').hidden = false;
}

// The first document (GET /v1/batches/{id}: its targets and their order),
// then the batch's event stream: "target" events update one row, "batch"
// events the whole batch's progress, the last "status" event carries the
// final document (the stream then closes). EventSource resumes a broken
// stream by itself, with the last "batch" event's id.
async function follow() {
  const id = batch.id;
  const r = await fetch(`v1/batches/${id}`, { headers: authHeaders() });
  if (batch.id !== id) return;
  if (!r.ok) {
    $('batch-error').textContent = (await r.json().catch(() => ({}))).detail || `HTTP ${r.status}`;
    return;
  }
  const doc = await r.json();
  batch.doc = doc;
  batch.firstStatus = doc.status;
  showTargets(doc);
  if (FINAL.has(doc.status)) {
    finished(id, doc);
    return;
  }
  const es = new EventSource(withToken(`v1/batches/${id}/events`));
  batch.es = es;
  const data = (e) => JSON.parse(e.data);
  es.addEventListener('target', (e) => {
    const t = data(e);
    const k = batch.doc.targets.findIndex((x) => x.jobID === t.jobID);
    if (k >= 0) {
      const { type, batchID, ...entry } = t; // eslint-disable-line no-unused-vars
      batch.doc.targets[k] = entry;
    }
  });
  es.addEventListener('batch', (e) => {
    const { status, progress, counts, eta } = data(e);
    Object.assign(batch.doc, { status, progress, counts, eta });
    showTargets(batch.doc);
  });
  es.addEventListener('status', (e) => {
    es.close();
    if (batch.id !== id) return;
    const { type, ...final } = data(e); // eslint-disable-line no-unused-vars
    batch.doc = final;
    showTargets(final);
    finished(id, final);
  });
  es.onerror = () => {
    if (es.readyState === EventSource.CLOSED && batch.id === id && !FINAL.has(batch.doc.status)) {
      $('batch-error').textContent = 'the batch\'s event stream was refused or lost; open the batch again';
    }
  };
}

async function finished(id, doc) {
  if (doc.status === 'successful') {
    await loadModel(id).catch((e) => { $('batch-error').textContent = String(e.message || e); });
  }
}

export function openBatch(id) {
  if (batch) { if (batch.es) batch.es.close(); batch.plot?.ro?.disconnect(); }
  batch = { id, es: null, doc: null, model: null, plot: null };
  $('batch-panel').hidden = false;
  $('batch-id').textContent = id;
  $('batch-error').textContent = '';
  $('batch-model').hidden = true;
  follow();
}

function fromHash() {
  const m = /batch=([0-9a-f]{32})/.exec(location.hash);
  if (m) openBatch(m[1]);
}

$('batch-open').onclick = () => {
  const id = $('batch-input').value.trim();
  if (/^[0-9a-f]{32}$/.test(id)) location.hash = `batch=${id}`;
  else $('batch-error').textContent = 'a batch id is 32 hexadecimal digits';
};
window.addEventListener('hashchange', fromHash);
fromHash();
