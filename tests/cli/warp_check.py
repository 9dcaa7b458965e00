#!/usr/bin/env python3
"""Cases and independent checks of tests/cli/warp.sh (plain Python, no
numpy): result folders made from a template under a known map (affine,
or a smooth bend), random points, and the expected answers computed here
by brute force (every element tried, barycentric coordinates solved by
Cramer's rule), never by shapematch.

  warp_check.py make TEMPLATE DIR affine|bend
  warp_check.py points TEMPLATE OUT.csv N SEED
  warp_check.py forward TEMPLATE KIND IN.csv OUT.csv [R]
                 (R: the template is the disk or ball of radius R about
                 (0.5, ...) and KIND affine: inside flags by the radius,
                 up to the facets' chord error)
  warp_check.py roundtrip IN.csv BACK.csv TEMPLATE
  warp_check.py mesh TEMPLATE KIND IN OUT          (vertices of IN mapped)
  warp_check.py field TEMPLATE OUT.sol normalize   (vector (1, 2[, 3]) -> A v)
  warp_check.py surface TEMPLATE OUT.obj OUT.stl   (the template's boundary)
  warp_check.py surfcheck IN OUT TOL [KIND]        (OBJ/STL vertices mapped)
  warp_check.py vtu TEMPLATE KIND IN OUT.vtu
Exit 0 when the check holds, 1 with the first difference printed."""
import math
import os
import random
import struct
import sys

A = [[1.2, 0.3, -0.1], [-0.2, 0.9, 0.25], [0.05, -0.15, 1.1]]
B = [0.5, -1.0, 2.0]


def read_medit(path):
    toks = open(path).read().split()
    dim = int(toks[toks.index("Dimension") + 1])
    i = toks.index("Vertices")
    n = int(toks[i + 1])
    vs, p = [], i + 2
    for _ in range(n):
        vs.append([float(t) for t in toks[p:p + dim]])
        p += dim + 1
    kw = "Tetrahedra" if dim == 3 and "Tetrahedra" in toks else "Triangles"
    j = toks.index(kw)
    m, k = int(toks[j + 1]), (4 if kw == "Tetrahedra" else 3)
    es, p = [], j + 2
    for _ in range(m):
        es.append([int(t) - 1 for t in toks[p:p + k]])
        p += k + 1
    return dim, vs, es, toks


def mapping(kind, dim):
    def affine(x):
        return [B[i] + sum(A[i][k] * x[k] for k in range(dim)) for i in range(dim)]

    def bend(x):
        t = 2 * math.pi
        y = [x[0] + 0.05 * math.sin(t * x[1]), x[1] + 0.05 * math.sin(t * x[0])]
        if dim == 3:
            y[0] += 0.03 * x[2] * x[2]
            y.append(x[2] + 0.04 * math.sin(t * (x[0] + x[1]) / 2))
        return y
    return {"affine": affine, "bend": bend, "identity": lambda x: x}[kind]


def det(m):
    if len(m) == 2:
        return m[0][0] * m[1][1] - m[0][1] * m[1][0]
    return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))


def bary(vs, e, x):
    dim = len(x)
    cols = [[vs[e[k + 1]][i] - vs[e[0]][i] for i in range(dim)] for k in range(dim)]
    J = [[cols[k][i] for k in range(dim)] for i in range(dim)]
    d = det(J)
    r = [x[i] - vs[e[0]][i] for i in range(dim)]
    lam = []
    for k in range(dim):
        Jk = [row[:] for row in J]
        for i in range(dim):
            Jk[i][k] = r[i]
        lam.append(det(Jk) / d)
    return [1 - sum(lam)] + lam


def locate(vs, es, x):
    for e in es:
        lam = bary(vs, e, x)
        if min(lam) >= -1e-9:
            return e, lam
    return None, None


def read_csv(path):
    rows = [l.strip() for l in open(path) if l.strip()]
    out = []
    for r in rows:
        try:
            out.append([float(t) for t in r.split(",")])
        except ValueError:
            continue  # the header
    return out


def fail(msg):
    print(msg)
    sys.exit(1)


