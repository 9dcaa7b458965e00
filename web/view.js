// Mesh views of the web app: a Medit (.mesh, ASCII) reader, a 2D canvas
// drawing of triangles (boundary edges dark) and a three.js view of the
// boundary surface of tetrahedra (orbit, coloured by the target distance
// |d| at the vertices; by the displacement from the first shape shown when
// the mesh carries no distance).
import * as THREE from 'three';
import { OrbitControls } from './orbit.js';

const WIDTH = { Vertices: 0, Edges: 3, Triangles: 4, Quadrilaterals: 5, Tetrahedra: 5, Hexahedra: 9,
  Corners: 1, RequiredVertices: 1, Ridges: 1, RequiredEdges: 1 };

const align8 = (n) => (n + 7) & ~7;

// The binary mesh payload (proto/PAYLOAD.md, version 1) of the live and
// final meshes: {dim, xyz, tris | tets, distance (|d| source, or null)};
// throws on what is not one.
export function parsePayload(buf) {
  const v = new DataView(buf);
  const magic = new TextDecoder().decode(new Uint8Array(buf, 0, Math.min(6, buf.byteLength)));
  if (buf.byteLength < 44 || magic !== 'SMMESH' || v.getUint32(8, true) !== 1) throw new Error('not a mesh payload');
  const dim = v.getUint32(12, true), nv = v.getUint32(16, true), ne = v.getUint32(20, true), nf = v.getUint32(24, true);
  const flags = v.getUint32(28, true);
  let off = 40;
  const take = (Type, count) => {
    const bytes = count * Type.BYTES_PER_ELEMENT;
    if (off + bytes > buf.byteLength - 4) throw new Error('truncated mesh payload');
    const a = new Type(buf.slice(off, off + bytes));
    off = align8(off + bytes);
    return a;
  };
  const xyz = take(Float64Array, nv * dim);
  take(Int32Array, nv);
  const elems = new Int32Array(take(Uint32Array, ne * (dim + 1)));
  take(Int32Array, ne);
  take(Uint32Array, nf * dim);
  take(Int32Array, nf);
  if (flags & 1) take(Float64Array, nv * dim);
  const distance = flags & 2 ? take(Float64Array, nv) : null;
  const mesh = { dim, xyz, tris: new Int32Array(0), tets: new Int32Array(0), distance };
  if (dim === 2) mesh.tris = elems; else mesh.tets = elems;
  return mesh;
}

// Colour of |d| relative to the largest |d| (blue: on the target, red: far).
function heat(t) { return `hsl(${Math.round(220 - 220 * Math.min(1, t))} 70% 62%)`; }
// The largest |d| over the vertices of the boundary facets (d matters there).
function dmax(mesh, facets) {
  let m = 1e-300;
  if (mesh.distance) for (const f of facets) for (const v of f) m = Math.max(m, Math.abs(mesh.distance[v]));
  return m;
}

// {dim, xyz (Float64Array, dim per vertex), tris, tets (0-based Int32Array)}
export function parseMedit(text) {
  const tok = text.split(/\s+/).filter(Boolean);
  const mesh = { dim: 3, xyz: new Float64Array(0), tris: new Int32Array(0), tets: new Int32Array(0) };
  for (let i = 0; i < tok.length; i++) {
    const key = tok[i];
    if (key === 'Dimension') { mesh.dim = Number(tok[++i]); continue; }
    if (key === 'End') break;
    if (!(key in WIDTH)) continue;
    const n = Number(tok[++i]);
    const w = key === 'Vertices' ? mesh.dim + 1 : WIDTH[key];
    const take = key === 'Vertices' ? mesh.dim : key === 'Triangles' ? 3 : key === 'Tetrahedra' ? 4 : 0;
    const out = key === 'Vertices' ? new Float64Array(n * take) : new Int32Array(n * take);
    for (let e = 0; e < n; e++)
      for (let k = 0; k < take; k++)
        out[e * take + k] = key === 'Vertices' ? Number(tok[i + 1 + e * w + k]) : Number(tok[i + 1 + e * w + k]) - 1;
    i += n * w;
    if (key === 'Vertices') mesh.xyz = out;
    if (key === 'Triangles') mesh.tris = out;
    if (key === 'Tetrahedra') mesh.tets = out;
  }
  return mesh;
}

// Edges (2D) or faces (3D) that belong to one element only.
function boundary(cells, per, sub) {
  const count = new Map();
  const keep = new Map();
  for (let c = 0; c < cells.length / per; c++)
    for (const s of sub) {
      const v = s.map((k) => cells[c * per + k]);
      const key = [...v].sort((a, b) => a - b).join(',');
      count.set(key, (count.get(key) || 0) + 1);
      keep.set(key, v);
    }
  return [...count].filter(([, n]) => n === 1).map(([k]) => keep.get(k));
}

