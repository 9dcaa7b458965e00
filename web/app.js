// The shapematch web app (served by shapematchd at /, issue 11): submit a
// job with the multipart parts of POST /v1/jobs, follow its event stream
// (uPlot: J and the RMS distances, result→target and target→result,
// against the iteration), draw the
// live and final shape (2D canvas for triangles, three.js for the boundary
// of tetrahedra, both coloured by |d| with a colour scale, the target's
// zero level set or surface overlaid), show the outcome (converged or not,
// and why) and every warning, download the results; landmark files and
// the alignment (align.js), warp through a finished job's map (warp.js).  Plain ES modules;
// every URL is relative to the page, so it also works behind a path
// prefix.  With a token: Authorization for fetch, access_token for
// EventSource and links.
import uPlot from './uplot.js';
import { View2d, View3d, parsePayload, heatCss, fmtNum, tickLabel } from './view.js';
import { loadTarget } from './target.js';
import { setupLandmarks, landmarkProblems, appendLandmarks, showAlignment } from './align.js';
import { warpPanel } from './warp.js';
import { openBatch } from './batch.js';

const $ = (id) => document.getElementById(id);
const token = () => $('token').value.trim();
const authHeaders = () => (token() ? { Authorization: `Bearer ${token()}` } : {});
const withToken = (path) => (token() ? `${path}${path.includes('?') ? '&' : '?'}access_token=${encodeURIComponent(token())}` : path);
const FILES = ['template', 'template_surface', 'template_image', 'target_mesh', 'target_sol', 'target_surface', 'target_image'];

let schema = null;
let current = null; // the job followed: {id, es, timer, plot, data, view, ...}
// for the browser tests: the job followed (its plot and views)
window.shapematch = { get current() { return current; } };

function errorSpan(name) { return document.querySelector(`.err[data-for="${CSS.escape(name)}"]`); }
function clearErrors() {
  document.querySelectorAll('.err').forEach((e) => { e.textContent = ''; });
  document.querySelectorAll('.invalid').forEach((e) => e.classList.remove('invalid'));
}
function showError(name, message) {
  const span = errorSpan(name);
  const input = document.querySelector(`[name="${CSS.escape(name)}"]`);
  if (input) input.classList.add('invalid');
  // a field of a folded section: unfold it, so that the message is seen
  const folded = (input || span)?.closest('details');
  if (folded) folded.open = true;
  if (span) span.textContent = message; else $('form-error').textContent = message;
}
const el = (tag, props = {}, ...children) => {
  const e = Object.assign(document.createElement(tag), props);
  e.append(...children);
  return e;
};

// ------------------------------------------------------------ the form

function resolve(prop) {
  if (prop && prop.$ref && prop.$ref.startsWith('#/$defs/')) return { ...schema.$defs[prop.$ref.slice(8)], ...prop };
  return prop;
}
// What a parameter's field is: number, enum, boolean, refs (a list of
// references), clamp (its own fields) or json (anything else).
function kindOf(name, p) {
  if (name === 'clamp') return 'clamp';
  if (p.type === 'number' || p.type === 'integer') return 'number';
  if (p.type === 'boolean') return 'boolean';
  if (p.enum) return 'enum';
  if (p.type === 'array' && p.items && (p.items.$ref === '#/$defs/ref' || p.items.type === 'integer')) return 'refs';
  return 'json';
}

// The clamp as fields: its kind, the ball's centre and radius, the
// references of the elements or vertices, alpha of kind none.
function clampFields(p) {
  const kinds = (p.properties && p.properties.kind && p.properties.kind.enum) || ['ball', 'elements', 'vertices', 'none', 'auto'];
  const kind = el('select', { id: 'p-clamp', name: 'params.clamp' }, ...kinds.map((k) => el('option', { value: k, textContent: k === 'auto' ? 'auto (a ball at the deepest point)' : k })));
  if (p.default && kinds.includes(p.default.kind)) kind.value = p.default.kind; // the schema's: auto
  const num = (id, label, ph) => el('label', { className: 'small' }, label, el('input', { id, type: 'text', inputMode: 'decimal', placeholder: ph }));
  const ball = el('div', { className: 'clamp-ball' }, num('p-clamp-x', 'centre x', '0'), num('p-clamp-y', 'y', '0'),
    num('p-clamp-z', 'z (3D)', '2D: empty'), num('p-clamp-radius', 'radius', 'e.g. 0.1'));
  const refs = el('div', { className: 'clamp-refs' }, el('label', {}, 'references (of the elements or vertices): numbers or Gmsh physical names',
    el('input', { id: 'p-clamp-refs', type: 'text', placeholder: 'e.g. 1, 2 or core' })));
  const none = el('div', { className: 'clamp-none' }, num('p-clamp-alpha', 'alpha (0th-order term)', '0: from the scale'));
  const show = () => { ball.hidden = kind.value !== 'ball'; refs.hidden = !['elements', 'vertices'].includes(kind.value); none.hidden = kind.value !== 'none'; };
  kind.addEventListener('change', show);
  show();
  return el('div', { className: 'row wide clamp' }, el('label', { title: p.description || '' }, 'clamp', kind), ball, refs, none);
}

