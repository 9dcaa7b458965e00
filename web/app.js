// The shapematch web app (served by shapematchd at /, issue 11): submit a
// job with the multipart parts of POST /v1/jobs, follow its event stream
// (uPlot: J and the boundary error against the iteration), draw the live
// and final shape (2D canvas for triangles, three.js for the boundary of
// tetrahedra), download the results.  Plain ES modules; every URL is
// relative to the page, so it also works behind a path prefix.  With a
// token: Authorization for fetch, access_token for EventSource and links.
import uPlot from './uplot.js';
import { drawMesh2d, View3d, parsePayload } from './view.js';

const $ = (id) => document.getElementById(id);
const token = () => $('token').value.trim();
const authHeaders = () => (token() ? { Authorization: `Bearer ${token()}` } : {});
const withToken = (path) => (token() ? `${path}${path.includes('?') ? '&' : '?'}access_token=${encodeURIComponent(token())}` : path);
const FILES = ['template', 'target_mesh', 'target_sol', 'target_surface'];

let schema = null;
let current = null; // the job followed: {id, es, timer, plot, data, view3d, first}

function errorSpan(name) { return document.querySelector(`.err[data-for="${CSS.escape(name)}"]`); }
function clearErrors() {
  document.querySelectorAll('.err').forEach((e) => { e.textContent = ''; });
  document.querySelectorAll('.invalid').forEach((e) => e.classList.remove('invalid'));
}
function showError(name, message) {
  const span = errorSpan(name);
  const input = document.querySelector(`[name="${CSS.escape(name)}"]`);
  if (input) input.classList.add('invalid');
  if (span) span.textContent = message; else $('form-error').textContent = message;
}

// ------------------------------------------------------------ the form

function resolve(prop) {
  if (prop && prop.$ref && prop.$ref.startsWith('#/$defs/')) return { ...schema.$defs[prop.$ref.slice(8)], ...prop };
  return prop;
}

function paramRow(name, prop) {
  const p = resolve(prop);
  const row = document.createElement('div');
  row.className = p.type === 'number' || p.type === 'integer' ? 'row' : 'row wide';
  const label = document.createElement('label');
  const required = (schema.required || []).includes(name);
  const scalar = p.type === 'number' || p.type === 'integer';
  label.textContent = `${name}${required ? ' (required)' : ''}`;
  label.title = p.description || '';
  const input = document.createElement(scalar ? 'input' : 'textarea');
  input.name = `params.${name}`;
  input.id = `p-${name}`;
  if (scalar) {
    input.type = 'text';
    input.inputMode = 'decimal';
    if (p.default !== undefined) input.placeholder = String(p.default);
  } else {
    input.placeholder = p.default !== undefined ? JSON.stringify(p.default) : 'JSON, e.g. {"kind": "ball", "center": [0, 0], "radius": 0.1}';
  }
  label.append(input);
  const err = document.createElement('span');
  err.className = 'err';
  err.dataset.for = `params.${name}`;
  row.append(label, err);
  return row;
}

// The page says whether the daemon wants a token (data-tokens="1", set by
// the daemon when it serves it): then nothing is asked before one is typed.
const needsToken = () => document.documentElement.dataset.tokens === '1' && !token();

async function loadSchema() {
  if (schema) return;
  if (needsToken()) { $('params').innerHTML = '<p>This daemon requires a token: type it above.</p>'; return; }
  const r = await fetch('v1/params.schema.json', { headers: authHeaders() });
  if (!r.ok) { $('params').innerHTML = `<p class="err">cannot load the parameters schema (${r.status})</p>`; return; }
  schema = await r.json();
  const fs = $('params');
  fs.replaceChildren(Object.assign(document.createElement('legend'), { textContent: 'Parameters' }));
  for (const [name, prop] of Object.entries(schema.properties)) fs.append(paramRow(name, prop));
}

// The client-side check of one value against its schema (numbers only;
// the server's check is the one that counts).
function checkNumber(p, text) {
  const v = Number(text);
  if (!Number.isFinite(v)) return 'must be a number';
  if (p.type === 'integer' && !Number.isInteger(v)) return 'must be an integer';
  if (p.minimum !== undefined && v < p.minimum) return `must be >= ${p.minimum}`;
  if (p.maximum !== undefined && v > p.maximum) return `must be <= ${p.maximum}`;
  if (p.exclusiveMinimum !== undefined && v <= p.exclusiveMinimum) return `must be > ${p.exclusiveMinimum}`;
  if (p.exclusiveMaximum !== undefined && v >= p.exclusiveMaximum) return `must be < ${p.exclusiveMaximum}`;
  return null;
}

function collectParams() {
  const params = {};
  let ok = true;
  for (const [name, prop] of Object.entries(schema.properties)) {
    const p = resolve(prop);
    const text = $(`p-${name}`).value.trim();
    if (!text) continue;
    if (p.type === 'number' || p.type === 'integer') {
      const why = checkNumber(p, text);
      if (why) { showError(`params.${name}`, `${name}: ${why}`); ok = false; continue; }
      params[name] = Number(text);
    } else {
      try { params[name] = JSON.parse(text); } catch (e) { showError(`params.${name}`, `${name}: not JSON (${e.message})`); ok = false; }
    }
  }
  for (const name of schema.required || [])
    if (!(name in params) && ok) { showError(`params.${name}`, `${name}: required`); ok = false; }
  return ok ? params : null;
}

