// The target of a job, for the web app's overlay: read from the job's
// stored inputs (GET v1/jobs/{id}/inputs lists them, /inputs/{part} is
// one, gzip or not) and turned
// into what the views draw: the zero level set of target_sol on
// target_mesh (2D: segments, by marching triangles; 3D: triangles, by
// marching tetrahedra), or the target_surface itself (3D: STL, OBJ or
// Medit triangles; 2D: Medit edges).  Reads the ASCII formats (Medit
// .mesh/.sol, STL, OBJ); for others (.meshb, .solb, Gmsh, PLY, VTK) it
// says that it does not draw them.  Hostile input costs at most MAX_BYTES
// and throws a plain Error.
const MAX_BYTES = 64 << 20;

async function bytesOf(response) {
  let buf = new Uint8Array(await response.arrayBuffer());
  if (buf.length >= 2 && buf[0] === 0x1f && buf[1] === 0x8b) {
    const stream = new Blob([buf]).stream().pipeThrough(new DecompressionStream('gzip'));
    const reader = stream.getReader();
    const parts = [];
    let total = 0;
    for (;;) {
      const { done, value } = await reader.read();
      if (done) break;
      total += value.length;
      if (total > MAX_BYTES) { reader.cancel(); throw new Error('too large to draw'); }
      parts.push(value);
    }
    buf = new Uint8Array(total);
    let off = 0;
    for (const p of parts) { buf.set(p, off); off += p.length; }
  }
  if (buf.length > MAX_BYTES) throw new Error('too large to draw');
  return buf;
}

// A tokenizer over ASCII bytes: numbers parsed in place (no strings for
// the millions of coordinates), words as strings; '#' starts a comment.
class Tokens {
  constructor(buf) { this.b = buf; this.i = 0; }
  skip() {
    const b = this.b;
    for (;;) {
      while (this.i < b.length && b[this.i] <= 32) this.i++;
      if (this.i < b.length && b[this.i] === 35) { while (this.i < b.length && b[this.i] !== 10) this.i++; continue; }
      return this.i < b.length;
    }
  }
  // the next word (letters first), or null at a number or the end
  word() {
    if (!this.skip()) return null;
    const c = this.b[this.i];
    if (!((c >= 65 && c <= 90) || (c >= 97 && c <= 122))) return null;
    const s = this.i;
    while (this.i < this.b.length && this.b[this.i] > 32) this.i++;
    return new TextDecoder().decode(this.b.subarray(s, this.i));
  }
  number() {
    if (!this.skip()) throw new Error('unexpected end of file');
    const b = this.b;
    const s = this.i;
    while (this.i < b.length && b[this.i] > 32) this.i++;
    // the common shapes by hand; anything else through Number()
    let k = s, sign = 1, v = 0, frac = 0, scale = 1, ok = true;
    if (b[k] === 45 || b[k] === 43) { sign = b[k] === 45 ? -1 : 1; k++; }
    let digits = 0;
    while (k < this.i && b[k] >= 48 && b[k] <= 57) { v = v * 10 + (b[k++] - 48); digits++; }
    if (k < this.i && b[k] === 46) { k++; while (k < this.i && b[k] >= 48 && b[k] <= 57) { frac = frac * 10 + (b[k++] - 48); scale *= 10; digits++; } }
    if (digits === 0 || digits > 15) ok = false;
    let exp = 0;
    if (ok && k < this.i && (b[k] === 101 || b[k] === 69)) {
      k++;
      let es = 1, ed = 0;
      if (b[k] === 45 || b[k] === 43) { es = b[k] === 45 ? -1 : 1; k++; }
      while (k < this.i && b[k] >= 48 && b[k] <= 57) { exp = exp * 10 + (b[k++] - 48); ed++; }
      exp *= es;
      if (!ed) ok = false;
    }
    if (ok && k === this.i) return sign * (v + frac / scale) * (exp ? 10 ** exp : 1);
    const x = Number(new TextDecoder().decode(b.subarray(s, this.i)));
    if (!Number.isFinite(x)) throw new Error('not a number');
    return x;
  }
}

const isBinaryMedit = (b) => b.length >= 4 && (b[0] | (b[1] << 8) | (b[2] << 16) | (b[3] << 24)) === 1;

