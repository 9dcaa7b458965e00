// The web app's target reader (web/target.js) in Node, without a browser:
// the Medit ASCII reader against a mesh and a .sol written here, the
// level sets against analytic shapes (a circle, a sphere: every point of
// the level set at the radius, to the interpolation error h^2/(2R); the
// 2D level set's length against 2 pi R), STL and OBJ surfaces, and
// malformed input (a truncated file, a count the file cannot hold, an
// index out of range, binary Medit, an unknown keyword) refused with an
// Error, quickly.  Prints one JSON line per check: {desc, ok, detail}.
import { parseMeditAscii, levelSet2d, levelSet3d, loadTarget } from '../../web/target.js';

const report = (desc, ok, detail = '') => console.log(JSON.stringify({ desc, ok: !!ok, detail: String(detail).slice(0, 1000) }));
const enc = (s) => new TextEncoder().encode(s);

// A structured grid of [-1, 1]^dim with n cells a side (triangles or the
// six tetrahedra of each cube), as Medit ASCII, and the signed distance to
// the circle or sphere of radius R at its vertices as a .sol.
function grid(dim, n, R) {
  const idx = (...c) => c.reduce((a, x, k) => a + x * (n + 1) ** k, 0) + 1;
  const v = [], cells = [], sol = [];
  const coords = (i) => -1 + (2 * i) / n;
  if (dim === 2) {
    for (let j = 0; j <= n; j++) for (let i = 0; i <= n; i++) { v.push(`${coords(i)} ${coords(j)} 0`); sol.push(Math.hypot(coords(i), coords(j)) - R); }
    for (let j = 0; j < n; j++) for (let i = 0; i < n; i++) {
      const [a, b, c, d] = [idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)];
      cells.push(`${a} ${b} ${c} 1`, `${a} ${c} ${d} 1`);
    }
  } else {
    for (let k = 0; k <= n; k++) for (let j = 0; j <= n; j++) for (let i = 0; i <= n; i++) {
      v.push(`${coords(i)} ${coords(j)} ${coords(k)} 0`);
      sol.push(Math.hypot(coords(i), coords(j), coords(k)) - R);
    }
    // the Kuhn split of each cube: the six paths from corner 000 to 111
    const paths = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    for (let k = 0; k < n; k++) for (let j = 0; j < n; j++) for (let i = 0; i < n; i++)
      for (const p of paths) {
        const c = [i, j, k];
        const t = [idx(...c)];
        for (const axis of p) { c[axis]++; t.push(idx(...c)); }
        cells.push(`${t.join(' ')} 1`);
      }
  }
  const mesh = `MeshVersionFormatted 2\n# a comment\nDimension ${dim}\nVertices\n${v.length}\n${v.map((s) => (dim === 2 ? s.split(' ').slice(0, 2).join(' ') + ' 0' : s)).join('\n')}\n`
    + `${dim === 2 ? 'Triangles' : 'Tetrahedra'}\n${cells.length}\n${cells.join('\n')}\nEnd\n`;
  const solText = `MeshVersionFormatted 2\nDimension ${dim}\nSolAtVertices\n${sol.length}\n1 1\n${sol.map((x) => x.toPrecision(17)).join('\n')}\nEnd\n`;
  return { mesh, sol: solText, h: 2 / n };
}