// A problem+json's invalid-params next to their fields: "params.clamp.radius" -> params.clamp.
function showProblem(problem) {
  const shown = [];
  for (const ip of problem['invalid-params'] || []) {
    const parts = String(ip.name || '').split('.');
    const field = parts[0] === 'params' && parts.length > 1 ? `params.${parts[1]}` : parts[0];
    if (errorSpan(field)) { showError(field, problem.detail || ip.reason); shown.push(field); }
  }
  if (!shown.length) $('form-error').textContent = problem.detail || problem.title || `HTTP ${problem.status}`;
}

async function submit(ev) {
  ev.preventDefault();
  clearErrors();
  if (!schema) await loadSchema();
  const params = collectParams();
  if (!params) return;
  const fd = new FormData();
  for (const f of FILES) {
    const file = $(`f-${f}`).files[0];
    if (file) fd.append(f, file, file.name);
  }
  fd.append('params', JSON.stringify(params));
  $('submit').disabled = true;
  try {
    const r = await fetch('v1/jobs', { method: 'POST', body: fd, headers: authHeaders() });
    const body = await r.json().catch(() => ({}));
    if (r.status === 201 || r.status === 200) follow(body.jobID);
    else showProblem({ status: r.status, ...body });
  } catch (e) {
    $('form-error').textContent = `the request failed: ${e.message}`;
  } finally {
    $('submit').disabled = false;
    refreshJobs();
  }
}

// ------------------------------------------------------------ following

function newPlot() {
  const el = $('plot');
  el.replaceChildren();
  const data = [[], [], []];
  const plot = new uPlot({
    width: Math.min(el.clientWidth || 480, 640), height: 220,
    scales: { x: { time: false }, y: {}, e: { distr: 3 } }, // J changes sign: linear
    series: [{ label: 'iteration' }, { label: 'J', stroke: '#3d7bd9', scale: 'y' }, { label: 'boundary error', stroke: '#d9503d', scale: 'e' }],
    axes: [{}, { scale: 'y', label: 'J', size: 70, values: (u, vals) => vals.map((v) => v.toPrecision(4)) }, { scale: 'e', side: 1, label: '‖d‖ boundary', grid: { show: false } }],
  }, data, el);
  return { plot, data };
}

function setStatus(status, extra) {
  $('status').textContent = status;
  $('status').dataset.status = status;
  if (extra !== undefined) $('stop-reason').textContent = extra;
}

function stopFollowing() {
  if (!current) return;
  current.es?.close();
  clearInterval(current.timer);
  cancelAnimationFrame(current.frame);
  current.done = true;
}

// The binary payload (coordinates, elements and |d| at the vertices).
async function getMesh(path) {
  const r = await fetch(path, { headers: { ...authHeaders(), Accept: 'application/vnd.shapematch.mesh' } });
  if (!r.ok) return null;
  return parsePayload(await r.arrayBuffer());
}

function draw(mesh, final) {
  if (!mesh || !current) return;
  if (!current.first) current.first = mesh;
  const is3d = mesh.dim === 3 && mesh.tets.length > 0;
  $('view2d').hidden = is3d;
  $('view3d').hidden = !is3d;
  if (is3d) {
    if (!current.view3d) current.view3d = new View3d($('view3d'));
    current.view3d.show(mesh, current.first);
  } else {
    drawMesh2d($('view2d'), mesh);
  }
  const view = is3d ? $('view3d') : $('view2d');
  view.dataset.drawn = final ? 'final' : 'live';
  if (!final) view.dataset.liveDraws = String(Number(view.dataset.liveDraws || 0) + 1);
  view.dataset.elements = String(is3d ? mesh.tets.length / 4 : mesh.tris.length / 3);
}

function downloads(id) {
  const base = `v1/jobs/${id}/results`;
  const items = [['summary.json', ''], ['result.mesh', '/mesh?format=mesh'], ['result.meshb', '/mesh?format=meshb'],
    ['result.vtu', '/mesh?format=vtu'], ['displacement.sol', '/displacement?format=sol'],
    ['displacement.solb', '/displacement?format=solb'], ['history.csv', '/history?format=csv'], ['history.json', '/history?format=json']];
  $('downloads').replaceChildren(...items.map(([name, suffix]) => {
    const a = document.createElement('a');
    a.href = withToken(base + suffix);
    a.download = name;
    a.textContent = name;
    a.dataset.file = name;
    return a;
  }));
}