def cmd_make(template, outdir, kind):
    dim, vs, es, toks = read_medit(template)
    f = mapping(kind, dim)
    ys = [f(v) for v in vs]
    lines = open(template).read().split("\n")
    out, i = [], 0
    while i < len(lines):
        out.append(lines[i])
        if lines[i].strip() == "Vertices":
            out.append(lines[i + 1])
            n = int(lines[i + 1])
            for k in range(n):
                ref = lines[i + 2 + k].split()[-1]
                out.append(" ".join("%.17g" % c for c in ys[k]) + " " + ref)
            i += 2 + n
            continue
        i += 1
    open(outdir + "/result.mesh", "w").write("\n".join(out))
    with open(outdir + "/displacement.sol", "w") as s:
        s.write("MeshVersionFormatted 2\nDimension %d\nSolAtVertices\n%d\n1 2\n" % (dim, len(vs)))
        for v, y in zip(vs, ys):
            s.write(" ".join("%.17g" % (y[i] - v[i]) for i in range(dim)) + "\n")
        s.write("End\n")


def cmd_points(template, out, n, seed):
    dim, vs, es, _ = read_medit(template)
    lo = [min(v[i] for v in vs) for i in range(dim)]
    hi = [max(v[i] for v in vs) for i in range(dim)]
    rnd = random.Random(int(seed))
    with open(out, "w") as f:
        f.write("x,y,z\n" if dim == 3 else "x,y\n")
        for _ in range(int(n)):
            p = [lo[i] - 0.1 * (hi[i] - lo[i]) + rnd.random() * 1.2 * (hi[i] - lo[i])
                 for i in range(dim)]
            f.write(",".join("%.17g" % c for c in p) + "\n")
        # a vertex of the template and the middle of an element's facet
        f.write(",".join("%.17g" % c for c in vs[7]) + "\n")
        e = es[len(es) // 2]
        f.write(",".join("%.17g" % (sum(vs[e[k]][i] for k in range(dim)) / dim)
                         for i in range(dim)) + "\n")


def cmd_forward(template, kind, inp, outp, radius=None):
    dim, vs, es, _ = read_medit(template)
    if radius is not None:  # an affine map of a disk or ball: no location needed
        es = []
    f = mapping(kind, dim)
    ys = [f(v) for v in vs]
    xs, got = read_csv(inp), read_csv(outp)
    if len(xs) != len(got):
        fail("%d points in, %d out" % (len(xs), len(got)))
    diam = math.dist([min(v[i] for v in vs) for i in range(dim)],
                     [max(v[i] for v in vs) for i in range(dim)])
    for n, (x, g) in enumerate(zip(xs, got)):
        if len(g) != dim + 1:
            fail("line %d: %d columns" % (n + 2, len(g)))
        if radius is not None:
            r = math.dist(x, [0.5] * dim)
            flag = 1 if r < 0.996 * float(radius) else 0 if r > 1.0001 * float(radius) else g[dim]
            if g[dim] != flag:
                fail("point %d %s at radius %g flagged %g" % (n + 1, x, r, g[dim]))
            if math.dist(g[:dim], mapping(kind, dim)(x)) > 1e-12 * diam:
                fail("point %d: %s, expected %s" % (n + 1, g[:dim], mapping(kind, dim)(x)))
            continue
        e, lam = locate(vs, es, x)
        if e is None:
            if g[dim] != 0:
                fail("point %d %s is outside, flagged %g" % (n + 1, x, g[dim]))
            if kind == "affine" and math.dist(g[:dim], f(x)) > 1e-12 * diam:
                fail("point %d outside: %s, expected %s" % (n + 1, g[:dim], f(x)))
            continue
        # on the boundary within 1e-9: either flag is honest
        if g[dim] != 1 and min(lam) > 1e-9:
            fail("point %d %s is inside, flagged %g" % (n + 1, x, g[dim]))
        want = [sum(lam[k] * ys[e[k]][i] for k in range(dim + 1)) for i in range(dim)]
        if math.dist(g[:dim], want) > 1e-12 * diam:
            fail("point %d: %s, expected %s" % (n + 1, g[:dim], want))
    print("%d points checked" % len(xs))


def cmd_roundtrip(inp, back, template):
    dim, vs, es, _ = read_medit(template)
    diam = math.dist([min(v[i] for v in vs) for i in range(dim)],
                     [max(v[i] for v in vs) for i in range(dim)])
    xs, got = read_csv(inp), read_csv(back)
    worst = 0
    for n, (x, g) in enumerate(zip(xs, got)):
        worst = max(worst, math.dist(x[:dim], g[:dim]))
    if len(xs) != len(got) or worst > 1e-9 * diam:
        fail("inverse(forward(x)) differs from x by %g (diameter %g)" % (worst, diam))
    print("max |inverse(forward(x)) - x| = %.3g, diameter %.3g" % (worst, diam))


def cmd_mesh(template, kind, inp, outp):
    dim = read_medit(template)[0]
    f = mapping(kind, dim)
    _, vin, ein, _ = read_medit(inp)
    _, vout, eout, _ = read_medit(outp)
    if ein != eout or len(vin) != len(vout):
        fail("topology changed")
    for n, (x, y) in enumerate(zip(vin, vout)):
        if math.dist(f(x), y) > 1e-12:
            fail("vertex %d: %s, expected %s" % (n + 1, y, f(x)))
    print("%d vertices checked" % len(vin))


def cmd_field(template, outp, normalize):
    dim = read_medit(template)[0]
    toks = open(outp).read().split()
    i = toks.index("SolAtVertices")
    n = int(toks[i + 1])
    vals = [float(t) for t in toks[i + 4:i + 4 + n * dim]]
    v = [1.0, 2.0, 3.0][:dim]
    want = [sum(A[r][k] * v[k] for k in range(dim)) for r in range(dim)]
    if normalize == "1":
        ln = math.sqrt(sum(w * w for w in want))
        want = [w / ln for w in want]
    for p in range(n):
        got = vals[p * dim:(p + 1) * dim]
        if math.dist(got, want) > 1e-12:
            fail("vertex %d: %s, expected %s" % (p + 1, got, want))
    print("%d vectors checked" % n)


def cmd_surface(template, obj, stl):
    dim, vs, es, toks = read_medit(template)
    j = toks.index("Triangles")
    m = int(toks[j + 1])
    tris = [[int(t) - 1 for t in toks[j + 2 + 4 * k:j + 5 + 4 * k]] for k in range(m)]
    tris = [t for k, t in enumerate(tris) if toks[j + 5 + 4 * k] == "1"]  # the outer sphere
    used = sorted({k for t in tris for k in t})
    num = {k: i + 1 for i, k in enumerate(used)}
    with open(obj, "w") as f:
        for k in used:
            f.write("v %.17g %.17g %.17g\n" % tuple(vs[k]))
        for t in tris:
            f.write("f %d %d %d\n" % (num[t[0]], num[t[1]], num[t[2]]))
    with open(stl, "wb") as f:
        f.write(b"\0" * 80 + struct.pack("<I", len(tris)))
        for t in tris:
            f.write(struct.pack("<3f", 0, 0, 0))
            for k in t:
                f.write(struct.pack("<3f", *vs[k]))
            f.write(b"\0\0")


def read_surface_vertices(path):
    data = open(path, "rb").read()
    if path.endswith(".stl"):
        n = struct.unpack("<I", data[80:84])[0]
        pts = []
        for k in range(n):
            rec = struct.unpack("<12f", data[84 + 50 * k:84 + 50 * k + 48])
            pts += [list(rec[3 + 3 * i:6 + 3 * i]) for i in range(3)]
        return pts
    if path.endswith(".vtu"):
        return read_vtu_points(path)
    text = data.decode()
    if path.endswith((".ply", ".off", ".vtk")):
        # ASCII PLY (after end_header), OFF (after the counts line), VTK
        # legacy (after POINTS n double): n lines of x y z, read here
        # independently of the C readers
        lines = text.splitlines()
        if path.endswith(".ply"):
            n = int(next(l for l in lines if l.startswith("element vertex")).split()[2])
            at = lines.index("end_header") + 1
        elif path.endswith(".off"):
            n, at = int(lines[1].split()[0]), 2
        else:
            at = next(i for i, l in enumerate(lines) if l.startswith("POINTS"))
            n, at = int(lines[at].split()[1]), at + 1
        return [[float(t) for t in l.split()[:3]] for l in lines[at:at + n]]
    return [[float(t) for t in l.split()[1:4]] for l in text.splitlines()
            if l.startswith("v ")]


def cmd_surfcheck(inp, outp, tol, kind="affine"):
    f = mapping(kind, 3)
    # every expected vertex has an output vertex within tol (a grid of
    # cells far larger than tol, each point looked up in its 27 cells)
    a = [f(x) for x in read_surface_vertices(inp)]
    b = read_surface_vertices(outp)
    if len(a) != len(b):
        fail("%d vertices in, %d out" % (len(a), len(b)))
    cell = 1e-3
    grid = {}
    for y in b:
        grid.setdefault(tuple(int(math.floor(c / cell)) for c in y), []).append(y)
    for n, fx in enumerate(a):
        k = [int(math.floor(c / cell)) for c in fx]
        near = [y for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1)
                for y in grid.get((k[0] + dx, k[1] + dy, k[2] + dz), [])]
        if not near or min(math.dist(fx, y) for y in near) > float(tol):
            fail("vertex %d: no output vertex within %s of %s" % (n + 1, tol, fx))
    print("%d surface vertices checked" % len(a))