try {
  const g2 = grid(2, 40, 0.6);
  const m2 = parseMeditAscii(enc(g2.mesh));
  const s2 = parseMeditAscii(enc(g2.sol)).sol;
  report('Medit ASCII 2D: vertices, triangles and the .sol read', m2.dim === 2 && m2.xyz.length === 2 * 41 * 41 && m2.tris.length === 3 * 2 * 1600 && s2.length === 41 * 41,
    `${m2.xyz.length} ${m2.tris.length} ${s2.length}`);
  const seg = levelSet2d(m2.xyz, m2.tris, s2);
  let worst = 0, length = 0;
  for (let i = 0; i < seg.length; i += 2) worst = Math.max(worst, Math.abs(Math.hypot(seg[i], seg[i + 1]) - 0.6));
  for (let i = 0; i < seg.length; i += 4) length += Math.hypot(seg[i + 2] - seg[i], seg[i + 3] - seg[i + 1]);
  report('the 2D zero level set lies on the circle of radius 0.6 (within h^2/(2R)) and has its length 2 pi R (0.5%)',
    seg.length > 0 && worst < (g2.h ** 2) / (2 * 0.6) && Math.abs(length / (2 * Math.PI * 0.6) - 1) < 0.005, `worst ${worst} length ${length}`);

  const g3 = grid(3, 12, 0.7);
  const m3 = parseMeditAscii(enc(g3.mesh));
  const s3 = parseMeditAscii(enc(g3.sol)).sol;
  const tri = levelSet3d(m3.xyz, m3.tets, s3);
  let worst3 = 0, area = 0;
  for (let i = 0; i < tri.length; i += 3) worst3 = Math.max(worst3, Math.abs(Math.hypot(tri[i], tri[i + 1], tri[i + 2]) - 0.7));
  for (let i = 0; i < tri.length; i += 9) {
    const u = [0, 1, 2].map((k) => tri[i + 3 + k] - tri[i + k]), w = [0, 1, 2].map((k) => tri[i + 6 + k] - tri[i + k]);
    area += Math.hypot(u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]) / 2;
  }
  report('the 3D zero level set lies on the sphere of radius 0.7 (within h^2/(2R)) and has its area 4 pi R^2 (3%)',
    tri.length > 0 && worst3 < (g3.h ** 2) / (2 * 0.7) && Math.abs(area / (4 * Math.PI * 0.49) - 1) < 0.03, `worst ${worst3} area ${area} triangles ${tri.length / 9}`);

  // surfaces through loadTarget, with a fake fetch of the inputs routes
  const tetra = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]];
  const faces = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
  const stlAscii = `solid t\n${faces.map((f) => `facet normal 0 0 0\nouter loop\n${f.map((i) => `vertex ${tetra[i].join(' ')}`).join('\n')}\nendloop\nendfacet`).join('\n')}\nendsolid t\n`;
  const stlBin = new Uint8Array(84 + 50 * 4);
  const dv = new DataView(stlBin.buffer);
  dv.setUint32(80, 4, true);
  faces.forEach((f, k) => f.forEach((i, j) => tetra[i].forEach((x, c) => dv.setFloat32(84 + 50 * k + 12 + 12 * j + 4 * c, x, true))));
  const obj = enc(`v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\n`);
  const serve = (files) => async (url) => {
    const part = url.split('/').pop();
    if (part === 'inputs') return new Response(JSON.stringify({ inputs: Object.entries(files).map(([p, b]) => ({ part: p, bytes: b.length })) }));
    return files[part] ? new Response(files[part]) : new Response('', { status: 404 });
  };
  const gz = async (bytes) => new Uint8Array(await new Response(new Blob([bytes]).stream().pipeThrough(new CompressionStream('gzip'))).arrayBuffer());
  for (const [name, bytes] of [['ASCII STL', enc(stlAscii)], ['binary STL', stlBin], ['OBJ', obj], ['gzip ASCII STL', await gz(enc(stlAscii))]]) {
    const t = await loadTarget(serve({ target_surface: bytes }), 'x', 3);
    report(`a target_surface in ${name}: its 4 triangles`, t.positions.length === 36 && t.positions.every((x) => x === 0 || x === 1), t.positions.length);
  }
  const t2 = await loadTarget(serve({ target_mesh: await gz(enc(g2.mesh)), target_sol: enc(g2.sol) }), 'x', 2);
  report('loadTarget: target_mesh (gzip) and target_sol give the 2D level set', t2.segments.length === seg.length, t2.segments.length);

  // malformed input: an Error, never a hang or a huge allocation
  const bad = {
    'a truncated vertex list': 'MeshVersionFormatted 2\nDimension 2\nVertices\n3\n0 0 0\n1 0',
    'a count the file cannot hold': 'MeshVersionFormatted 2\nDimension 3\nVertices\n2000000000\n0 0 0 0\n',
    'a vertex index out of range': 'MeshVersionFormatted 2\nDimension 2\nVertices\n3\n0 0 0\n1 0 0\n0 1 0\nTriangles\n1\n1 2 9 0\nEnd\n',
    'an unknown keyword': 'MeshVersionFormatted 2\nDimension 2\nSomethingElse\n1\n',
    'a dimension of 7': 'MeshVersionFormatted 2\nDimension 7\n',
    'a word for a number': 'MeshVersionFormatted 2\nDimension 2\nVertices\n1\n0 x 0\n',
  };
  for (const [what, text] of Object.entries(bad)) {
    let err = null;
    const t0 = Date.now();
    try { parseMeditAscii(enc(text)); } catch (e) { err = e; }
    report(`malformed Medit (${what}): an Error`, err instanceof Error && Date.now() - t0 < 1000, err && err.message);
  }
  let err = null;
  try { parseMeditAscii(new Uint8Array([1, 0, 0, 0, 2, 0, 0, 0])); } catch (e) { err = e; }
  report('binary Medit: said not drawn', err && /binary Medit/.test(err.message), err && err.message);
  err = null;
  try { await loadTarget(serve({ target_surface: enc('ply\nformat ascii 1.0\n') }), 'x', 3); } catch (e) { err = e; }
  report('a surface in a format not drawn (PLY): said so', err && /not one the web app draws/.test(err.message), err && err.message);
} catch (e) {
  report('the target reader checks run', false, e.stack);
}