// Medit ASCII: {dim, xyz, edges, tris, tets} (0-based) or {sol} for a .sol.
export function parseMeditAscii(buf) {
  if (isBinaryMedit(buf)) throw new Error('binary Medit (.meshb, .solb) is not drawn');
  const t = new Tokens(buf);
  const out = { dim: 3, xyz: null, edges: null, tris: null, tets: null, sol: null };
  // numbers per entry (-1: the dimension) and whether a reference follows
  const ENTRY = { Edges: [2, 1], Triangles: [3, 1], Quadrilaterals: [4, 1], Tetrahedra: [4, 1], Hexahedra: [8, 1], Prisms: [6, 1],
    Corners: [1, 0], Ridges: [1, 0], RequiredVertices: [1, 0], RequiredEdges: [1, 0], Normals: [-1, 0], Tangents: [-1, 0],
    NormalAtVertices: [2, 0], TangentAtVertices: [2, 0] };
  for (;;) {
    const w = t.word();
    if (w === null) { if (!t.skip()) break; t.number(); continue; }
    if (w === 'End') break;
    if (w === 'MeshVersionFormatted') { t.number(); continue; }
    if (w === 'Dimension') { out.dim = t.number(); if (out.dim !== 2 && out.dim !== 3) throw new Error('bad dimension'); continue; }
    const n = t.number();
    // every entry takes at least one number and a blank: a count the file
    // cannot hold allocates nothing
    if (!Number.isInteger(n) || n < 0 || 2 * n > buf.length) throw new Error(`bad count after ${w}`);
    if (w === 'Vertices') {
      const xyz = new Float64Array(n * out.dim);
      for (let v = 0; v < n; v++) { for (let k = 0; k < out.dim; k++) xyz[v * out.dim + k] = t.number(); t.number(); }
      out.xyz = xyz;
    } else if (w === 'SolAtVertices') {
      const nf = t.number();
      let width = 0;
      for (let f = 0; f < nf; f++) { const type = t.number(); width += type === 1 ? 1 : type === 2 ? out.dim : type === 3 ? (out.dim * (out.dim + 1)) / 2 : out.dim * out.dim; }
      if (nf < 1 || width < 1) throw new Error('bad solution header');
      const sol = new Float64Array(n);
      for (let v = 0; v < n; v++) { sol[v] = t.number(); for (let k = 1; k < width; k++) t.number(); }
      out.sol = sol;
    } else if (w in ENTRY) {
      const per = ENTRY[w][0] < 0 ? out.dim : ENTRY[w][0];
      const keep = w === 'Edges' || w === 'Triangles' || w === 'Tetrahedra';
      const cells = keep ? new Int32Array(n * per) : null;
      for (let e = 0; e < n; e++) {
        for (let k = 0; k < per; k++) { const x = t.number(); if (keep) cells[e * per + k] = x - 1; }
        if (ENTRY[w][1]) t.number();
      }
      if (w === 'Edges') out.edges = cells;
      if (w === 'Triangles') out.tris = cells;
      if (w === 'Tetrahedra') out.tets = cells;
    } else {
      throw new Error(`keyword ${w} is not drawn`);
    }
  }
  const nv = out.xyz ? out.xyz.length / out.dim : 0;
  for (const cells of [out.edges, out.tris, out.tets]) if (cells) for (const c of cells) if (c < 0 || c >= nv) throw new Error('a vertex index out of range');
  return out;
}

// STL (binary or ASCII) or OBJ: triangle positions (3 per vertex).
function parseStl(buf) {
  const dv = new DataView(buf.buffer, buf.byteOffset, buf.byteLength);
  const head = new TextDecoder().decode(buf.subarray(0, Math.min(buf.length, 512)));
  const n = buf.length >= 84 ? dv.getUint32(80, true) : -1;
  if (n >= 0 && 84 + 50 * n === buf.length) {
    const pos = new Float32Array(9 * n);
    for (let f = 0; f < n; f++) for (let k = 0; k < 9; k++) pos[9 * f + k] = dv.getFloat32(84 + 50 * f + 12 + 4 * k, true);
    return pos;
  }
  if (!/^\s*solid/.test(head)) return null;
  const t = new Tokens(buf);
  const pos = [];
  for (let w = t.word(); ; w = t.word()) {
    if (w === null) { if (!t.skip()) break; t.number(); continue; }
    if (w === 'vertex') pos.push(t.number(), t.number(), t.number());
  }
  return Float32Array.from(pos);
}
function parseObj(buf) {
  const text = new TextDecoder().decode(buf);
  const v = [];
  const pos = [];
  for (const line of text.split('\n')) {
    const p = line.trim().split(/\s+/);
    if (p[0] === 'v') v.push([Number(p[1]), Number(p[2]), Number(p[3])]);
    else if (p[0] === 'f') {
      const ids = p.slice(1).map((s) => { const i = parseInt(s, 10); return i < 0 ? v.length + i : i - 1; });
      for (let k = 1; k + 1 < ids.length; k++)
        for (const i of [ids[0], ids[k], ids[k + 1]]) { if (!v[i]) throw new Error('OBJ face index out of range'); pos.push(...v[i]); }
    }
  }
  return pos.length ? Float32Array.from(pos) : null;
}

const cross = (a, b) => (a < 0) !== (b < 0);

