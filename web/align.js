// Pre-alignment in the web app (issue 22): the landmark parts of a job
// (template_landmarks, target_landmarks: CSV, one point a row, matching
// row for row) and the job's alignment shown in the outcome panel (the
// "alignment" event while it runs, summary.json's "alignment" block once
// it is over).  The form's hints are only hints: what the daemon checks
// (enough points for the dimension, not collinear, numbers) comes back as
// its problem+json detail next to the landmark field.
export const LANDMARK_PARTS = ['template_landmarks', 'target_landmarks'];

// The daemon refuses a landmark part over 1 MiB; the hint reads no more.
const HINT_BYTES = 1 << 20;

const $ = (id) => document.getElementById(id);
const fileOf = (part) => $(`f-${part}`)?.files[0] || null;

// What a landmark CSV looks like, for the hint under its field: its rows
// of numbers and how many coordinates they have.  {rows, cols} or
// {error}; a header line (not all numbers) and '#' comments are skipped,
// as the daemon's reader does.
export function describeCsv(text) {
  let rows = 0;
  const cols = new Set();
  const lines = text.split(/\r?\n/);
  for (let i = 0; i < lines.length; i++) {
    const line = lines[i].trim();
    if (!line || line.startsWith('#')) continue;
    const cells = line.split(',').map((c) => c.trim());
    const numbers = cells.every((c) => c !== '' && Number.isFinite(Number(c)));
    if (!numbers) {
      if (rows === 0) continue; // a header
      return { error: `line ${i + 1} is not numbers` };
    }
    cols.add(cells.length);
    rows++;
  }
  if (cols.size > 1) return { error: `rows of ${[...cols].join(' and ')} coordinates` };
  return { rows, cols: [...cols][0] || 0 };
}

// The hint of one landmark field, from its file (read once per choice).
const described = new Map();
async function hint(part) {
  const span = document.querySelector(`.hint[data-for="${part}"]`);
  const file = fileOf(part);
  described.delete(part);
  if (!span) return;
  span.textContent = '';
  if (!file) return;
  if (file.size > HINT_BYTES) { span.textContent = `${file.size} bytes: over the daemon's 1 MiB for a landmark file`; return; }
  const d = describeCsv(await file.text());
  if (fileOf(part) !== file) return; // chosen again meanwhile
  described.set(part, d);
  span.textContent = d.error ? `not a landmark CSV: ${d.error}` : `${d.rows} point${d.rows === 1 ? '' : 's'} of ${d.cols} coordinates`;
}

export function setupLandmarks() {
  for (const part of LANDMARK_PARTS) $(`f-${part}`).addEventListener('change', () => hint(part));
}

// The form's checks before a submit: [[field, message], ...].  Both files
// or none; an alignment to start; the same number of rows when both are
// read.  The daemon checks the rest.
export function landmarkProblems(align) {
  const given = LANDMARK_PARTS.filter((p) => fileOf(p));
  if (given.length === 0) return [];
  if (given.length === 1) {
    const missing = LANDMARK_PARTS.find((p) => !fileOf(p));
    return [[missing, `${missing}: give both landmark files (the template's points and where they are on the target, row for row), or neither`]];
  }
  if (!align || align === 'none')
    return [['params.align', 'align: landmarks start an alignment: choose rigid, similarity or affine (or leave the landmark files out)']];
  const [a, b] = LANDMARK_PARTS.map((p) => described.get(p));
  if (a && b && !a.error && !b.error && a.rows !== b.rows)
    return [['target_landmarks', `target_landmarks: ${b.rows} points, and template_landmarks has ${a.rows}: the rows must match`]];
  return [];
}

export function appendLandmarks(fd) {
  for (const part of LANDMARK_PARTS) {
    const file = fileOf(part);
    if (file) fd.append(part, file, file.name);
  }
}

// ------------------------------------------------------------ the result

const num = (x) => (x == null ? '–' : Math.abs(x) >= 1e4 || (Math.abs(x) < 1e-3 && x !== 0) ? x.toExponential(3) : String(Number(x.toPrecision(6))));

// The alignment block: a (the event's or the summary's alignment) or null
// to hide it.  The summary's has the matrix (row-major, homogeneous,
// template -> target) and the landmark count.
export function showAlignment(box, a) {
  box.replaceChildren();
  box.hidden = !a;
  if (!a) { delete box.dataset.mode; delete box.dataset.source; delete box.dataset.seen; return; }
  box.dataset.mode = a.mode;
  box.dataset.source = a.matrix ? 'summary' : 'event';
  // what was shown for this job, in order (the browser tests read it)
  box.dataset.seen = `${box.dataset.seen ? `${box.dataset.seen} ` : ''}${box.dataset.source}`;
  const from = a.landmarks > 0 ? `, started from ${a.landmarks} landmarks` : a.matrix ? ', started from the moments' : '';
  const title = document.createElement('p');
  title.className = 'alignment-title';
  title.textContent = `Alignment (${a.mode}${from}): boundary RMS of the distance ${num(a.rms_before)} → ${num(a.rms_after)}`
    + `, ${a.iterations} iterations, ${num(a.seconds)} s${a.scale != null && a.mode !== 'rigid' ? `, scale ${num(a.scale)}` : ''}`;
  box.append(title);
  if (!Array.isArray(a.matrix)) return;
  const n = Math.round(Math.sqrt(a.matrix.length));
  const table = document.createElement('table');
  table.className = 'matrix';
  table.title = 'template → target, homogeneous, row-major';
  for (let i = 0; i < n - 1; i++) { // the last row is 0 … 0 1
    const tr = table.insertRow();
    for (let j = 0; j < n; j++) {
      const td = tr.insertCell();
      td.textContent = num(a.matrix[i * n + j]);
      td.dataset.value = String(a.matrix[i * n + j]);
    }
  }
  const caption = table.createCaption();
  caption.textContent = 'x_target = A x_template + b  ([A | b])';
  box.append(table);
}
