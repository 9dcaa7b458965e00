// Mesh views of the web app: the binary mesh payload's reader, a 2D canvas
// view of triangles (boundary edges coloured by |d|) and a three.js view of
// the boundary surface of tetrahedra (orbit, coloured by the target
// distance |d| at the vertices; by the displacement from the first shape
// shown when the mesh carries no distance).  Both draw the target (its zero
// level set in 2D, its surface in 3D) when they are given it, and frame the
// shape and the target together at every draw, so a shape that grows stays
// in view; in 3D until the user moves the camera (then "reset view").
import * as THREE from 'three';
import { OrbitControls } from './orbit.js';

const align8 = (n) => (n + 7) & ~7;

// A number as a short label that keeps its magnitude: 1e-4 stays "1e-4",
// 0.25 stays "0.25" (uPlot's default log-axis labels round 1e-4 to "0").
export function tickLabel(v) {
  if (v === null || v === undefined || Number.isNaN(v)) return '';
  const a = Math.abs(v);
  if (a === 0) return '0';
  if (a >= 0.01 && a < 1e4) return String(Number(v.toPrecision(3)));
  return v.toExponential(2).replace(/\.?0+e/, 'e').replace('e+', 'e');
}
// The same with three significant digits always (figures in sentences).
export function fmtNum(v) {
  if (v === null || v === undefined || !Number.isFinite(v)) return String(v);
  const a = Math.abs(v);
  return a !== 0 && (a < 0.01 || a >= 1e4) ? v.toExponential(2) : String(Number(v.toPrecision(3)));
}

// The binary mesh payload (proto/PAYLOAD.md, version 1) of the live and
// final meshes: {dim, xyz, tris | tets, facets, distance (|d|, or null)};
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
  const facets = new Int32Array(take(Uint32Array, nf * dim));
  take(Int32Array, nf);
  if (flags & 1) take(Float64Array, nv * dim);
  const distance = flags & 2 ? take(Float64Array, nv) : null;
  const mesh = { dim, xyz, tris: new Int32Array(0), tets: new Int32Array(0), facets, distance };
  if (dim === 2) mesh.tris = elems; else mesh.tets = elems;
  return mesh;
}

// The colour of t in [0, 1] (|d| over the largest |d|): blue on the
// target, red far from it; the colour scale under the view uses the same.
const HUE0 = 220;
export function heatCss(t) { return `hsl(${Math.round(HUE0 - HUE0 * Math.min(1, Math.max(0, t)))} 70% 55%)`; }
function heatRgb(t, c) { return c.setHSL((HUE0 - HUE0 * Math.min(1, Math.max(0, t))) / 360, 0.7, 0.55); }

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

// The bounding box [min..., max...] of dim-wide points, grown by another box.
function bbox(xyz, dim, box = null) {
  const b = box ? [...box] : [...Array(dim).fill(Infinity), ...Array(dim).fill(-Infinity)];
  for (let i = 0; i < xyz.length; i += dim)
    for (let k = 0; k < dim; k++) {
      if (xyz[i + k] < b[k]) b[k] = xyz[i + k];
      if (xyz[i + k] > b[dim + k]) b[dim + k] = xyz[i + k];
    }
  return b;
}

// The largest of values over the vertices of the boundary facets.
function maxOver(values, facets) {
  let m = 0;
  for (const f of facets) for (const v of f) m = Math.max(m, values[v]);
  return m;
}

export class View2d {
  constructor(canvas) {
    this.canvas = canvas;
    this.target = null; // {segments: Float64Array x0 y0 x1 y1 ...}
    this.edgesOf = null;
  }

  setTarget(target, shown = true) { this.target = target; this.shown = shown; }
  reset() {}