// The zero level set of sol on 2D triangles: segments x0 y0 x1 y1 ...
export function levelSet2d(xyz, tris, sol) {
  const out = [];
  const at = (a, b) => { const s = sol[a] / (sol[a] - sol[b]); out.push(xyz[2 * a] + s * (xyz[2 * b] - xyz[2 * a]), xyz[2 * a + 1] + s * (xyz[2 * b + 1] - xyz[2 * a + 1])); };
  for (let t = 0; t < tris.length; t += 3) {
    const v = [tris[t], tris[t + 1], tris[t + 2]];
    const e = [[0, 1], [1, 2], [2, 0]].filter(([i, j]) => cross(sol[v[i]], sol[v[j]]));
    if (e.length === 2) for (const [i, j] of e) at(v[i], v[j]);
  }
  return Float64Array.from(out);
}

// The zero level set of sol on tetrahedra: triangle positions.
export function levelSet3d(xyz, tets, sol) {
  const out = [];
  const p = (a, b) => { const s = sol[a] / (sol[a] - sol[b]); return [0, 1, 2].map((k) => xyz[3 * a + k] + s * (xyz[3 * b + k] - xyz[3 * a + k])); };
  for (let t = 0; t < tets.length; t += 4) {
    const v = [tets[t], tets[t + 1], tets[t + 2], tets[t + 3]];
    const neg = v.filter((x) => sol[x] < 0), pos = v.filter((x) => !(sol[x] < 0));
    if (neg.length === 1 || neg.length === 3) {
      const [a, others] = neg.length === 1 ? [neg[0], pos] : [pos[0], neg];
      out.push(...p(a, others[0]), ...p(a, others[1]), ...p(a, others[2]));
    } else if (neg.length === 2) {
      // the quadrilateral a-c, a-d, b-d, b-c, as two triangles
      const [a, b] = neg, [c, d] = pos;
      const q = [p(a, c), p(a, d), p(b, d), p(b, c)];
      out.push(...q[0], ...q[1], ...q[2], ...q[0], ...q[2], ...q[3]);
    }
  }
  return Float32Array.from(out);
}

// The target of job id for a view of dimension dim: {segments} (2D) or
// {positions} (3D), with what it is ({what}); throws an Error saying why
// it is not drawn.
export async function loadTarget(get, id, dim) {
  const list = await get(`v1/jobs/${id}/inputs`);
  if (!list.ok) throw new Error(`the job's inputs: HTTP ${list.status}`);
  const sent = new Map(((await list.json()).inputs || []).map((i) => [i.part, i]));
  for (const i of sent.values()) if (i.bytes > MAX_BYTES) throw new Error(`${i.part} is too large to draw`);
  const part = async (name) => {
    if (!sent.has(name)) return null;
    const r = await get(`v1/jobs/${id}/inputs/${name}`);
    if (!r.ok) throw new Error(`${name}: HTTP ${r.status}`);
    return bytesOf(r);
  };
  const surface = await part('target_surface');
  if (surface) {
    if (dim === 2) {
      const m = parseMeditAscii(surface);
      if (!m.edges || m.dim !== 2) throw new Error('a 2D target surface is drawn from Medit edges only');
      const seg = [];
      for (let e = 0; e < m.edges.length; e += 2) for (const v of [m.edges[e], m.edges[e + 1]]) seg.push(m.xyz[2 * v], m.xyz[2 * v + 1]);
      return { segments: Float64Array.from(seg), what: 'target surface' };
    }
    let positions = parseStl(surface);
    if (!positions && /^\s*(MeshVersion|#|Dimension)/.test(new TextDecoder().decode(surface.subarray(0, 64)))) {
      const m = parseMeditAscii(surface);
      if (m.tris) positions = Float32Array.from([...m.tris].flatMap((v) => [m.xyz[3 * v], m.xyz[3 * v + 1], m.xyz[3 * v + 2]]));
    }
    if (!positions) positions = parseObj(surface);
    if (!positions || !positions.length) throw new Error('its format is not one the web app draws (STL, OBJ, Medit ASCII)');
    return { positions, what: 'target surface' };
  }
  const [mb, sb] = [await part('target_mesh'), await part('target_sol')];
  if (!mb || !sb) throw new Error('the job has no target_mesh and target_sol');
  const mesh = parseMeditAscii(mb);
  const { sol } = parseMeditAscii(sb);
  const nv = mesh.xyz ? mesh.xyz.length / mesh.dim : 0;
  if (!sol || sol.length !== nv) throw new Error('target_sol does not match target_mesh');
  if (mesh.dim === 3 && dim === 2 && mesh.xyz.every((x, i) => i % 3 !== 2 || x === 0)) {
    // a flat mesh written in 3D (as Gmsh does): its x and y
    mesh.xyz = mesh.xyz.filter((x, i) => i % 3 !== 2);
    mesh.dim = 2;
  }
  if (mesh.dim !== dim) throw new Error('the target has another dimension');
  if (dim === 2) {
    if (!mesh.tris) throw new Error('target_mesh has no triangles');
    return { segments: levelSet2d(mesh.xyz, mesh.tris, sol), what: 'zero level set of target_sol' };
  }
  if (!mesh.tets) throw new Error('target_mesh has no tetrahedra');
  return { positions: levelSet3d(mesh.xyz, mesh.tets, sol), what: 'zero level set of target_sol' };
}
