#!/usr/bin/env python3
"""Independent figures for tests/cli/template_mesh.sh (numpy, nibabel).

  template_mesh_check.py volume SURFACE.stl|CURVE.mesh
      the volume a closed STL encloses (area for a Medit curve), by the
      divergence theorem: sum over facets of det(a, b, c) / 6 (2D: the
      shoelace sum of cross(a, b) / 2)
  template_mesh_check.py mesh TEMPLATE.mesh
      a Medit volume mesh: "dim vertices elements volume inverted
      min_quality", the quality computed here as the core documents it
      (2D 4 sqrt(3) A / sum l^2, 3D 12 (3 V)^(2/3) / sum l^2)
  template_mesh_check.py star OUT.mesh SCALE DX DY
      a closed non-convex 2D curve (r = 1 + 0.3 cos 5t, 240 segments,
      counter-clockwise) scaled by SCALE along x and moved by (DX, DY),
      as Medit Edges
  template_mesh_check.py label OUT.nii.gz [SHIFT]
      a label map (NIfTI, 1.5 mm voxels): label 3 a dumbbell (two balls
      joined by a bar: non-convex), label 1 a separate block; SHIFT (mm)
      moves it along x and grows its second ball by SHIFT / 3
  template_mesh_check.py voxels IMAGE LABEL
      the volume of the label's voxels (count times the voxel volume)
  template_mesh_check.py broken KIND OUT.stl
      malformed closed-surface cases built from an octahedron: open (one
      face dropped), nonmanifold (a fin on one edge), selfintersect (two
      octahedra crossing each other, each closed), flat (every vertex in
      one plane: zero volume)
"""
import math
import struct
import sys

import numpy as np


def read_stl(path):
    data = open(path, 'rb').read()
    if data[:5] == b'solid' and b'facet' in data[:400]:
        tris = []
        for line in data.decode().splitlines():
            w = line.split()
            if w and w[0] == 'vertex':
                tris.append([float(x) for x in w[1:4]])
        return np.array(tris).reshape(-1, 3, 3)
    n = struct.unpack('<I', data[80:84])[0]
    rec = np.frombuffer(data[84:84 + 50 * n], dtype=np.dtype([('n', '<f4', 3), ('v', '<f4', (3, 3)), ('a', '<u2')]))
    return rec['v'].astype(float)


def read_medit(path):
    words = open(path).read().split()
    i, out = 0, {}
    while i < len(words):
        k = words[i]
        if k == 'Dimension':
            out['dim'] = int(words[i + 1])
            i += 2
        elif k in ('Vertices', 'Edges', 'Triangles', 'Tetrahedra'):
            n = int(words[i + 1])
            width = {'Vertices': out['dim'] + 1, 'Edges': 3, 'Triangles': 4, 'Tetrahedra': 5}[k]
            a = np.array(words[i + 2:i + 2 + n * width], dtype=float).reshape(n, width)
            out[k] = a
            i += 2 + n * width
        else:
            i += 1
    return out


def volume(path):
    if path.endswith('.stl'):
        t = read_stl(path)
        return float(np.sum(np.einsum('ij,ij->i', t[:, 0], np.cross(t[:, 1], t[:, 2]))) / 6.0)
    m = read_medit(path)
    p = m['Vertices'][:, :2]
    e = m['Edges'][:, :2].astype(int) - 1
    a, b = p[e[:, 0]], p[e[:, 1]]
    return float(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]) / 2.0)


def mesh(path):
    m = read_medit(path)
    d = m['dim']
    p = m['Vertices'][:, :d]
    if d == 3:
        t = m['Tetrahedra'][:, :4].astype(int) - 1
        a, b, c, e = (p[t[:, k]] for k in range(4))
        v = np.einsum('ij,ij->i', b - a, np.cross(c - a, e - a)) / 6.0
        pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
        l2 = sum(np.sum((p[t[:, i]] - p[t[:, j]]) ** 2, axis=1) for i, j in pairs)
        q = 12.0 * np.cbrt(3.0 * np.abs(v)) ** 2 / l2 * np.sign(v)
    else:
        t = m['Triangles'][:, :3].astype(int) - 1
        a, b, c = (p[t[:, k]] for k in range(3))
        u, w = b - a, c - a
        v = (u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0]) / 2.0
        l2 = np.sum(u ** 2, 1) + np.sum(w ** 2, 1) + np.sum((c - b) ** 2, 1)
        q = 4.0 * math.sqrt(3.0) * v / l2
    print(d, len(p), len(t), float(np.sum(v)), int(np.sum(v <= 0)), float(np.min(q)))