function paramRow(name, prop) {
  const p = resolve(prop);
  const kind = kindOf(name, p);
  const required = (schema.required || []).includes(name);
  const err = el('span', { className: 'err' });
  err.dataset.for = `params.${name}`;
  if (kind === 'clamp') { const row = clampFields(p); row.append(err); return row; }
  const label = el('label', { textContent: `${name}${required ? ' (required)' : ''}`, title: p.description || '' });
  let input;
  if (kind === 'enum') {
    input = el('select', {}, el('option', { value: '', textContent: p.default !== undefined ? `default (${p.default})` : '' }),
      ...p.enum.map((v) => el('option', { value: String(v), textContent: String(v) })));
  } else if (kind === 'boolean') {
    input = el('select', {}, el('option', { value: '', textContent: `default (${p.default})` }),
      el('option', { value: 'true', textContent: 'true' }), el('option', { value: 'false', textContent: 'false' }));
  } else if (kind === 'json') {
    input = el('textarea', { placeholder: p.default !== undefined ? JSON.stringify(p.default) : 'JSON' });
  } else {
    input = el('input', { type: 'text' });
    if (kind === 'number') input.inputMode = 'decimal';
    input.placeholder = kind === 'refs' ? 'references or physical names, e.g. 1, 2 or cut' : p.default !== undefined ? String(p.default) : '';
  }
  input.name = `params.${name}`;
  input.id = `p-${name}`;
  label.append(input);
  const row = el('div', { className: kind === 'number' || kind === 'enum' || kind === 'boolean' ? 'row' : 'row wide' }, label, err);
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
  $('params').replaceChildren(...paramGroups());
}