  // Draws the mesh; returns the colour scale {max, label} (or null).
  show(mesh) {
    const canvas = this.canvas;
    const ctx = canvas.getContext('2d');
    const { xyz, dim, tris } = mesh;
    let [x0, y0, x1, y1] = bbox(xyz, dim);
    const target = this.target && this.shown ? this.target : null;
    if (target) [x0, y0, x1, y1] = bbox(target.segments, 2, [x0, y0, x1, y1]);
    const s = 0.92 * Math.min(canvas.width / (x1 - x0 || 1), canvas.height / (y1 - y0 || 1));
    const px = (x, y) => [canvas.width / 2 + s * (x - (x0 + x1) / 2), canvas.height / 2 - s * (y - (y0 + y1) / 2)];
    const pv = (v) => px(xyz[v * dim], xyz[v * dim + 1]);
    this.box = { x0, y0, x1, y1 };
    this.project = px;
    ctx.clearRect(0, 0, canvas.width, canvas.height);
    ctx.lineWidth = 0.5;
    ctx.strokeStyle = '#9aa7b8';
    ctx.fillStyle = '#e4ebf4';
    ctx.beginPath();
    for (let t = 0; t < tris.length / 3; t++) {
      const [a, b, c] = [pv(tris[3 * t]), pv(tris[3 * t + 1]), pv(tris[3 * t + 2])];
      ctx.moveTo(...a); ctx.lineTo(...b); ctx.lineTo(...c); ctx.closePath();
    }
    ctx.fill();
    ctx.stroke();
    // the boundary, coloured by |d| (the boundary error: blue on the target)
    if (!this.edgesOf || this.edgesOf.tris !== tris.length) this.edgesOf = { tris: tris.length, edges: boundary(tris, 3, [[0, 1], [1, 2], [2, 0]]) };
    const edges = this.edgesOf.edges;
    const ad = mesh.distance ? Float64Array.from(mesh.distance, Math.abs) : null;
    const m = ad ? maxOver(ad, edges) : 0;
    ctx.lineWidth = 3;
    ctx.lineCap = 'round';
    for (const [a, b] of edges) {
      ctx.strokeStyle = ad ? heatCss((ad[a] + ad[b]) / (2 * (m || 1))) : '#24364b';
      ctx.beginPath(); ctx.moveTo(...pv(a)); ctx.lineTo(...pv(b)); ctx.stroke();
    }
    // the target's zero level set, thin and dashed over everything
    if (target) {
      const sg = target.segments;
      ctx.lineWidth = 1.2;
      ctx.strokeStyle = '#111';
      ctx.setLineDash([5, 3]);
      ctx.beginPath();
      for (let i = 0; i < sg.length; i += 4) { ctx.moveTo(...px(sg[i], sg[i + 1])); ctx.lineTo(...px(sg[i + 2], sg[i + 3])); }
      ctx.stroke();
      ctx.setLineDash([]);
    }
    return ad ? { max: m, label: '|d| on the boundary' } : null;
  }

  // For the browser tests: the fraction of the shape's vertices (and the
  // target's points) drawn inside the canvas, and the drawing's extent.
  framing(mesh) {
    const pts = [];
    for (let v = 0; v < mesh.xyz.length / mesh.dim; v++) pts.push(this.project(mesh.xyz[v * mesh.dim], mesh.xyz[v * mesh.dim + 1]));
    const t = this.target && this.shown ? this.target.segments : [];
    for (let i = 0; i < t.length; i += 2) pts.push(this.project(t[i], t[i + 1]));
    const inside = pts.filter(([x, y]) => x >= 0 && y >= 0 && x <= this.canvas.width && y <= this.canvas.height).length;
    return { inside: inside / pts.length, points: pts.length };
  }
}

const VIEW_DIR = new THREE.Vector3(1.6, 1.2, 2.2).normalize();

export class View3d {
  constructor(el) {
    this.el = el;
    this.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
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
    // the user took the camera: no more framing at each draw until reset()
    this.controls.addEventListener('start', () => { this.autoFit = false; });
    this.autoFit = true;
    this.camera.position.copy(VIEW_DIR);
    this.mesh = null;
    this.targetMesh = null;
    this.first = null;
    this.resize();
    this.ro = new ResizeObserver(() => this.resize());
    this.ro.observe(el);
  }

  resize() {
    const size = Math.max(120, Math.round(this.el.clientWidth || 480));
    if (size === this.size) return;
    this.size = size;
    this.renderer.setSize(size, size, false);
    this.render();
  }

  // target: {positions: Float32Array (3 per vertex, 3 vertices per
  // triangle)}, drawn as a translucent surface when shown
  setTarget(target, shown = true) {
    if (this.target !== target) {
      this.target = target;
      if (this.targetMesh) { this.scene.remove(this.targetMesh); this.targetMesh.geometry.dispose(); }
      const geo = new THREE.BufferGeometry();
      geo.setAttribute('position', new THREE.BufferAttribute(target.positions, 3));
      geo.computeVertexNormals();
      this.targetMesh = new THREE.Mesh(geo, new THREE.MeshStandardMaterial({ color: 0x445566, transparent: true, opacity: 0.25,
        depthWrite: false, side: THREE.DoubleSide, polygonOffset: true, polygonOffsetFactor: 2, polygonOffsetUnits: 2 }));
      // drawn after the shape and pushed back a little: where the two meet
      // the shape wins (no flicker of coplanar faces)
      this.targetMesh.renderOrder = 1;
      this.scene.add(this.targetMesh);
    }
    this.targetMesh.visible = shown;
  }