def read_vtu_points(path):
    """The points of a .vtu, ASCII or binary (tests/lib/vtu.py)."""
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
    import vtu
    vals = vtu.read(path)[1]["Points"]
    return [vals[k:k + 3] for k in range(0, len(vals), 3)]


def cmd_vtu(template, kind, inp, outp):
    dim = read_medit(template)[0]
    f = mapping(kind, dim)
    vin = read_medit(inp)[1]
    vout = read_vtu_points(outp)
    if len(vin) != len(vout):
        fail("%d vertices in, %d out" % (len(vin), len(vout)))
    for n, (x, y) in enumerate(zip(vin, vout)):
        if math.dist(f(x), y[:dim]) > 1e-12:
            fail("vertex %d: %s, expected %s" % (n + 1, y, f(x)))
    print("%d vtu points checked" % len(vin))


# Symmetric tensors in Medit's order (the lower triangle row by row):
# (i, j) -> index, 2D xx xy yy, 3D xx xy yy xz yz zz.
TENSOR_INDEX = {2: [[0, 1], [1, 2]], 3: [[0, 1, 3], [1, 2, 4], [3, 4, 5]]}


def vertex_tensor(x, dim):
    """A symmetric tensor that varies from vertex to vertex, with distinct
    off-diagonal entries (a swapped order would show)."""
    t = [[0.0] * dim for _ in range(dim)]
    for i in range(dim):
        for j in range(i, dim):
            t[i][j] = t[j][i] = (i + 1) * 0.7 + (j + 2) * x[j % dim] - 0.3 * (i == j) * x[i]
    return t


