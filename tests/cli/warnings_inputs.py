import math, sys
def box(path, solpath, x0, x1, y0, y1, n, d):
    vs = []
    for j in range(n + 1):
        for i in range(n + 1):
            vs.append((x0 + (x1 - x0) * i / n, y0 + (y1 - y0) * j / n))
    tris = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i + 1; b = a + 1; c = a + n + 1; e = c + 1
            tris += [(a, b, e), (a, e, c)]
    with open(path, "w") as f:
        f.write("MeshVersionFormatted 2\nDimension 2\nVertices\n%d\n" % len(vs))
        f.writelines("%.17g %.17g 0\n" % v for v in vs)
        f.write("Triangles\n%d\n" % len(tris))
        f.writelines("%d %d %d 1\n" % t for t in tris)
        f.write("End\n")
    with open(solpath, "w") as f:
        f.write("MeshVersionFormatted 2\nDimension 2\nSolAtVertices\n%d\n1 1\n" % len(vs))
        f.writelines("%.17g\n" % d(v) for v in vs)
        f.write("End\n")
circle = lambda v: math.hypot(v[0] - 0.5, v[1] - 0.5) - 0.3
out = sys.argv[1]
box(out + "/part.mesh", out + "/part.sol", 0.0, 0.6, 0.0, 1.0, 120, circle)
box(out + "/full.mesh", out + "/inverted.sol", 0.0, 1.0, 0.0, 1.0, 150, lambda v: -circle(v))
box(out + "/full2.mesh", out + "/elsewhere.sol", 0.0, 1.0, 0.0, 1.0, 150,
    lambda v: math.hypot(v[0] - 0.12, v[1] - 0.12) - 0.08)
# a far field of the right sign around a small inverted blob: negative at
# the background's hull, positive only near the centre of the template
box(out + "/full3.mesh", out + "/inverted_small.sol", 0.0, 1.0, 0.0, 1.0, 150,
    lambda v: -(math.hypot(v[0] - 0.5, v[1] - 0.5) - 0.1))
# the 2D example's target drawn 1000 times larger (a unit apart)
box(out + "/big.mesh", out + "/big.sol", 0.0, 1000.0, 0.0, 1000.0, 150,
    lambda v: math.hypot(v[0] - 500, v[1] - 500) - 300)
# overlapping the template, but not at its clamp ball (0.7, 0.5)
box(out + "/full4.mesh", out + "/left.sol", 0.0, 1.0, 0.0, 1.0, 150,
    lambda v: math.hypot(v[0] - 0.3, v[1] - 0.5) - 0.2)


def polygons(path, loops):
    """A 2D Medit surface (Edges) of closed polygons, each (cx, cy, r, n,
    skip): n edges on the circle, the last `skip` of them left out."""
    verts, edges = [], []
    for cx, cy, r, n, skip in loops:
        base = len(verts)
        verts += [(cx + r * math.cos(2 * math.pi * k / n), cy + r * math.sin(2 * math.pi * k / n))
                  for k in range(n)]
        edges += [(base + k + 1, base + (k + 1) % n + 1) for k in range(n - skip)]
    with open(path, "w") as f:
        f.write("MeshVersionFormatted 2\nDimension 2\nVertices\n%d\n" % len(verts))
        f.writelines("%.17g %.17g 0\n" % v for v in verts)
        f.write("Edges\n%d\n" % len(edges))
        f.writelines("%d %d 1\n" % e for e in edges)
        f.write("End\n")


polygons(out + "/holed.mesh", [(0.5, 0.5, 0.3, 96, 12)])
polygons(out + "/two.mesh", [(0.5, 0.5, 0.3, 96, 0), (0.5, 0.5, 0.05, 24, 0), (0.9, 0.9, 0.05, 24, 0)])