// The parameters in the sections of the schema's x-groups (the parameter
// table's group column, core/sm_params.c), in its order: a fieldset each,
// a folded one (advanced) closed until opened.
function paramGroups() {
  const groups = schema['x-groups'] || [{ name: 'advanced', title: 'Parameters' }];
  const grids = new Map();
  const boxes = groups.map((g) => {
    const grid = el('div', { className: 'param-grid' });
    grids.set(g.name, grid);
    const box = g.folded ? el('details', {}, el('summary', { textContent: g.title }), grid)
      : el('fieldset', {}, el('legend', { textContent: g.title }), grid);
    box.className = 'param-group';
    box.dataset.group = g.name;
    return box;
  });
  for (const [name, prop] of Object.entries(schema.properties))
    (grids.get(prop['x-group']) || grids.get('advanced') || [...grids.values()].pop()).append(paramRow(name, prop));
  return boxes.filter((b) => b.querySelector('.row'));
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

// "1, 2, rim edge" -> [1, 2, "rim edge"]: integers as numbers, anything
// else as a Gmsh physical name (which may hold spaces), resolved by the
// daemon against the template (its 422 lists the names it has).
function parseRefs(text) {
  return text.split(/[,;]/).map((t) => t.trim()).filter(Boolean).map((t) => (/^[-+]?\d+$/.test(t) ? Number(t) : t));
}

// The clamp object from its fields, or a string saying what is wrong.
function collectClamp() {
  const kind = $('p-clamp').value;
  const val = (id) => $(id).value.trim();
  if (kind === 'ball') {
    const coords = ['p-clamp-x', 'p-clamp-y', 'p-clamp-z'].map(val);
    if (!coords[2]) coords.pop();
    if (!coords[0] || !coords[1] || !val('p-clamp-radius')) return 'clamp: a ball needs its centre (x, y and, in 3D, z) and its radius';
    const center = coords.map(Number);
    const radius = Number(val('p-clamp-radius'));
    if (![...center, radius].every(Number.isFinite)) return 'clamp: the centre and the radius must be numbers';
    return { kind, center, radius };
  }
  if (kind === 'elements' || kind === 'vertices') {
    const refs = parseRefs(val('p-clamp-refs'));
    if (!refs.length) return `clamp: give the references of the ${kind} to clamp`;
    return { kind, refs };
  }
  const clamp = { kind };
  if (kind === 'none' && val('p-clamp-alpha')) {
    clamp.alpha = Number(val('p-clamp-alpha'));
    if (!Number.isFinite(clamp.alpha)) return 'clamp: alpha must be a number';
  }
  return clamp;
}

function collectParams() {
  const params = {};
  let ok = true;
  for (const [name, prop] of Object.entries(schema.properties)) {
    const p = resolve(prop);
    const kind = kindOf(name, p);
    if (kind === 'clamp') {
      const c = collectClamp();
      if (typeof c === 'string') { showError('params.clamp', c); ok = false; } else params.clamp = c;
      continue;
    }
    const text = $(`p-${name}`).value.trim();
    if (!text) continue;
    if (kind === 'number') {
      const why = checkNumber(p, text);
      if (why) { showError(`params.${name}`, `${name}: ${why}`); ok = false; continue; }
      params[name] = Number(text);
    } else if (kind === 'enum') {
      params[name] = p.enum.find((v) => String(v) === text);
    } else if (kind === 'boolean') {
      params[name] = text === 'true';
    } else if (kind === 'refs') {
      params[name] = parseRefs(text);
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
  const lm = landmarkProblems(params.align);
  for (const [field, message] of lm) showError(field, message);
  if (lm.length) return;
  const fd = new FormData();
  for (const f of FILES) {
    const file = $(`f-${f}`).files[0];
    if (file) fd.append(f, file, file.name);
  }
  appendLandmarks(fd);
  fd.append('params', JSON.stringify(params));
  const name = $('f-name').value.trim();
  if (name) fd.append('name', name);
  $('submit').disabled = true;
  try {
    const r = await fetch('v1/jobs', { method: 'POST', body: fd, headers: authHeaders() });
    const body = await r.json().catch(() => ({}));
    if (r.status === 201 || r.status === 200) follow(body.jobID, name);
    else showProblem({ status: r.status, ...body });
  } catch (e) {
    $('form-error').textContent = `the request failed: ${e.message}`;
  } finally {
    $('submit').disabled = false;
    refreshJobs();
  }
}

// ------------------------------------------------------------ the plot

function newPlot() {
  const box = $('plot');
  box.replaceChildren();
  const data = [[], [], [], []];
  const width = () => Math.max(240, box.clientWidth || 480);
  const plot = new uPlot({
    width: width(), height: 220,
    scales: { x: { time: false }, y: {}, e: { distr: 3 } }, // J changes sign: linear
    series: [{ label: 'iteration' }, { label: 'J', stroke: '#3d7bd9', scale: 'y', value: (u, v) => (v == null ? '–' : v.toPrecision(6)) },
      { label: 'result→target RMS', stroke: '#d9503d', scale: 'e', value: (u, v) => (v == null ? '–' : tickLabel(v)) },
      { label: 'target→result RMS', stroke: '#8a4fd0', dash: [5, 3], scale: 'e', value: (u, v) => (v == null ? '–' : tickLabel(v)) }],
    // iterations are whole numbers: ticks at 1, 2, 5, 10, ... apart
    axes: [{ incrs: [0, 1, 2, 3, 4, 5, 6, 7, 8].flatMap((k) => [1, 2, 5].map((m) => m * 10 ** k)) }, { scale: 'y', label: 'J', size: 70, values: (u, vals) => vals.map((v) => (v === null ? '' : v.toPrecision(4))) },
      { scale: 'e', side: 1, label: 'distance RMS', size: 60, grid: { show: false }, values: (u, vals) => vals.map(tickLabel) }],
  }, data, box);
  // the plot follows its panel's width (800 px windows, resized windows)
  const ro = new ResizeObserver(() => { if (Math.abs(plot.width - width()) > 2) plot.setSize({ width: width(), height: 220 }); });
  ro.observe(box);
  return { plot, data, ro };
}

// ------------------------------------------------------------ outcome

function setStatus(status, extra) {
  $('status').textContent = status;
  $('status').dataset.status = status;
  if (extra !== undefined) $('stop-reason').textContent = extra;
}

const STOP_TEXT = {
  max_iterations: 'the iteration cap (max_iter) was reached',
  quality_blocked: 'the quality floor (min_quality) rejected every step',
  step_tolerance: 'the step fell below tol_step',
  stalled: 'the L2 norm of d on the boundary stopped improving (tol_stall)',
  boundary_tolerance: 'the L2 norm of d on the boundary reached tol_boundary',
  cancelled: 'cancelled',
};
// "not converged: <reason>" from the results summary: the stop reason and
// how far the boundary error is from what the background resolves.
function notConvergedReason(s) {
  const parts = [STOP_TEXT[s.stop_reason] ? `${STOP_TEXT[s.stop_reason]} (${s.stop_reason})` : `stopped: ${s.stop_reason}`];
  if (s.boundary_rms != null && s.resolution > 0)
    parts.push(`boundary RMS ${fmtNum(s.boundary_rms)} is ${(s.boundary_rms / s.resolution).toFixed(1)}× the background resolution ${fmtNum(s.resolution)}`);
  return parts.join('; ');
}

function showOutcome(kind, text) {
  const o = $('outcome');
  o.dataset.outcome = kind;
  o.textContent = text;
  o.hidden = !kind;
}

// Warnings by code: live warning events, then the summary's list (the
// complete one) replaces them.
function showWarnings(list) {
  const ul = $('warnings');
  ul.replaceChildren(...list.map((w) => {
    const li = el('li', {}, el('code', { textContent: w.code || 'warning' }), ` ${w.message || ''}`);
    li.dataset.code = w.code || '';
    return li;
  }));
  ul.hidden = list.length === 0;
  $('warnings-title').hidden = list.length === 0;
  $('warnings-title').textContent = list.length === 1 ? '1 warning' : `${list.length} warnings`;
}

// The figures of a summary, by their names there, in groups: the
// two-sided distances (distance.result_to_target and .target_to_result:
// RMS, max, p99, in the meshes' unit) when the summary has them, else the
// RMS and max of d on the boundary; the L2 norm under its own name.
// [[group label, [[name, label, value], ...]], ...].
function figures(s) {
  const groups = [];
  const d = s.distance;
  if (d && d.result_to_target && d.target_to_result) {
    for (const [side, label] of [['result_to_target', 'result→target'], ['target_to_result', 'target→result']])
      groups.push([label, ['rms', 'max', 'p99'].filter((k) => d[side][k] != null)
        .map((k) => [`distance.${side}.${k}`, k === 'rms' ? 'RMS' : k, d[side][k]])]);
  } else if (s.boundary_rms != null) {
    groups.push(['boundary', [['boundary_rms', 'RMS', s.boundary_rms]]
      .concat(s.boundary_max != null ? [['boundary_max', 'max', s.boundary_max]] : [])]);
  }
  if (groups.length && s.boundary_l2 != null) groups.push(['', [['boundary_l2', 'L2 of d on the boundary', s.boundary_l2]]]);
  return groups;
}

// The headline: each figure a span that names its summary member (the
// browser tests read them back), then the unit and the iterations.
function headline(s) {
  const groups = figures(s);
  if (!groups.length) return [];
  const parts = [];
  groups.forEach(([group, figs], g) => {
    parts.push(g ? '; ' : '', group ? `${group} ` : '');
    figs.forEach(([name, label, v], i) => {
      const span = el('span', { className: 'figure', textContent: fmtNum(v) });
      span.dataset.figure = name;
      span.dataset.value = String(v);
      parts.push(i ? ', ' : '', `${label} `, span);
    });
  });
  // the meshes carry no unit: the distances are in theirs (unit null)
  const unit = s.distance ? ` (${s.distance.unit || 'in the meshes\' unit'})` : '';
  parts.push(`${unit}; ${s.iterations} iterations`);
  return parts;
}

// ------------------------------------------------------------ following

function stopFollowing() {
  if (!current) return;
  current.es?.close();
  clearInterval(current.timer);
  cancelAnimationFrame(current.frame);
  current.ro?.disconnect();
  current.view?.dispose?.();
  current.done = true;
}

// The binary payload (coordinates, elements and |d| at the vertices).
async function getMesh(path) {
  const r = await fetch(path, { headers: { ...authHeaders(), Accept: 'application/vnd.shapematch.mesh' } });
  if (!r.ok) return null;
  return parsePayload(await r.arrayBuffer());
}

// The colour scale under the view: 0 to the largest value shown.
function showScale(scale) {
  const box = $('scale');
  box.hidden = !scale;
  if (!scale) return;
  $('scale-bar').style.background = `linear-gradient(to right, ${[0, 0.25, 0.5, 0.75, 1].map(heatCss).join(', ')})`;
  $('scale-min').textContent = '0';
  $('scale-max').textContent = tickLabel(scale.max);
  $('scale-label').textContent = scale.label;
  box.dataset.max = String(scale.max);
}

// The target overlay, loaded once per job from its stored inputs (the
// first shape drawn says the dimension); the shape is drawn again with it.
function overlayTarget(job, dim) {
  job.targetState = 'loading';
  const note = $('target-note');
  $('target-toggle').hidden = false;
  $('show-target').disabled = true;
  note.textContent = '(loading)';
  loadTarget((url) => fetch(url, { headers: authHeaders() }), job.id, dim).then((t) => {
    if (job !== current) return;
    job.target = t;
    job.targetState = 'shown';
    $('show-target').disabled = false;
    note.textContent = `(${t.what})`;
    job.view.setTarget(t, $('show-target').checked);
    if (job.last) draw(job.last.mesh, job.last.final);
  }).catch((e) => {
    if (job !== current) return;
    job.targetState = 'none';
    note.textContent = `not drawn: ${e.message}`;
  }).finally(() => { if (job === current) $('target-toggle').dataset.state = job.targetState; });
}

function draw(mesh, final) {
  if (!mesh || !current) return;
  const is3d = mesh.dim === 3 && mesh.tets.length > 0;
  $('view2d').hidden = is3d;
  $('view3d').hidden = !is3d;
  if (!current.view) current.view = is3d ? new View3d($('view3d')) : new View2d($('view2d'));
  $('reset-view').hidden = !is3d;
  current.last = { mesh, final };
  if (!current.targetState) overlayTarget(current, mesh.dim);
  const scale = current.view.show(mesh);
  showScale(scale);
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
    const a = el('a', { href: withToken(base + suffix), download: name, textContent: name });
    a.dataset.file = name;
    return a;
  }));
}