export function drawMesh2d(canvas, mesh) {
  const ctx = canvas.getContext('2d');
  const { xyz, dim, tris } = mesh;
  let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
  for (let v = 0; v < xyz.length / dim; v++) {
    x0 = Math.min(x0, xyz[v * dim]); x1 = Math.max(x1, xyz[v * dim]);
    y0 = Math.min(y0, xyz[v * dim + 1]); y1 = Math.max(y1, xyz[v * dim + 1]);
  }
  const s = 0.9 * Math.min(canvas.width / (x1 - x0 || 1), canvas.height / (y1 - y0 || 1));
  const px = (v) => [canvas.width / 2 + s * (xyz[v * dim] - (x0 + x1) / 2), canvas.height / 2 - s * (xyz[v * dim + 1] - (y0 + y1) / 2)];
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  ctx.lineWidth = 0.5;
  ctx.strokeStyle = '#9aa7b8';
  ctx.fillStyle = '#e4ebf4';
  ctx.beginPath();
  for (let t = 0; t < tris.length / 3; t++) {
    const [a, b, c] = [px(tris[3 * t]), px(tris[3 * t + 1]), px(tris[3 * t + 2])];
    ctx.moveTo(...a); ctx.lineTo(...b); ctx.lineTo(...c); ctx.closePath();
  }
  ctx.fill();
  ctx.stroke();
  // the boundary, coloured by |d| (the boundary error: blue on the target)
  const edges = boundary(tris, 3, [[0, 1], [1, 2], [2, 0]]);
  const m = dmax(mesh, edges);
  ctx.lineWidth = 3;
  ctx.lineCap = 'round';
  for (const [a, b] of edges) {
    ctx.strokeStyle = mesh.distance ? heat((Math.abs(mesh.distance[a]) + Math.abs(mesh.distance[b])) / (2 * m)) : '#24364b';
    ctx.beginPath(); ctx.moveTo(...px(a)); ctx.lineTo(...px(b)); ctx.stroke();
  }
}

export class View3d {
  constructor(el) {
    this.el = el;
    this.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    const size = el.clientWidth || 480;
    this.renderer.setSize(size, size);
    el.replaceChildren(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0xffffff);
    this.camera = new THREE.PerspectiveCamera(40, 1, 0.01, 1000);
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x667788, 2.0));
    const sun = new THREE.DirectionalLight(0xffffff, 1.5);
    sun.position.set(2, 3, 4);
    this.scene.add(sun);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.addEventListener('change', () => this.render());
    this.mesh = null;
  }

  show(mesh, first) {
    const faces = boundary(mesh.tets, 4, [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]);
    const pos = new Float32Array(mesh.xyz);
    const col = new Float32Array(pos.length);
    let umax = 1e-30;
    const u = new Float64Array(pos.length / 3);
    const same = first && first.xyz.length === mesh.xyz.length;
    for (let v = 0; v < u.length; v++)
      u[v] = mesh.distance ? Math.abs(mesh.distance[v])
        : same ? Math.hypot(mesh.xyz[3 * v] - first.xyz[3 * v], mesh.xyz[3 * v + 1] - first.xyz[3 * v + 1], mesh.xyz[3 * v + 2] - first.xyz[3 * v + 2]) : 0;
    for (const f of faces) for (const v of f) umax = Math.max(umax, u[v]);
    const c = new THREE.Color();
    for (let v = 0; v < u.length; v++) {
      c.setHSL(0.61 - 0.61 * (u[v] / umax), 0.7, 0.5);
      col.set([c.r, c.g, c.b], 3 * v);
    }
    const geo = new THREE.BufferGeometry();
    geo.setAttribute('position', new THREE.BufferAttribute(pos, 3));
    geo.setAttribute('color', new THREE.BufferAttribute(col, 3));
    geo.setIndex(faces.flat());
    geo.computeVertexNormals();
    geo.computeBoundingSphere();
    if (this.mesh) { this.scene.remove(this.mesh); this.mesh.geometry.dispose(); }
    this.mesh = new THREE.Mesh(geo, new THREE.MeshStandardMaterial({ vertexColors: true, flatShading: true, side: THREE.DoubleSide }));
    this.scene.add(this.mesh);
    if (!this.framed) {
      const { center, radius } = geo.boundingSphere;
      this.camera.position.set(center.x + 1.6 * radius, center.y + 1.2 * radius, center.z + 2.2 * radius);
      this.controls.target.copy(center);
      this.controls.update();
      this.framed = true;
    }
    this.faces = faces.length;
    this.render();
  }

  render() { this.renderer.render(this.scene, this.camera); }
}
