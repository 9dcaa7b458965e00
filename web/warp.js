// Warp in the web app (issue 24): carry points, a mesh or a field through
// a finished job's map with POST v1/jobs/{id}/warp (docs/warp.md:
// forward is template -> target, inverse target -> template; inside 0
// marks a point outside the mesh, mapped by its nearest element).  Points
// come from a CSV file or are pasted (x,y[,z] a line); the answer is
// shown as a table with the inside flag and offered as a download, as is
// a warped mesh or field.  The daemon's problem+json detail (a malformed
// line, the wrong dimension, a job without a map) is shown as it is.
const ROWS_SHOWN = 200; // the table shows the first rows; the download has all

const el = (tag, props = {}, ...children) => {
  const e = Object.assign(document.createElement(tag), props);
  e.append(...children);
  return e;
};

// The request's media type from the file's name (the daemon reads meshes
// and fields by content, the name only picks the kind).
export function mediaOf(name) {
  const n = name.toLowerCase().replace(/\.gz$/, '');
  if (/\.meshb$/.test(n)) return ['application/x-medit-meshb', 'mesh'];
  if (/\.(mesh|msh)$/.test(n)) return ['application/x-medit-mesh', 'mesh'];
  if (/\.solb$/.test(n)) return ['application/x-medit-solb', 'field'];
  if (/\.sol$/.test(n)) return ['application/x-medit-sol', 'field'];
  return ['text/csv', 'points'];
}

// The warped points CSV (a header, then x,y[,z],inside) as rows of numbers.
export function parseWarped(text) {
  const lines = text.split(/\r?\n/).filter((l) => l.trim());
  const header = lines.shift() || '';
  return { header: header.split(','), rows: lines.map((l) => l.split(',').map(Number)) };
}

// The panel of a job: fetchFn(url, init) is the app's fetch with its
// token; id the job (null hides the panel).
export function warpPanel(box, id, fetchFn) {
  if (box.warpUrl) URL.revokeObjectURL(box.warpUrl);
  box.warpUrl = null;
  box.replaceChildren();
  box.hidden = !id;
  delete box.dataset.state;
  if (!id) return;
  const file = el('input', { type: 'file', id: 'warp-file', accept: '.csv,.txt,.mesh,.meshb,.msh,.sol,.solb,.gz' });
  const text = el('textarea', { id: 'warp-text', rows: 3, placeholder: 'or paste points: x,y[,z] a line' });
  const direction = el('select', { id: 'warp-direction' },
    el('option', { value: 'forward', textContent: 'forward: template → target' }),
    el('option', { value: 'inverse', textContent: 'inverse: target → template' }));
  const go = el('button', { type: 'button', id: 'warp-go', textContent: 'Warp' });
  const error = el('p', { className: 'err', id: 'warp-error', role: 'alert' });
  const result = el('div', { id: 'warp-result' });
  box.append(el('h3', { textContent: 'Warp through this job\'s map' }),
    el('label', {}, 'points (CSV), a mesh or a field at the template\'s vertices ', file), text,
    el('label', {}, 'direction ', direction), go, error, result);

  go.addEventListener('click', async () => {
    error.textContent = '';
    result.replaceChildren();
    const f = file.files[0];
    const pasted = text.value.trim();
    if (!f && !pasted) { error.textContent = 'choose a file or paste points'; return; }
    const [type, kind] = f ? mediaOf(f.name) : ['text/csv', 'points'];
    const base = f ? f.name.replace(/\.gz$/i, '').replace(/\.[^.]*$/, '') : 'points';
    box.dataset.state = 'busy';
    go.disabled = true;
    try {
      const r = await fetchFn(`v1/jobs/${id}/warp?direction=${direction.value}`, {
        method: 'POST', headers: { 'Content-Type': type }, body: f || `${pasted}\n` });
      if (!r.ok) {
        const p = await r.json().catch(() => ({}));
        error.textContent = `${r.status}: ${p.detail || p.title || r.statusText}`;
        box.dataset.state = 'error';
        return;
      }
      const blob = await r.blob();
      const ext = kind === 'points' ? 'csv' : kind === 'mesh' ? 'mesh' : 'sol';
      if (box.warpUrl) URL.revokeObjectURL(box.warpUrl);
      box.warpUrl = URL.createObjectURL(blob);
      const name = `${base}-${direction.value === 'inverse' ? 'template' : 'target'}.${ext}`;
      const link = el('a', { id: 'warp-download', href: box.warpUrl, download: name, textContent: `download ${name}` });
      if (kind !== 'points') {
        result.append(el('p', { textContent: `the ${kind} warped ${direction.value} (${blob.size} bytes, Medit ASCII) ` }), link);
      } else {
        const { header, rows } = parseWarped(await blob.text());
        const outside = rows.filter((row) => row[row.length - 1] === 0).length;
        const table = el('table', { id: 'warp-table' }, el('thead', {}, el('tr', {}, ...header.map((h) => el('th', { textContent: h })))));
        const body = el('tbody');
        for (const row of rows.slice(0, ROWS_SHOWN)) {
          const tr = el('tr', {}, ...row.map((v) => el('td', { textContent: String(v) })));
          if (row[row.length - 1] === 0) tr.className = 'outside';
          body.append(tr);
        }
        table.append(body);
        result.append(el('p', { id: 'warp-summary',
          textContent: `${rows.length} point${rows.length === 1 ? '' : 's'} warped ${direction.value}; ${outside} outside the mesh (inside 0: mapped by the nearest element)`
            + `${rows.length > ROWS_SHOWN ? `; the first ${ROWS_SHOWN} shown` : ''} ` }), link, table);
        result.dataset.points = String(rows.length);
        result.dataset.outside = String(outside);
      }
      box.dataset.state = 'done';
    } catch (e) {
      error.textContent = `the request failed: ${e.message}`;
      box.dataset.state = 'error';
    } finally {
      go.disabled = false;
    }
  });
}