def cmd_tensor_make(template, out):
    dim, verts = read_medit(template)[:2]
    idx = TENSOR_INDEX[dim]
    lines = []
    for x in verts:
        t = vertex_tensor(x, dim)
        comps = [0.0] * (dim * (dim + 1) // 2)
        for i in range(dim):
            for j in range(i + 1):
                comps[idx[i][j]] = t[i][j]
        lines.append(" ".join("%.17g" % c for c in comps))
    open(out, "w").write("MeshVersionFormatted 2\nDimension %d\nSolAtVertices\n%d\n1 3\n%s\nEnd\n"
                         % (dim, len(verts), "\n".join(lines)))


def cmd_tensor_check(template, outp, kind):
    """outp holds A T Aᵀ (kind "affine") or T itself ("identity") at each
    template vertex, T = vertex_tensor(template vertex), A the affine map's
    matrix: the analytic F T Fᵀ of an affine map, whose gradient is A in
    every element."""
    dim, verts = read_medit(template)[:2]
    idx = TENSOR_INDEX[dim]
    nc = dim * (dim + 1) // 2
    toks = open(outp).read().split()
    i = toks.index("SolAtVertices")
    n = int(toks[i + 1])
    if n != len(verts) or toks[i + 2:i + 4] != ["1", "3"]:
        fail("expected %d vertices of type 3, found %s" % (len(verts), toks[i + 1:i + 4]))
    vals = [float(t) for t in toks[i + 4:i + 4 + n * nc]]
    a = [row[:dim] for row in A[:dim]]
    worst = 0.0
    for p, x in enumerate(verts):
        t = vertex_tensor(x, dim)
        if kind == "affine":
            at = [[sum(a[r][k] * t[k][c] for k in range(dim)) for c in range(dim)]
                  for r in range(dim)]
            t = [[sum(at[r][k] * a[c][k] for k in range(dim)) for c in range(dim)]
                 for r in range(dim)]
        scale = max(abs(v) for row in t for v in row)
        for r in range(dim):
            for c in range(r + 1):
                err = abs(vals[p * nc + idx[r][c]] - t[r][c]) / scale
                worst = max(worst, err)
                if err > 1e-12:
                    fail("vertex %d (%d,%d): %r, expected %r" % (p + 1, r, c,
                                                                  vals[p * nc + idx[r][c]],
                                                                  t[r][c]))
    print("%d tensors checked, worst relative error %.2g" % (n, worst))


if __name__ == "__main__":
    cmds = {"make": cmd_make, "points": cmd_points, "forward": cmd_forward,
            "roundtrip": cmd_roundtrip, "mesh": cmd_mesh, "field": cmd_field,
            "surface": cmd_surface, "surfcheck": cmd_surfcheck, "vtu": cmd_vtu,
            "tensor_make": cmd_tensor_make, "tensor_check": cmd_tensor_check}
    cmds[sys.argv[1]](*sys.argv[2:])