async function finish(id) {
  const job = current;
  const r = await fetch(`v1/jobs/${id}`, { headers: authHeaders() });
  const doc = await r.json().catch(() => ({}));
  if (job === current && doc.name) $('job-name').textContent = doc.name;
  let reason = doc.message || '';
  // results exist for a finished run: successful, or one whose status
  // document says it did not converge (whatever status that is given)
  if (doc.status === 'successful' || doc.converged === false) {
    const s = await fetch(`v1/jobs/${id}/results`, { headers: authHeaders() }).then((x) => x.json()).catch(() => ({}));
    if (job !== current) return;
    job.summary = s;
    if (s.stop_reason) reason = `stop: ${s.stop_reason}`;
    $('headline').replaceChildren(...headline(s));
    if (s.converged === true) showOutcome('converged', 'converged');
    else if (s.converged === false) showOutcome('not-converged', `not converged: ${notConvergedReason(s)}`);
    if (Array.isArray(s.warnings)) showWarnings(s.warnings);
    if (s.alignment) showAlignment($('alignment'), s.alignment);
    draw(await getMesh(`v1/jobs/${id}/results/mesh?format=binary`), true);
    downloads(id);
    if (doc.status === 'successful') warpPanel($('warp'), id, (url, init) => fetch(url, { ...init, headers: { ...init.headers, ...authHeaders() } }));
  }
  if (doc.status === 'failed' && !job.summary?.stop_reason) {
    showOutcome('failed', `failed: ${doc.message || 'see the job\'s events'}`);
  } else if (doc.status === 'dismissed') {
    showOutcome('dismissed', 'cancelled');
  }
  if (job === current) setStatus(doc.status || 'unknown', reason);
  refreshJobs();
}