  // Draws the mesh; returns the colour scale {max, label}.
  show(mesh) {
    if (!this.first) this.first = mesh;
    if (!this.faces || this.facesOf !== mesh.tets.length) {
      this.faces = boundary(mesh.tets, 4, [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]);
      this.facesOf = mesh.tets.length;
    }
    const faces = this.faces;
    const pos = new Float32Array(mesh.xyz);
    const col = new Float32Array(pos.length);
    const u = new Float64Array(pos.length / 3);
    const first = this.first;
    const same = first.xyz.length === mesh.xyz.length;
    for (let v = 0; v < u.length; v++)
      u[v] = mesh.distance ? Math.abs(mesh.distance[v])
        : same ? Math.hypot(mesh.xyz[3 * v] - first.xyz[3 * v], mesh.xyz[3 * v + 1] - first.xyz[3 * v + 1], mesh.xyz[3 * v + 2] - first.xyz[3 * v + 2]) : 0;
    const umax = maxOver(u, faces);
    const c = new THREE.Color();
    for (let v = 0; v < u.length; v++) {
      heatRgb(u[v] / (umax || 1), c);
      col.set([c.r, c.g, c.b], 3 * v);
    }
    const geo = new THREE.BufferGeometry();
    geo.setAttribute('position', new THREE.BufferAttribute(pos, 3));
    geo.setAttribute('color', new THREE.BufferAttribute(col, 3));
    geo.setIndex(faces.flat());
    geo.computeVertexNormals();
    if (this.mesh) { this.scene.remove(this.mesh); this.mesh.geometry.dispose(); }
    this.mesh = new THREE.Mesh(geo, new THREE.MeshStandardMaterial({ vertexColors: true, flatShading: true, side: THREE.DoubleSide }));
    this.scene.add(this.mesh);
    this.surfaceVerts = [...new Set(faces.flat())];
    this.xyz = mesh.xyz;
    if (this.autoFit) this.fit();
    this.render();
    return { max: umax, label: mesh.distance ? '|d| on the boundary' : 'displacement from the first shape shown' };
  }

  // The points framed: the shape's boundary and the target (shown).
  forPoints(fn) {
    for (const v of this.surfaceVerts || []) fn(this.xyz[3 * v], this.xyz[3 * v + 1], this.xyz[3 * v + 2]);
    if (this.targetMesh && this.targetMesh.visible) {
      const t = this.target.positions;
      for (let i = 0; i < t.length; i += 3) fn(t[i], t[i + 1], t[i + 2]);
    }
  }

  // The camera on the points' bounding sphere (centred on their box), from
  // its current direction: the whole sphere fits the field of view.
  fit() {
    const b = new THREE.Box3();
    const p = new THREE.Vector3();
    this.forPoints((x, y, z) => b.expandByPoint(p.set(x, y, z)));
    if (b.isEmpty()) return;
    const center = b.getCenter(new THREE.Vector3());
    let r2 = 0;
    this.forPoints((x, y, z) => { r2 = Math.max(r2, center.distanceToSquared(p.set(x, y, z))); });
    const r = Math.max(Math.sqrt(r2), 1e-12);
    const dist = (1.04 * r) / Math.sin(THREE.MathUtils.degToRad(this.camera.fov / 2));
    const dir = this.camera.position.clone().sub(this.controls.target);
    if (dir.lengthSq() === 0) dir.copy(VIEW_DIR);
    this.camera.position.copy(center).addScaledVector(dir.normalize(), dist);
    this.camera.near = dist / 100;
    this.camera.far = dist * 10;
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(center);
    this.controls.update();
  }

  // Back to the first direction, framing the shape and the target again
  // at each draw.
  reset() {
    this.autoFit = true;
    this.camera.position.copy(this.controls.target).add(VIEW_DIR);
    this.fit();
    this.render();
  }

  // For the browser tests: the fraction of the boundary vertices (and the
  // target's) inside the view, and the largest |NDC| coordinate.
  framing() {
    const p = new THREE.Vector3();
    let inside = 0, n = 0, extent = 0;
    this.forPoints((x, y, z) => {
      p.set(x, y, z).project(this.camera);
      n++;
      extent = Math.max(extent, Math.abs(p.x), Math.abs(p.y));
      if (Math.abs(p.x) <= 1 && Math.abs(p.y) <= 1) inside++;
    });
    return { inside: inside / n, extent, points: n };
  }

  render() { this.renderer.render(this.scene, this.camera); }

  dispose() {
    this.ro.disconnect();
    this.controls.dispose();
    this.renderer.dispose();
    this.renderer.forceContextLoss();
  }
}