def star(out, scale, dx, dy):
    n = 240
    pts = []
    for i in range(n):
        t = 2 * math.pi * i / n
        r = 1 + 0.3 * math.cos(5 * t)
        pts.append((scale * r * math.cos(t) + dx, r * math.sin(t) + dy))
    with open(out, 'w') as f:
        f.write('MeshVersionFormatted 2\nDimension 2\nVertices\n%d\n' % n)
        for x, y in pts:
            f.write('%.17g %.17g 0\n' % (x, y))
        f.write('Edges\n%d\n' % n)
        for i in range(n):
            f.write('%d %d 1\n' % (i + 1, (i + 1) % n + 1))
        f.write('End\n')


def label(out, shift=0.0):
    import nibabel as nib
    h = 1.5
    n = (48, 28, 28)
    idx = np.indices(n).astype(float)
    x, y, z = (idx[k] * h - n[k] * h / 2 for k in range(3))
    lab = np.zeros(n, dtype=np.int16)
    # moved by shift along x, its second ball grown by shift / 3
    x = x - shift
    ball1 = (x + 14) ** 2 + y ** 2 + z ** 2 <= 10 ** 2
    ball2 = (x - 16) ** 2 + y ** 2 + z ** 2 <= (8 + shift / 3) ** 2
    bar = (np.abs(x) <= 16) & (y ** 2 + z ** 2 <= 4 ** 2)
    lab[ball1 | ball2 | bar] = 3
    lab[(x > 28) & (np.abs(y) < 6) & (np.abs(z) < 6)] = 1
    aff = np.diag([h, h, h, 1.0])
    aff[:3, 3] = [-n[0] * h / 2, -n[1] * h / 2, -n[2] * h / 2]
    nib.save(nib.Nifti1Image(lab, aff), out)


OCTA_V = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
OCTA_F = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]


def write_stl(out, tris):
    with open(out, 'w') as f:
        f.write('solid broken\n')
        for t in tris:
            f.write(' facet normal 0 0 0\n  outer loop\n')
            for p in t:
                f.write('   vertex %.17g %.17g %.17g\n' % tuple(p))
            f.write('  endloop\n endfacet\n')
        f.write('endsolid broken\n')


def octa(shift=(0, 0, 0), scale=1.0):
    return [[tuple(scale * OCTA_V[i][k] + shift[k] for k in range(3)) for i in f] for f in OCTA_F]


def broken(kind, out):
    t = octa()
    if kind == 'open':
        t = t[1:]
    elif kind == 'nonmanifold':
        t.append([(1, 0, 0), (0, 1, 0), (1, 1, 1)])
    elif kind == 'selfintersect':
        t = t + octa((0.5, 0.2, 0.1))
    write_stl(out, t)


if __name__ == '__main__':
    cmd = sys.argv[1]
    if cmd == 'volume':
        print(volume(sys.argv[2]))
    elif cmd == 'mesh':
        mesh(sys.argv[2])
    elif cmd == 'star':
        star(sys.argv[2], float(sys.argv[3]), float(sys.argv[4]), float(sys.argv[5]))
    elif cmd == 'label':
        label(sys.argv[2], float(sys.argv[3]) if len(sys.argv) > 3 else 0.0)
    elif cmd == 'voxels':
        import nibabel as nib
        im = nib.load(sys.argv[2])
        n = int(np.sum(np.asarray(im.dataobj) == int(sys.argv[3])))
        print(n * abs(float(np.linalg.det(im.affine[:3, :3]))))
    elif cmd == 'broken':
        broken(sys.argv[2], sys.argv[3])
    else:
        sys.exit('unknown command ' + cmd)