function follow(id, name) {
  stopFollowing();
  const { plot, data, ro } = newPlot();
  current = { id, plot, data, ro, done: false, view: null, target: null, targetState: null, warnings: [] };
  $('target-toggle').hidden = true;
  $('target-note').textContent = '';
  delete $('target-toggle').dataset.state;
  $('job-id').textContent = id;
  $('job-name').textContent = name || '';
  for (const v of [$('view2d'), $('view3d')]) { delete v.dataset.liveDraws; delete v.dataset.drawn; }
  $('view3d').replaceChildren();
  $('downloads').replaceChildren();
  $('headline').replaceChildren();
  showOutcome('', '');
  showWarnings([]);
  showAlignment($('alignment'), null);
  warpPanel($('warp'), null);
  showScale(null);
  $('reset-view').hidden = true;
  setStatus('accepted', '');
  const job = current;
  const es = new EventSource(withToken(`v1/jobs/${id}/events`));
  job.es = es;
  es.addEventListener('started', () => setStatus('running'));
  es.addEventListener('alignment', (e) => { if (job === current && !job.summary) showAlignment($('alignment'), JSON.parse(e.data)); });
  es.addEventListener('warning', (e) => {
    const w = JSON.parse(e.data);
    if (job !== current || job.summary || job.warnings.some((x) => x.code === w.code)) return;
    job.warnings.push(w);
    showWarnings(job.warnings);
  });
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
    // the RMS distances (lengths): from the result's boundary (today's
    // boundary_rms) and, when the event has it, from the target's surface
    const d = p.distance;
    data[0].push(p.iteration); data[1].push(p.J);
    data[2].push(d?.result_to_target?.rms ?? p.boundary_rms ?? p.boundary_l2);
    data[3].push(d?.target_to_result?.rms ?? null);
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

// The batch view of a model job (web/batch.js), by its #batch=ID address
// (a reload keeps it); the same address again opens it anew.
function showBatch(id) {
  if (location.hash === `#batch=${id}`) openBatch(id);
  else location.hash = `batch=${id}`;
}

async function refreshJobs() {
  if (needsToken()) return;
  const r = await fetch('v1/jobs?limit=20', { headers: authHeaders() });
  if (!r.ok) { $('jobs').replaceChildren(); return; }
  const list = await r.json();
  $('jobs').replaceChildren(...(list.jobs || []).map((j) => {
    const td = (t) => el('td', { textContent: t });
    // a batch's model job has no match result to show: its batch view instead
    const model = j.processID === 'shape-model';
    const view = el('button', { type: 'button', textContent: model ? 'batch' : 'view' });
    view.dataset.action = model ? 'batch' : 'view';
    view.onclick = model ? () => showBatch(j.jobID) : () => { follow(j.jobID, j.name); };
    const actions = el('td', {}, view);
    if (j.status === 'accepted' || j.status === 'running') {
      const cancel = el('button', { type: 'button', textContent: 'cancel' });
      cancel.onclick = async () => { await fetch(`v1/jobs/${j.jobID}`, { method: 'DELETE', headers: authHeaders() }); refreshJobs(); };
      actions.append(cancel);
    }
    // the whole id: the one `shapematch status|wait|fetch` takes
    const id = el('td', {}, el('code', { className: 'job-id', textContent: j.jobID }));
    const name = td(j.name || '');
    name.className = 'job-name';
    return el('tr', {}, id, name, td(j.status), actions);
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
        : /\.(nii|nrrd|mha)(\.gz)?$/.test(n) ? (n.includes('template') ? 'template_image' : 'target_image')
        : /\.(stl|obj|ply|off)(\.gz)?$/.test(n) && n.includes('template') ? 'template_surface'
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
$('reset-view').addEventListener('click', () => current?.view?.reset());
$('show-target').addEventListener('change', () => {
  if (!current?.view || !current.target) return;
  current.view.setTarget(current.target, $('show-target').checked);
  if (current.last) draw(current.last.mesh, current.last.final);
});
$('token').addEventListener('change', () => { loadSchema(); refreshJobs(); });
setupDrop();
setupLandmarks();
loadSchema();
refreshJobs();
