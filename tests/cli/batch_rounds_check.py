"""Inputs and independent checks for tests/cli/batch_rounds.sh (numpy).

  batch_rounds_check.py square OUT.mesh CX CY SIDE N
      a square of side SIDE centred at (CX, CY), N x N cells each cut into
      two triangles (diagonals alternating), as a 2D Medit mesh: a
      template other than the example's disc
  batch_rounds_check.py rms A.mesh B.mesh
      prints the two-sided RMS distance between the boundaries of two 2D
      triangle meshes, brute force: every boundary vertex of each to every
      boundary segment of the other (the boundary: the edges of one
      triangle only), the root of the mean of the squares over the
      vertices of both; then that over B's bounding-box diagonal
  batch_rounds_check.py moved TEMPLATE.mesh MEAN.mesh
      the movement of a mean as the batch defines it: MEAN moved onto
      TEMPLATE (the same mesh) by the least-squares rigid motion over the
      corresponding vertices (Kabsch, numpy SVD), then `rms` between
      TEMPLATE and the moved MEAN, over the moved MEAN's bounding-box
      diagonal; prints that ratio
  batch_rounds_check.py medoid ROUND_DIR NAME...
      each target's sum over the others of the two-sided RMS distance
      between the matched shapes (ROUND_DIR/targets/NAME/result.mesh),
      the other first moved onto it by Kabsch over all the vertices, as
      JSON {name: sum}
  batch_rounds_check.py inverted MESH
      prints how many triangles of a 2D mesh have a signed area <= 0, in
      the order of their vertices in the file
Exits 1 on a malformed input."""
import json
import sys

import numpy as np


def read_mesh(path):
    """(vertices n x 2, triangles m x 3, 0-based) of a 2D ASCII Medit mesh."""
    tok = open(path).read().split()
    v = t = None
    i = 0
    while i < len(tok):
        if tok[i] == "Vertices":
            n = int(tok[i + 1])
            v = np.array(tok[i + 2:i + 2 + 3 * n], dtype=float).reshape(n, 3)[:, :2]
            i += 2 + 3 * n
        elif tok[i] == "Triangles":
            n = int(tok[i + 1])
            t = np.array(tok[i + 2:i + 2 + 4 * n], dtype=int).reshape(n, 4)[:, :3] - 1
            i += 2 + 4 * n
        else:
            i += 1
    if v is None or t is None:
        raise SystemExit(path + ": no Vertices or Triangles")
    return v, t


def boundary(t):
    """The edges that belong to one triangle only (k x 2)."""
    e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    u, count = np.unique(e, axis=0, return_counts=True)
    return u[count == 1]


def point_segments(p, a, b):
    """Distance of every point p (n x 2) to its nearest segment [a, b] (m)."""
    ab = b - a
    ap = p[:, None, :] - a[None, :, :]
    s = np.clip((ap * ab[None]).sum(2) / np.maximum((ab * ab).sum(1), 1e-300)[None], 0, 1)
    d = ap - s[:, :, None] * ab[None]
    return np.sqrt((d * d).sum(2)).min(1)


def two_sided(va, ta, vb, tb):
    ea, eb = boundary(ta), boundary(tb)
    da = point_segments(va[np.unique(ea)], vb[eb[:, 0]], vb[eb[:, 1]])
    db = point_segments(vb[np.unique(eb)], va[ea[:, 0]], va[ea[:, 1]])
    return np.sqrt((np.sum(da ** 2) + np.sum(db ** 2)) / (len(da) + len(db)))


def rms(pa, pb):
    va, ta = read_mesh(pa)
    vb, tb = read_mesh(pb)
    r = two_sided(va, ta, vb, tb)
    diag = np.linalg.norm(vb.max(0) - vb.min(0))
    print("%.17g %.17g" % (r, r / diag))


def kabsch(vm, vt):
    """vm moved onto vt (corresponding rows) by the least-squares rigid motion."""
    ct, cm = vt.mean(0), vm.mean(0)
    u, _, wt = np.linalg.svd((vm - cm).T @ (vt - ct))
    d = np.sign(np.linalg.det(u @ wt))
    return (vm - cm) @ (u @ np.diag([1, d]) @ wt) + ct


def moved(pt, pm):
    vt, tt = read_mesh(pt)
    vm, tm = read_mesh(pm)
    placed = kabsch(vm, vt)
    diag = np.linalg.norm(placed.max(0) - placed.min(0))
    print("%.17g" % (two_sided(vt, tt, placed, tm) / diag))


def medoid(d, names):
    shapes = [read_mesh("%s/targets/%s/result.mesh" % (d, n)) for n in names]
    sums = dict.fromkeys(names, 0.0)
    for i, (vi, ti) in enumerate(shapes):
        for j in range(i + 1, len(shapes)):
            vj, tj = shapes[j]
            r = two_sided(vi, ti, kabsch(vj, vi), tj)
            sums[names[i]] += r
            sums[names[j]] += r
    print(json.dumps(sums))


def square(out, cx, cy, side, n):
    x = np.linspace(cx - side / 2, cx + side / 2, n + 1)
    y = np.linspace(cy - side / 2, cy + side / 2, n + 1)
    tris = []
    for j in range(n):
        for i in range(n):
            a, b = j * (n + 1) + i, j * (n + 1) + i + 1
            c, d = a + n + 1, b + n + 1
            tris += [(a, b, d), (a, d, c)] if (i + j) % 2 == 0 else [(a, b, c), (b, d, c)]
    with open(out, "w") as f:
        f.write("MeshVersionFormatted 2\nDimension 2\nVertices\n%d\n" % ((n + 1) ** 2))
        for yy in y:
            for xx in x:
                f.write("%.17g %.17g 0\n" % (xx, yy))
        f.write("Triangles\n%d\n" % len(tris))
        f.writelines("%d %d %d 1\n" % (a + 1, b + 1, c + 1) for a, b, c in tris)
        f.write("End\n")


if __name__ == "__main__":
    if sys.argv[1] == "square":
        square(sys.argv[2], float(sys.argv[3]), float(sys.argv[4]), float(sys.argv[5]),
               int(sys.argv[6]))
    elif sys.argv[1] == "inverted":
        v, t = read_mesh(sys.argv[2])
        a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
        area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
        print(int(np.sum(area <= 0)))
    elif sys.argv[1] == "moved":
        moved(sys.argv[2], sys.argv[3])
    elif sys.argv[1] == "medoid":
        medoid(sys.argv[2], sys.argv[3:])
    elif sys.argv[1] == "rms":
        rms(sys.argv[2], sys.argv[3])
    else:
        raise SystemExit("usage: batch_rounds_check.py square|rms|moved|medoid|inverted ...")