async function finish(id) {
  const job = current;
  const r = await fetch(`v1/jobs/${id}`, { headers: authHeaders() });
  const doc = await r.json().catch(() => ({}));
  let reason = doc.message || '';
  if (doc.status === 'successful') {
    const s = await fetch(`v1/jobs/${id}/results`, { headers: authHeaders() }).then((x) => x.json()).catch(() => ({}));
    if (s.stop_reason) reason = `stop: ${s.stop_reason}`;
    draw(await getMesh(`v1/jobs/${id}/results/mesh?format=binary`), true);
    downloads(id);
  }
  if (job === current) setStatus(doc.status || 'unknown', reason);
  refreshJobs();
}

function follow(id) {
  stopFollowing();
  const { plot, data } = newPlot();
  current = { id, plot, data, first: null, done: false };
  $('job-id').textContent = id;
  for (const v of [$('view2d'), $('view3d')]) { delete v.dataset.liveDraws; delete v.dataset.drawn; }
  $('downloads').replaceChildren();
  setStatus('accepted', '');
  const job = current;
  const es = new EventSource(withToken(`v1/jobs/${id}/events`));
  job.es = es;
  es.addEventListener('started', () => setStatus('running'));
  // The live shape: fetched as soon as there is one, then at most every
  // LIVE_MS while the job runs.  The worker publishes at its first
  // iteration: by the second progress event there is a shape (no 404
  // result-not-ready to log).
  const LIVE_MS = 500;
  const fetchLive = async () => {
    if (job.done || job.busy || data[0].length < 2 || Date.now() - (job.liveAt || 0) < LIVE_MS) return;
    job.busy = true;
    job.liveAt = Date.now();
    try { const m = await getMesh(`v1/jobs/${id}/mesh/latest`); if (!job.done) draw(m, false); } finally { job.busy = false; }
  };
  // A fast job sends thousands of progress events a second: the plot is
  // redrawn once per frame, not once per event, so the page keeps up.
  const redraw = () => {
    job.frame = 0;
    plot.setData(data);
    $('plot').dataset.points = String(data[0].length);
    $('iteration').textContent = data[0][data[0].length - 1];
  };
  es.addEventListener('progress', (e) => {
    const p = JSON.parse(e.data);
    data[0].push(p.iteration); data[1].push(p.J); data[2].push(p.boundary_l2);
    if (!job.frame) job.frame = requestAnimationFrame(redraw);
    if ($('status').dataset.status !== 'running') setStatus('running');
    fetchLive();
  });
  es.addEventListener('failed', (e) => setStatus('failed', JSON.parse(e.data).message || ''));
  es.addEventListener('status', () => { es.close(); clearInterval(job.timer); if (!job.done) finish(id); job.done = true; });
  es.onerror = () => { if (es.readyState === EventSource.CLOSED && !job.done) { job.done = true; finish(id); } };
  job.timer = setInterval(fetchLive, LIVE_MS);
}

// ------------------------------------------------------------ job list

async function refreshJobs() {
  if (needsToken()) return;
  const r = await fetch('v1/jobs?limit=20', { headers: authHeaders() });
  if (!r.ok) { $('jobs').replaceChildren(); return; }
  const list = await r.json();
  $('jobs').replaceChildren(...(list.jobs || []).map((j) => {
    const tr = document.createElement('tr');
    const td = (t) => Object.assign(document.createElement('td'), { textContent: t });
    const view = Object.assign(document.createElement('button'), { type: 'button', textContent: 'view' });
    view.onclick = () => { follow(j.jobID); };
    const actions = document.createElement('td');
    actions.append(view);
    if (j.status === 'accepted' || j.status === 'running') {
      const cancel = Object.assign(document.createElement('button'), { type: 'button', textContent: 'cancel' });
      cancel.onclick = async () => { await fetch(`v1/jobs/${j.jobID}`, { method: 'DELETE', headers: authHeaders() }); refreshJobs(); };
      actions.append(cancel);
    }
    tr.append(td(j.jobID.slice(0, 8)), td(j.status), actions);
    return tr;
  }));
}

// ------------------------------------------------------------ drag and drop

function setupDrop() {
  const drop = $('drop');
  const form = $('job-form');
  form.addEventListener('dragover', (e) => { e.preventDefault(); drop.classList.add('over'); });
  form.addEventListener('dragleave', () => drop.classList.remove('over'));
  form.addEventListener('drop', (e) => {
    e.preventDefault();
    drop.classList.remove('over');
    // a dropped file goes to the field its name says (background.sol -> target_sol, ...)
    for (const file of e.dataTransfer.files) {
      const n = file.name.toLowerCase();
      const part = /\.solb?(\.gz)?$/.test(n) ? 'target_sol'
        : /\.(stl|obj)(\.gz)?$/.test(n) || n.includes('surface') ? 'target_surface'
        : n.includes('template') ? 'template' : 'target_mesh';
      const dt = new DataTransfer();
      dt.items.add(file);
      $(`f-${part}`).files = dt.files;
    }
  });
}

$('job-form').addEventListener('submit', submit);
$('refresh').addEventListener('click', refreshJobs);
$('token').addEventListener('change', () => { loadSchema(); refreshJobs(); });
setupDrop();
loadSchema();
refreshJobs();
